//! The real Niryo Ned2 over its TCP protocol (port 40001).
//!
//! `robot.driver = "niryo"` with `robot.host` selects it. [`open`] returns the arm, gripper
//! and camera drivers at once, whether or not the robot answers: they share one [`link`]
//! whose reconnector keeps trying (at most `robot.niryo.reconnect_max_ms` apart), and until
//! it succeeds every command fails with `robot not connected: <reason>`.
//!
//! - [`wire`]: the framing and message shapes, validated both ways;
//! - [`link`]: the one connection — commands one at a time with deadlines, stale replies
//!   dropped, never a command sent twice, reconnection that reads the robot's state first;
//! - [`arm`], [`gripper`], [`camera`]: the driver traits on top of it.
//!
//! The crate depends on no simulator: the fake Ned2 that serves the simulator behind this
//! protocol (`robotd fake-niryo`, and the driver's tests against it) is its own crate,
//! `robotd-fake-niryo` in `fakes/niryo/`, which uses [`wire`] from here.
//!
//! The protocol and the robot's quirks the design follows: `docs/niryo-tcp.md`.

pub mod arm;
pub mod camera;
pub mod gripper;
pub mod link;
pub mod wire;

pub use arm::NiryoArm;
pub use camera::NiryoCamera;
pub use gripper::NiryoGripper;
pub use link::{Link, LinkSettings};

use robotd_driver::{RobotConfig, RobotDrivers};
use robotd_kinematics::Kinematics;
use robotd_protocol::geometry::RobotModel;
use robotd_safety::Safety;
use std::sync::Arc;
use std::time::Duration;

/// The drivers of a Ned2 and the link they share.
pub struct NiryoDrivers {
    /// The drivers for the actors.
    pub drivers: RobotDrivers,
    /// The connection (status, what is known of the robot).
    pub link: Arc<Link>,
    /// The reconnector, camera fetcher and idle poller; abort them to let go of the robot.
    pub tasks: Vec<tokio::task::JoinHandle<()>>,
}

/// The link settings of `[robot]`.
pub fn link_settings(config: &RobotConfig) -> LinkSettings {
    let niryo = &config.niryo;
    LinkSettings {
        host: config.host.clone().unwrap_or_default(),
        port: config.port,
        connect_timeout: niryo.connect_timeout(),
        query_timeout: niryo.query_timeout(),
        reconnect_max: niryo.reconnect_max(),
        auto_calibrate: niryo.auto_calibrate,
        calibrate_timeout: arm::CALIBRATE_TIMEOUT,
    }
}

/// Opens the Ned2 of `[robot]` (on the current tokio runtime): starts connecting and waits up
/// to `wait_for_robot` for the first connection, so that the camera's intrinsics are the
/// robot's; an unreachable robot is not an error (the drivers say why until it answers).
/// `policy` admits the automatic calibration on connecting (see [`link`]).
pub async fn open(config: &RobotConfig, wait_for_robot: Duration, policy: Safety) -> NiryoDrivers {
    let link = Link::new(link_settings(config), Some(policy));
    let kinematics = Kinematics::new(RobotModel::Ned2);
    let arm = Arc::new(NiryoArm::new(
        link.clone(),
        arm::ArmSettings {
            max_velocity_rad_s: kinematics
                .joint_limits()
                .iter()
                .map(|l| l.max_velocity_rad_s)
                .collect(),
            segment_rad: config.niryo.segment_rad,
            arrival_tolerance_rad: config.niryo.arrival_tolerance_rad,
        },
    ));
    let camera = NiryoCamera::with_mount(
        link.clone(),
        config.niryo.images_rectified,
        camera_mount(config),
    );
    let mut tasks = vec![tokio::spawn(link.clone().run_reconnector())];
    if let Err(reason) = link.wait_connected(wait_for_robot).await {
        tracing::warn!(%reason, "the Niryo robot is not connected yet; robotd keeps trying");
    }
    tasks.push(tokio::spawn(camera.clone().run_fetcher(config.camera.fps)));
    tasks.push(tokio::spawn(poll_while_idle(arm.clone())));
    NiryoDrivers {
        drivers: RobotDrivers {
            model: RobotModel::Ned2,
            arm,
            gripper: Arc::new(NiryoGripper::new(link.clone(), &config.niryo)),
            camera,
        },
        link,
        tasks,
    }
}

/// Reads the joints once a second while the arm is not moving, so that an arm moved by hand
/// (learning mode) is noticed and camera poses stay right.
async fn poll_while_idle(arm: Arc<NiryoArm>) {
    use robotd_driver::ArmDriver;
    let mut ticker = tokio::time::interval(Duration::from_secs(1));
    ticker.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    loop {
        ticker.tick().await;
        if arm.connection().is_err() || arm.flags().moving {
            continue;
        }
        if let Err(error) = arm.read_joints().await {
            tracing::debug!(%error, "reading the idle arm's joints");
        }
    }
}

/// `[robot.camera.mount]`, else the Ned2's nominal mount. The config's checks refuse a mount
/// that cannot be one before a driver starts; should one get here, it is logged and the
/// nominal mount used.
fn camera_mount(config: &RobotConfig) -> robotd_kinematics::CameraMount {
    config.camera_mount().unwrap_or_else(|error| {
        tracing::error!(%error, "robot.camera.mount is unusable; using the Ned2's nominal mount");
        robotd_kinematics::CameraMount::default_for(RobotModel::Ned2)
    })
}
