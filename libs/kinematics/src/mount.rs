//! Where the wrist camera sits on the arm: the **camera mount**.
//!
//! A camera frame is only useful with the pose the camera had when it was taken. That pose is
//! the pose of the link the camera is bolted to (its *parent*), from the joints, times a
//! fixed transform: the mount. The parent differs per robot:
//!
//! - **Ned2**: the wrist (`wrist_link`, turned by joints 1–5). The camera does not turn with
//!   joint 6, which turns only the tool.
//! - **WidowX 250**: the tool centre point (`ee_gripper_link`), since the camera is clamped
//!   to the gripper.
//!
//! The mount is given as a translation in metres in the parent's axes and a rotation as roll,
//! pitch and yaw in degrees (R = Rz(yaw)·Ry(pitch)·Rx(roll), as robotd's poses) that turns the
//! parent's axes into the camera's **optical** axes: z along the viewing direction, x to the
//! image's right, y to the image's bottom. [`CameraMount::default_for`] is each model's
//! nominal mount (the Ned2's from its URDF, the WidowX's the clamp robotd assumes);
//! `[robot.camera.mount]` replaces it, and `robotd commission` measures it on a real arm.
//!
//! ```
//! use robotd_kinematics::{CameraMount, Kinematics, RobotModel};
//!
//! let nominal = CameraMount::default_for(RobotModel::WidowX250);
//! // 1 cm further forward along the tool's x axis than the nominal clamp.
//! let [x, y, z, roll, pitch, yaw] = nominal.to_xyz_rpy_deg();
//! let moved = CameraMount::from_xyz_rpy_deg([x + 0.01, y, z, roll, pitch, yaw]).unwrap();
//! let arm = Kinematics::new(RobotModel::WidowX250);
//! let q = arm.home_joints();
//! let before = arm.camera_pose(&q).unwrap();
//! let after = arm.clone().with_camera_mount(moved).camera_pose(&q).unwrap();
//! let gap = (after.translation.vector - before.translation.vector).norm();
//! assert!((gap - 0.01).abs() < 1e-9);
//! ```

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use robotd_protocol::geometry::RobotModel;

/// Farthest a camera may sit from its parent link, metres: a camera mounted farther away is
/// a typing mistake (millimetres written as metres), not a mount.
pub const MAX_MOUNT_OFFSET_M: f64 = 0.3;

/// The fixed transform from the camera's parent link to its optical frame (see the module
/// documentation).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CameraMount {
    /// Parent link → optical frame.
    pub transform: Isometry3<f64>,
}

/// A mount that cannot be one.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MountError {
    /// A value is NaN or infinite.
    #[error("the camera mount's {what} must be finite numbers, got {value}")]
    NotFinite {
        /// Which value.
        what: &'static str,
        /// What it was.
        value: f64,
    },
    /// The camera is farther from its parent link than any real mount.
    #[error(
        "the camera mount puts the camera {distance_m:.3} m from the link it is mounted on; \
         at most {MAX_MOUNT_OFFSET_M} m is accepted (translations are in metres, not millimetres)"
    )]
    TooFar {
        /// Its distance, metres.
        distance_m: f64,
    },
    /// An angle outside ±360°.
    #[error("the camera mount's {what} is {value}°; angles are degrees from -360 to 360")]
    Angle {
        /// Which angle.
        what: &'static str,
        /// What it was.
        value: f64,
    },
}

impl CameraMount {
    /// The mount from `[x_m, y_m, z_m, roll_deg, pitch_deg, yaw_deg]`, checked.
    pub fn from_xyz_rpy_deg(values: [f64; 6]) -> Result<CameraMount, MountError> {
        const NAMES: [&str; 6] = ["x_m", "y_m", "z_m", "roll_deg", "pitch_deg", "yaw_deg"];
        for (what, value) in NAMES.into_iter().zip(values) {
            if !value.is_finite() {
                return Err(MountError::NotFinite { what, value });
            }
        }
        for (what, value) in NAMES[3..].iter().zip(&values[3..]) {
            if value.abs() > 360.0 {
                return Err(MountError::Angle {
                    what,
                    value: *value,
                });
            }
        }
        let [x, y, z, roll, pitch, yaw] = values;
        let distance_m = Vector3::new(x, y, z).norm();
        if distance_m > MAX_MOUNT_OFFSET_M {
            return Err(MountError::TooFar { distance_m });
        }
        Ok(CameraMount {
            transform: Isometry3::from_parts(
                Translation3::new(x, y, z),
                UnitQuaternion::from_euler_angles(
                    roll.to_radians(),
                    pitch.to_radians(),
                    yaw.to_radians(),
                ),
            ),
        })
    }

    /// `[x_m, y_m, z_m, roll_deg, pitch_deg, yaw_deg]` of this mount.
    pub fn to_xyz_rpy_deg(&self) -> [f64; 6] {
        let t = self.transform.translation.vector;
        let (roll, pitch, yaw) = roll_pitch_yaw(&self.transform.rotation);
        [
            t.x,
            t.y,
            t.z,
            roll.to_degrees(),
            pitch.to_degrees(),
            yaw.to_degrees(),
        ]
    }

    /// The model's nominal mount: the Ned2's camera as its URDF places it on the wrist, the
    /// WidowX's assumed clamp 5 cm behind and 5 cm above the tool centre, looking along the
    /// tool's −z with the tool's forward direction at the top of the image.
    pub fn default_for(model: RobotModel) -> CameraMount {
        match model {
            RobotModel::Ned2 => {
                // camera_joint: wrist_link → camera_link, then camera_link's x axis is the
                // viewing direction and its y axis image up.
                let link = Isometry3::from_parts(
                    Translation3::new(0.0385, 0.0, 0.0),
                    UnitQuaternion::from_euler_angles(0.0, 0.0, -1.396_263_401_595_463_6),
                );
                CameraMount {
                    transform: link * optical_of_x_forward(),
                }
            }
            RobotModel::WidowX250 => {
                // Optical axes in tool axes: x = −y_tool, y = −x_tool, z = −z_tool.
                let rotation = nalgebra::Rotation3::from_matrix_unchecked(nalgebra::Matrix3::new(
                    0.0, -1.0, 0.0, //
                    -1.0, 0.0, 0.0, //
                    0.0, 0.0, -1.0,
                ));
                CameraMount {
                    transform: Isometry3::from_parts(
                        Translation3::new(-0.05, 0.0, 0.05),
                        UnitQuaternion::from_rotation_matrix(&rotation),
                    ),
                }
            }
        }
    }

    /// This mount moved by `offset` expressed in the optical frame (`self · offset`): what a
    /// camera knocked `offset` away from where it was believed to be looks from.
    pub fn offset_by(&self, offset: &Isometry3<f64>) -> CameraMount {
        CameraMount {
            transform: self.transform * offset,
        }
    }

    /// Distance (m) and angle (degrees) between two mounts.
    pub fn difference(&self, other: &CameraMount) -> (f64, f64) {
        let delta = self.transform.inverse() * other.transform;
        (
            delta.translation.vector.norm(),
            delta.rotation.angle().to_degrees(),
        )
    }
}

/// Roll, pitch and yaw (radians, R = Rz(yaw)·Ry(pitch)·Rx(roll)) of `rotation`, read from
/// its matrix, with yaw = 0 at pitch ±90° where only roll ∓ yaw is defined.
pub fn roll_pitch_yaw(rotation: &UnitQuaternion<f64>) -> (f64, f64, f64) {
    let r = rotation.to_rotation_matrix().into_inner();
    let cos_pitch = r[(0, 0)].hypot(r[(1, 0)]);
    let pitch = (-r[(2, 0)]).atan2(cos_pitch);
    if cos_pitch > 1e-6 {
        (
            r[(2, 1)].atan2(r[(2, 2)]),
            pitch,
            r[(1, 0)].atan2(r[(0, 0)]),
        )
    } else if pitch > 0.0 {
        (r[(0, 1)].atan2(r[(1, 1)]), pitch, 0.0)
    } else {
        ((-r[(0, 1)]).atan2(r[(1, 1)]), pitch, 0.0)
    }
}

/// The optical frame of a link that looks along its x axis with y as image up.
fn optical_of_x_forward() -> UnitQuaternion<f64> {
    // Optical axes in link coordinates: x = z_link, y = −y_link, z = x_link.
    UnitQuaternion::from_rotation_matrix(&nalgebra::Rotation3::from_matrix_unchecked(
        nalgebra::Matrix3::new(
            0.0, 0.0, 1.0, //
            0.0, -1.0, 0.0, //
            1.0, 0.0, 0.0,
        ),
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_round_trip() {
        for model in [RobotModel::Ned2, RobotModel::WidowX250] {
            let mount = CameraMount::default_for(model);
            let back = CameraMount::from_xyz_rpy_deg(mount.to_xyz_rpy_deg()).unwrap();
            let (d, a) = mount.difference(&back);
            assert!(d < 1e-12 && a < 1e-9, "{model:?}: {d} m {a}°");
        }
    }

    /// The nominal mounts are the camera robotd had hard-coded before the mount was
    /// configuration: the Ned2's `camera_link` from its URDF, the WidowX's clamp.
    #[test]
    fn nominal_mounts_put_the_camera_where_it_always_was() {
        let robot = urdf_rs::read_from_string(crate::NED2_URDF).unwrap();
        let chain = k::Chain::<f64>::from(&robot);
        let camera = k::SerialChain::from_end(chain.find_link("camera_link").unwrap());
        let ned2 = crate::Kinematics::new(RobotModel::Ned2);
        let q = [0.3, 0.2, -0.9, 0.4, -0.7, 1.1];
        camera.set_joint_positions_unchecked(&q[..5]);
        let expected = camera.end_transform() * optical_of_x_forward();
        let (d, a) = CameraMount {
            transform: expected,
        }
        .difference(&CameraMount {
            transform: ned2.camera_pose(&q).unwrap(),
        });
        assert!(d < 1e-9 && a < 1e-6, "Ned2: {d} m, {a}°");

        let widowx = crate::Kinematics::new(RobotModel::WidowX250);
        let q = widowx.home_joints();
        let tcp = widowx.tool_pose(&q).unwrap();
        let (tx, tz) = (tcp.rotation * Vector3::x(), tcp.rotation * Vector3::z());
        let camera = widowx.camera_pose(&q).unwrap();
        let position = tcp.translation.vector - tx * 0.05 + tz * 0.05;
        assert!((camera.translation.vector - position).norm() < 1e-12);
        assert!((camera.rotation * Vector3::z() + tz).norm() < 1e-12);
        assert!((camera.rotation * Vector3::y() + tx).norm() < 1e-12);
    }

    /// The numbers `config/default.toml` and docs/configuration.md give for the nominal mounts.
    #[test]
    fn nominal_mounts_are_the_documented_numbers() {
        for (model, documented) in [
            (RobotModel::Ned2, [0.0385, 0.0, 0.0, 100.0, -90.0, 0.0]),
            (RobotModel::WidowX250, [-0.05, 0.0, 0.05, 180.0, 0.0, -90.0]),
        ] {
            let mount = CameraMount::from_xyz_rpy_deg(documented).unwrap();
            let (d, a) = mount.difference(&CameraMount::default_for(model));
            assert!(d < 1e-12 && a < 1e-6, "{model:?}: {d} m {a}°");
        }
    }

    #[test]
    fn angles_round_trip_even_at_pitch_90() {
        for rpy in [
            [0.3, 1.2, -2.0],
            [-1.0, std::f64::consts::FRAC_PI_2, 0.0],
            [0.4, -std::f64::consts::FRAC_PI_2, 0.0],
            [3.0, -0.2, 1.5],
        ] {
            let q = UnitQuaternion::from_euler_angles(rpy[0], rpy[1], rpy[2]);
            let (r, p, y) = roll_pitch_yaw(&q);
            let back = UnitQuaternion::from_euler_angles(r, p, y);
            assert!(q.angle_to(&back) < 1e-9, "{rpy:?} → {:?}", (r, p, y));
        }
    }

    #[test]
    fn impossible_mounts_are_refused_with_the_reason() {
        let far = CameraMount::from_xyz_rpy_deg([50.0, 0.0, 0.0, 0.0, 0.0, 0.0]).unwrap_err();
        assert!(far.to_string().contains("not millimetres"), "{far}");
        let nan = CameraMount::from_xyz_rpy_deg([0.0, f64::NAN, 0.0, 0.0, 0.0, 0.0]).unwrap_err();
        assert!(nan.to_string().contains("y_m"), "{nan}");
        let angle = CameraMount::from_xyz_rpy_deg([0.0, 0.0, 0.0, 0.0, 400.0, 0.0]).unwrap_err();
        assert!(angle.to_string().contains("pitch_deg"), "{angle}");
    }
}
