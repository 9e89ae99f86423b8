//! Finding the workspace markers in a frame.
//!
//! Each corner of a workspace sheet carries a marker of concentric dark rings on white. One of
//! the four, the sheet's origin (upper-left = far-left corner), is drawn differently from the
//! other three: in the simulator its centre is white where the others' is black; on Niryo's
//! printed sheets it has a solid centre disc where the others have rings round a small dot.
//!
//! Candidates are dark blobs that cluster (the rings of one marker, even when blur and
//! compression break a thin ring into arcs). "Dark" is decided against the neighbourhood, not
//! against a fixed grey level: a pixel is dark when it is well below the mean of the square
//! around it (an integral image makes that mean cost four look-ups), so a marker in the
//! arm's shade, under a lamp's glare or in a vignetted corner is still seen, while the classic
//! sheet's grey stripes and logo stay light. Each candidate is then judged on its own ink and
//! paper levels by [`crate::rings`]: rings all round, one ring width, an ellipse; its centre
//! comes from there.
//!
//! [`MarkerFinder::find_markers`] returns every marker that passes; [`sheet_candidates`]
//! lists the fours that can make a sheet: the reference is the odd centre (the other three
//! agree), the four are drawn alike (same outer-ring width: one design), of similar size, in a
//! convex quadrilateral with plausible sides and angles, ordered upper-left, upper-right,
//! lower-left, lower-right. The pipeline then checks each four through the homography it gives
//! ([`crate::sheet`]); [`SheetCheck`] names the check a four failed.

use crate::components::{union_root, Blob, Components};
use crate::rings::{ring_check, RingProfile, RingReject};
use crate::shade::LocalMean;

/// Class of dark pixels in the class map.
const DARK: u8 = 1;
/// A pixel is dark when its grey level is below this share (per cent) of its neighbourhood's
/// mean. Printed black under any light is far below; the sheet's grey stripes are not.
const DARK_PERCENT: u32 = 62;
/// Dark pixels have little hue (max − min of r, g, b below this): a dark-blue object is not
/// printed black.
const MAX_DARK_CHROMA: u8 = 60;

/// One marker in the image.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MarkerObservation {
    /// Centre, raw (distorted) pixel coordinates.
    pub centre_px: [f64; 2],
    /// Outer radius, pixels (half the mean bounding-box side of the outer ring).
    pub radius_px: f64,
    /// Whether it is light an eighth of its radius from the centre (the simulated sheet's
    /// origin marker; the printed sheets' markers other than the reference).
    pub white_centre: bool,
    /// Dark rings (or disc) a ray from its centre crosses, counted from an eighth of its
    /// radius outwards: the same for the four markers of one sheet.
    pub rings: u8,
    /// Dark/light changes along a ray from its centre to beyond its outer ring
    /// ([`crate::rings`]): 3 or more for a real marker.
    pub ring_changes: u8,
    /// Grey level of the paper around it (the brightest of its surroundings), 0..=255.
    pub paper_grey: u8,
    /// Where its outer ring's inner edge lies, as a fraction of its radius: the design's
    /// signature (the simulator's 0.7, Niryo's printed markers 0.85), the same for the four
    /// markers of one sheet.
    pub ring_fraction: f64,
    /// How it was seen.
    pub evidence: MarkerEvidence,
}

/// How a marker was seen.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum MarkerEvidence {
    /// Its rings came out dark and its gaps light, pixel by pixel ([`crate::rings`]).
    Rings,
    /// Its blurred radial profile is its design's ([`crate::ring_fit`]).
    Profile {
        /// The blur (Gaussian σ, pixels) the profile showed.
        blur_px: f64,
        /// Whether no disc of one grey inside a ring of another explains it as well (the rings
        /// still show through the blur). When not, the sheet it makes must show its border
        /// too ([`crate::sheet`]).
        distinct: bool,
    },
}

/// What became of one marker candidate of the last search ([`MarkerFinder::candidates`]):
/// for finding out why a marker was missed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CandidateTrace {
    /// The box of its dark blobs: `[u_min, u_max, v_min, v_max]`, pixels.
    pub box_px: [u32; 4],
    /// What became of it.
    pub outcome: CandidateOutcome,
}

/// What became of a marker candidate, in the order of the checks.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum CandidateOutcome {
    /// Its dark blobs joined with more (a dark frame or pad, a cable) into something larger
    /// than a marker can be.
    TooLarge,
    /// One blob only, too small or too elongated to be a marker.
    NotRingLike,
    /// Its ink and paper differ too little.
    LowContrast,
    /// The ring check ([`crate::rings`]) failed.
    Ring(RingReject),
    /// A marker already found at the same place.
    Duplicate,
    /// A marker.
    Marker,
}

/// Reusable buffers of the marker search.
#[derive(Debug, Default)]
pub struct MarkerFinder {
    classes: Vec<u8>,
    pub(crate) shade: LocalMean,
    components: Components,
    pub(crate) trace: Vec<CandidateTrace>,
    pub(crate) scan: crate::disc_scan::DiscScan,
    /// The blurred-profile fits of the last [`MarkerFinder::find_blurred_markers`] call.
    pub(crate) fits: Vec<(
        crate::disc_scan::DiscCandidate,
        Option<crate::ring_fit::ModelFit>,
    )>,
}

impl MarkerFinder {
    /// A finder with no buffers yet.
    pub fn new() -> Self {
        Self::default()
    }

    /// Marks the dark pixels of an RGB8 image in `self.classes`.
    fn classify(&mut self, rgb: &[u8], width: usize, height: usize) {
        self.shade.compute(rgb, width, height);
        let half = neighbourhood(width, height);
        self.classes.clear();
        self.classes.resize(width * height, 0);
        for v in 0..height {
            for u in 0..width {
                let i = v * width + u;
                let p = &rgb[i * 3..i * 3 + 3];
                let chroma = p[0].max(p[1]).max(p[2]) - p[0].min(p[1]).min(p[2]);
                if chroma < MAX_DARK_CHROMA && self.shade.darker_than(u, v, half, DARK_PERCENT) {
                    self.classes[i] = DARK;
                }
            }
        }
    }

    /// What became of every candidate of the last [`MarkerFinder::find_markers`] call.
    pub fn candidates(&self) -> &[CandidateTrace] {
        &self.trace
    }

    /// Every marker in an RGB8 image of `width` × `height` pixels.
    pub fn find_markers(
        &mut self,
        rgb: &[u8],
        width: usize,
        height: usize,
    ) -> Vec<MarkerObservation> {
        let n = width * height;
        self.trace.clear();
        if rgb.len() < n * 3 || n == 0 {
            return Vec::new();
        }
        self.classify(rgb, width, height);
        self.components.label(&self.classes, width, height, 4);
        let max_side = 200.max(width.min(height) as u32 / 3);
        let blobs: Vec<Blob> = self
            .components
            .blobs()
            .iter()
            .filter(|b| {
                let (w, h) = (b.box_width(), b.box_height());
                (2..=max_side).contains(&w)
                    && (2..=max_side).contains(&h)
                    && w <= 3 * h
                    && h <= 3 * w
            })
            .copied()
            .collect();

        // Blobs whose boxes come within a few pixels are one candidate: the rings of one
        // marker, even when blur and compression break a thin ring into arcs.
        let clusters = cluster_blobs(&blobs, CLUSTER_GAP_PX);
        let mut markers: Vec<MarkerObservation> = Vec::new();
        for cluster in clusters {
            let (w, h) = (
                cluster.u_max - cluster.u_min + 1,
                cluster.v_max - cluster.v_min + 1,
            );
            let mut trace = |outcome| {
                self.trace.push(CandidateTrace {
                    box_px: [cluster.u_min, cluster.u_max, cluster.v_min, cluster.v_max],
                    outcome,
                })
            };
            if w > max_side || h > max_side {
                trace(CandidateOutcome::TooLarge);
                continue;
            }
            let size = 0.5 * f64::from(w + h);
            if cluster.blobs < 2 || size < 6.0 || w > 3 * h || h > 3 * w {
                trace(CandidateOutcome::NotRingLike);
                continue;
            }
            let radius = size / 2.0;
            let seed = [cluster.u_sum / cluster.area, cluster.v_sum / cluster.area];
            let (profile, paper) = match self.ring_check(width, height, seed, radius) {
                Ok(found) => found,
                Err(outcome) => {
                    self.trace.push(CandidateTrace {
                        box_px: [cluster.u_min, cluster.u_max, cluster.v_min, cluster.v_max],
                        outcome,
                    });
                    continue;
                }
            };
            // One marker may be seeded twice (a ring and its inside in two clusters).
            let duplicate = markers.iter().any(|m| {
                (m.centre_px[0] - profile.centre[0]).hypot(m.centre_px[1] - profile.centre[1])
                    < 0.5 * m.radius_px.max(radius)
            });
            self.trace.push(CandidateTrace {
                box_px: [cluster.u_min, cluster.u_max, cluster.v_min, cluster.v_max],
                outcome: if duplicate {
                    CandidateOutcome::Duplicate
                } else {
                    CandidateOutcome::Marker
                },
            });
            if duplicate {
                continue;
            }
            markers.push(MarkerObservation {
                centre_px: profile.centre,
                radius_px: profile.outer_radius_px,
                white_centre: !profile.centre_dark,
                rings: profile.dark_runs,
                ring_changes: profile.changes,
                paper_grey: paper,
                ring_fraction: profile.ring_inner_fraction,
                evidence: MarkerEvidence::Rings,
            });
        }
        markers
    }

    /// The ring structure around `seed` (radius about `radius` pixels), judged on the grey
    /// levels with a threshold of the candidate's own: halfway between its ink (10th
    /// percentile) and its paper (90th), so thin rings that blur has turned grey still count.
    /// With the paper's grey level; the reason when it is no ring marker.
    fn ring_check(
        &self,
        width: usize,
        height: usize,
        seed: [f64; 2],
        radius: f64,
    ) -> Result<(RingProfile, u8), CandidateOutcome> {
        let mut greys: Vec<u8> = Vec::with_capacity(256);
        for k in 0..16 {
            let a = k as f64 * std::f64::consts::TAU / 16.0;
            let mut r = 0.0;
            while r <= 1.3 * radius {
                let (u, v) = (
                    (seed[0] + r * a.cos()).round(),
                    (seed[1] + r * a.sin()).round(),
                );
                if u >= 0.0 && v >= 0.0 && (u as usize) < width && (v as usize) < height {
                    greys.push(self.shade.grey(u as usize, v as usize));
                }
                r += (radius / 16.0).max(0.5);
            }
        }
        if greys.len() < 32 {
            return Err(CandidateOutcome::Ring(RingReject::Unusable));
        }
        greys.sort_unstable();
        let ink = greys[greys.len() / 10];
        let paper = greys[greys.len() * 9 / 10];
        if paper < ink.saturating_add(MIN_RING_CONTRAST) {
            return Err(CandidateOutcome::LowContrast);
        }
        let threshold = (u16::from(ink) + u16::from(paper)) / 2;
        let shade = &self.shade;
        let dark = |u: i64, v: i64| {
            (u >= 0 && v >= 0 && (u as usize) < width && (v as usize) < height)
                .then(|| u16::from(shade.grey(u as usize, v as usize)) < threshold)
        };
        ring_check(&dark, seed, radius)
            .map(|p| (p, paper))
            .map_err(CandidateOutcome::Ring)
    }
}

/// Blobs whose boxes come this close (pixels) are one marker candidate.
const CLUSTER_GAP_PX: u32 = 2;
/// A marker's ink and paper differ by at least this many grey levels.
const MIN_RING_CONTRAST: u8 = 40;

/// Dark blobs near each other: their joint box, pixel count and dark-pixel sums.
#[derive(Debug, Clone, Copy)]
struct Cluster {
    u_min: u32,
    u_max: u32,
    v_min: u32,
    v_max: u32,
    area: f64,
    u_sum: f64,
    v_sum: f64,
    blobs: usize,
}

/// Groups blobs whose boxes come within `gap` pixels of each other.
fn cluster_blobs(blobs: &[Blob], gap: u32) -> Vec<Cluster> {
    let n = blobs.len();
    let mut parent: Vec<usize> = (0..n).collect();
    let mut by_u: Vec<usize> = (0..n).collect();
    by_u.sort_by_key(|&i| blobs[i].u_min);
    for (k, &i) in by_u.iter().enumerate() {
        for &j in &by_u[k + 1..] {
            if blobs[j].u_min > blobs[i].u_max + gap {
                break;
            }
            let near =
                blobs[j].v_min <= blobs[i].v_max + gap && blobs[i].v_min <= blobs[j].v_max + gap;
            if near {
                let (a, b) = (union_root(&mut parent, i), union_root(&mut parent, j));
                if a != b {
                    parent[a.max(b)] = a.min(b);
                }
            }
        }
    }
    let mut clusters: Vec<Option<Cluster>> = vec![None; n];
    for (i, b) in blobs.iter().enumerate() {
        let r = union_root(&mut parent, i);
        let area = f64::from(b.area);
        let c = clusters[r].get_or_insert(Cluster {
            u_min: b.u_min,
            u_max: b.u_max,
            v_min: b.v_min,
            v_max: b.v_max,
            area: 0.0,
            u_sum: 0.0,
            v_sum: 0.0,
            blobs: 0,
        });
        c.u_min = c.u_min.min(b.u_min);
        c.u_max = c.u_max.max(b.u_max);
        c.v_min = c.v_min.min(b.v_min);
        c.v_max = c.v_max.max(b.v_max);
        c.area += area;
        c.u_sum += b.u_mean * area;
        c.v_sum += b.v_mean * area;
        c.blobs += 1;
    }
    clusters.into_iter().flatten().collect()
}

/// Half-side of the neighbourhood "dark" is judged against: a good deal larger than a marker
/// at the usual distance.
fn neighbourhood(width: usize, height: usize) -> usize {
    (width.min(height) / 12).max(12)
}

/// Of four markers, the reference (origin): the one whose centre differs from the other
/// three, which agree (the simulator's reference has a white centre where the others' is
/// black; Niryo's printed reference a solid centre where the others have rings round a dot),
/// the four having the same number of rings (one design). `None` when no one stands out, or
/// the signs disagree: then the sheet's orientation is unknown, and guessing it would give a
/// workspace turned by a quarter.
fn odd_one_out(four: &[MarkerObservation; 4]) -> Option<usize> {
    let whites = four.iter().filter(|m| m.white_centre).count();
    let odd = match whites {
        1 => four.iter().position(|m| m.white_centre)?,
        3 => four.iter().position(|m| !m.white_centre)?,
        _ => return None,
    };
    let (lo, hi) = four.iter().fold((u8::MAX, 0), |(lo, hi), m| {
        (lo.min(m.rings), hi.max(m.rings))
    });
    (hi <= lo + 1).then_some(odd)
}

/// The check that four ring markers failed to make the workspace sheet, in the order they
/// are made; a sheet is reported only when all of them pass.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum SheetCheck {
    /// No marker of the four stands out as the reference (upper-left) marker: the sheet's
    /// orientation is unknown.
    Reference,
    /// They are not drawn alike: markers of different sheets.
    Design,
    /// Their sizes in the image differ too much for markers of one sheet.
    MarkerSizes,
    /// They do not make a convex quadrilateral with plausible sides and angles.
    Shape,
    /// No pinhole camera sees the configured rectangle as that quadrilateral (one of the
    /// four is not at a corner).
    Perspective,
    /// Through the homography, the markers' sizes on the table disagree.
    TableSizes,
    /// Through the homography, the sheet's white centre is not there.
    Appearance,
    /// A marker is only like its design (blur merged its rings), and the sheet does not show
    /// its border (or its markers' sizes on the table differ).
    Border,
    /// The sheet would put the camera far from where the arm's kinematics say it is: it is
    /// another sheet than the configured workspace.
    NotThisWorkspace,
}

impl std::fmt::Display for SheetCheck {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Self::Reference => {
                "none of them is the reference marker (the upper-left one, drawn differently \
                 from the other three), so the sheet's orientation is unknown"
            }
            Self::Design => "they are not drawn alike (markers of different sheets)",
            Self::MarkerSizes => "their sizes differ too much for the markers of one sheet",
            Self::Shape => {
                "they do not make a convex quadrilateral with plausible sides and angles"
            }
            Self::Perspective => {
                "no camera could see the workspace rectangle as the quadrilateral they make \
                 (one of them is not a corner of this sheet)"
            }
            Self::TableSizes => "seen through the sheet's geometry, their sizes disagree",
            Self::Appearance => "the sheet's white centre is not between them",
            Self::Border => {
                "one of them is too blurred to be told from a round object, and the sheet's \
                 border between them does not show"
            }
            Self::NotThisWorkspace => {
                "they make a sheet, but not the configured workspace: seen through it, the \
                 camera would be far from where the arm holds it (another sheet in view?)"
            }
        })
    }
}

/// Smallest interior angle of a sheet's quadrilateral in the image, degrees (a camera tilted
/// 60° from straight down still sees more than this).
const MIN_CORNER_ANGLE_DEG: f64 = 25.0;
/// Opposite sides of the quadrilateral differ by at most this factor.
const MAX_OPPOSITE_SIDE_RATIO: f64 = 3.0;
/// The outer ring's width (as a fraction of the radius) of the four markers of one sheet
/// differs by at most this much (the simulator's and Niryo's designs differ by 0.15).
const MAX_DESIGN_SPREAD: f64 = 0.1;
/// Markers of one sheet differ in image radius by at most this factor.
const MAX_RADIUS_RATIO: f64 = 2.5;
/// At most this many candidates (the most rings, the largest) are combined four at a time.
const MAX_CANDIDATES: usize = 12;

/// Four markers in sheet order: upper-left (the reference), upper-right, lower-left,
/// lower-right; both assignments of the two neighbours of the reference (a mirror order gives
/// no valid camera, so the caller tries both), the more likely first.
pub type CornerOrders = [[MarkerObservation; 4]; 2];

/// Every set of four markers that can be one sheet seen by a camera, best first (the most
/// rings, the most similar sizes), or the furthest check that every set failed.
///
/// With fewer than four markers there is nothing to combine: the caller says so.
pub fn sheet_candidates(markers: &[MarkerObservation]) -> Result<Vec<CornerOrders>, SheetCheck> {
    let mut candidates = markers.to_vec();
    candidates.sort_by(|a, b| {
        b.rings
            .cmp(&a.rings)
            .then(b.radius_px.total_cmp(&a.radius_px))
    });
    candidates.truncate(MAX_CANDIDATES);
    let n = candidates.len();
    let mut passed: Vec<(f64, CornerOrders)> = Vec::new();
    let mut furthest = SheetCheck::Reference;
    for a in 0..n {
        for b in a + 1..n {
            for c in b + 1..n {
                for d in c + 1..n {
                    let four = [candidates[a], candidates[b], candidates[c], candidates[d]];
                    match order_as_sheet(&four) {
                        Ok(found) => passed.push(found),
                        Err(check) => furthest = furthest.max(check),
                    }
                }
            }
        }
    }
    if passed.is_empty() {
        return Err(furthest);
    }
    passed.sort_by(|x, y| y.0.total_cmp(&x.0));
    Ok(passed.into_iter().map(|(_, orders)| orders).collect())
}

/// Four markers as a sheet, with a score, or the check they fail.
fn order_as_sheet(four: &[MarkerObservation; 4]) -> Result<(f64, CornerOrders), SheetCheck> {
    let origin_index = odd_one_out(four).ok_or(SheetCheck::Reference)?;
    let (f_min, f_max) = four.iter().fold((f64::MAX, f64::MIN), |(lo, hi), m| {
        (lo.min(m.ring_fraction), hi.max(m.ring_fraction))
    });
    if f_max - f_min > MAX_DESIGN_SPREAD {
        return Err(SheetCheck::Design);
    }
    let (r_min, r_max) = four.iter().fold((f64::MAX, 0f64), |(lo, hi), m| {
        (lo.min(m.radius_px), hi.max(m.radius_px))
    });
    if r_max > MAX_RADIUS_RATIO * r_min {
        return Err(SheetCheck::MarkerSizes);
    }
    let origin = four[origin_index];
    let dist = |m: &MarkerObservation| {
        (m.centre_px[0] - origin.centre_px[0]).hypot(m.centre_px[1] - origin.centre_px[1])
    };
    let mut others: Vec<MarkerObservation> = (0..4)
        .filter(|&i| i != origin_index)
        .map(|i| four[i])
        .collect();
    others.sort_by(|x, y| dist(x).total_cmp(&dist(y)));
    let (a, b, diagonal) = (others[0], others[1], others[2]);
    // Around the edge: origin, a, diagonal, b.
    let ring = [
        origin.centre_px,
        a.centre_px,
        diagonal.centre_px,
        b.centre_px,
    ];
    if !plausible_quadrilateral(&ring, r_max) {
        return Err(SheetCheck::Shape);
    }
    let rings: u32 = four.iter().map(|m| u32::from(m.rings)).sum();
    let score = f64::from(rings) - r_max / r_min;
    Ok((score, [[origin, a, b, diagonal], [origin, b, a, diagonal]]))
}

/// Whether four image points, in order around the edge, make a quadrilateral a camera can
/// see a sheet as: convex, no corner sharper than [`MIN_CORNER_ANGLE_DEG`] (or flatter than
/// its supplement), opposite sides within [`MAX_OPPOSITE_SIDE_RATIO`], every side many marker
/// radii long (markers sit at the corners of a sheet far larger than they are).
fn plausible_quadrilateral(ring: &[[f64; 2]; 4], marker_radius: f64) -> bool {
    let side = |i: usize| {
        let (p, q) = (ring[i], ring[(i + 1) % 4]);
        (q[0] - p[0]).hypot(q[1] - p[1])
    };
    let sides = [side(0), side(1), side(2), side(3)];
    if sides.iter().any(|s| *s < 4.0 * marker_radius) {
        return false;
    }
    for (x, y) in [(sides[0], sides[2]), (sides[1], sides[3])] {
        if x > MAX_OPPOSITE_SIDE_RATIO * y || y > MAX_OPPOSITE_SIDE_RATIO * x {
            return false;
        }
    }
    let mut sign = 0.0;
    let min_sin = MIN_CORNER_ANGLE_DEG.to_radians().sin();
    for i in 0..4 {
        let (p, q, r) = (ring[(i + 3) % 4], ring[i], ring[(i + 1) % 4]);
        let (ux, uy) = (p[0] - q[0], p[1] - q[1]);
        let (vx, vy) = (r[0] - q[0], r[1] - q[1]);
        let cross = ux * vy - uy * vx;
        let sine = cross / (ux.hypot(uy) * vx.hypot(vy));
        if !sine.is_finite() || sine.abs() < min_sin {
            return false;
        }
        if sign == 0.0 {
            sign = sine.signum();
        } else if sine.signum() != sign {
            return false; // not convex
        }
    }
    true
}

#[cfg(test)]
mod tests {
    use super::*;

    fn draw_marker(img: &mut [u8], width: usize, c: [f64; 2], r: f64, white_centre: bool) {
        let height = img.len() / 3 / width;
        for v in 0..height {
            for u in 0..width {
                let d = (u as f64 - c[0]).hypot(v as f64 - c[1]) / r;
                let dark = if d > 1.0 {
                    continue;
                } else if d > 0.7 {
                    true
                } else if d > 0.45 {
                    false
                } else if d > 0.2 {
                    true
                } else {
                    !white_centre
                };
                let value = if dark { 20 } else { 245 };
                img[(v * width + u) * 3..][..3].fill(value);
            }
        }
    }

    #[test]
    fn finds_four_markers_and_orders_them() {
        let (w, h) = (200, 150);
        let mut img = vec![245u8; w * h * 3];
        draw_marker(&mut img, w, [30.0, 30.0], 12.0, true);
        draw_marker(&mut img, w, [170.0, 32.0], 12.0, false);
        draw_marker(&mut img, w, [28.0, 120.0], 12.0, false);
        draw_marker(&mut img, w, [168.0, 118.0], 12.0, false);
        // A dark bar (a pen) is not a marker.
        for v in 70..76 {
            for u in 60..140 {
                img[(v * w + u) * 3..][..3].fill(25);
            }
        }
        let mut finder = MarkerFinder::new();
        let markers = finder.find_markers(&img, w, h);
        assert_eq!(markers.len(), 4, "{markers:?}");
        let [first, _] = sheet_candidates(&markers).unwrap()[0];
        assert!(first[0].white_centre);
        assert!((first[0].centre_px[0] - 30.0).abs() < 0.2);
        assert!((first[3].centre_px[0] - 168.0).abs() < 0.2, "diagonal last");
        assert!((first[3].centre_px[1] - 118.0).abs() < 0.2);

        // Without its origin marker a sheet is not usable.
        let no_origin: Vec<_> = markers
            .iter()
            .filter(|m| !m.white_centre)
            .copied()
            .collect();
        assert_eq!(sheet_candidates(&no_origin), Err(SheetCheck::Reference));
        assert!(finder.find_markers(&[245; 30], 5, 2).is_empty());
    }

    #[test]
    fn a_dark_rimmed_cube_with_a_spot_beside_a_marker_is_not_a_marker() {
        let (w, h) = (200, 150);
        let mut img = vec![245u8; w * h * 3];
        draw_marker(&mut img, w, [30.0, 30.0], 12.0, true);
        draw_marker(&mut img, w, [170.0, 32.0], 12.0, false);
        draw_marker(&mut img, w, [28.0, 120.0], 12.0, false);
        // Where the fourth marker should be: a cube seen from above, its dark rim (shadowed
        // sides) around a lighter top with a dark knot in the middle.
        for v in 104..132 {
            for u in 154..182 {
                let edge = (v - 104).min(131 - v).min(u - 154).min(181 - u);
                let knot = (v as i32 - 118).abs() <= 2 && (u as i32 - 168).abs() <= 2;
                let value = if edge < 4 || knot { 25 } else { 200 };
                img[(v * w + u) * 3..][..3].fill(value);
            }
        }
        let mut finder = MarkerFinder::new();
        let markers = finder.find_markers(&img, w, h);
        assert_eq!(markers.len(), 3, "{markers:?}");
    }

    /// A real Niryo marker: dark between the given radii (fractions of `r`) on light grey.
    fn draw_bands(
        img: &mut [u8],
        width: usize,
        c: [f64; 2],
        r: f64,
        bands: &[(f64, f64)],
        ink: u8,
    ) {
        let height = img.len() / 3 / width;
        for v in 0..height {
            for u in 0..width {
                let d = (u as f64 - c[0]).hypot(v as f64 - c[1]) / r;
                if bands.iter().any(|&(a, b)| d >= a && d <= b) {
                    img[(v * width + u) * 3..][..3].fill(ink);
                }
            }
        }
    }

    #[test]
    fn the_real_sheets_reference_has_a_solid_centre_even_in_shade() {
        let (w, h) = (320, 240);
        let mut img = vec![0u8; w * h * 3];
        // Lit from the left: the sheet goes from 230 down to 120.
        for v in 0..h {
            for u in 0..w {
                img[(v * w + u) * 3..][..3].fill((230 - 110 * u / w) as u8);
            }
        }
        let reference = [(0.0, 0.3), (0.5, 0.7), (0.85, 1.0)];
        let other = [(0.0, 0.08), (0.25, 0.4), (0.55, 0.7), (0.85, 1.0)];
        let centres = [[60.0, 50.0], [260.0, 52.0], [58.0, 190.0], [262.0, 188.0]];
        for (k, c) in centres.iter().enumerate() {
            // Printed black is dark grey, and darker still in the shade on the right.
            let ink = if c[0] > 160.0 { 35 } else { 70 };
            draw_bands(
                &mut img,
                w,
                *c,
                18.0,
                if k == 0 { &reference } else { &other },
                ink,
            );
        }
        let mut finder = MarkerFinder::new();
        let markers = finder.find_markers(&img, w, h);
        assert_eq!(markers.len(), 4, "{markers:?}");
        let [first, _] = sheet_candidates(&markers).unwrap()[0];
        assert!((first[0].centre_px[0] - 60.0).abs() < 0.5, "{first:?}");
        assert!((first[0].centre_px[1] - 50.0).abs() < 0.5, "{first:?}");
        assert!(!first[0].white_centre && first[1].white_centre, "{first:?}");
        assert!((first[3].centre_px[0] - 262.0).abs() < 0.5, "diagonal last");
    }
}
