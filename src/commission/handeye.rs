//! Hand-eye calibration from the workspace sheet: where the camera sits on the arm, and how
//! high the table is, from views of the sheet's four markers taken at several arm poses.
//!
//! Each view `i` gives the pose `P_i` of the link the camera is fixed to (from the joints, see
//! `robotd_kinematics::CameraMount`) and, for each marker `j`, the ideal (undistorted) pixel
//! `u_ij` where its centre appears. The markers lie on the table at the configured corners of
//! the workspace, at the unknown table height `h`. With the mount `X` (link → optical frame)
//! the camera is at `C_i = P_i · X`, and a marker should appear at `π(C_i⁻¹ · (x_j, y_j, h))`
//! for the pinhole projection `π`. [`solve`] finds the `X` (and `h`) that make the predicted
//! pixels closest to the measured ones (least squares, Levenberg–Marquardt on 6 or 7
//! unknowns: a small motion of the camera in its own frame, and `h`), starting from the
//! believed mount.
//!
//! The leftover disagreement is reported in **millimetres on the table** (a pixel's size where
//! the marker is): a good calibration leaves a fraction of a millimetre; several millimetres
//! mean the views disagree (the sheet moved, the arm does not stand where it says, a marker
//! was mistaken), and the caller refuses the result. Only views whose viewing directions
//! differ (tilted about the sheet) separate the camera's height on its link from the table's:
//! the planner in `camera.rs` turns the wrist and the base between views. With the few degrees
//! of tilt that keep a sheet in view, that separation is weak: a millimetre of noise in the
//! arm's joints (a servo's tick is 1.5 mrad) moves the two together by millimetres. So the
//! camera step fits the mount with the table where robotd's model puts it (z = 0, where the
//! workspaces are defined) and fits the table height separately, as a check.

use nalgebra::{DMatrix, DVector, Isometry3, Point3, Translation3, UnitQuaternion, Vector3};

/// A pinhole camera: focal lengths and principal point, pixels.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pinhole {
    /// Focal length along x, pixels.
    pub fx: f64,
    /// Focal length along y, pixels.
    pub fy: f64,
    /// Principal point x, pixels.
    pub cx: f64,
    /// Principal point y, pixels.
    pub cy: f64,
}

/// One view of the sheet.
#[derive(Debug, Clone, PartialEq)]
pub struct View {
    /// Pose of the camera's parent link in the base frame when the frame was taken.
    pub parent: Isometry3<f64>,
    /// Each marker: its table position (x, y in metres, base frame) and the ideal pixel where
    /// its centre was seen.
    pub markers: Vec<([f64; 2], [f64; 2])>,
}

/// What [`solve`] found.
#[derive(Debug, Clone, PartialEq)]
pub struct Solution {
    /// Link → optical frame.
    pub mount: Isometry3<f64>,
    /// Height of the table's surface (the markers), metres, base frame.
    pub table_z_m: f64,
    /// Root mean square of the markers' disagreement, millimetres on the table.
    pub residual_mm_rms: f64,
    /// The largest disagreement of one marker, millimetres on the table.
    pub residual_mm_max: f64,
    /// The view with the largest disagreement (index into the views given).
    pub worst_view: usize,
}

/// Why no calibration came out.
#[derive(Debug, Clone, PartialEq)]
pub enum SolveError {
    /// Too few views, or too few markers in them.
    TooFewViews(usize),
    /// The solver left a marker behind the camera or did not settle.
    Diverged(String),
}

impl std::fmt::Display for SolveError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::TooFewViews(n) => write!(
                f,
                "{n} views with all four markers are too few; at least {MIN_VIEWS} are needed"
            ),
            Self::Diverged(why) => write!(
                f,
                "the calibration did not converge ({why}); the views may show another sheet"
            ),
        }
    }
}

impl std::error::Error for SolveError {}

/// Fewest views [`solve`] accepts.
pub const MIN_VIEWS: usize = 4;

fn camera_of(view: &View, mount: &Isometry3<f64>) -> Isometry3<f64> {
    view.parent * mount
}

/// Predicted pixel of `world` for a camera at `camera`; `None` behind the camera.
fn project(pin: &Pinhole, camera: &Isometry3<f64>, world: Point3<f64>) -> Option<[f64; 2]> {
    let p = camera.inverse_transform_point(&world);
    (p.z > 1e-3).then(|| [pin.fx * p.x / p.z + pin.cx, pin.fy * p.y / p.z + pin.cy])
}

/// A small motion `d` (translation, rotation vector) applied in the camera's own frame.
fn perturb(mount: &Isometry3<f64>, d: &[f64]) -> Isometry3<f64> {
    let step = Isometry3::from_parts(
        Translation3::new(d[0], d[1], d[2]),
        UnitQuaternion::from_scaled_axis(Vector3::new(d[3], d[4], d[5])),
    );
    mount * step
}

fn residuals(pin: &Pinhole, views: &[View], mount: &Isometry3<f64>, h: f64) -> Option<Vec<f64>> {
    let mut out = Vec::new();
    for view in views {
        let camera = camera_of(view, mount);
        for (table, seen) in &view.markers {
            let predicted = project(pin, &camera, Point3::new(table[0], table[1], h))?;
            out.push(predicted[0] - seen[0]);
            out.push(predicted[1] - seen[1]);
        }
    }
    Some(out)
}

/// The mount (and with `fit_table` the table height) that best explain `views`, from `start`
/// (the believed mount) and `table_z_m` (the believed table height, kept without
/// `fit_table`).
pub fn solve(
    pin: &Pinhole,
    views: &[View],
    start: &Isometry3<f64>,
    table_z_m: f64,
    fit_table: bool,
) -> Result<Solution, SolveError> {
    if views.len() < MIN_VIEWS {
        return Err(SolveError::TooFewViews(views.len()));
    }
    let mut mount = *start;
    let mut h = table_z_m;
    let cost = |r: &[f64]| r.iter().map(|v| v * v).sum::<f64>();
    let mut r = residuals(pin, views, &mount, h)
        .ok_or_else(|| SolveError::Diverged("a marker is behind the camera".into()))?;
    let mut lambda = 1e-3;
    for _ in 0..200 {
        // Numerical Jacobian: 6 camera motions and the table height.
        let n = r.len();
        let unknowns = if fit_table { 7 } else { 6 };
        let mut jac = DMatrix::<f64>::zeros(n, unknowns);
        for k in 0..unknowns {
            let eps = 1e-6;
            let (m2, h2) = if k < 6 {
                let mut d = [0.0; 6];
                d[k] = eps;
                (perturb(&mount, &d), h)
            } else {
                (mount, h + eps)
            };
            let r2 = residuals(pin, views, &m2, h2)
                .ok_or_else(|| SolveError::Diverged("a marker went behind the camera".into()))?;
            for i in 0..n {
                jac[(i, k)] = (r2[i] - r[i]) / eps;
            }
        }
        let rv = DVector::from_column_slice(&r);
        let jtj = jac.transpose() * &jac;
        let jtr = jac.transpose() * rv;
        let before = cost(&r);
        let mut improved = false;
        for _ in 0..10 {
            let mut a = jtj.clone();
            for k in 0..unknowns {
                a[(k, k)] += lambda * (1.0 + jtj[(k, k)]);
            }
            let Some(step) = a.lu().solve(&(-&jtr)) else {
                lambda *= 10.0;
                continue;
            };
            let m2 = perturb(&mount, &step.as_slice()[..6]);
            let h2 = if fit_table { h + step[6] } else { h };
            if let Some(r2) = residuals(pin, views, &m2, h2) {
                if cost(&r2) < before {
                    mount = m2;
                    h = h2;
                    r = r2;
                    lambda = (lambda / 10.0).max(1e-12);
                    improved = true;
                    break;
                }
            }
            lambda *= 10.0;
        }
        if !improved || before - cost(&r) < 1e-12 * before.max(1e-12) {
            break;
        }
    }
    // Each marker's disagreement, in millimetres on the table.
    let (mut sum, mut count, mut max, mut worst_view) = (0.0, 0usize, 0.0_f64, 0usize);
    let mut i = 0;
    for (v, view) in views.iter().enumerate() {
        let camera = camera_of(view, &mount);
        for (table, _) in &view.markers {
            let world = Point3::new(table[0], table[1], h);
            let depth = camera.inverse_transform_point(&world).z;
            let px = (r[i].powi(2) + r[i + 1].powi(2)).sqrt();
            let mm = px * depth / ((pin.fx + pin.fy) / 2.0) * 1000.0;
            sum += mm * mm;
            count += 1;
            if mm > max {
                max = mm;
                worst_view = v;
            }
            i += 2;
        }
    }
    if !(max.is_finite() && h.is_finite()) {
        return Err(SolveError::Diverged("not a finite result".into()));
    }
    Ok(Solution {
        mount,
        table_z_m: h,
        residual_mm_rms: (sum / count.max(1) as f64).sqrt(),
        residual_mm_max: max,
        worst_view,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    const PIN: Pinhole = Pinhole {
        fx: 508.0,
        fy: 506.0,
        cx: 320.0,
        cy: 240.0,
    };

    /// Views of markers at the corners of a 17 cm square at z = `h`, from a camera at `truth`
    /// on parent poses tilted about the sheet's centre.
    fn views(truth: &Isometry3<f64>, h: f64, noise_px: f64) -> Vec<View> {
        let corners = [[0.34, 0.09], [0.34, -0.08], [0.17, 0.09], [0.17, -0.08]];
        let centre = Point3::new(0.255, 0.005, h);
        // A camera 25 cm above the centre looking down, then the parent that carries it.
        let look_down = Isometry3::from_parts(
            Translation3::new(centre.x, centre.y, h + 0.25),
            UnitQuaternion::from_euler_angles(std::f64::consts::PI, 0.0, 0.0),
        );
        let mut out = Vec::new();
        let mut seed = 7u64;
        let mut noise = || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((seed >> 33) as f64 / (1u64 << 31) as f64 - 0.5) * 2.0 * noise_px
        };
        for (axis, angle) in [
            (Vector3::x(), 0.0),
            (Vector3::x(), 0.3),
            (Vector3::x(), -0.3),
            (Vector3::y(), 0.3),
            (Vector3::y(), -0.3),
            (Vector3::z(), 0.4),
            (Vector3::z(), -0.4),
            (Vector3::new(1.0, 1.0, 0.0), 0.25),
        ] {
            let about_centre = Isometry3::from_parts(
                Translation3::from(centre.coords),
                UnitQuaternion::from_scaled_axis(axis.normalize() * angle),
            ) * Isometry3::from_parts(
                Translation3::from(-centre.coords),
                UnitQuaternion::identity(),
            );
            let camera = about_centre * look_down;
            let parent = camera * truth.inverse();
            let markers = corners
                .iter()
                .map(|c| {
                    let p = project(&PIN, &camera, Point3::new(c[0], c[1], h)).unwrap();
                    (*c, [p[0] + noise(), p[1] + noise()])
                })
                .collect();
            out.push(View { parent, markers });
        }
        out
    }

    #[test]
    fn a_mount_off_by_8_mm_and_3_degrees_is_found() {
        let believed = Isometry3::from_parts(
            Translation3::new(0.0385, 0.0, 0.0),
            UnitQuaternion::from_euler_angles(1.0, -1.2, 0.3),
        );
        let offset = Isometry3::from_parts(
            Translation3::new(0.008, -0.003, 0.004),
            UnitQuaternion::from_euler_angles(0.0, 3f64.to_radians(), 0.01),
        );
        let truth = believed * offset;
        let found = solve(&PIN, &views(&truth, 0.002, 0.2), &believed, 0.0, true).unwrap();
        let delta = truth.inverse() * found.mount;
        assert!(delta.translation.vector.norm() < 0.001, "{delta:?}");
        assert!(delta.rotation.angle().to_degrees() < 0.2, "{delta:?}");
        assert!(
            (found.table_z_m - 0.002).abs() < 0.001,
            "{}",
            found.table_z_m
        );
        assert!(found.residual_mm_max < 0.5, "{found:?}");
    }

    #[test]
    fn views_that_disagree_leave_millimetres() {
        let truth = Isometry3::identity();
        let mut views = views(&truth, 0.0, 0.0);
        // The sheet moved 1 cm between the third view and the others.
        for (table, _) in &mut views[2].markers {
            table[0] += 0.01;
        }
        let found = solve(&PIN, &views, &truth, 0.0, true).unwrap();
        assert!(found.residual_mm_max > 3.0, "{found:?}");
        let too_few = solve(&PIN, &views[..2], &truth, 0.0, true).unwrap_err();
        assert!(too_few.to_string().contains("at least"), "{too_few}");
    }
}
