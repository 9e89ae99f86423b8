//! Proving a sheet: the checks four markers must pass through the homography they give.
//!
//! Four points always fit a homography, so four blobs in a plausible quadrilateral
//! ([`crate::markers::sheet_candidates`]) are not yet a workspace: a robot that trusted them
//! would place objects wherever a wrong blob sent it. [`verify_sheet`] asks what is true of
//! every real view of the sheet, whatever its design (the simulator's plain sheet, Niryo's
//! classic striped one, the Ned2's black-framed one):
//!
//! 1. **A camera can see it.** The homography must be what a pinhole camera (square pixels,
//!    principal point at the image centre, any focal length) sees of the configured
//!    rectangle: the two table axes come out orthogonal and of equal scale
//!    ([`TablePlane::pinhole_misfit`]). One point 1 cm from its corner breaks this when the
//!    camera's intrinsics are known; with a guessed focal length the check is weaker.
//! 2. **The markers are one size on the table.** Each marker's image radius over the view's
//!    scale at its corner is its size on the table: the four agree, and are a plausible
//!    fraction of the sheet.
//! 3. **The sheet's white centre is between them.** Every design has plain white paper in the
//!    middle: most of a grid of points there (objects cover some) must be about as light and
//!    as grey as the paper around the markers.
//! 4. **When a marker is only like its design** (found by its blurred profile, which a disc of
//!    one grey inside a ring of another explains as well: [`MarkerEvidence::Profile`]), the
//!    sheet must show more of itself: the four markers' sizes on the table agree closely, and
//!    the border between neighbouring markers is the design's — white paper on the
//!    simulator's sheet; on a printed sheet either the Ned2 sheet's black frame or the classic
//!    sheet's grey stripes, the same on at least three sides.

use crate::camera::Camera;
use crate::detector::FrameView;
use crate::markers::{MarkerEvidence, MarkerObservation, SheetCheck};
use crate::plane::TablePlane;

/// Largest pinhole misfit of a real sheet seen by a camera of known intrinsics: marker
/// centres a pixel off stay well under it; a corner 1 cm off does not.
pub const MAX_PINHOLE_MISFIT: f64 = 0.08;
/// The same for a camera whose focal length is a guess (a photo from an unknown camera): the
/// focal length is searched, which explains some wrong corners away, so this check is weaker
/// there and the others carry more.
pub const MAX_PINHOLE_MISFIT_GUESSED: f64 = 0.12;

/// How much is known of the camera that took a frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Intrinsics {
    /// Its intrinsics are calibrated (a configured camera, the simulator).
    #[default]
    Known,
    /// Its focal length is a guess (a photo from an unknown camera).
    Guessed,
}
/// The four markers' sizes on the table may differ by this factor (blur and perspective make
/// the far ones look a little larger or smaller).
const MAX_TABLE_SIZE_RATIO: f64 = 1.6;
/// A marker's radius on the table, as a fraction of the sheet's shorter side, lies in this
/// range (Niryo's sheets: about 0.06).
const MARKER_SIZE_FRACTION: std::ops::Range<f64> = 0.015..0.2;
/// The grid of points sampled in the sheet's centre, per side.
const GRID: usize = 9;
/// The grid covers this part of the rectangle between the markers (clear of the markers and
/// of the printed borders, which reach about 8 % in).
const GRID_SPAN: (f64, f64) = (0.12, 0.88);
/// At least this share of the grid points in view must look like the sheet's paper (a large
/// box standing in the middle hides half of it).
const MIN_PAPER_SHARE: f64 = 0.25;

/// Checks that `four` markers (upper-left, upper-right, lower-left, lower-right), giving
/// `plane`, are the sheet whose marker centres are at `world` on the table. `Err` names the
/// first check that failed.
pub fn verify_sheet(
    camera: &Camera,
    intrinsics: Intrinsics,
    frame: &FrameView<'_>,
    plane: &TablePlane,
    four: &[MarkerObservation; 4],
    world: &[[f64; 2]; 4],
) -> Result<(), SheetCheck> {
    let k = camera.intrinsics();
    let size = f64::from(k.width.max(k.height));
    let (search, limit) = match intrinsics {
        Intrinsics::Known => ((0.0, 0.0), MAX_PINHOLE_MISFIT),
        Intrinsics::Guessed => ((0.2 * size, 8.0 * size), MAX_PINHOLE_MISFIT_GUESSED),
    };
    let misfit = plane.pinhole_misfit((k.cx, k.cy), k.fy / k.fx, k.fx, search);
    if misfit > limit {
        return Err(SheetCheck::Perspective);
    }

    let sizes: Vec<f64> = four
        .iter()
        .zip(world)
        .map(|(m, p)| m.radius_px / plane.pixels_per_metre_at(p[0], p[1]))
        .collect();
    let (lo, hi) = sizes
        .iter()
        .fold((f64::MAX, 0f64), |(lo, hi), s| (lo.min(*s), hi.max(*s)));
    let xs = world.map(|p| p[0]);
    let ys = world.map(|p| p[1]);
    let span = |v: [f64; 4]| {
        v.iter().copied().fold(f64::MIN, f64::max) - v.iter().copied().fold(f64::MAX, f64::min)
    };
    let shorter_side = span(xs).min(span(ys));
    let fraction = |s: f64| s / shorter_side;
    let agree = lo > 0.0 && hi <= MAX_TABLE_SIZE_RATIO * lo;
    let plausible = MARKER_SIZE_FRACTION.contains(&fraction(lo))
        && MARKER_SIZE_FRACTION.contains(&fraction(hi));
    if !(agree && plausible) {
        return Err(SheetCheck::TableSizes);
    }

    if paper_share(camera, frame, plane, four, world) < MIN_PAPER_SHARE {
        return Err(SheetCheck::Appearance);
    }
    let only_alike = four.iter().any(|m| {
        matches!(
            m.evidence,
            MarkerEvidence::Profile {
                distinct: false,
                ..
            }
        )
    });
    if only_alike
        && (hi > MAX_TABLE_SIZE_RATIO_ALIKE * lo
            || !border_matches(camera, frame, plane, four, world))
    {
        return Err(SheetCheck::Border);
    }
    Ok(())
}

/// With a marker only like its design, the four markers' sizes on the table may differ by
/// this factor at most.
const MAX_TABLE_SIZE_RATIO_ALIKE: f64 = 1.3;
/// Points sampled along each side between neighbouring markers (about five per stripe of the
/// classic sheet).
const BORDER_SAMPLES: usize = 60;
/// Stripes: the side's light and dark samples (90th and 10th percentiles) differ by this
/// share of the paper's level at least...
const STRIPE_CONTRAST: f64 = 0.07;
/// ...and alternate this many times at least.
const MIN_STRIPE_CROSSINGS: usize = 8;
/// They cover this part of the side (clear of the markers and their light discs).
const BORDER_SPAN: (f64, f64) = (0.15, 0.85);
/// A side shows its design when this share of its samples does.
const BORDER_SHARE: f64 = 0.7;

/// The sheet's border between neighbouring markers, through the homography: white paper for
/// the simulator's design (its markers' outer ring at 0.7 of their radius), the black frame
/// or the grey stripes for a printed one, the same on three sides of four at least (an object
/// may lie on one).
fn border_matches(
    camera: &Camera,
    frame: &FrameView<'_>,
    plane: &TablePlane,
    four: &[MarkerObservation; 4],
    world: &[[f64; 2]; 4],
) -> bool {
    let printed = four.iter().all(|m| m.ring_fraction > 0.775);
    // Around the edge: upper-left, upper-right, lower-right, lower-left.
    let sides = [(0, 1), (1, 3), (3, 2), (2, 0)];
    let mut kinds = [0usize; 3]; // paper, black, striped
    for (a, b) in sides {
        let paper = 0.5 * (f64::from(four[a].paper_grey) + f64::from(four[b].paper_grey));
        let mut greys = Vec::with_capacity(BORDER_SAMPLES);
        for i in 0..BORDER_SAMPLES {
            let t = BORDER_SPAN.0
                + (BORDER_SPAN.1 - BORDER_SPAN.0) * i as f64 / (BORDER_SAMPLES - 1) as f64;
            let (x, y) = (
                world[a][0] + t * (world[b][0] - world[a][0]),
                world[a][1] + t * (world[b][1] - world[a][1]),
            );
            let raw = camera.raw_of(plane.table_to_pixel(x, y));
            let (u, v) = (raw[0].round(), raw[1].round());
            if !(u >= 0.0 && v >= 0.0 && u < frame.width as f64 && v < frame.height as f64) {
                continue;
            }
            let at = (v as usize * frame.width + u as usize) * 3;
            if let Some(p) = frame.rgb.get(at..at + 3) {
                greys.push(
                    (f64::from(p[0]) * 77.0 + f64::from(p[1]) * 150.0 + f64::from(p[2]) * 29.0)
                        / 256.0,
                );
            }
        }
        if greys.len() < BORDER_SAMPLES / 2 {
            continue;
        }
        let share = |f: &dyn Fn(f64) -> bool| {
            greys.iter().filter(|g| f(**g)).count() as f64 / greys.len() as f64
        };
        let mut sorted = greys.clone();
        sorted.sort_by(f64::total_cmp);
        let (low, high) = (sorted[sorted.len() / 10], sorted[sorted.len() * 9 / 10]);
        let middle = 0.5 * (low + high);
        let crossings = greys
            .windows(2)
            .filter(|w| (w[0] < middle) != (w[1] < middle))
            .count();
        // The classic sheet's stripes cross the side every 13 mm or so, grey on white: light
        // and dark alternate many times (a light gradient or a shadow crosses once or twice).
        if high - low >= STRIPE_CONTRAST * paper && crossings >= MIN_STRIPE_CROSSINGS {
            kinds[2] += 1;
        } else if share(&|g| g >= 0.6 * paper) >= BORDER_SHARE {
            kinds[0] += 1;
        } else if share(&|g| g <= 0.45 * paper) >= BORDER_SHARE {
            kinds[1] += 1;
        }
    }
    if printed {
        kinds[1] >= 3 || kinds[2] >= 3
    } else {
        kinds[0] >= 3
    }
}

/// The share of a grid of points in the middle of the sheet that look like its paper: at
/// least 55 % as bright as the paper around the markers (shade and vignetting allowed) and
/// about grey (tinted light allowed). Points out of the frame do not count; with too few in
/// the frame, 0 (a sheet is found only when it is seen).
fn paper_share(
    camera: &Camera,
    frame: &FrameView<'_>,
    plane: &TablePlane,
    four: &[MarkerObservation; 4],
    world: &[[f64; 2]; 4],
) -> f64 {
    let paper = f64::from(four.iter().map(|m| m.paper_grey).min().unwrap_or(0));
    let (x0, x1) = (world[3][0], world[0][0]);
    let (y0, y1) = (world[3][1], world[0][1]);
    let (mut inside, mut light) = (0usize, 0usize);
    for i in 0..GRID {
        for j in 0..GRID {
            let t =
                |k: usize| GRID_SPAN.0 + (GRID_SPAN.1 - GRID_SPAN.0) * k as f64 / (GRID - 1) as f64;
            let (x, y) = (x0 + (x1 - x0) * t(i), y0 + (y1 - y0) * t(j));
            let raw = camera.raw_of(plane.table_to_pixel(x, y));
            let (u, v) = (raw[0].round(), raw[1].round());
            if !(u >= 0.0 && v >= 0.0 && u < frame.width as f64 && v < frame.height as f64) {
                continue;
            }
            let at = (v as usize * frame.width + u as usize) * 3;
            let Some(p) = frame.rgb.get(at..at + 3) else {
                continue;
            };
            inside += 1;
            let max = f64::from(p[0].max(p[1]).max(p[2]));
            let min = f64::from(p[0].min(p[1]).min(p[2]));
            let grey =
                (f64::from(p[0]) * 77.0 + f64::from(p[1]) * 150.0 + f64::from(p[2]) * 29.0) / 256.0;
            if grey >= 0.55 * paper && max - min <= (0.3 * max).max(25.0) {
                light += 1;
            }
        }
    }
    if inside < GRID * GRID / 4 {
        return 0.0;
    }
    light as f64 / inside as f64
}
