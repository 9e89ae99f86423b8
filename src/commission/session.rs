//! The arm `robotd commission` works with: robotd's own actors on the configured driver,
//! started in this process, with every motion sent as a request on `arm/command` from the
//! origin `cli` (session `robotd commission`) — so the motion policy admits, caps and audits
//! each one, and the e-stop (`robotd estop`, the dashboard, the MCP tool) stops it, exactly as
//! for any other motion.
//!
//! Commissioning needs the robot to itself: a Ned2 serves one client, a servo bus one master.
//! When a robotd already serves the configured bus namespace, [`Session::start`] refuses and
//! says so rather than fight it for the robot.
//!
//! Its speed is capped low: `safety.max_tcp_speed_m_s` is lowered to the `--speed` cap for
//! this process (never raised). The WidowX gripper runs with a widened tick range and a low
//! PWM, for the gripper step (see `gripper.rs`).

use anyhow::{bail, Context, Result};
use robotd_config::Config;
use robotd_protocol::arm::{ArmCommand, ArmReply, ArmState};
use robotd_protocol::camera::CameraIntrinsics;
use robotd_protocol::geometry::Pose;
use robotd_protocol::gripper::{GripperCommand, GripperReply};
use robotd_protocol::health::{EStopRelease, EmergencyStop};
use robotd_protocol::safety::{Origin, OriginKind};
use robotd_robot::Hardware;
use robotd_runtime::bus::{Bus, BusOptions, FrameSubscriber, Subscriber};
use robotd_topics::{
    ARM_COMMAND, ARM_STATE, CAMERA_FRAMES, GRIPPER_COMMAND, SAFETY_ESTOP, SAFETY_RELEASE,
};
use std::time::{Duration, Instant};

/// A frame counts as still when taken this long after the arm came to rest, ns: a camera
/// stamps its frames with an estimate of their capture time (an MJPEG stream's latency is a
/// configured guess), and an arm rings a little after it arrives.
const SETTLE_NS: u64 = 300_000_000;

/// One still camera frame and the joints it was taken at.
pub struct StillFrame {
    /// RGB8 pixels, `width × height × 3`.
    pub rgb: Vec<u8>,
    /// Image width, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
    /// The frame's number.
    pub frame_id: u64,
    /// The arm's joints while the frame was taken (it stood still).
    pub joints: Vec<f64>,
}

/// robotd's actors on the configured driver, and the bus to talk to them.
pub struct Session {
    bus: Bus,
    hardware: Hardware,
    states: Subscriber<ArmState>,
    frames: FrameSubscriber,
    last_state: Option<ArmState>,
    /// How long one motion may take before commissioning gives up on it.
    pub motion_timeout: Duration,
}

impl Session {
    /// Starts the actors on `config`'s driver, its speed capped at `speed_m_s`.
    pub async fn start(config: &Config, speed_m_s: f64) -> Result<Session> {
        let namespace = &config.bus.namespace;
        let bus = Bus::open(BusOptions::new(namespace, "robotd-commission"))
            .with_context(|| format!("joining the bus '{namespace}'"))?;
        if bus.client(&ARM_COMMAND)?.has_server() {
            bail!(
                "a robotd already drives the arm on bus namespace '{namespace}'; commissioning \
                 needs the robot to itself (a Ned2 serves one client, a servo bus one master): \
                 stop that robotd first"
            );
        }
        let mut config = config.clone();
        let safety = &mut config.safety;
        safety.max_tcp_speed_m_s = safety.max_tcp_speed_m_s.min(speed_m_s);
        safety.motions_per_minute = 0;
        // The gripper step finds the fingers' real stops: let them go past the configured ends.
        let widowx = &mut config.robot.widowx;
        (widowx.gripper_closed_ticks, widowx.gripper_open_ticks) =
            super::gripper::widened(widowx.gripper_closed_ticks, widowx.gripper_open_ticks);
        widowx.gripper_pwm = widowx.gripper_pwm.min(super::gripper::LOW_PWM);
        let hardware = Hardware::start(&bus, &config.robot_sections(), |_| {
            robotd_runtime::supervision::observer_fn(
                |_: &robotd_runtime::supervision::SupervisionEvent| {},
            )
        })
        .await
        .context("starting robotd's arm, gripper and camera on the configured driver")?;
        let states = bus.subscriber(&ARM_STATE)?;
        let frames = bus.frame_subscriber(&CAMERA_FRAMES)?;
        Ok(Session {
            bus,
            hardware,
            states,
            frames,
            last_state: None,
            motion_timeout: Duration::from_secs(60),
        })
    }

    /// The robot's versions as its arm driver reads them.
    pub async fn hardware_info(
        &self,
    ) -> Result<robotd_driver::HardwareInfo, robotd_driver::DriverError> {
        self.hardware.arm_context.driver.hardware_info().await
    }

    /// Where the gripper's fingers stopped on its last close and the load there.
    pub fn last_close(&self) -> Result<robotd_driver::CloseStop, robotd_driver::DriverError> {
        self.hardware.gripper_driver.last_close()
    }

    /// The camera's intrinsics as the driver reports them.
    pub fn intrinsics(&self) -> CameraIntrinsics {
        self.hardware.camera_intrinsics.clone()
    }

    /// The newest arm state, waiting up to `wait` for the first one.
    pub async fn state(&mut self, wait: Duration) -> Result<ArmState> {
        let deadline = Instant::now() + wait;
        loop {
            while let Some(envelope) = self.states.try_recv()? {
                self.last_state = Some(envelope.body);
            }
            if let Some(state) = &self.last_state {
                return Ok(state.clone());
            }
            let left = deadline.saturating_duration_since(Instant::now());
            if left.is_zero() {
                bail!("the arm published no state within {wait:?}: is the robot connected?");
            }
            if let Ok(envelope) = tokio::time::timeout(left, self.states.recv()).await {
                self.last_state = Some(envelope?.body);
            }
        }
    }

    /// Sends `command` as the operator's CLI would, and returns the arm's reply.
    pub async fn command(&self, command: ArmCommand) -> Result<ArmReply, String> {
        let client = self.bus.client(&ARM_COMMAND).map_err(|e| e.to_string())?;
        let origin = Origin::new(OriginKind::Cli).session("robotd commission");
        let timeout = self.motion_timeout;
        let reply = robotd_runtime::origin::with_origin(origin, async move {
            client.request(&command, timeout).await
        })
        .await
        .map_err(|e| format!("the arm did not answer: {e}"))?;
        reply.into_result().map_err(|e| e.to_string())
    }

    /// Sends `command` to the gripper as the operator's CLI would.
    pub async fn gripper(&self, command: GripperCommand) -> Result<GripperReply> {
        let client = self.bus.client(&GRIPPER_COMMAND)?;
        let origin = Origin::new(OriginKind::Cli).session("robotd commission");
        let timeout = self.motion_timeout;
        robotd_runtime::origin::with_origin(origin, async move {
            client.request(&command, timeout).await
        })
        .await
        .context("the gripper did not answer")
    }

    /// Moves the tool to `target` (joint-space path), admitted by the motion policy.
    pub async fn move_to(&self, target: Pose) -> Result<Pose, String> {
        match self.command(ArmCommand::move_to(target)).await? {
            ArmReply::Ok { pose } => Ok(pose),
            other => Err(format!("unexpected reply {other:?}")),
        }
    }

    /// Starts moving the tool to `target` without waiting: the motion's reply comes from the
    /// task.
    pub fn spawn_move(&self, target: Pose) -> Result<tokio::task::JoinHandle<Result<(), String>>> {
        let client = self.bus.client(&ARM_COMMAND)?;
        let origin = Origin::new(OriginKind::Cli).session("robotd commission");
        let timeout = self.motion_timeout;
        Ok(tokio::spawn(robotd_runtime::origin::with_origin(
            origin,
            async move {
                let reply = client
                    .request(&ArmCommand::move_to(target), timeout)
                    .await
                    .map_err(|e| format!("the arm did not answer: {e}"))?;
                reply.into_result().map(|_| ()).map_err(|e| e.to_string())
            },
        )))
    }

    /// The next arm state published, if one comes within `wait`.
    pub async fn next_state(&mut self, wait: Duration) -> Result<Option<ArmState>> {
        match tokio::time::timeout(wait, self.states.recv()).await {
            Ok(envelope) => {
                let state = envelope?.body;
                self.last_state = Some(state.clone());
                Ok(Some(state))
            }
            Err(_) => Ok(None),
        }
    }

    /// Engages the e-stop on `safety/estop`, the path of every entry point.
    pub fn engage_estop(&self, reason: &str) -> Result<()> {
        self.bus.publisher(&SAFETY_ESTOP)?.publish(&EmergencyStop {
            engaged: true,
            reason: reason.into(),
            source: "robotd commission".into(),
        })?;
        Ok(())
    }

    /// The e-stop's reason while it is engaged.
    pub fn estop_reason(&self) -> Option<String> {
        self.hardware.safety.estop()
    }

    /// Releases the e-stop through the motion policy's `safety/release` (origin `cli`).
    pub async fn release_estop(&self, by: &str) -> Result<()> {
        let client = self.bus.client(&SAFETY_RELEASE)?;
        let origin = Origin::new(OriginKind::Cli).session("robotd commission");
        let request = EStopRelease {
            confirm: "release".into(),
            by: by.into(),
        };
        robotd_runtime::origin::with_origin(origin, async move {
            client.request(&request, Duration::from_secs(5)).await
        })
        .await
        .context("releasing the e-stop")?;
        Ok(())
    }

    /// Moves the joints to `positions_rad`, admitted by the motion policy.
    pub async fn move_joints(&self, positions_rad: Vec<f64>) -> Result<(), String> {
        self.command(ArmCommand::MoveJoints { positions_rad })
            .await
            .map(|_| ())
    }

    /// A frame taken after the arm came to rest, with the joints it rests at.
    pub async fn still_frame(&mut self, wait: Duration) -> Result<StillFrame> {
        let deadline = Instant::now() + wait;
        loop {
            let state = self.state(wait).await?;
            let left = deadline.saturating_duration_since(Instant::now());
            if left.is_zero() {
                bail!(
                    "no camera frame of the arm standing still within {wait:?}: is the camera \
                     connected?"
                );
            }
            let Ok(frame) = tokio::time::timeout(left, self.frames.recv()).await else {
                continue;
            };
            let frame = frame?;
            let header = *frame.header();
            // The newest state again: the frame must be younger than the arm's rest.
            let state = match self.states.try_recv()? {
                Some(envelope) => {
                    self.last_state = Some(envelope.body.clone());
                    envelope.body
                }
                None => state,
            };
            let rest = state.still_since_unix_ns;
            if state.moving || rest == 0 || header.timestamp_unix_ns < rest + SETTLE_NS {
                continue;
            }
            return Ok(StillFrame {
                rgb: frame.pixels().to_vec(),
                width: header.width,
                height: header.height,
                frame_id: header.frame_id,
                joints: state.joints.positions_rad.clone(),
            });
        }
    }
}
