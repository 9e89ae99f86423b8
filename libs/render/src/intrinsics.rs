//! Camera intrinsics: pinhole projection and the OpenCV (Brown–Conrady) lens distortion model.

use nalgebra::{Isometry3, Point2, Point3};
use robotd_protocol::camera::CameraIntrinsics;

/// Pinhole intrinsics and lens distortion of a camera, in pixels, for one image size.
///
/// Pixel coordinates follow OpenCV: `(0, 0)` is the *centre* of the top-left pixel, `u` grows to
/// the right and `v` downwards, so the pixel that a projected point falls on is
/// `(u.round(), v.round())`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Intrinsics {
    /// Image width, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
    /// Focal length along `u`, pixels.
    pub fx: f64,
    /// Focal length along `v`, pixels.
    pub fy: f64,
    /// Principal point `u`, pixels.
    pub cx: f64,
    /// Principal point `v`, pixels.
    pub cy: f64,
    /// Distortion coefficients `[k1, k2, p1, p2, k3]` (OpenCV order and model).
    pub distortion: [f64; 5],
}

/// Largest normalised radius (`r = |(x/z, y/z)|`, i.e. about 76° off axis) the distortion model
/// is evaluated at.
const R_LIMIT: f64 = 4.0;

impl Intrinsics {
    /// The Niryo Ned2 wrist camera: 640×480, fx 508.069, fy 506.445, cx 332.821, cy 242.984,
    /// distortion k1 −0.4146402, k2 0.2407384, p1 0, p2 0, k3 −0.1040042 (what the robot's
    /// `GET_CAMERA_INTRINSICS` answers).
    pub fn ned2() -> Self {
        Self {
            width: 640,
            height: 480,
            fx: 508.069,
            fy: 506.445,
            cx: 332.821,
            cy: 242.984,
            distortion: [-0.4146402, 0.2407384, 0.0, 0.0, -0.1040042],
        }
    }

    /// Where a world point appears in the ideal (undistorted) image: pinhole projection with
    /// `fx, fy, cx, cy`, no lens distortion. `camera_from_world` is the inverse of the camera's
    /// optical-frame pose (z forward, x right, y down).
    ///
    /// `None` when the point is on or behind the camera plane, or when anything is not finite.
    /// The result may lie outside the image. Apply [`Intrinsics::distort`] to get where the
    /// point appears in an image rendered with lens distortion.
    pub fn project(
        &self,
        camera_from_world: &Isometry3<f64>,
        p_world: &Point3<f64>,
    ) -> Option<Point2<f64>> {
        let p = camera_from_world * p_world;
        if p.z.is_nan() || p.z <= 0.0 {
            return None;
        }
        let u = self.fx * p.x / p.z + self.cx;
        let v = self.fy * p.y / p.z + self.cy;
        (u.is_finite() && v.is_finite()).then(|| Point2::new(u, v))
    }

    /// Moves an ideal pixel to where the lens puts it (OpenCV's model with `k1, k2, p1, p2, k3`).
    /// With the Ned2's barrel distortion, points move towards the principal point, the more the
    /// farther out they are.
    pub fn distort(&self, ideal_px: Point2<f64>) -> Point2<f64> {
        let x = (ideal_px.x - self.cx) / self.fx;
        let y = (ideal_px.y - self.cy) / self.fy;
        let (xd, yd) = distort_normalised(&self.distortion, x, y);
        Point2::new(xd * self.fx + self.cx, yd * self.fy + self.cy)
    }

    /// The inverse of [`Intrinsics::distort`]: the ideal pixel that the lens moved to
    /// `distorted_px` (what a detector needs to turn a pixel into a viewing ray).
    ///
    /// A polynomial model like the Ned2's folds back far off axis: its distorted radius stops
    /// growing about 47° off axis, and the Ned2's image corners lie a little beyond that. There
    /// the inverse is continued radially in proportion, so it stays monotonic and finite.
    pub fn undistort(&self, distorted_px: Point2<f64>) -> Point2<f64> {
        Undistorter::new(&self.distortion).ideal_pixel(self, distorted_px)
    }

    /// Whether the numbers can describe a camera: positive image size, finite positive focal
    /// lengths, finite principal point and distortion.
    pub fn is_valid(&self) -> bool {
        self.width > 0
            && self.height > 0
            && self.fx.is_finite()
            && self.fy.is_finite()
            && self.fx > 0.0
            && self.fy > 0.0
            && self.cx.is_finite()
            && self.cy.is_finite()
            && self.distortion.iter().all(|k| k.is_finite())
    }
}

impl From<CameraIntrinsics> for Intrinsics {
    fn from(c: CameraIntrinsics) -> Self {
        Self {
            width: c.width,
            height: c.height,
            fx: c.fx,
            fy: c.fy,
            cx: c.cx,
            cy: c.cy,
            distortion: c.distortion,
        }
    }
}

impl From<Intrinsics> for CameraIntrinsics {
    fn from(i: Intrinsics) -> Self {
        Self {
            width: i.width,
            height: i.height,
            fx: i.fx,
            fy: i.fy,
            cx: i.cx,
            cy: i.cy,
            distortion: i.distortion,
        }
    }
}

/// OpenCV's distortion of normalised image coordinates.
fn distort_normalised(k: &[f64; 5], x: f64, y: f64) -> (f64, f64) {
    let [k1, k2, p1, p2, k3] = *k;
    let r2 = x * x + y * y;
    let radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
    let xd = x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x);
    let yd = y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y;
    (xd, yd)
}

/// Inverts the distortion model, precomputing where its radial part stops being monotonic.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Undistorter {
    k: [f64; 5],
    /// Largest ideal radius up to which the radial map `g(r) = r (1 + k1 r² + k2 r⁴ + k3 r⁶)`
    /// increases.
    r_max: f64,
    /// `g(r_max)`.
    rd_max: f64,
}

impl Undistorter {
    pub(crate) fn new(k: &[f64; 5]) -> Self {
        let k = *k;
        let probe = Self {
            k,
            r_max: R_LIMIT,
            rd_max: 0.0,
        };
        // First radius where g' drops to zero: scan, then bisect.
        let steps = 4000;
        let mut r_max = R_LIMIT;
        let mut prev = 0.0;
        for i in 1..=steps {
            let r = R_LIMIT * f64::from(i) / f64::from(steps);
            let slope = probe.dg(r);
            if slope.is_nan() || slope <= 0.0 {
                let (mut lo, mut hi) = (prev, r);
                for _ in 0..60 {
                    let mid = 0.5 * (lo + hi);
                    if probe.dg(mid) > 0.0 {
                        lo = mid;
                    } else {
                        hi = mid;
                    }
                }
                r_max = lo;
                break;
            }
            prev = r;
        }
        let mut rd_max = probe.g(r_max);
        if !(rd_max.is_finite() && rd_max > 0.0) {
            // Only with absurd coefficients: fall back to no radial distortion.
            r_max = R_LIMIT;
            rd_max = R_LIMIT;
            return Self {
                k: [0.0, 0.0, k[2], k[3], 0.0],
                r_max,
                rd_max,
            };
        }
        Self { k, r_max, rd_max }
    }

    fn g(&self, r: f64) -> f64 {
        let [k1, k2, _, _, k3] = self.k;
        let r2 = r * r;
        r * (1.0 + r2 * (k1 + r2 * (k2 + r2 * k3)))
    }

    fn dg(&self, r: f64) -> f64 {
        let [k1, k2, _, _, k3] = self.k;
        let r2 = r * r;
        1.0 + r2 * (3.0 * k1 + r2 * (5.0 * k2 + r2 * 7.0 * k3))
    }

    /// Ideal radius whose distorted radius is `rd` (radial part only).
    fn radial_inverse(&self, rd: f64) -> f64 {
        if rd >= self.rd_max {
            return self.r_max * rd / self.rd_max;
        }
        // Safeguarded Newton on [0, r_max], where g increases.
        let (mut lo, mut hi) = (0.0, self.r_max);
        let mut r = rd.clamp(lo, hi);
        for _ in 0..60 {
            let f = self.g(r) - rd;
            if f.abs() < 1e-13 {
                break;
            }
            if f > 0.0 {
                hi = r;
            } else {
                lo = r;
            }
            let d = self.dg(r);
            let next = r - f / d;
            r = if d > 0.0 && next > lo && next < hi {
                next
            } else {
                0.5 * (lo + hi)
            };
        }
        r
    }

    /// Ideal normalised coordinates for distorted normalised coordinates.
    fn ideal_normalised(&self, xd: f64, yd: f64) -> (f64, f64) {
        let rd = xd.hypot(yd);
        if !rd.is_finite() {
            return (xd, yd);
        }
        let (x0, y0) = if rd > 0.0 {
            let s = self.radial_inverse(rd) / rd;
            (xd * s, yd * s)
        } else {
            (0.0, 0.0)
        };
        let [k1, k2, p1, p2, k3] = self.k;
        if p1 == 0.0 && p2 == 0.0 {
            return (x0, y0);
        }
        // Tangential terms: OpenCV's fixed-point iteration from the radial solution.
        let (mut x, mut y) = (x0, y0);
        for _ in 0..20 {
            let r2 = x * x + y * y;
            let radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
            let dx = 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x);
            let dy = p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y;
            x = (xd - dx) / radial;
            y = (yd - dy) / radial;
        }
        let (ex, ey) = distort_normalised(&self.k, x, y);
        let (e0x, e0y) = distort_normalised(&self.k, x0, y0);
        let better = (ex - xd).hypot(ey - yd) < (e0x - xd).hypot(e0y - yd);
        if x.is_finite() && y.is_finite() && better {
            (x, y)
        } else {
            (x0, y0)
        }
    }

    pub(crate) fn ideal_pixel(&self, intr: &Intrinsics, distorted: Point2<f64>) -> Point2<f64> {
        let xd = (distorted.x - intr.cx) / intr.fx;
        let yd = (distorted.y - intr.cy) / intr.fy;
        let (x, y) = self.ideal_normalised(xd, yd);
        Point2::new(x * intr.fx + intr.cx, y * intr.fy + intr.cy)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn undistort_inverts_distort_inside_the_field_of_view() {
        let mut intr = Intrinsics::ned2();
        for tangential in [[0.0, 0.0], [0.001, -0.002]] {
            intr.distortion[2] = tangential[0];
            intr.distortion[3] = tangential[1];
            for &(u, v) in &[(0.0, 0.0), (320.0, 240.0), (600.0, 450.0), (-20.0, 500.0)] {
                let ideal = Point2::new(u, v);
                let back = intr.undistort(intr.distort(ideal));
                assert!((back - ideal).norm() < 1e-6, "{ideal} -> {back}");
            }
        }
    }

    #[test]
    fn ned2_model_folds_beyond_its_field_of_view() {
        let u = Undistorter::new(&Intrinsics::ned2().distortion);
        assert!(u.r_max > 0.9 && u.r_max < 1.3, "r_max {}", u.r_max);
        // Past the fold the inverse keeps growing.
        assert!(u.radial_inverse(u.rd_max * 1.1) > u.r_max);
        let intr = Intrinsics::ned2();
        let corner = intr.undistort(Point2::new(0.0, 0.0));
        assert!(corner.x < 0.0 && corner.y < 0.0 && corner.x.is_finite());
    }

    #[test]
    fn projection_and_validity() {
        let intr = Intrinsics::ned2();
        assert!(intr.is_valid());
        let id = Isometry3::identity();
        let p = intr.project(&id, &Point3::new(0.0, 0.0, 1.0)).unwrap();
        assert!((p.x - intr.cx).abs() < 1e-12 && (p.y - intr.cy).abs() < 1e-12);
        assert!(intr.project(&id, &Point3::new(0.0, 0.0, -1.0)).is_none());
        assert!(intr
            .project(&id, &Point3::new(f64::NAN, 0.0, 1.0))
            .is_none());
        let proto: CameraIntrinsics = intr.into();
        assert_eq!(Intrinsics::from(proto), intr);
        assert!(!Intrinsics { fx: 0.0, ..intr }.is_valid());
    }
}
