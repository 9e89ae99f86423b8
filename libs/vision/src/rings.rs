//! Is a marker candidate really a ring marker? Rays from its centre tell.
//!
//! The blob stage ([`crate::markers`]) proposes a candidate wherever a hollow dark blob has
//! another dark blob inside it around the same centre. Many things on a table come close: a
//! cube with a dark rim and a dark spot, a letter "O" of the sheet's logo with a speck inside,
//! a roll of tape. A Niryo marker is more than that: concentric rings, so that *every* line
//! from its centre outwards crosses the same alternation of dark and light, at the same
//! fractions of the marker's radius (perspective turns the circles into ellipses, which keeps
//! those fractions along each line through the centre).
//!
//! [`ring_profile`] samples [`RAYS`] rays from the candidate's centre to a little beyond its
//! outer radius on the dark/light map the blob stage made, and accepts the candidate only when:
//! - on nearly every ray the outer edge is found, and inside it at least two dark elements
//!   (an outer ring and a second ring, disc or dot): three or more dark/light changes;
//! - most rays agree on where the outer ring's inner edge is, as a fraction of the ray's
//!   outer edge (a ring has one width all round; a blob's rim does not);
//! - the outer edges lie on an ellipse around the centre (a circle in perspective; a square
//!   rim's corners stick out of any ellipse), no ray more than [`MAX_ELLIPSE_RATIO`] times
//!   longer than another (a camera tilted up to ~65°).
//!
//! ```
//! use robotd_vision::rings::ring_profile;
//!
//! // A target of three dark rings of 20 px on a light background...
//! let dark = |u: i64, v: i64| {
//!     let d = ((u - 50) as f64).hypot((v - 50) as f64) / 20.0;
//!     Some(d <= 1.0 && ((d * 6.0) as i64) % 2 == 1 || d < 0.17)
//! };
//! assert!(ring_profile(&dark, [50.0, 50.0], 20.0).is_some());
//! // ...but a dark square with a dark dot in it is not a marker.
//! let square = |u: i64, v: i64| {
//!     let (a, b) = ((u - 50).abs(), (v - 50).abs());
//!     Some(a.max(b) <= 20 && (a.max(b) >= 17 || a.max(b) <= 2))
//! };
//! assert!(ring_profile(&square, [50.0, 50.0], 20.0).is_none());
//! ```

/// How many rays are cast from a candidate's centre.
pub const RAYS: usize = 16;
/// How many rays must show the ring structure.
const MIN_GOOD_RAYS: usize = 11;
/// The rays' outer edges may differ by this factor at most (an ellipse seen at up to ~65°).
pub const MAX_ELLIPSE_RATIO: f64 = 2.5;
/// The inner edge of the outer ring, as a fraction of each ray's outer edge, must lie this
/// close to its median on at least [`MIN_GOOD_RAYS`] rays.
const MAX_RING_SPREAD: f64 = 0.1;
/// The outer edges may be this far (root mean square, relative) from the best ellipse (or
/// a pixel over the radius, for small markers).
const MAX_ELLIPSE_MISFIT: f64 = 0.05;
/// Rays go this far beyond the candidate's radius (its blob's box may be a pixel short).
const REACH: f64 = 1.35;

/// What the rays saw of a candidate that passed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RingProfile {
    /// The marker's centre, refined from where the rays met its outer edge.
    pub centre: [f64; 2],
    /// Dark/light changes along a typical ray, the outer edge included (3 or more).
    pub changes: u8,
    /// Dark rings (or disc) crossed by a typical ray from an eighth of the radius outwards.
    pub dark_runs: u8,
    /// Whether the marker is dark an eighth of its radius from the centre (a solid centre
    /// disc; the simulator's non-reference markers), on most rays.
    pub centre_dark: bool,
    /// Where the outer ring's inner edge lies, as a fraction of the outer edge (median).
    pub ring_inner_fraction: f64,
    /// Median distance from the centre to the outer edge, pixels.
    pub outer_radius_px: f64,
}

/// Why a candidate is not a ring marker: the first of [`ring_profile`]'s checks it failed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum RingReject {
    /// Too small to look at, or reaching out of the image.
    Unusable,
    /// Too few rays crossed an outer ring with a second dark element inside it.
    TooFewRings,
    /// The outer edges do not lie on an ellipse around the centre.
    NotAnEllipse,
    /// The rays disagree on the outer ring's width.
    RingWidth,
}

/// What one ray saw.
#[derive(Debug, Clone, Copy)]
struct Ray {
    angle: f64,
    /// Distance to the outer edge (the last change from dark to light), pixels.
    outer: f64,
    /// The outer ring's inner edge over `outer`.
    inner_fraction: f64,
    /// Changes up to and including the outer edge.
    changes: usize,
    /// Dark runs from an eighth of the radius out to the outer edge.
    dark_runs: usize,
    /// Dark an eighth of the radius from the centre.
    centre_dark: bool,
}

/// The changes along one ray: radii (pixels) where dark turns light or light turns dark,
/// from the centre outwards, and whether the ray starts dark.
fn changes_along(
    dark: &impl Fn(i64, i64) -> Option<bool>,
    centre: [f64; 2],
    direction: [f64; 2],
    reach: f64,
    step: f64,
    out: &mut Vec<f64>,
) -> Option<bool> {
    out.clear();
    let sample = |r: f64| {
        dark(
            (centre[0] + direction[0] * r).round() as i64,
            (centre[1] + direction[1] * r).round() as i64,
        )
    };
    let first = sample(0.0)?;
    let mut state = first;
    // A change counts once two samples in a row agree on it (one stray pixel is noise).
    let mut pending: Option<f64> = None;
    let mut r = step;
    while r <= reach {
        let here = sample(r)?;
        if here != state {
            match pending {
                Some(at) => {
                    out.push(at);
                    state = here;
                    pending = None;
                }
                None => pending = Some(r),
            }
        } else {
            pending = None;
        }
        r += step;
    }
    Some(first)
}

/// Casts the rays from `centre`; `None` for a ray that leaves the image or shows no ring.
fn cast(
    dark: &impl Fn(i64, i64) -> Option<bool>,
    centre: [f64; 2],
    radius_px: f64,
) -> Vec<Option<Ray>> {
    let reach = radius_px * REACH;
    let step = (radius_px / 48.0).clamp(0.35, 2.0);
    let core = radius_px / 8.0;
    let mut changes = Vec::new();
    (0..RAYS)
        .map(|k| {
            let angle = (k as f64 + 0.5) * std::f64::consts::TAU / RAYS as f64;
            let direction = [angle.cos(), angle.sin()];
            let starts_dark = changes_along(dark, centre, direction, reach, step, &mut changes)?;
            // Changes alternate: from dark to light are the even ones when the ray starts dark.
            // The outer edge is the change from dark to light nearest the candidate's radius
            // (beyond it the rays may reach a striped border or a dark pad).
            let dark_to_light = |i: usize| i.is_multiple_of(2) == starts_dark;
            let edge = (0..changes.len())
                .filter(|&i| dark_to_light(i))
                .min_by(|&a, &b| {
                    (changes[a] - radius_px)
                        .abs()
                        .total_cmp(&(changes[b] - radius_px).abs())
                })?;
            // At least an outer ring and a second dark element inside it: three changes up to
            // the outer edge (ring's outer edge, ring's inner edge, the next element's edge).
            if edge < 2 || changes[edge] < 0.5 * radius_px {
                return None;
            }
            let dark_at = |r: f64| {
                let before = changes[..=edge].iter().filter(|c| **c <= r).count();
                before.is_multiple_of(2) == starts_dark
            };
            let centre_dark = dark_at(core);
            let dark_runs = usize::from(centre_dark)
                + (0..=edge)
                    .filter(|&i| !dark_to_light(i) && changes[i] > core)
                    .count();
            Some(Ray {
                angle,
                outer: changes[edge],
                inner_fraction: changes[edge - 1] / changes[edge],
                changes: edge + 1,
                dark_runs,
                centre_dark,
            })
        })
        .collect()
}

/// How far the true centre is from `centre`, from opposite rays' outer edges: along each
/// line through the centre, the edges are equally far on both sides of the true centre.
fn centre_correction(rays: &[Option<Ray>]) -> Option<[f64; 2]> {
    let half = RAYS / 2;
    let (mut a, mut b, mut c, mut rx, mut ry, mut pairs) = (0.0, 0.0, 0.0, 0.0, 0.0, 0);
    for k in 0..half {
        let (Some(p), Some(q)) = (rays[k], rays[k + half]) else {
            continue;
        };
        let (dx, dy) = (p.angle.cos(), p.angle.sin());
        let shift = 0.5 * (p.outer - q.outer);
        a += dx * dx;
        b += dx * dy;
        c += dy * dy;
        rx += dx * shift;
        ry += dy * shift;
        pairs += 1;
    }
    let det = a * c - b * b;
    if pairs < 4 || det.abs() < 1e-9 {
        return None;
    }
    Some([(c * rx - b * ry) / det, (a * ry - b * rx) / det])
}

/// The ring structure of a candidate centred about `centre` with outer radius about
/// `radius_px`, on a dark/light map (`dark(u, v)`, `None` outside the image). The centre is
/// refined first (twice at most) from where opposite rays meet the outer edge. `None` when it
/// is not a ring marker (or reaches out of the image).
pub fn ring_profile(
    dark: &impl Fn(i64, i64) -> Option<bool>,
    centre: [f64; 2],
    radius_px: f64,
) -> Option<RingProfile> {
    ring_check(dark, centre, radius_px).ok()
}

/// [`ring_profile`], saying which check a candidate failed.
pub fn ring_check(
    dark: &impl Fn(i64, i64) -> Option<bool>,
    centre: [f64; 2],
    radius_px: f64,
) -> Result<RingProfile, RingReject> {
    if !(radius_px.is_finite() && radius_px >= 3.0) {
        return Err(RingReject::Unusable);
    }
    let mut centre = centre;
    let mut rays = cast(dark, centre, radius_px);
    for _ in 0..2 {
        let Some(shift) = centre_correction(&rays) else {
            break;
        };
        if shift[0].hypot(shift[1]) < 0.25 || shift[0].hypot(shift[1]) > 0.4 * radius_px {
            break;
        }
        centre = [centre[0] + shift[0], centre[1] + shift[1]];
        rays = cast(dark, centre, radius_px);
    }
    let good: Vec<Ray> = rays.into_iter().flatten().collect();
    if good.len() < MIN_GOOD_RAYS {
        return Err(RingReject::TooFewRings);
    }
    let outer: Vec<f64> = good.iter().map(|r| r.outer).collect();
    let angles: Vec<f64> = good.iter().map(|r| r.angle).collect();
    let (lo, hi) = outer
        .iter()
        .fold((f64::MAX, 0f64), |(lo, hi), r| (lo.min(*r), hi.max(*r)));
    // Edges are found to about a pixel: small markers get that much slack.
    let tolerance = MAX_ELLIPSE_MISFIT.max(1.0 / radius_px);
    let misfit = ellipse_misfit(&angles, &outer).ok_or(RingReject::NotAnEllipse)?;
    if hi > MAX_ELLIPSE_RATIO * lo || misfit > tolerance {
        return Err(RingReject::NotAnEllipse);
    }
    // The outer ring's width agrees on most rays (a faint inner ring that blur merged with
    // the gap may move it on a few).
    let fractions: Vec<f64> = good.iter().map(|r| r.inner_fraction).collect();
    let mut sorted = fractions.clone();
    sorted.sort_by(f64::total_cmp);
    let typical = sorted[sorted.len() / 2];
    let agreeing = fractions
        .iter()
        .filter(|f| (*f - typical).abs() <= MAX_RING_SPREAD)
        .count();
    if agreeing < MIN_GOOD_RAYS || !(0.3..0.97).contains(&typical) {
        return Err(RingReject::RingWidth);
    }
    let median = |mut v: Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let median_count = |mut v: Vec<usize>| {
        v.sort_unstable();
        v[v.len() / 2].min(255) as u8
    };
    let dark_centres = good.iter().filter(|r| r.centre_dark).count();
    Ok(RingProfile {
        centre,
        changes: median_count(good.iter().map(|r| r.changes).collect()),
        dark_runs: median_count(good.iter().map(|r| r.dark_runs).collect()),
        centre_dark: 2 * dark_centres > good.len(),
        ring_inner_fraction: typical,
        outer_radius_px: median(outer),
    })
}

/// How far (root mean square of the relative radius error) the points at `radii` along
/// `angles` from a centre are from the best ellipse centred there: `1/r² = a·cos² + b·sin² +
/// c·cos·sin`, fitted by least squares. `None` when the fit is degenerate.
pub(crate) fn ellipse_misfit(angles: &[f64], radii: &[f64]) -> Option<f64> {
    use nalgebra::{Matrix3, Vector3};
    let mut normal = Matrix3::<f64>::zeros();
    let mut rhs = Vector3::<f64>::zeros();
    for (a, r) in angles.iter().zip(radii) {
        let (s, c) = a.sin_cos();
        let row = Vector3::new(c * c, s * s, c * s);
        normal += row * row.transpose();
        rhs += row / (r * r);
    }
    let coefficients = normal.try_inverse()? * rhs;
    let mut sum = 0.0;
    for (a, r) in angles.iter().zip(radii) {
        let (s, c) = a.sin_cos();
        let inverse_square = coefficients.dot(&Vector3::new(c * c, s * s, c * s));
        if inverse_square <= 0.0 {
            return None;
        }
        let fitted = inverse_square.sqrt().recip();
        sum += ((fitted - r) / r).powi(2);
    }
    Some((sum / radii.len() as f64).sqrt())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A dark/light map of concentric bands (inner, outer fractions of `r`), squashed along v
    /// by `squash` (a tilted view).
    fn target(
        bands: &'static [(f64, f64)],
        r: f64,
        squash: f64,
    ) -> impl Fn(i64, i64) -> Option<bool> {
        move |u, v| {
            if !(0..200).contains(&u) || !(0..200).contains(&v) {
                return None;
            }
            let d = ((u - 100) as f64).hypot((v - 100) as f64 / squash) / r;
            Some(bands.iter().any(|(a, b)| (*a..=*b).contains(&d)))
        }
    }

    #[test]
    fn simulator_and_real_markers_pass_even_tilted() {
        let sim_origin: &[(f64, f64)] = &[(0.2, 0.45), (0.7, 1.0)];
        let sim_other: &[(f64, f64)] = &[(0.0, 0.45), (0.7, 1.0)];
        let real_reference: &[(f64, f64)] = &[(0.0, 0.3), (0.5, 0.7), (0.85, 1.0)];
        for bands in [sim_origin, sim_other, real_reference] {
            for (r, squash) in [(12.0, 1.0), (30.0, 1.0), (20.0, 0.55)] {
                let p = ring_profile(&target(bands, r, squash), [100.0, 100.0], r);
                assert!(p.is_some(), "{bands:?} r {r} squash {squash}");
                assert!(p.unwrap().changes >= 3);
            }
        }
    }

    #[test]
    fn discs_rings_alone_and_off_centre_points_fail() {
        let disc: &[(f64, f64)] = &[(0.0, 1.0)];
        let one_ring: &[(f64, f64)] = &[(0.7, 1.0)];
        let marker: &[(f64, f64)] = &[(0.0, 0.45), (0.7, 1.0)];
        assert!(ring_profile(&target(disc, 20.0, 1.0), [100.0, 100.0], 20.0).is_none());
        assert!(ring_profile(&target(one_ring, 20.0, 1.0), [100.0, 100.0], 20.0).is_none());
        // A true marker seeded 3 px off its centre: found, centre refined.
        let p = ring_profile(&target(marker, 20.0, 1.0), [103.0, 98.0], 20.0).unwrap();
        assert!(
            (p.centre[0] - 100.0).abs() < 0.6 && (p.centre[1] - 100.0).abs() < 0.6,
            "{p:?}"
        );
        // Out of the image.
        assert!(ring_profile(&target(marker, 20.0, 1.0), [190.0, 100.0], 20.0).is_none());
    }
}
