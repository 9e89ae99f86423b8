//! The real WidowX 250 s over DYNAMIXEL Protocol 2.0 (no ROS).
//!
//! `robot.driver = "widowx"` selects it; `[robot.widowx]` names the serial device of the U2D2
//! adapter and the camera stream. [`open`] starts the bus thread and returns the drivers at
//! once, whether or not the servos answer: until they do, every command fails with `robot not
//! connected: <reason>`, and the thread keeps reopening the port.
//!
//! - [`control_table`]: servo IDs, models, control-table addresses, units;
//! - [`startup`]: ping and model check of every servo, the settings written, torque on;
//! - [`bus`]: the bus thread and its control loop (sync write of goals, sync read of positions,
//!   hardware-error recovery, reconnection), on the `dynamixel2` crate;
//! - [`packet`]: Protocol 2.0 framing (the bus's sync reads and the fake's instructions);
//! - [`arm`], [`gripper`]: the driver traits on top of it;
//! - the camera: an MJPEG-over-HTTP stream (`robotd-driver-mjpeg`) or a V4L2 device
//!   (`robotd-driver-v4l2`), posed on the wrist.
//!
//! The crate depends on no simulator: the fake servo bus that serves the simulator as nine
//! servos on a pty (`robotd fake-widowx`, which the vendor's dynamixel-sdk accepts, and the
//! driver's tests against it) is its own crate, `robotd-fake-widowx` in `fakes/widowx/`, which
//! uses [`packet`] and [`control_table`] from here.
//!
//! Wire-level facts the design follows: `docs/dynamixel.md`.

pub mod arm;
pub mod bus;
pub mod control_table;
pub mod gripper;
pub mod packet;
pub mod startup;

pub use arm::WidowxArm;
pub use bus::{BusSettings, ServoBus};
pub use gripper::WidowxGripper;

use robotd_driver::{
    CameraDriver, CaptureInfo, DriverError, RobotConfig, RobotDrivers, WidowxConfig,
};
use robotd_kinematics::Kinematics;
use robotd_protocol::camera::CameraIntrinsics;
use robotd_protocol::geometry::RobotModel;
use std::sync::Arc;

/// The serial bus as the driver uses it.
pub type DxlBus = dynamixel2::Bus<Vec<u8>, Vec<u8>>;

/// The drivers of a WidowX and the bus they share.
pub struct WidowxDrivers {
    /// The drivers for the actors.
    pub drivers: RobotDrivers,
    /// The servo bus (status, counters).
    pub bus: Arc<ServoBus>,
    /// The camera receiver; abort it to let go of the stream.
    pub tasks: Vec<tokio::task::JoinHandle<()>>,
}

/// The bus settings of `[robot]`.
pub fn bus_settings(config: &RobotConfig) -> BusSettings {
    let widowx = &config.widowx;
    BusSettings {
        device: widowx.device.clone(),
        baud_rate: widowx.baud_rate,
        control_period: config.control_period(),
        reconnect_max: widowx.reconnect_max(),
        startup: startup::StartupSettings {
            profile_velocity: widowx.profile_velocity,
            profile_acceleration: widowx.profile_acceleration,
        },
    }
}

/// The camera's intrinsics: `[robot.widowx] camera_intrinsics`, else the simulated wrist
/// camera's (the Ned2's, 640×480, undistorted: what `robotd fake-widowx` serves).
pub fn camera_intrinsics(widowx: &WidowxConfig) -> CameraIntrinsics {
    widowx.camera_intrinsics.clone().unwrap_or_else(|| {
        let mut intrinsics = robotd_driver::hardware::ned2_camera_intrinsics();
        intrinsics.distortion = [0.0; 5];
        intrinsics
    })
}

/// Opens the WidowX of `[robot]` (on the current tokio runtime).
pub fn open(config: &RobotConfig) -> WidowxDrivers {
    let widowx = &config.widowx;
    let bus = ServoBus::start(bus_settings(config));
    let mount = config.camera_mount().unwrap_or_else(|error| {
        // The config's checks refuse such a mount before a driver starts.
        tracing::error!(%error, "robot.camera.mount is unusable; using the nominal mount");
        robotd_kinematics::CameraMount::default_for(RobotModel::WidowX250)
    });
    let kinematics = Kinematics::new(RobotModel::WidowX250).with_camera_mount(mount);
    let arm = Arc::new(WidowxArm::new(
        bus.clone(),
        arm::ArmSettings {
            max_velocity_rad_s: kinematics
                .joint_limits()
                .iter()
                .map(|l| l.max_velocity_rad_s)
                .collect(),
            tracking_tolerance_rad: widowx.tracking_tolerance_rad,
            arrival_tolerance_rad: widowx.arrival_tolerance_rad,
        },
    ));
    let gripper = Arc::new(WidowxGripper::new(
        bus.clone(),
        gripper::GripperSettings {
            closed_ticks: widowx.gripper_closed_ticks.into(),
            open_ticks: widowx.gripper_open_ticks.into(),
            pwm: widowx.gripper_pwm as i16,
            hold_pwm: widowx.gripper_hold_pwm as i16,
            holding_load: widowx.gripper_holding_load as i16,
            max_width_m: robotd_driver::hardware::gripper_max_width(RobotModel::WidowX250),
        },
    ));
    let intrinsics = camera_intrinsics(widowx);
    let mut tasks = Vec::new();
    let camera: Arc<dyn CameraDriver> = match &widowx.camera_url {
        Some(source) => {
            let pose_arm = arm.clone();
            let pose: robotd_driver::camera_feed::PoseSource = Arc::new(move || {
                use robotd_driver::ArmDriver;
                let q = pose_arm.joints().ok()?;
                kinematics.camera_pose(&q)
            });
            let latency = std::time::Duration::from_millis(widowx.camera_latency_ms);
            if source.starts_with("/dev/") {
                match robotd_driver_v4l2::V4l2Camera::start(
                    std::path::Path::new(source),
                    intrinsics.clone(),
                    latency,
                    pose,
                ) {
                    Ok(camera) => camera,
                    Err(e) => Arc::new(NoCamera {
                        intrinsics,
                        reason: format!("cannot start the capture thread of {source}: {e}"),
                    }),
                }
            } else {
                let camera =
                    robotd_driver_mjpeg::MjpegCamera::new(source, intrinsics, latency, pose);
                tasks.push(tokio::spawn(camera.clone().run_receiver()));
                camera
            }
        }
        None => Arc::new(NoCamera {
            intrinsics,
            reason: "no camera configured: set robot.widowx.camera_url to the camera's V4L2 \
                     device (/dev/video0) or MJPEG stream (http://…)"
                .into(),
        }),
    };
    WidowxDrivers {
        drivers: RobotDrivers {
            model: RobotModel::WidowX250,
            arm,
            gripper,
            camera,
        },
        bus,
        tasks,
    }
}

/// A WidowX without a usable camera: every capture says why and how to add one.
struct NoCamera {
    intrinsics: CameraIntrinsics,
    reason: String,
}

impl CameraDriver for NoCamera {
    fn size(&self) -> (u32, u32) {
        (self.intrinsics.width, self.intrinsics.height)
    }
    fn intrinsics(&self) -> CameraIntrinsics {
        self.intrinsics.clone()
    }
    fn frame_ready(&self) -> robotd_driver::DriverFuture<'_, ()> {
        Box::pin(async {
            tokio::time::sleep(std::time::Duration::from_secs(1)).await;
            Err(DriverError::Hardware(self.reason.clone()))
        })
    }
    fn capture_into(&self, _out: &mut [u8]) -> Result<CaptureInfo, DriverError> {
        Err(DriverError::Hardware(self.reason.clone()))
    }
}
