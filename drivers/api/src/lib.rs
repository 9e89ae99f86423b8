//! The driver traits: what the arm, gripper and camera actors need from a robot.
//!
//! A driver is the one piece that differs between the simulator and a real robot. The actors
//! plan, check and report; the driver only executes. The traits are shaped for the drivers
//! robotd has and will have:
//!
//! - **sim** (`drivers/sim`): a kinematic Ned2 or WidowX in a simulated world;
//! - **niryo**: the Ned2's TCP protocol, whose motion commands block until the motion ends;
//! - **widowx**: Dynamixel servos over a serial line, polled for their positions.
//!
//! So a motion is one call that returns when the motion has ended (or was stopped, or hit
//! something), queries are cheap reads, and [`ArmDriver::halt`] works from any task while a
//! motion runs, because the supervisor's safe-state hook must be able to stop an arm whose
//! actor just died.
//!
//! **One door.** Every method that moves something — [`ArmDriver::execute`],
//! [`ArmDriver::calibrate`], [`ArmDriver::clear_collision`], [`GripperDriver::open`],
//! [`GripperDriver::close`], [`GripperDriver::set_width`] — takes a [`Permit`] for that act,
//! which only the safety policy (`robotd-safety`, in `libs/safety`) can make. Holding a driver
//! is therefore not enough to move the robot: the caller must have passed the policy. Only
//! [`ArmDriver::halt`] needs none (stopping is always allowed), and the queries need none.
//!
//! A driver crate hands the actors a [`RobotDrivers`]: one driver per actor and the robot's
//! model. The workspaces (and their observation poses) come from `[robot] workspaces`, not
//! from the driver, so a real robot starts with the same ones as the simulator. Adding a driver = a crate in `drivers/`
//! implementing these traits, plus one line where `robotd-robot` chooses the driver.

pub mod camera_feed;
pub mod config;
pub mod hardware;
pub mod niryo_config;
pub mod replay_config;
pub mod timed_path;
pub mod widowx_config;
pub use config::{CameraConfig, FaultConfig, FaultsConfig, RobotConfig, RobotDriver};
pub use niryo_config::NiryoConfig;
pub use replay_config::ReplayConfig;
pub use timed_path::{PathSample, TimedPath};
pub use widowx_config::WidowxConfig;

use nalgebra::Isometry3;
use robotd_protocol::geometry::{Pose, RobotModel};
pub use robotd_safety::control::{nominal_travel_time_s, Motion, MotionControl, Stopped};
pub use robotd_safety::permit::{
    ArmMotion, Calibration, ClearCollision, Close, Open, Permit, SetWidth,
};
use std::future::Future;
use std::pin::Pin;
use std::sync::Arc;

/// A driver's answer that arrives later (a motion, a calibration).
pub type DriverFuture<'a, T> = Pin<Box<dyn Future<Output = Result<T, DriverError>> + Send + 'a>>;

/// Why a driver command did not do what was asked.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DriverError {
    /// The arm touched something (an object, the table) and stopped.
    #[error("collision with {what}; the arm stopped")]
    Collision {
        /// What was hit.
        what: String,
    },
    /// A collision was detected earlier and not cleared.
    #[error("collision detected earlier; clear it (clear_collision_detected) before moving")]
    CollisionPending,
    /// The motion was interrupted by a stop or the emergency stop.
    #[error("motion stopped: {reason}")]
    Stopped {
        /// A stop command, or the e-stop's reason.
        reason: String,
    },
    /// The arm must be calibrated first.
    #[error("the arm is not calibrated; run calibrate first")]
    NotCalibrated,
    /// A joint target is outside the robot's limits (drivers check again).
    #[error("joint target out of range: {0}")]
    OutOfRange(String),
    /// The robot (connection, servo, camera) failed.
    #[error("{0}")]
    Hardware(String),
}

impl From<Stopped> for DriverError {
    fn from(stopped: Stopped) -> Self {
        DriverError::Stopped {
            reason: stopped.reason,
        }
    }
}

/// `Err(OutOfRange)` unless `speed_scale` is in (0, 1], the range [`ArmDriver::execute`]
/// takes.
pub fn check_speed_scale(speed_scale: f64) -> Result<(), DriverError> {
    if speed_scale > 0.0 && speed_scale <= 1.0 {
        Ok(())
    } else {
        Err(DriverError::OutOfRange(format!(
            "speed scale must be in (0, 1], got {speed_scale}"
        )))
    }
}

/// What an arm driver reports besides joints.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct ArmFlags {
    /// A motion is under way.
    pub moving: bool,
    /// A collision was detected and not cleared.
    pub collision_detected: bool,
    /// The arm is calibrated.
    pub calibrated: bool,
}

/// What the robot reports about its versions: the protocol's types, so that a running
/// robotd can answer them on the bus (`system/hardware`).
pub use robotd_protocol::hardware::{HardwareInfo, MotorInfo};

/// The error of a driver that reports no hardware or firmware versions.
pub fn versions_not_reported() -> DriverError {
    DriverError::Hardware("hardware and firmware versions are not reported by this driver".into())
}

/// An arm: joint motions that finish when the arm has arrived, and cheap queries.
pub trait ArmDriver: Send + Sync + 'static {
    /// Which robot this is.
    fn model(&self) -> RobotModel;
    /// Current joint positions, radians, base to wrist.
    fn joints(&self) -> Result<Vec<f64>, DriverError>;
    /// Moving / collision / calibration flags.
    fn flags(&self) -> ArmFlags;
    /// When the arm came to rest (ns since the Unix epoch; 0 while it moves), for a driver
    /// that knows it better than the arm actor, which notes the end of the motions it ran: a
    /// replayed recording, whose arm came to rest at recorded times. `None` (the default):
    /// the actor's own note.
    fn still_since_unix_ns(&self) -> Option<u64> {
        None
    }
    /// Executes the permitted motion at its speed scale (0 < scale ≤ 1: the fraction of the
    /// joint velocity limits, so every segment takes [`nominal_travel_time_s`] / scale);
    /// returns when it has ended. Checks `control` at every control tick and returns
    /// [`DriverError::Stopped`] when asked to stop. The motion and its scale are what the
    /// safety policy checked ([`ArmMotion`]).
    fn execute<'a>(
        &'a self,
        permit: Permit<ArmMotion>,
        control: &'a MotionControl,
    ) -> DriverFuture<'a, ()>;
    /// Runs the calibration (Ned2) or homing.
    fn calibrate(&self, permit: Permit<Calibration>) -> DriverFuture<'_, ()>;
    /// Clears the collision flag (a real robot is asked over its connection).
    fn clear_collision(&self, permit: Permit<ClearCollision>) -> DriverFuture<'_, ()>;
    /// Stops any motion now and holds position. Safe to call from any task, also while an
    /// [`execute`](Self::execute) is running elsewhere and after the arm actor died.
    fn halt(&self) -> Result<(), DriverError>;
    /// The robot's hardware, software and motor firmware versions, as far as its protocol
    /// reports them. The default (the simulator, a replay): [`versions_not_reported`].
    fn hardware_info(&self) -> DriverFuture<'_, HardwareInfo> {
        Box::pin(async { Err(versions_not_reported()) })
    }
    /// Whether the robot can be used now: `Err(reason)` while a real robot is not connected
    /// (`/health`, `get_system_status` and the tools say why). The simulator always can.
    fn connection(&self) -> Result<(), String> {
        Ok(())
    }
}

/// What a gripper reports.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GripperStatus {
    /// Whether an object is between the fingers (they stopped before closing fully).
    pub holding: bool,
    /// Distance between the fingers, metres.
    pub width_m: f64,
}

/// Where the fingers stopped on the last close, and how hard the motor pushed there.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CloseStop {
    /// The servo's position, ticks.
    pub ticks: i32,
    /// The motor's load there (a DYNAMIXEL's Present Load, 0.1 % units, unsigned).
    pub load: u16,
    /// The drive (PWM, of 885) the fingers were closed with.
    pub pwm: u16,
    /// Whether the driver decided it holds something.
    pub holding: bool,
}

/// A gripper.
pub trait GripperDriver: Send + Sync + 'static {
    /// Widest opening, metres.
    fn max_width_m(&self) -> f64;
    /// Opens fully (releasing what it holds).
    fn open(&self, permit: Permit<Open>) -> DriverFuture<'_, GripperStatus>;
    /// Closes until fully closed or blocked by an object.
    fn close(&self, permit: Permit<Close>) -> DriverFuture<'_, GripperStatus>;
    /// Moves the fingers to the permitted width ([`SetWidth::width_m`]) apart.
    fn set_width(&self, permit: Permit<SetWidth>) -> DriverFuture<'_, GripperStatus>;
    /// Reads the state.
    fn status(&self) -> Result<GripperStatus, DriverError>;
    /// Where the fingers stopped on the last close and the load there, for commissioning's
    /// grasp threshold. The default: an error, the driver does not report it.
    fn last_close(&self) -> Result<CloseStop, DriverError> {
        Err(DriverError::Hardware(
            "the fingers' stop and load are not reported by this driver".into(),
        ))
    }
}

/// Where and when a frame was taken.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CaptureInfo {
    /// Pose of the camera's optical frame (z = viewing direction) in the base frame.
    pub camera_pose: Isometry3<f64>,
    /// Capture time, nanoseconds since the Unix epoch.
    pub timestamp_unix_ns: u64,
}

/// A camera producing 640×480 RGB8 frames.
pub trait CameraDriver: Send + Sync + 'static {
    /// Image width and height in pixels.
    fn size(&self) -> (u32, u32);
    /// Intrinsics: fx, fy, cx, cy and the distortion k1, k2, p1, p2, k3.
    fn intrinsics(&self) -> robotd_protocol::camera::CameraIntrinsics;
    /// Waits until a new frame can be captured. A camera that takes pictures on request (the
    /// simulator) is always ready and is paced by `robot.camera.fps`; one that receives them
    /// at the robot's own pace (a Ned2 over TCP) resolves when the next one has arrived.
    fn frame_ready(&self) -> DriverFuture<'_, ()> {
        Box::pin(async { Ok(()) })
    }
    /// Writes one frame (row-major RGB8, width × height × 3 bytes) into `out`, which is the
    /// shared-memory frame on the bus, so the image is written exactly once.
    fn capture_into(&self, out: &mut [u8]) -> Result<CaptureInfo, DriverError>;
}

/// A workspace's observation pose, by id.
#[derive(Debug, Clone, PartialEq)]
pub struct ObservationPose {
    /// Workspace id, e.g. `niryo_ws`.
    pub workspace_id: String,
    /// Tool pose from which the camera sees the whole workspace.
    pub pose: Pose,
}

/// What a driver hands the robot's actors.
#[derive(Clone)]
pub struct RobotDrivers {
    /// The robot's model (its kinematics and limits).
    pub model: RobotModel,
    /// The arm driver.
    pub arm: Arc<dyn ArmDriver>,
    /// The gripper driver.
    pub gripper: Arc<dyn GripperDriver>,
    /// The camera driver.
    pub camera: Arc<dyn CameraDriver>,
}

impl std::fmt::Debug for RobotDrivers {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RobotDrivers")
            .field("model", &self.model)
            .finish_non_exhaustive()
    }
}
