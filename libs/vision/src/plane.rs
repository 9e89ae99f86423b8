//! The table plane as the camera sees it: a homography from four markers, the camera's
//! position recovered from it, and pixel → world with parallax for raised points.
//!
//! The four corner markers of a workspace sheet are at known table coordinates. Their
//! (undistorted) pixel positions fix the homography `H` between the table plane and the
//! image, and with the camera's intrinsics `K`, `K⁻¹·H = λ·[r₁ r₂ t]` gives the camera's pose
//! relative to the table — so the camera's height and position come from pixels too, not from
//! the arm's kinematics. A pixel then maps to the table point under it, and a point known to
//! be at height `z` (the top face of a 3 cm cube) to where it really is: along the viewing ray,
//! `X = C + (X₀ − C)·(C_z − z)/C_z`.
//!
//! ```
//! use robotd_vision::plane::TablePlane;
//! use robotd_render::Intrinsics;
//!
//! // A camera 0.3 m above (0.25, 0), looking straight down, image x along world −y.
//! let k = Intrinsics { distortion: [0.0; 5], ..Intrinsics::ned2() };
//! let project = |x: f64, y: f64| {
//!     let (xc, yc, zc) = (-(y - 0.0), -(x - 0.25), 0.3);
//!     [k.fx * xc / zc + k.cx, k.fy * yc / zc + k.cy]
//! };
//! let world = [[0.3, 0.1], [0.3, -0.1], [0.2, 0.1], [0.2, -0.1]];
//! let pixels = world.map(|[x, y]| project(x, y));
//! let plane = TablePlane::from_correspondences(&pixels, &world, &k).unwrap();
//! assert!((plane.camera_centre()[2] - 0.3).abs() < 1e-6);
//! let p = plane.pixel_to_plane(project(0.27, 0.02), 0.0);
//! assert!((p[0] - 0.27).abs() < 1e-9 && (p[1] - 0.02).abs() < 1e-9);
//! ```

use nalgebra::{Matrix3, SMatrix, SVector, Vector3};
use robotd_render::Intrinsics;

/// The table plane of one frame: homography both ways and the camera centre.
#[derive(Debug, Clone, PartialEq)]
pub struct TablePlane {
    /// Table (x, y, 1) → ideal pixel (u, v, w).
    world_to_pixel: Matrix3<f64>,
    /// Ideal pixel → table point.
    pixel_to_world: Matrix3<f64>,
    /// Camera centre in the robot base frame, metres.
    camera: Vector3<f64>,
}

impl TablePlane {
    /// The plane through four (or more, least squares) correspondences of ideal pixels and
    /// table points. `None` when the points are degenerate (three in a line, repeated) or
    /// when they are in mirror order (the camera would have to be under the table).
    pub fn from_correspondences(
        ideal_px: &[[f64; 2]],
        world: &[[f64; 2]],
        intrinsics: &Intrinsics,
    ) -> Option<TablePlane> {
        let world_to_pixel = homography(world, ideal_px)?;
        let pixel_to_world = world_to_pixel.try_inverse()?;
        let k = Matrix3::new(
            intrinsics.fx,
            0.0,
            intrinsics.cx,
            0.0,
            intrinsics.fy,
            intrinsics.cy,
            0.0,
            0.0,
            1.0,
        );
        let m = k.try_inverse()? * world_to_pixel;
        let (a1, a2, a3) = (m.column(0), m.column(1), m.column(2));
        let norm = 0.5 * (a1.norm() + a2.norm());
        if !(norm.is_finite() && norm > 0.0) {
            return None;
        }
        let mut lambda = 1.0 / norm;
        if a3.z < 0.0 {
            lambda = -lambda; // the table must be in front of the camera
        }
        let r1: Vector3<f64> = a1 * lambda;
        let r2: Vector3<f64> = a2 * lambda;
        let t: Vector3<f64> = a3 * lambda;
        let r3 = r1.cross(&r2);
        let r = Matrix3::from_columns(&[r1, r2, r3]);
        let camera = -(r.transpose() * t);
        if !(camera.iter().all(|c| c.is_finite()) && camera.z > 0.0) {
            return None;
        }
        Some(TablePlane {
            world_to_pixel,
            pixel_to_world,
            camera,
        })
    }

    /// How far the plane is from what any pinhole camera could see of the table rectangle:
    /// the smallest, over focal lengths from `f_min` to `f_max` pixels (and `f_hint`), of the
    /// relative difference in length plus the cosine between the two table axes as the
    /// camera sees them (`K⁻¹·H = λ·[r₁ r₂ t]`: `r₁`, `r₂` must be orthonormal). The principal
    /// point is taken at `(cx, cy)`; pixels are `aspect` (fy/fx) times as tall as wide.
    ///
    /// Four points always fit a homography, so this is the check that four image points can be
    /// the four corners of the configured rectangle at all: a quadrilateral through a wrong
    /// point (an object taken for a marker), or the corners of two different sheets, has no
    /// focal length that makes it a rectangle of the right proportions. 0 is a perfect fit; a
    /// real sheet through a real lens scores a few hundredths.
    pub fn pinhole_misfit(
        &self,
        (cx, cy): (f64, f64),
        aspect: f64,
        f_hint: f64,
        (f_min, f_max): (f64, f64),
    ) -> f64 {
        let h = &self.world_to_pixel;
        let column = |j: usize| {
            [
                h[(0, j)] - cx * h[(2, j)],
                h[(1, j)] - cy * h[(2, j)],
                h[(2, j)],
            ]
        };
        let (m1, m2) = (column(0), column(1));
        let misfit = |f: f64| {
            let fy = f * aspect;
            let a1 = Vector3::new(m1[0] / f, m1[1] / fy, m1[2]);
            let a2 = Vector3::new(m2[0] / f, m2[1] / fy, m2[2]);
            let (n1, n2) = (a1.norm(), a2.norm());
            if !(n1 > 0.0 && n2 > 0.0) {
                return f64::INFINITY;
            }
            2.0 * (n1 - n2).abs() / (n1 + n2) + (a1.dot(&a2) / (n1 * n2)).abs()
        };
        let mut best = misfit(f_hint);
        if f_min > 0.0 && f_max > f_min {
            const STEPS: usize = 96;
            let ratio = (f_max / f_min).ln();
            for k in 0..=STEPS {
                let f = f_min * (ratio * k as f64 / STEPS as f64).exp();
                best = best.min(misfit(f));
            }
        }
        if best.is_finite() {
            best
        } else {
            f64::INFINITY
        }
    }

    /// How many raw-image pixels a metre of table spans around table point `(x, y)`, along x
    /// and along y (mean): the local scale of the view.
    pub fn pixels_per_metre_at(&self, x_m: f64, y_m: f64) -> f64 {
        let d = 0.005;
        let p = self.table_to_pixel(x_m, y_m);
        let px = self.table_to_pixel(x_m + d, y_m);
        let py = self.table_to_pixel(x_m, y_m + d);
        let along = |q: [f64; 2]| (q[0] - p[0]).hypot(q[1] - p[1]) / d;
        0.5 * (along(px) + along(py))
    }

    /// The camera centre (x, y, z) in the base frame, metres.
    pub fn camera_centre(&self) -> [f64; 3] {
        [self.camera.x, self.camera.y, self.camera.z]
    }

    /// The table point (z = 0) an ideal pixel looks at.
    pub fn pixel_to_table(&self, ideal_px: [f64; 2]) -> [f64; 2] {
        let p = self.pixel_to_world * Vector3::new(ideal_px[0], ideal_px[1], 1.0);
        [p.x / p.z, p.y / p.z]
    }

    /// The point at height `z_m` that an ideal pixel looks at.
    pub fn pixel_to_plane(&self, ideal_px: [f64; 2], z_m: f64) -> [f64; 2] {
        let [x0, y0] = self.pixel_to_table(ideal_px);
        let c = &self.camera;
        let s = (c.z - z_m) / c.z;
        [c.x + (x0 - c.x) * s, c.y + (y0 - c.y) * s]
    }

    /// The ideal pixel a table point (z = 0) appears at.
    pub fn table_to_pixel(&self, x_m: f64, y_m: f64) -> [f64; 2] {
        let p = self.world_to_pixel * Vector3::new(x_m, y_m, 1.0);
        [p.x / p.z, p.y / p.z]
    }
}

/// The homography mapping `from[i]` to `to[i]` (at least four pairs), with `h₃₃ = 1`, solved
/// on normalised coordinates for good conditioning. `None` when degenerate.
pub fn homography(from: &[[f64; 2]], to: &[[f64; 2]]) -> Option<Matrix3<f64>> {
    if from.len() < 4 || from.len() != to.len() {
        return None;
    }
    let (nf, f) = normaliser(from)?;
    let (nt, t) = normaliser(to)?;
    // Normal equations of the 2n × 8 system A·h = b.
    let mut ata = SMatrix::<f64, 8, 8>::zeros();
    let mut atb = SVector::<f64, 8>::zeros();
    for (p, q) in f.iter().zip(&t) {
        let (x, y, u, v) = (p[0], p[1], q[0], q[1]);
        let rows = [
            ([x, y, 1.0, 0.0, 0.0, 0.0, -u * x, -u * y], u),
            ([0.0, 0.0, 0.0, x, y, 1.0, -v * x, -v * y], v),
        ];
        for (row, rhs) in rows {
            let r = SVector::<f64, 8>::from_row_slice(&row);
            ata += r * r.transpose();
            atb += r * rhs;
        }
    }
    let h = ata.lu().solve(&atb)?;
    if h.iter().any(|v| !v.is_finite()) {
        return None;
    }
    let hn = Matrix3::new(h[0], h[1], h[2], h[3], h[4], h[5], h[6], h[7], 1.0);
    let full = nt.try_inverse()? * hn * nf;
    let scale = full[(2, 2)];
    if !(scale.is_finite() && scale.abs() > 1e-12) {
        return None;
    }
    let full = full / scale;
    (full.determinant().abs() > 1e-12).then_some(full)
}

/// A similarity moving the points' centroid to the origin with mean distance √2.
fn normaliser(points: &[[f64; 2]]) -> Option<(Matrix3<f64>, Vec<[f64; 2]>)> {
    let n = points.len() as f64;
    let cx = points.iter().map(|p| p[0]).sum::<f64>() / n;
    let cy = points.iter().map(|p| p[1]).sum::<f64>() / n;
    let mean = points
        .iter()
        .map(|p| ((p[0] - cx).powi(2) + (p[1] - cy).powi(2)).sqrt())
        .sum::<f64>()
        / n;
    if !(mean.is_finite() && mean > 1e-12) {
        return None;
    }
    let s = std::f64::consts::SQRT_2 / mean;
    let m = Matrix3::new(s, 0.0, -s * cx, 0.0, s, -s * cy, 0.0, 0.0, 1.0);
    let moved = points
        .iter()
        .map(|p| [s * (p[0] - cx), s * (p[1] - cy)])
        .collect();
    Some((m, moved))
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion};

    fn camera_looking_down(at: [f64; 3], tilt: f64) -> Isometry3<f64> {
        // Optical frame: z forward (down, tilted about world y), x along world −y.
        let down = UnitQuaternion::from_euler_angles(
            std::f64::consts::PI,
            0.0,
            -std::f64::consts::FRAC_PI_2,
        );
        let tilt = UnitQuaternion::from_euler_angles(0.0, tilt, 0.0);
        Isometry3::from_parts(Translation3::new(at[0], at[1], at[2]), tilt * down)
    }

    #[test]
    fn recovers_camera_and_parallax_of_a_tilted_camera() {
        let k = Intrinsics {
            distortion: [0.0; 5],
            ..Intrinsics::ned2()
        };
        let pose = camera_looking_down([0.17, 0.01, 0.28], 0.25);
        let inv = pose.inverse();
        let px = |x: f64, y: f64, z: f64| {
            let p = k.project(&inv, &Point3::new(x, y, z)).unwrap();
            [p.x, p.y]
        };
        let world = [
            [0.337, 0.087],
            [0.337, -0.087],
            [0.163, 0.087],
            [0.163, -0.087],
        ];
        let pixels = world.map(|[x, y]| px(x, y, 0.0));
        let plane = TablePlane::from_correspondences(&pixels, &world, &k).unwrap();
        let c = plane.camera_centre();
        for (a, b) in c.iter().zip([0.17, 0.01, 0.28]) {
            assert!((a - b).abs() < 1e-9, "camera {c:?}");
        }
        // The top corner of a 3 cm cube: the table point under its pixel is farther out, the
        // plane at 3 cm gives it back exactly.
        let top = px(0.30, 0.05, 0.03);
        let on_table = plane.pixel_to_table(top);
        assert!((on_table[0] - 0.30).abs() > 0.003);
        let back = plane.pixel_to_plane(top, 0.03);
        assert!((back[0] - 0.30).abs() < 1e-9 && (back[1] - 0.05).abs() < 1e-9);
        let round = plane.table_to_pixel(0.2, -0.05);
        let want = px(0.2, -0.05, 0.0);
        assert!((round[0] - want[0]).abs() < 1e-6 && (round[1] - want[1]).abs() < 1e-6);

        // Mirror order (two corners swapped) is refused.
        let mirrored = [pixels[0], pixels[2], pixels[1], pixels[3]];
        assert!(TablePlane::from_correspondences(&mirrored, &world, &k).is_none());
    }

    #[test]
    fn only_a_rectangle_of_the_right_proportions_fits_a_pinhole() {
        let k = Intrinsics {
            distortion: [0.0; 5],
            ..Intrinsics::ned2()
        };
        let inv = camera_looking_down([0.2, 0.03, 0.3], 0.4).inverse();
        let px = |x: f64, y: f64| {
            let p = k.project(&inv, &Point3::new(x, y, 0.0)).unwrap();
            [p.x, p.y]
        };
        let world = [
            [0.337, 0.087],
            [0.337, -0.087],
            [0.163, 0.087],
            [0.163, -0.087],
        ];
        let fit = |pixels: [[f64; 2]; 4]| {
            TablePlane::from_correspondences(&pixels, &world, &k)
                .map(|p| p.pinhole_misfit((k.cx, k.cy), k.fy / k.fx, k.fx, (100.0, 5000.0)))
        };
        let fixed = |pixels: [[f64; 2]; 4]| {
            TablePlane::from_correspondences(&pixels, &world, &k)
                .map(|p| p.pinhole_misfit((k.cx, k.cy), k.fy / k.fx, k.fx, (0.0, 0.0)))
        };
        let truth = world.map(|[x, y]| px(x, y));
        assert!(fit(truth).unwrap() < 1e-6, "{:?}", fit(truth));
        assert!(fixed(truth).unwrap() < 1e-6, "{:?}", fixed(truth));
        // The same square, but one corner is really an object 3 cm in from it.
        let mut moved = truth;
        moved[3] = px(0.163 + 0.03, -0.087 + 0.03);
        let fixed = |pixels: [[f64; 2]; 4]| {
            TablePlane::from_correspondences(&pixels, &world, &k)
                .map(|p| p.pinhole_misfit((k.cx, k.cy), k.fy / k.fx, k.fx, (0.0, 0.0)))
        };
        // A free focal length explains some of that away; the camera's own does not.
        assert!(fit(moved).unwrap() > 0.01, "{:?}", fit(moved));
        let misfit = fixed(moved).unwrap();
        assert!(misfit > 0.15, "{misfit}");
        let mut one_cm = truth;
        one_cm[3] = px(0.163 + 0.01, -0.087);
        assert!(fixed(one_cm).unwrap() > 0.08, "{:?}", fixed(one_cm));
        // Two corners of this sheet and two of a second one beside it: a 2:1 rectangle.
        let wide = [
            px(0.337, 0.087),
            px(0.337, -0.261),
            px(0.163, 0.087),
            px(0.163, -0.261),
        ];
        assert!(fixed(wide).is_none_or(|m| m > 0.3), "{:?}", fixed(wide));
    }

    #[test]
    fn degenerate_points_are_refused() {
        let k = Intrinsics::ned2();
        let line = [[0.0, 0.0], [1.0, 1.0], [2.0, 2.0], [3.0, 3.0]];
        assert!(TablePlane::from_correspondences(&line, &line, &k).is_none());
        let same = [[1.0, 1.0]; 4];
        assert!(homography(&same, &same).is_none());
        assert!(homography(&line[..3], &line[..3]).is_none());
    }
}
