//! Forward and inverse kinematics of the arms robotd drives: the Niryo Ned2 and the
//! WidowX 250s.
//!
//! The robot models are URDF files generated from the numbers of the robots' specifications
//! (`config/urdf/ned2.urdf`, `config/urdf/wx250s.urdf`), compiled in, and loaded into the `k`
//! crate's kinematic chains. [`Kinematics`] answers where the tool is for given joints
//! ([`Kinematics::tool_pose`]) and which joints put the tool at a pose
//! ([`Kinematics::inverse`]), always inside the joint limits and the Cartesian box the robot
//! accepts; an unreachable pose is an error that names the pose and the reason.
//!
//! Poses in robotd are the **tool centre point** (between the fingertips), with roll, pitch and
//! yaw as fixed-axis X, Y, Z angles (R = Rz(yaw)·Ry(pitch)·Rx(roll)); the tool points down at
//! pitch +π/2.
//!
//! ```
//! use robotd_kinematics::{isometry_to_pose, pose_to_isometry, Kinematics, RobotModel};
//! use robotd_protocol::geometry::Pose;
//!
//! let ned2 = Kinematics::new(RobotModel::Ned2);
//! let target = Pose::new(0.25, 0.0, 0.05, 0.0, std::f64::consts::FRAC_PI_2, 0.0);
//! let joints = ned2.inverse(&pose_to_isometry(&target), None).unwrap();
//! let reached = isometry_to_pose(&ned2.tool_pose(&joints).unwrap());
//! assert!(reached.position().distance_to(&target.position()) < 0.001);
//! ```

use k::prelude::*;
use nalgebra::{Isometry3, Translation3, UnitQuaternion};
use robotd_protocol::geometry::Pose;
mod body;
mod mount;

pub use body::BodyBox;
pub use mount::{CameraMount, MountError, MAX_MOUNT_OFFSET_M};
pub use robotd_protocol::geometry::RobotModel;
use std::sync::{Arc, Mutex};

const NED2_URDF: &str = include_str!("../../../config/urdf/ned2.urdf");
const WX250S_URDF: &str = include_str!("../../../config/urdf/wx250s.urdf");

/// Limits of one joint.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JointLimit {
    /// Lowest position, radians.
    pub min_rad: f64,
    /// Highest position, radians.
    pub max_rad: f64,
    /// Fastest speed, rad/s.
    pub max_velocity_rad_s: f64,
}

/// The box of tool positions the robot accepts, metres, base frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CartesianLimits {
    /// x range.
    pub x_m: (f64, f64),
    /// y range.
    pub y_m: (f64, f64),
    /// z range.
    pub z_m: (f64, f64),
}

/// Why a kinematics question has no answer.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum KinematicsError {
    /// The target lies outside the Cartesian box.
    #[error("({x:.3}, {y:.3}, {z:.3}) is outside the {robot}'s Cartesian limits x {x_range:?}, y {y_range:?}, z {z_range:?} m")]
    OutsideCartesianLimits {
        /// Robot name.
        robot: String,
        /// Target x, m.
        x: f64,
        /// Target y, m.
        y: f64,
        /// Target z, m.
        z: f64,
        /// Accepted x range.
        x_range: (f64, f64),
        /// Accepted y range.
        y_range: (f64, f64),
        /// Accepted z range.
        z_range: (f64, f64),
    },
    /// No joint solution within the limits.
    #[error("no joint solution: {reason}")]
    NoSolution {
        /// Why.
        reason: String,
    },
    /// A joint position outside its limits.
    #[error("joint {joint} at {value_rad:.4} rad is outside [{min_rad:.4}, {max_rad:.4}] rad")]
    JointLimit {
        /// Joint index from 0.
        joint: usize,
        /// Position asked for.
        value_rad: f64,
        /// Lower limit.
        min_rad: f64,
        /// Upper limit.
        max_rad: f64,
    },
    /// The wrong number of joint values.
    #[error("expected {expected} joint values, got {got}")]
    WrongJointCount {
        /// Joints of the robot.
        expected: usize,
        /// Values given.
        got: usize,
    },
    /// A value that is not a finite number.
    #[error("{what} must be finite numbers")]
    NotFinite {
        /// What was not finite.
        what: &'static str,
    },
}

/// Kinematics of one robot model. Cheap to clone; clones share one chain behind a lock.
#[derive(Clone)]
pub struct Kinematics {
    model: RobotModel,
    chain: Arc<Mutex<Chains>>,
    limits: Vec<JointLimit>,
    cartesian: CartesianLimits,
    /// The links' shapes, for [`Kinematics::body`].
    body: Arc<Vec<body::LinkShape>>,
    /// Where the wrist camera sits on its parent link ([`CameraMount`]).
    camera_mount: CameraMount,
}

struct Chains {
    /// Base to the tool centre point.
    tcp: k::SerialChain<f64>,
    /// Base to the flange (Ned2 tool_link, WidowX ee_gripper).
    flange: k::SerialChain<f64>,
    /// Base to the wrist camera's parent link (Ned2 wrist_link: joints 1–5); `None`: the
    /// camera is on the tool centre point (WidowX).
    camera_parent: Option<k::SerialChain<f64>>,
}

impl std::fmt::Debug for Kinematics {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Kinematics")
            .field("model", &self.model)
            .finish_non_exhaustive()
    }
}

fn serial_to(chain: &k::Chain<f64>, link: &str) -> k::SerialChain<f64> {
    let end = chain
        .find_link(link)
        .unwrap_or_else(|| panic!("built-in URDF has no link '{link}'"));
    k::SerialChain::from_end(end)
}

impl Kinematics {
    /// The kinematics of `model` (from the built-in URDF).
    pub fn new(model: RobotModel) -> Self {
        let (urdf, tcp_link, flange_link, cartesian) = match model {
            RobotModel::Ned2 => (
                NED2_URDF,
                "tcp_link",
                "tool_link",
                CartesianLimits {
                    x_m: (-0.5, 0.5),
                    y_m: (-0.5, 0.5),
                    z_m: (-0.15, 0.6),
                },
            ),
            RobotModel::WidowX250 => (
                WX250S_URDF,
                "ee_gripper_link",
                "ee_gripper_link",
                // The arm reaches about 0.65 m; the box keeps targets in front and above the
                // table's underside.
                CartesianLimits {
                    x_m: (-0.65, 0.65),
                    y_m: (-0.65, 0.65),
                    z_m: (-0.1, 0.75),
                },
            ),
        };
        // The URDFs are compiled in and tested: a parse failure is a build defect.
        let robot = urdf_rs::read_from_string(urdf).expect("built-in URDF parses");
        let chain = k::Chain::<f64>::from(&robot);
        let tcp = serial_to(&chain, tcp_link);
        let flange = serial_to(&chain, flange_link);
        let camera_parent = (model == RobotModel::Ned2).then(|| serial_to(&chain, "wrist_link"));
        let limits = tcp
            .iter_joints()
            .map(|joint| {
                let range = joint.limits.unwrap_or(k::joint::Range::new(
                    -std::f64::consts::PI,
                    std::f64::consts::PI,
                ));
                JointLimit {
                    min_rad: range.min,
                    max_rad: range.max,
                    max_velocity_rad_s: velocity_of(&robot, &joint.name),
                }
            })
            .collect();
        Self {
            model,
            chain: Arc::new(Mutex::new(Chains {
                tcp,
                flange,
                camera_parent,
            })),
            limits,
            cartesian,
            body: Arc::new(body::link_shapes(&robot, tcp_link)),
            camera_mount: CameraMount::default_for(model),
        }
    }

    /// The robot model.
    pub fn model(&self) -> RobotModel {
        self.model
    }

    /// Number of joints (6 for both robots).
    pub fn joint_count(&self) -> usize {
        self.limits.len()
    }

    /// Limits of every joint, base to wrist.
    pub fn joint_limits(&self) -> &[JointLimit] {
        &self.limits
    }

    /// The Cartesian box of accepted tool positions.
    pub fn cartesian_limits(&self) -> &CartesianLimits {
        &self.cartesian
    }

    /// A safe resting posture inside the limits (tool above the table, in front of the base).
    pub fn home_joints(&self) -> Vec<f64> {
        match self.model {
            RobotModel::Ned2 => vec![0.0, 0.3, -1.2, 0.0, -0.6, 0.0],
            RobotModel::WidowX250 => vec![0.0, -0.9, 0.6, 0.0, 1.2, 0.0],
        }
    }

    /// Checks count, finiteness and limits of joint positions.
    pub fn check_joints(&self, q: &[f64]) -> Result<(), KinematicsError> {
        if q.len() != self.limits.len() {
            return Err(KinematicsError::WrongJointCount {
                expected: self.limits.len(),
                got: q.len(),
            });
        }
        if q.iter().any(|v| !v.is_finite()) {
            return Err(KinematicsError::NotFinite {
                what: "joint positions",
            });
        }
        for (joint, (value, limit)) in q.iter().zip(&self.limits).enumerate() {
            if *value < limit.min_rad - 1e-9 || *value > limit.max_rad + 1e-9 {
                return Err(KinematicsError::JointLimit {
                    joint,
                    value_rad: *value,
                    min_rad: limit.min_rad,
                    max_rad: limit.max_rad,
                });
            }
        }
        Ok(())
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, Chains> {
        self.chain.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// Pose of the tool centre point for joints `q`.
    pub fn tool_pose(&self, q: &[f64]) -> Result<Isometry3<f64>, KinematicsError> {
        self.check_joints(q)?;
        let chains = self.lock();
        chains.tcp.set_joint_positions_unchecked(q);
        Ok(chains.tcp.end_transform())
    }

    /// The model's URDF (the built-in one the kinematics come from).
    pub fn urdf(&self) -> &'static str {
        match self.model {
            RobotModel::Ned2 => NED2_URDF,
            RobotModel::WidowX250 => WX250S_URDF,
        }
    }

    /// Every link from the base to the tool centre point with its pose in the base frame, for
    /// joints `q` (for viewers that draw the arm: Foxglove's transforms).
    pub fn link_poses(&self, q: &[f64]) -> Result<Vec<(String, Isometry3<f64>)>, KinematicsError> {
        self.check_joints(q)?;
        let chains = self.lock();
        chains.tcp.set_joint_positions_unchecked(q);
        let poses = chains.tcp.update_transforms();
        Ok(chains
            .tcp
            .iter()
            .zip(poses)
            .map(|(node, pose)| {
                let name = match node.link().as_ref() {
                    Some(link) => link.name.clone(),
                    None => node.joint().name.clone(),
                };
                (name, pose)
            })
            .collect())
    }

    /// Pose of the flange (Ned2 `tool_link`, WidowX `ee_gripper`) for joints `q`.
    pub fn flange_pose(&self, q: &[f64]) -> Result<Isometry3<f64>, KinematicsError> {
        self.check_joints(q)?;
        let chains = self.lock();
        chains.flange.set_joint_positions_unchecked(q);
        Ok(chains.flange.end_transform())
    }

    /// These kinematics with the wrist camera at `mount` instead of the model's nominal mount
    /// (`[robot.camera.mount]`, see [`CameraMount`]).
    pub fn with_camera_mount(mut self, mount: CameraMount) -> Self {
        self.camera_mount = mount;
        self
    }

    /// Where the wrist camera sits on its parent link.
    pub fn camera_mount(&self) -> CameraMount {
        self.camera_mount
    }

    /// Pose of the link the camera is mounted on for joints `q` (the Ned2's wrist, the
    /// WidowX's tool centre point; see [`CameraMount`]); `None` for invalid joints.
    pub fn camera_parent_pose(&self, q: &[f64]) -> Option<Isometry3<f64>> {
        self.check_joints(q).ok()?;
        let chains = self.lock();
        let parent = chains.camera_parent.as_ref().unwrap_or(&chains.tcp);
        let dof = parent.dof();
        parent.set_joint_positions_unchecked(q.get(..dof)?);
        Some(parent.end_transform())
    }

    /// Pose of the wrist camera's optical frame (z = viewing direction, x = image right,
    /// y = image down) for joints `q`; `None` for invalid joints: the parent link's pose times
    /// the [`CameraMount`].
    ///
    /// With the nominal mounts, the Ned2's camera looks along its `camera_link`'s x axis (at
    /// the observation pose straight at the table) with the far side of a workspace at the top
    /// of the image, as on the real robot; the WidowX's sits on the wrist 5 cm behind and above
    /// the tool centre, looking down the tool's −z (the simulator's and `robotd fake-widowx`'s
    /// camera).
    pub fn camera_pose(&self, q: &[f64]) -> Option<Isometry3<f64>> {
        Some(self.camera_parent_pose(q)? * self.camera_mount.transform)
    }

    /// Joints that put the tool centre point at `target`, inside the joint limits. Tries the
    /// seed advised for tabletop targets (base turned to the target, elbow bent), then `seed`,
    /// then a few other postures.
    pub fn inverse(
        &self,
        target: &Isometry3<f64>,
        seed: Option<&[f64]>,
    ) -> Result<Vec<f64>, KinematicsError> {
        let p = target.translation.vector;
        if !(p.iter().all(|v| v.is_finite())
            && target.rotation.coords.iter().all(|v| v.is_finite()))
        {
            return Err(KinematicsError::NotFinite { what: "the target" });
        }
        let c = &self.cartesian;
        if !((c.x_m.0..=c.x_m.1).contains(&p.x)
            && (c.y_m.0..=c.y_m.1).contains(&p.y)
            && (c.z_m.0..=c.z_m.1).contains(&p.z))
        {
            return Err(KinematicsError::OutsideCartesianLimits {
                robot: self.model.display_name().to_owned(),
                x: p.x,
                y: p.y,
                z: p.z,
                x_range: c.x_m,
                y_range: c.y_m,
                z_range: c.z_m,
            });
        }
        let base = p.y.atan2(p.x);
        let mut seeds: Vec<Vec<f64>> = Vec::new();
        match self.model {
            RobotModel::Ned2 => {
                seeds.push(vec![base, -0.3, -0.6, 0.0, -0.7, 0.0]);
                if let Some(seed) = seed {
                    seeds.push(seed.to_vec());
                }
                seeds.push(vec![base, 0.2, -1.0, 0.0, -0.8, 0.0]);
                seeds.push(vec![base, -0.6, -0.2, 0.0, -1.2, 0.0]);
                seeds.push(vec![base, 0.0, -0.3, 0.0, -1.5, 1.0]);
            }
            RobotModel::WidowX250 => {
                seeds.push(vec![base, -0.5, 0.5, 0.0, 1.0, 0.0]);
                if let Some(seed) = seed {
                    seeds.push(seed.to_vec());
                }
                seeds.push(vec![base, 0.0, 0.0, 0.0, 1.2, 0.0]);
                seeds.push(vec![base, -1.0, 1.0, 0.0, 0.5, 0.0]);
            }
        }
        let solver = k::JacobianIkSolver::new(0.0002, 0.002, 0.5, 60);
        let chains = self.lock();
        let mut last_error = String::new();
        for seed in seeds {
            if seed.len() != self.limits.len() || seed.iter().any(|v| !v.is_finite()) {
                continue;
            }
            chains.tcp.set_joint_positions_clamped(&seed);
            match solver.solve(&chains.tcp, target) {
                Ok(()) => {
                    let q = chains.tcp.joint_positions();
                    if self.check_joints(&q).is_ok() {
                        return Ok(q);
                    }
                    last_error = "the solution leaves the joint limits".into();
                }
                Err(error) => last_error = error.to_string(),
            }
        }
        let reach = p.norm();
        Err(KinematicsError::NoSolution {
            reason: format!(
                "did not converge from any seed ({last_error}); the target is {reach:.3} m from the base"
            ),
        })
    }
}

fn velocity_of(robot: &urdf_rs::Robot, joint: &str) -> f64 {
    robot
        .joints
        .iter()
        .find(|j| j.name == joint)
        .map(|j| j.limit.velocity)
        .filter(|v| *v > 0.0)
        .unwrap_or(1.0)
}

/// A robotd pose as an isometry (R = Rz(yaw)·Ry(pitch)·Rx(roll)).
pub fn pose_to_isometry(p: &Pose) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::new(p.x_m, p.y_m, p.z_m),
        UnitQuaternion::from_euler_angles(p.roll_rad, p.pitch_rad, p.yaw_rad),
    )
}

/// An isometry as a robotd pose.
pub fn isometry_to_pose(iso: &Isometry3<f64>) -> Pose {
    let (roll, pitch, yaw) = iso.rotation.euler_angles();
    let t = iso.translation.vector;
    Pose::new(t.x, t.y, t.z, roll, pitch, yaw)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::FRAC_PI_2;

    fn close(a: f64, b: f64, tol: f64) -> bool {
        (a - b).abs() <= tol
    }

    #[test]
    fn ned2_forward_kinematics_matches_the_spec() {
        let ned2 = Kinematics::new(RobotModel::Ned2);
        let p = isometry_to_pose(&ned2.flange_pose(&[0.0; 6]).unwrap());
        assert!(
            close(p.x_m, 0.2952, 0.001) && close(p.y_m, 0.0, 0.001),
            "{p}"
        );
        assert!(close(p.z_m, 0.4291, 0.001), "{p}");
        assert!(
            close(p.roll_rad, 0.0, 0.01) && close(p.pitch_rad, 0.0, 0.01),
            "{p}"
        );
        let p = isometry_to_pose(&ned2.flange_pose(&[0.0, 0.5, -1.25, 0.0, 0.0, 0.0]).unwrap());
        assert!(
            close(p.x_m, 0.1403, 0.001) && close(p.z_m, 0.2035, 0.001),
            "{p}"
        );
        assert!(close(p.pitch_rad, 0.75, 0.01), "{p}");
    }

    #[test]
    fn link_poses_run_from_the_base_to_the_tool() {
        for model in [RobotModel::Ned2, RobotModel::WidowX250] {
            let kinematics = Kinematics::new(model);
            let q = [0.1, 0.2, -0.3, 0.0, 0.4, 0.0];
            let links = kinematics.link_poses(&q).unwrap();
            assert!(links.len() >= 7, "{model:?}: {links:?}");
            let last = links.last().unwrap().1;
            let tool = kinematics.tool_pose(&q).unwrap();
            assert!((last.translation.vector - tool.translation.vector).norm() < 1e-9);
            assert!(kinematics.urdf().contains("<robot"));
        }
    }

    #[test]
    fn widowx_forward_kinematics_matches_the_spec() {
        let wx = Kinematics::new(RobotModel::WidowX250);
        let p = isometry_to_pose(&wx.tool_pose(&[0.0; 6]).unwrap());
        assert!(
            close(p.x_m, 0.458325, 0.001) && close(p.z_m, 0.36065, 0.001),
            "{p}"
        );
    }

    #[test]
    fn tool_down_points_the_tool_x_axis_down() {
        let iso = pose_to_isometry(&Pose::new(0.2, 0.0, 0.1, 0.0, FRAC_PI_2, 0.0));
        let x = iso.rotation * nalgebra::Vector3::x();
        assert!(close(x.z, -1.0, 1e-9), "{x}");
    }

    fn grid_rate(model: RobotModel, x: (f64, f64), y: (f64, f64)) -> f64 {
        let kin = Kinematics::new(model);
        let (mut ok, mut all) = (0, 0);
        for ix in 0..6 {
            for iy in 0..6 {
                for z in [0.01, 0.05, 0.10] {
                    for yaw in [0.0, 0.7] {
                        let px = x.0 + (x.1 - x.0) * ix as f64 / 5.0;
                        let py = y.0 + (y.1 - y.0) * iy as f64 / 5.0;
                        let target = pose_to_isometry(&Pose::new(px, py, z, 0.0, FRAC_PI_2, yaw));
                        all += 1;
                        if let Ok(q) = kin.inverse(&target, None) {
                            let reached = kin.tool_pose(&q).unwrap();
                            let error =
                                (reached.translation.vector - target.translation.vector).norm();
                            assert!(error < 0.001, "IK answer off by {error} m");
                            ok += 1;
                        }
                    }
                }
            }
        }
        let rate = ok as f64 / all as f64;
        println!("{model:?}: IK solved {ok} of {all} ({:.1} %)", rate * 100.0);
        rate
    }

    #[test]
    fn ik_solves_tool_down_targets_over_the_ned2_workspace() {
        let rate = grid_rate(RobotModel::Ned2, (0.163, 0.337), (-0.087, 0.087));
        assert!(rate >= 0.99, "solve rate {rate}");
    }

    #[test]
    fn ik_solves_tool_down_targets_over_the_widowx_workspace() {
        let rate = grid_rate(RobotModel::WidowX250, (0.15, 0.35), (-0.10, 0.10));
        assert!(rate >= 0.99, "solve rate {rate}");
    }

    #[test]
    fn unreachable_and_bad_targets_are_errors() {
        let ned2 = Kinematics::new(RobotModel::Ned2);
        let far = pose_to_isometry(&Pose::new(0.9, 0.0, 0.1, 0.0, FRAC_PI_2, 0.0));
        assert!(matches!(
            ned2.inverse(&far, None),
            Err(KinematicsError::OutsideCartesianLimits { .. })
        ));
        let out_of_reach = pose_to_isometry(&Pose::new(0.49, 0.0, 0.05, 0.0, FRAC_PI_2, 0.0));
        assert!(matches!(
            ned2.inverse(&out_of_reach, None),
            Err(KinematicsError::NoSolution { .. })
        ));
        let nan = pose_to_isometry(&Pose::new(f64::NAN, 0.0, 0.1, 0.0, 0.0, 0.0));
        assert!(ned2.inverse(&nan, None).is_err());
        assert!(matches!(
            ned2.tool_pose(&[0.0, 3.0, 0.0, 0.0, 0.0, 0.0]),
            Err(KinematicsError::JointLimit { joint: 1, .. })
        ));
        assert!(ned2.tool_pose(&[0.0; 5]).is_err());
    }
}
