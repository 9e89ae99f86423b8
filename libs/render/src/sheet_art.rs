//! The workspace sheets as printed: what a real camera sees of them, for testing perception.
//!
//! The simulator's own sheet is plain white paper with four ring markers. Labs have two
//! printed designs from Niryo, and perception must hold on both:
//!
//! - [`SheetDesign::Classic`]: a white sheet with a wide border of grey diagonal stripes, the
//!   four ring markers in the border on white discs, the reference (upper-left) marker with a
//!   solid centre and one ring fewer than the others (whose centre is a small dot), a grey
//!   "NIRYO" logo in the middle, and the dark edge of the plate under it.
//! - [`SheetDesign::Ned2`]: a black frame with white ruler ticks along its inner edge, the
//!   markers on square black pads at the corners (each ring marker on a white disc), a white
//!   centre.
//! - [`SheetDesign::Plain`]: the simulator's sheet, for comparison.
//!
//! [`sheet_art`] adds one sheet's flat parts (quads and discs) to a [`RenderScene`]; marker
//! geometry follows the sheet's marker-centre rectangle and radius, so a renderer's pixels can
//! be checked against where the markers really are.

use crate::scene::{Disc, RenderScene, Rgb};
use nalgebra::Point3;

/// A printed workspace sheet design.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SheetDesign {
    /// The simulator's plain white sheet.
    Plain,
    /// Niryo's classic sheet: grey striped border, logo in the middle.
    Classic,
    /// The Ned2 sheet: black frame with ruler ticks, markers on black corner pads.
    Ned2,
}

/// Printed black (never quite black on paper).
const INK: Rgb = [28, 28, 30];
/// The paper.
const PAPER: Rgb = [246, 246, 242];
/// The grey of the classic sheet's stripes and logo.
const STRIPE: Rgb = [168, 168, 170];
/// Heights of the printed layers, metres (above the paper, below any object).
const PAPER_Z: f64 = 0.0002;
const PRINT_Z: f64 = 0.0003;
const MARKER_Z: f64 = 0.0004;

/// Where one sheet lies: the rectangle of its four marker centres and the markers' size.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SheetPlacement {
    /// Marker centres span `x_min..x_max` × `y_min..y_max` (metres, table frame); the
    /// reference marker is at `(x_max, y_max)`, the sheet's upper-left.
    pub x_min: f64,
    /// See `x_min`.
    pub x_max: f64,
    /// See `x_min`.
    pub y_min: f64,
    /// See `x_min`.
    pub y_max: f64,
    /// Outer radius of a marker, metres.
    pub marker_radius_m: f64,
}

impl SheetPlacement {
    /// The four marker centres: upper-left (the reference), upper-right, lower-left,
    /// lower-right, as `(x, y)`.
    pub fn marker_centres(&self) -> [[f64; 2]; 4] {
        [
            [self.x_max, self.y_max],
            [self.x_max, self.y_min],
            [self.x_min, self.y_max],
            [self.x_min, self.y_min],
        ]
    }
}

/// Dark bands of a marker (inner, outer fractions of its radius), from the centre out.
fn marker_bands(design: SheetDesign, reference: bool) -> &'static [(f64, f64)] {
    match (design, reference) {
        // The simulator's: the origin's centre is white, the others' black.
        (SheetDesign::Plain, true) => &[(0.2, 0.45), (0.7, 1.0)],
        (SheetDesign::Plain, false) => &[(0.0, 0.45), (0.7, 1.0)],
        // Niryo's printed markers: the reference has a solid centre and one ring fewer.
        (_, true) => &[(0.0, 0.3), (0.5, 0.7), (0.85, 1.0)],
        (_, false) => &[(0.0, 0.08), (0.25, 0.4), (0.55, 0.7), (0.85, 1.0)],
    }
}

/// Adds the flat parts of a sheet of `design` at `placement` to `scene` (quads and discs, on
/// top of what is there).
pub fn sheet_art(design: SheetDesign, placement: &SheetPlacement, scene: &mut RenderScene) {
    let p = placement;
    let r = p.marker_radius_m;
    let quad = |x0: f64, x1: f64, y0: f64, y1: f64, z: f64| {
        [
            Point3::new(x0, y0, z),
            Point3::new(x1, y0, z),
            Point3::new(x1, y1, z),
            Point3::new(x0, y1, z),
        ]
    };
    // Paper reaches this far beyond the marker centres; the plain centre starts this far in.
    let (outer, inner) = match design {
        SheetDesign::Plain => (1.8 * r, 0.0),
        SheetDesign::Classic => (2.2 * r, 1.4 * r),
        SheetDesign::Ned2 => (2.0 * r, 1.5 * r),
    };
    let (ox0, ox1, oy0, oy1) = (
        p.x_min - outer,
        p.x_max + outer,
        p.y_min - outer,
        p.y_max + outer,
    );
    match design {
        SheetDesign::Plain => scene.quads.push((quad(ox0, ox1, oy0, oy1, PAPER_Z), PAPER)),
        SheetDesign::Classic => {
            // The plate's dark edge, the paper, the striped border, the plain centre.
            let rim = 0.004;
            scene.quads.push((
                quad(ox0 - rim, ox1 + rim, oy0 - rim, oy1 + rim, PAPER_Z * 0.5),
                INK,
            ));
            scene.quads.push((quad(ox0, ox1, oy0, oy1, PAPER_Z), PAPER));
            let band = [ox0 + 0.002, ox1 - 0.002, oy0 + 0.002, oy1 - 0.002];
            stripes(band, scene);
            let (ix0, ix1, iy0, iy1) = (
                p.x_min + inner,
                p.x_max - inner,
                p.y_min + inner,
                p.y_max - inner,
            );
            scene.quads.push((quad(ix0, ix1, iy0, iy1, PRINT_Z), PAPER));
            logo(p, scene);
        }
        SheetDesign::Ned2 => {
            scene.quads.push((quad(ox0, ox1, oy0, oy1, PAPER_Z), INK));
            let (ix0, ix1, iy0, iy1) = (
                p.x_min + inner,
                p.x_max - inner,
                p.y_min + inner,
                p.y_max - inner,
            );
            scene.quads.push((quad(ix0, ix1, iy0, iy1, PRINT_Z), PAPER));
            // Ruler ticks every 5 mm (longer every 10 mm) on the frame, along the inner edge.
            let step = 0.005;
            for k in 1..((ix1 - ix0) / step) as usize {
                let x = ix0 + k as f64 * step;
                let len = if k % 2 == 0 { 0.006 } else { 0.0035 };
                for (y_edge, dir) in [(iy0, -1.0), (iy1, 1.0)] {
                    let (a, b) = (y_edge + dir * 0.001, y_edge + dir * (0.001 + len));
                    scene.quads.push((
                        quad(x - 0.0004, x + 0.0004, a.min(b), a.max(b), PRINT_Z),
                        PAPER,
                    ));
                }
            }
            for k in 1..((iy1 - iy0) / step) as usize {
                let y = iy0 + k as f64 * step;
                let len = if k % 2 == 0 { 0.006 } else { 0.0035 };
                for (x_edge, dir) in [(ix0, -1.0), (ix1, 1.0)] {
                    let (a, b) = (x_edge + dir * 0.001, x_edge + dir * (0.001 + len));
                    scene.quads.push((
                        quad(a.min(b), a.max(b), y - 0.0004, y + 0.0004, PRINT_Z),
                        PAPER,
                    ));
                }
            }
        }
    }
    // The markers: on a white disc (the classic border's stripes, the Ned2's black pad).
    for (k, [x, y]) in p.marker_centres().into_iter().enumerate() {
        let reference = k == 0;
        let at = Point3::new(x, y, MARKER_Z);
        if design != SheetDesign::Plain {
            scene.discs.push(Disc {
                center: at,
                radius_m: 1.3 * r,
                color: PAPER,
            });
        }
        for &(inside, outside) in marker_bands(design, reference).iter().rev() {
            scene.discs.push(Disc {
                center: at,
                radius_m: outside * r,
                color: INK,
            });
            if inside > 0.0 {
                scene.discs.push(Disc {
                    center: at,
                    radius_m: inside * r,
                    color: PAPER,
                });
            }
        }
    }
}

/// Grey stripes at 45° over the rectangle `[x0, x1, y0, y1]` (clipped to it), 4 mm wide every
/// 9 mm.
fn stripes([x0, x1, y0, y1]: [f64; 4], scene: &mut RenderScene) {
    let (period, width) = (0.009, 0.004);
    // Stripes are the bands c ≤ x + y ≤ c + width.
    let (lo, hi) = (x0 + y0, x1 + y1);
    let mut c = lo - width;
    while c < hi {
        let band = [
            [x0, c - x0],
            [x1, c - x1],
            [x1, c + width - x1],
            [x0, c + width - x0],
        ];
        let clipped = clip_to_rect(&band, [x0, x1, y0, y1]);
        push_polygon(&clipped, PRINT_Z, STRIPE, scene);
        c += period;
    }
}

/// A stand-in for the printed logo: "NIRYO" in grey strokes 1.5 mm wide and a thin wave
/// above it, a little left of the sheet's centre (thin lines a detector must not take for
/// objects).
fn logo(p: &SheetPlacement, scene: &mut RenderScene) {
    let (cx, cy) = (0.5 * (p.x_min + p.x_max), 0.5 * (p.y_min + p.y_max));
    let (stroke, tall, wide, gap) = (0.0015, 0.012, 0.008, 0.004);
    // Letters run along −y (the image's left to right from the observation pose), rows along x.
    let mut y = cy + 2.5 * (wide + gap);
    // Strokes of each letter in its own box: (x0, y0) → (x1, y1) in units of (tall, wide).
    let letters: [&[[f64; 4]]; 5] = [
        &[
            [0.0, 0.0, 1.0, 0.0],
            [0.0, 1.0, 1.0, 1.0],
            [1.0, 0.0, 0.0, 1.0],
        ],
        &[[0.0, 0.5, 1.0, 0.5]],
        &[
            [0.0, 0.0, 1.0, 0.0],
            [1.0, 0.0, 1.0, 0.8],
            [1.0, 0.8, 0.5, 0.8],
            [0.5, 0.0, 0.0, 0.8],
        ],
        &[
            [1.0, 0.0, 0.5, 0.5],
            [1.0, 1.0, 0.5, 0.5],
            [0.5, 0.5, 0.0, 0.5],
        ],
        &[
            [0.0, 0.0, 1.0, 0.0],
            [0.0, 1.0, 1.0, 1.0],
            [0.0, 0.0, 0.0, 1.0],
            [1.0, 0.0, 1.0, 1.0],
        ],
    ];
    let x_base = cx - 0.5 * tall;
    for strokes in letters {
        for s in strokes {
            let a = [x_base + s[0] * tall, y - s[1] * wide];
            let b = [x_base + s[2] * tall, y - s[3] * wide];
            thick_line(a, b, stroke, PRINT_Z, STRIPE, scene);
        }
        y -= wide + gap;
    }
    // The wave: a thin curve above the letters.
    let n = 12;
    for k in 0..n {
        let t = |k: usize| k as f64 / n as f64;
        let pt = |t: f64| {
            [
                cx + 0.012 + 0.004 * (t * std::f64::consts::TAU).sin(),
                cy + 0.03 - 0.06 * t,
            ]
        };
        thick_line(pt(t(k)), pt(t(k + 1)), 0.0008, PRINT_Z, STRIPE, scene);
    }
}

/// A straight stroke from `a` to `b`, `width` wide, at height `z`.
pub fn thick_line(
    a: [f64; 2],
    b: [f64; 2],
    width: f64,
    z: f64,
    color: Rgb,
    scene: &mut RenderScene,
) {
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    let len = dx.hypot(dy);
    if len.is_nan() || len <= 0.0 {
        return;
    }
    let (nx, ny) = (-dy / len * width / 2.0, dx / len * width / 2.0);
    scene.quads.push((
        [
            Point3::new(a[0] + nx, a[1] + ny, z),
            Point3::new(b[0] + nx, b[1] + ny, z),
            Point3::new(b[0] - nx, b[1] - ny, z),
            Point3::new(a[0] - nx, a[1] - ny, z),
        ],
        color,
    ));
}

/// A convex polygon (at most 8 corners) as quads fanned from its first corner (a triangle
/// is a quad with a repeated corner).
fn push_polygon(points: &[[f64; 2]], z: f64, color: Rgb, scene: &mut RenderScene) {
    if points.len() < 3 {
        return;
    }
    let at = |p: [f64; 2]| Point3::new(p[0], p[1], z);
    let mut k = 1;
    while k + 1 < points.len() {
        let third = points[k + 1];
        let fourth = points.get(k + 2).copied().unwrap_or(third);
        scene
            .quads
            .push(([at(points[0]), at(points[k]), at(third), at(fourth)], color));
        k += 2;
    }
}

/// Sutherland–Hodgman: a convex polygon clipped to the rectangle `[x0, x1, y0, y1]`.
fn clip_to_rect(polygon: &[[f64; 2]], [x0, x1, y0, y1]: [f64; 4]) -> Vec<[f64; 2]> {
    let mut points = polygon.to_vec();
    // Each edge: inside when `value(p) ≥ 0`.
    let edges: [&dyn Fn([f64; 2]) -> f64; 4] =
        [&|p| p[0] - x0, &|p| x1 - p[0], &|p| p[1] - y0, &|p| {
            y1 - p[1]
        }];
    for inside in edges {
        let mut out = Vec::with_capacity(points.len() + 2);
        for i in 0..points.len() {
            let (a, b) = (points[i], points[(i + 1) % points.len()]);
            let (da, db) = (inside(a), inside(b));
            if da >= 0.0 {
                out.push(a);
            }
            if (da >= 0.0) != (db >= 0.0) {
                let t = da / (da - db);
                out.push([a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])]);
            }
        }
        points = out;
        if points.is_empty() {
            break;
        }
    }
    points
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stripes_stay_inside_their_rectangle() {
        let mut scene = RenderScene {
            background: [0; 3],
            table_z_m: 0.0,
            quads: vec![],
            discs: vec![],
            solids: vec![],
        };
        stripes([0.0, 0.1, -0.05, 0.05], &mut scene);
        assert!(scene.quads.len() > 10);
        for (corners, _) in &scene.quads {
            for c in corners {
                assert!((-1e-9..=0.1 + 1e-9).contains(&c.x), "{c:?}");
                assert!((-0.05 - 1e-9..=0.05 + 1e-9).contains(&c.y), "{c:?}");
            }
        }
    }
}
