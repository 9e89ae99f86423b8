//! Is a blurred dark disc a ring marker? Its radial profile, measured and compared.
//!
//! [`fit_marker`] casts [`RAYS`] rays from a candidate's centre and samples the grey levels
//! along them at sub-pixel positions (bilinear). It then alternates: the design that best
//! explains the rays' mean profile ([`crate::ring_model::fit_profile`]: every design at every
//! blur), each ray's own length for that design (a tilted camera sees the marker as an
//! ellipse), and an ellipse through the rays' ends, which a few rays that met something else
//! (an object's edge, a stripe) may miss; the ellipse gives the next centre and the rays'
//! next lengths. Once settled, every design and every shape that is not a marker
//! ([`crate::ring_model::NOT_MARKERS`]) is fitted at its own best scale and blur.
//!
//! [`ModelFit::verdict`] accepts a marker only when its design explains the pixels well, and
//! clearly better than the other role of its sheet (reference or not) and than the other
//! sheet family's designs; when nearly every ray agrees; and when the rays' ends lie on the
//! ellipse. When blur has washed out what tells the reference from the others, the candidate
//! is refused, not guessed. When a shape that is not a marker (a dark disc or ring, a disc of
//! one grey inside a ring of another) explains the pixels as well, the marker is accepted as
//! only *like* its design, and the sheet it makes must prove itself the more.

use crate::ring_model::{
    basis_profile, fit_profile, resample, surround_profile, Hypothesis, MarkerDesign, ProfileFit,
    FINE, NOT_MARKERS, PER_RADIUS, SAMPLES, SCALES, TWO_LEVELS,
};
use crate::shade::LocalMean;

/// Rays cast from a candidate's centre.
pub const RAYS: usize = 16;
/// A ray agrees with the fit when its residual is at most this share of the contrast.
const RAY_RESIDUAL: f64 = 0.2;
/// A ray's own best length may be this far (relative) from the fitted ellipse and still count.
const RAY_ON_ELLIPSE: f64 = 0.1;
/// Ink and paper differ by at least this many grey levels (as [`crate::markers`] asks).
const MIN_CONTRAST: f64 = 40.0;
/// The best dark disc or ring must leave at least this many times the design's residual.
const NOT_MARKER_MARGIN: f64 = 1.3;
/// The sibling design (the other role) must leave at least this many times the design's
/// residual.
const ROLE_MARGIN: f64 = 2.0;
/// The other family's designs must leave at least this many times the design's residual.
const FAMILY_MARGIN: f64 = 1.5;
/// Scales tried on the first round, before the rays have their own lengths.
const FIRST_SCALES: [f64; 7] = [0.75, 0.85, 0.95, 1.0, 1.05, 1.15, 1.3];

/// Grey levels along the rays, at `t = i / (2 · PER_RADIUS)` of each ray's length.
struct Rays {
    centre: [f64; 2],
    radii: [f64; RAYS],
    fine: [[f64; FINE]; RAYS],
}

fn direction(k: usize) -> [f64; 2] {
    let a = (k as f64 + 0.5) * std::f64::consts::TAU / RAYS as f64;
    [a.cos(), a.sin()]
}

impl Rays {
    /// Samples the rays from `centre` with lengths `radii`; `None` when one leaves the frame.
    fn sample(shade: &LocalMean, centre: [f64; 2], radii: [f64; RAYS]) -> Option<Rays> {
        let mut fine = [[0.0; FINE]; RAYS];
        for (k, row) in fine.iter_mut().enumerate() {
            let [dx, dy] = direction(k);
            for (i, g) in row.iter_mut().enumerate() {
                let r = i as f64 / (2 * PER_RADIUS) as f64 * radii[k];
                *g = shade.grey_at(centre[0] + dx * r, centre[1] + dy * r)?;
            }
        }
        Some(Rays {
            centre,
            radii,
            fine,
        })
    }

    fn mean(&self) -> [f64; FINE] {
        std::array::from_fn(|i| self.fine.iter().map(|r| r[i]).sum::<f64>() / RAYS as f64)
    }

    fn median_radius(&self) -> f64 {
        let mut sorted = self.radii;
        sorted.sort_by(f64::total_cmp);
        sorted[RAYS / 2]
    }
}

/// The model profile of `design` fitted as `fit` on a ray of length `radius` (before the
/// fit's scale).
fn model(design: MarkerDesign, fit: &ProfileFit, radius: f64) -> [f64; SAMPLES] {
    let r = fit.scale * radius;
    let basis = basis_profile(design.basis(), fit.blur_px, r);
    let surround = surround_profile(fit.blur_px, r);
    std::array::from_fn(|j| fit.paper + fit.bands[0] * basis[j] + fit.beyond * surround[j])
}

/// Residual (rms) of `grey` against `model` with the offset between them free.
fn offset_residual(grey: &[f64; SAMPLES], model: &[f64; SAMPLES]) -> f64 {
    let offset = grey.iter().zip(model).map(|(g, m)| g - m).sum::<f64>() / SAMPLES as f64;
    let sum: f64 = grey
        .iter()
        .zip(model)
        .map(|(g, m)| (g - m - offset).powi(2))
        .sum();
    (sum / SAMPLES as f64).sqrt()
}

/// The best length of ray `k` for `design` fitted as `fit`, searched ±20 % around its current
/// length in steps of 5 % (refined between them) (the levels and blur kept, its paper level free: light falls unevenly).
fn best_length(rays: &Rays, k: usize, design: MarkerDesign, fit: &ProfileFit) -> f64 {
    let base = rays.radii[k] * fit.scale;
    let mut scored = [(0.0, 0.0); 9];
    for (i, step) in (-4i32..=4).enumerate() {
        let factor = fit.scale * (1.0 + 0.05 * f64::from(step));
        let grey = resample(&rays.fine[k], factor);
        let m = model(
            design,
            &ProfileFit {
                scale: factor,
                ..*fit
            },
            rays.radii[k],
        );
        scored[i] = (
            base * (1.0 + 0.05 * f64::from(step)),
            offset_residual(&grey, &m),
        );
    }
    let at = (0..scored.len())
        .min_by(|&a, &b| scored[a].1.total_cmp(&scored[b].1))
        .unwrap_or(4);
    let mut length = scored[at].0;
    if at > 0 && at + 1 < scored.len() {
        // A parabola through the best and its neighbours.
        let (a, b, c) = (scored[at - 1].1, scored[at].1, scored[at + 1].1);
        let denominator = a - 2.0 * b + c;
        if denominator > 1e-9 {
            let shift = (0.5 * (a - c) / denominator).clamp(-0.5, 0.5);
            length += shift * (scored[at + 1].0 - scored[at].0);
        }
    }
    length
}

/// An ellipse through edge points: `A·x² + B·xy + C·y² + D·x + E·y = 1` in coordinates
/// around `origin` (which must lie inside it).
#[derive(Debug, Clone, Copy)]
struct Ellipse {
    origin: [f64; 2],
    conic: [f64; 5],
}

impl Ellipse {
    /// The least-squares conic through the points of `points` that are `used`; `None` unless
    /// it is an ellipse.
    fn fit(origin: [f64; 2], points: &[[f64; 2]], used: &[bool]) -> Option<Ellipse> {
        use nalgebra::{SMatrix, SVector};
        let mut normal = SMatrix::<f64, 5, 5>::zeros();
        let mut rhs = SVector::<f64, 5>::zeros();
        for (p, _) in points.iter().zip(used).filter(|(_, u)| **u) {
            let (x, y) = (p[0] - origin[0], p[1] - origin[1]);
            let row = SVector::<f64, 5>::from([x * x, x * y, y * y, x, y]);
            normal += row * row.transpose();
            rhs += row;
        }
        let c = normal.try_inverse()? * rhs;
        let conic = [c[0], c[1], c[2], c[3], c[4]];
        (conic[0] > 0.0 && 4.0 * conic[0] * conic[2] - conic[1] * conic[1] > 0.0)
            .then_some(Ellipse { origin, conic })
    }

    fn centre(&self) -> [f64; 2] {
        let [a, b, c, d, e] = self.conic;
        let det = 4.0 * a * c - b * b;
        [
            self.origin[0] + (b * e - 2.0 * c * d) / det,
            self.origin[1] + (b * d - 2.0 * a * e) / det,
        ]
    }

    /// How far from `from` (inside it) the ellipse is along the unit vector `dir`.
    fn reach(&self, from: [f64; 2], dir: [f64; 2]) -> Option<f64> {
        let [a, b, c, d, e] = self.conic;
        let (x, y) = (from[0] - self.origin[0], from[1] - self.origin[1]);
        let q = a * dir[0] * dir[0] + b * dir[0] * dir[1] + c * dir[1] * dir[1];
        let l = 2.0 * a * x * dir[0]
            + b * (x * dir[1] + y * dir[0])
            + 2.0 * c * y * dir[1]
            + d * dir[0]
            + e * dir[1];
        let k = a * x * x + b * x * y + c * y * y + d * x + e * y - 1.0;
        let disc = l * l - 4.0 * q * k;
        (q > 0.0 && disc >= 0.0).then(|| (-l + disc.sqrt()) / (2.0 * q))
    }
}

/// An ellipse through the rays' ends at `lengths` from `centre`, refitted without the rays
/// that end far off it; with the rays kept.
fn robust_ellipse(centre: [f64; 2], lengths: &[f64; RAYS]) -> Option<(Ellipse, [bool; RAYS])> {
    let points: Vec<[f64; 2]> = (0..RAYS)
        .map(|k| {
            let [dx, dy] = direction(k);
            [centre[0] + dx * lengths[k], centre[1] + dy * lengths[k]]
        })
        .collect();
    let mut used = [true; RAYS];
    let mut ellipse = Ellipse::fit(centre, &points, &used)?;
    for _ in 0..3 {
        let c = ellipse.centre();
        let next: [bool; RAYS] = std::array::from_fn(|k| {
            let (dx, dy) = (points[k][0] - c[0], points[k][1] - c[1]);
            let r = dx.hypot(dy);
            ellipse
                .reach(c, [dx / r, dy / r])
                .is_some_and(|e| (r - e).abs() <= RAY_ON_ELLIPSE * e)
        });
        if next == used || next.iter().filter(|u| **u).count() < RAYS / 2 {
            break;
        }
        used = next;
        ellipse = Ellipse::fit(centre, &points, &used)?;
    }
    Some((ellipse, used))
}

/// Where each ray from `seed` leaves the marker: the outermost rise from dark to light between
/// 0.6 and 1.5 of `radius_px` at least half as steep as the steepest there (the outer ring's
/// outer edge: beyond it the light disc or the paper, whose stripes or frame edges are fainter
/// or fall from light to dark). `None` when a ray leaves the frame.
fn outer_edges(shade: &LocalMean, seed: [f64; 2], radius_px: f64) -> Option<[f64; RAYS]> {
    let step = (radius_px / 24.0).max(0.25);
    let (from, to) = (0.6 * radius_px, 1.5 * radius_px);
    let n = ((to - from) / step) as usize + 1;
    let mut edges = [radius_px; RAYS];
    let mut grey = Vec::with_capacity(n);
    for (k, edge) in edges.iter_mut().enumerate() {
        let [dx, dy] = direction(k);
        grey.clear();
        for i in 0..n {
            let r = from + i as f64 * step;
            grey.push(shade.grey_at(seed[0] + dx * r, seed[1] + dy * r)?);
        }
        // Rises over two steps (a little noise averaged).
        let rise: Vec<f64> = (0..n.saturating_sub(2))
            .map(|i| grey[i + 2] - grey[i])
            .collect();
        let steepest = rise.iter().copied().fold(0.0, f64::max);
        if steepest <= 0.0 {
            continue;
        }
        if let Some(i) = (1..rise.len().saturating_sub(1)).rev().find(|&i| {
            rise[i] >= 0.5 * steepest && rise[i] >= rise[i - 1] && rise[i] >= rise[i + 1]
        }) {
            *edge = from + (i as f64 + 1.0) * step;
        }
    }
    Some(edges)
}

/// What the fit of a candidate found.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ModelFit {
    /// The best-fitting design.
    pub design: MarkerDesign,
    /// The marker's centre, pixels.
    pub centre: [f64; 2],
    /// Median outer radius over the rays, pixels.
    pub radius_px: f64,
    /// The estimated blur (Gaussian σ), pixels.
    pub blur_px: f64,
    /// Paper and ink differ by this many grey levels (before blur).
    pub contrast: f64,
    /// The paper's grey level.
    pub paper: f64,
    /// Residual (rms, grey levels) of the best design.
    pub residual: f64,
    /// Residual of the best dark disc or ring (reaching the outer edge): not a marker.
    pub not_marker_residual: f64,
    /// Residual of the best disc of one grey inside a ring of another: not a marker either.
    pub two_level_residual: f64,
    /// Residual of the design of the same sheet with the other role (reference or not).
    pub sibling_residual: f64,
    /// Residual of the best design of the other family (simulator vs printed).
    pub other_family_residual: f64,
    /// Rays on the ellipse whose own residual is within a fifth of the contrast.
    pub rays_agreeing: usize,
    /// How far the rays' own ends are from the ellipse (relative rms, the rays on it).
    pub ellipse_misfit: f64,
    /// Longest over shortest ray.
    pub ellipse_ratio: f64,
}

/// The best design for the rays' mean profile at `scales`.
fn best_design(rays: &Rays, scales: &[f64]) -> Option<(MarkerDesign, ProfileFit)> {
    let mean = rays.mean();
    let radius = rays.median_radius();
    MarkerDesign::ALL
        .iter()
        .filter_map(|&d| fit_profile(&mean, radius, d.hypothesis(), scales).map(|f| (d, f)))
        .min_by(|a, b| a.1.residual.total_cmp(&b.1.residual))
}

/// Fits the marker designs to the candidate at `seed` of outer radius about `radius_px`.
/// `None` when the rays leave the frame or nothing fits.
pub fn fit_marker(shade: &LocalMean, seed: [f64; 2], radius_px: f64) -> Option<ModelFit> {
    if !(radius_px.is_finite() && radius_px >= 3.0) {
        return None;
    }
    // A first outline from the marker's outer edge (an ellipse when the camera is tilted).
    let mut rays = match outer_edges(shade, seed, radius_px)
        .and_then(|edges| robust_ellipse(seed, &edges))
        .and_then(|(ellipse, _)| {
            let centre = ellipse.centre();
            let radii: Option<Vec<f64>> = (0..RAYS)
                .map(|k| ellipse.reach(centre, direction(k)))
                .collect();
            let radii: [f64; RAYS] = radii?.try_into().ok()?;
            let plausible = (centre[0] - seed[0]).hypot(centre[1] - seed[1]) < 0.5 * radius_px
                && radii
                    .iter()
                    .all(|r| (0.5 * radius_px..=1.6 * radius_px).contains(r));
            plausible.then_some((centre, radii))
        }) {
        Some((centre, radii)) => Rays::sample(shade, centre, radii)?,
        None => Rays::sample(shade, seed, [radius_px; RAYS])?,
    };
    let mut on_ellipse = [true; RAYS];
    let mut lengths = [radius_px; RAYS];
    for round in 0..4 {
        let scales: &[f64] = if round == 0 { &FIRST_SCALES } else { &[1.0] };
        let (design, fit) = best_design(&rays, scales)?;
        // Nothing like a marker: no need to go on.
        if round == 0 && (-fit.bands[0] < 0.5 * MIN_CONTRAST || fit.residual > 0.2 * -fit.bands[0])
        {
            return None;
        }
        for (k, length) in lengths.iter_mut().enumerate() {
            *length = best_length(&rays, k, design, &fit);
        }
        let (ellipse, used) = robust_ellipse(rays.centre, &lengths)?;
        on_ellipse = used;
        if round == 3 {
            break;
        }
        let centre = ellipse.centre();
        if (centre[0] - seed[0]).hypot(centre[1] - seed[1]) > radius_px {
            return None;
        }
        let mut radii = [0.0; RAYS];
        for (k, r) in radii.iter_mut().enumerate() {
            *r = ellipse.reach(centre, direction(k))?;
            if !(*r >= 2.5 && *r <= 3.0 * radius_px) {
                return None;
            }
        }
        // Settled: another round would see the same rays.
        let moved = (centre[0] - rays.centre[0]).hypot(centre[1] - rays.centre[1]);
        let stretched = (0..RAYS)
            .map(|k| (radii[k] / rays.radii[k] - 1.0).abs())
            .fold(0.0, f64::max);
        if round > 0 && moved < 0.05 && stretched < 0.005 {
            break;
        }
        rays = Rays::sample(shade, centre, radii)?;
    }
    // Every explanation at its own best scale and blur.
    let mean = rays.mean();
    let radius = rays.median_radius();
    let fit_of = |h: Hypothesis| fit_profile(&mean, radius, h, &SCALES);
    let designs: Vec<(MarkerDesign, ProfileFit)> = MarkerDesign::ALL
        .iter()
        .filter_map(|&d| fit_of(d.hypothesis()).map(|f| (d, f)))
        .collect();
    let &(design, fit) = designs
        .iter()
        .min_by(|a, b| a.1.residual.total_cmp(&b.1.residual))?;
    let residual_of = |d: MarkerDesign| {
        designs
            .iter()
            .find(|(x, _)| *x == d)
            .map_or(f64::INFINITY, |(_, f)| f.residual)
    };
    // Each ray against the common fit; its own end against the ellipse.
    let mut rays_agreeing = 0;
    let mut misfit = 0.0;
    for k in 0..RAYS {
        if !on_ellipse[k] {
            continue;
        }
        let grey = resample(&rays.fine[k], fit.scale);
        if offset_residual(&grey, &model(design, &fit, rays.radii[k]))
            <= RAY_RESIDUAL * -fit.bands[0]
        {
            rays_agreeing += 1;
        }
        misfit += ((lengths[k] - rays.radii[k]) / rays.radii[k]).powi(2);
    }
    let kept = on_ellipse.iter().filter(|u| **u).count().max(1);
    let (lo, hi) = rays
        .radii
        .iter()
        .fold((f64::MAX, 0f64), |(lo, hi), r| (lo.min(*r), hi.max(*r)));
    let mut fit_found = ModelFit {
        design,
        centre: rays.centre,
        radius_px: radius * fit.scale,
        blur_px: fit.blur_px,
        contrast: -fit.bands[0],
        paper: fit.paper,
        residual: fit.residual,
        not_marker_residual: f64::NAN,
        two_level_residual: f64::NAN,
        sibling_residual: residual_of(design.sibling()),
        other_family_residual: MarkerDesign::ALL
            .iter()
            .filter(|d| d.printed() != design.printed())
            .map(|d| residual_of(*d))
            .fold(f64::INFINITY, f64::min),
        rays_agreeing,
        ellipse_misfit: (misfit / kept as f64).sqrt(),
        ellipse_ratio: hi / lo,
    };
    // What is not a marker only for what could be one (it costs most).
    if fit_found.basics().is_ok() {
        fit_found.not_marker_residual = NOT_MARKERS
            .iter()
            .filter_map(|h| fit_of(*h))
            .map(|f| f.residual)
            .fold(f64::INFINITY, f64::min);
        fit_found.two_level_residual = TWO_LEVELS
            .iter()
            .filter_map(|h| fit_of(*h))
            .map(|f| f.residual)
            .fold(f64::INFINITY, f64::min);
    }
    Some(fit_found)
}

/// Why a fit is not accepted as a marker.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum ModelReject {
    /// Ink and paper differ too little.
    Contrast,
    /// No design explains the pixels well.
    Misfit,
    /// The reference and the other design of its sheet explain them about as well.
    Role,
    /// A design of the other sheet family explains them about as well.
    Family,
    /// Too few rays agree with the fit.
    Rays,
    /// The rays' ends are not on an ellipse.
    Ellipse,
}

impl ModelFit {
    /// The checks that need no other explanation: contrast, fit, rays, ellipse.
    fn basics(&self) -> Result<(), ModelReject> {
        let c = self.contrast;
        // (NaN fails too.)
        if c.is_nan() || c < MIN_CONTRAST {
            return Err(ModelReject::Contrast);
        }
        if self.residual > 0.08 * c {
            return Err(ModelReject::Misfit);
        }
        if self.rays_agreeing < 13 {
            return Err(ModelReject::Rays);
        }
        if self.ellipse_misfit > 0.05 || self.ellipse_ratio > 2.5 {
            return Err(ModelReject::Ellipse);
        }
        Ok(())
    }

    /// Whether the fit shows a marker of its design: `Ok(true)` when no shape that is not a
    /// marker explains the pixels as well (the rings still show through the blur), `Ok(false)`
    /// when one does — a dark disc or ring, a disc of one grey inside a ring of another: blur
    /// has merged the rings, the marker is only *like* its design, and the sheet it makes must
    /// prove itself the more ([`crate::sheet`]). Either way its role (reference or not) and its
    /// family (simulator or printed) must be clear: a reference taken for another marker turns
    /// the workspace by a quarter; markers of two families are two sheets.
    pub fn verdict(&self) -> Result<bool, ModelReject> {
        self.basics()?;
        let c = self.contrast;
        if !(self.sibling_residual >= ROLE_MARGIN * self.residual
            && self.sibling_residual >= self.residual + 0.02 * c)
        {
            return Err(ModelReject::Role);
        }
        if self.other_family_residual < FAMILY_MARGIN * self.residual {
            return Err(ModelReject::Family);
        }
        let distinct = self.not_marker_residual >= NOT_MARKER_MARGIN * self.residual
            && self.not_marker_residual >= self.residual + 0.01 * c
            && self.two_level_residual >= self.residual;
        Ok(distinct)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ring_model::blurred_bands;

    /// A 120 × 120 frame with one marker of `design` (or other `bands`) at `centre`, outer
    /// radius `radius` px, blurred by `blur` px, squashed to `squash` along the direction
    /// `angle` (a tilted view), on a light disc of 1.3 radii inside a black pad (the Ned2
    /// sheet), with a little noise.
    fn frame(
        bands: &[(f64, f64)],
        centre: [f64; 2],
        radius: f64,
        blur: f64,
        squash: f64,
        angle: f64,
    ) -> LocalMean {
        let (w, h) = (120usize, 120usize);
        let (paper, ink) = (215.0, 35.0);
        let (s, c) = angle.sin_cos();
        let mut rgb = vec![0u8; w * h * 3];
        let mut seed = 12345u32;
        for v in 0..h {
            for u in 0..w {
                let (dx, dy) = (u as f64 - centre[0], v as f64 - centre[1]);
                // Into the marker's own frame: along `angle` shortened by `squash`.
                let (a, b) = ((c * dx + s * dy) / squash, -s * dx + c * dy);
                let t = a.hypot(b) / radius;
                let sigma = blur / radius;
                let dark = blurred_bands(bands, t, sigma) + blurred_bands(&[(1.3, 50.0)], t, sigma);
                seed = seed.wrapping_mul(1_103_515_245).wrapping_add(12345);
                let noise = f64::from((seed >> 16) % 7) - 3.0;
                let g = (paper - (paper - ink) * dark.min(1.0) + noise).clamp(0.0, 255.0) as u8;
                rgb[(v * w + u) * 3..][..3].fill(g);
            }
        }
        let mut shade = LocalMean::default();
        shade.compute(&rgb, w, h);
        shade
    }

    #[test]
    fn blurred_markers_are_fitted_with_their_design_centre_and_blur() {
        for design in [MarkerDesign::PrintedReference, MarkerDesign::PrintedOther] {
            for (blur, squash) in [(1.2, 1.0), (1.6, 1.0), (1.2, 0.8)] {
                let shade = frame(design.bands(), [60.3, 57.8], 11.0, blur, squash, 0.5);
                // Seeded off its centre and a little large, as the disc scan gives it.
                let fit = fit_marker(&shade, [61.5, 57.0], 12.5).unwrap();
                let case = format!("{design:?} blur {blur} squash {squash}: {fit:?}");
                assert_eq!(fit.design, design, "{case}");
                assert!(
                    (fit.centre[0] - 60.3).abs() < 0.3 && (fit.centre[1] - 57.8).abs() < 0.3,
                    "{case}"
                );
                assert!((fit.blur_px - blur).abs() < 0.6, "{case}");
                assert!(fit.verdict().is_ok(), "{case}: {:?}", fit.verdict());
            }
        }
    }

    #[test]
    fn a_dark_disc_is_never_a_distinct_marker_and_a_sharp_one_no_marker() {
        for blur in [0.6, 1.2, 2.0] {
            let shade = frame(&[(0.0, 1.0)], [60.0, 60.0], 11.0, blur, 1.0, 0.0);
            let verdict = fit_marker(&shade, [60.0, 60.0], 11.0).map(|f| f.verdict());
            assert!(
                !matches!(verdict, Some(Ok(true))),
                "blur {blur}: {verdict:?}"
            );
            if blur < 1.0 {
                assert!(!matches!(verdict, Some(Ok(_))), "blur {blur}: {verdict:?}");
            }
        }
        // A dark ring alone (a roll of tape) is no marker either.
        let shade = frame(&[(0.6, 1.0)], [60.0, 60.0], 11.0, 0.6, 1.0, 0.0);
        let verdict = fit_marker(&shade, [60.0, 60.0], 11.0).map(|f| f.verdict());
        assert!(!matches!(verdict, Some(Ok(_))), "{verdict:?}");
    }

    #[test]
    fn the_disc_scan_puts_a_candidate_on_a_blurred_marker() {
        let shade = frame(
            MarkerDesign::PrintedOther.bands(),
            [58.0, 63.0],
            11.0,
            1.4,
            0.85,
            1.0,
        );
        let mut scan = crate::disc_scan::DiscScan::new();
        let found = scan.scan(&shade, 6.0, 20.0, 10);
        assert!(
            found
                .iter()
                .any(|c| (c.centre[0] - 58.0).hypot(c.centre[1] - 63.0) < 3.0
                    && (8.0..15.0).contains(&c.radius_px)),
            "{found:?}"
        );
    }
}
