//! The arm `robotd commission` works with, and the bus to talk to it. Every motion is a
//! request on `arm/command` from the origin `cli` (session `robotd commission`) — so the
//! motion policy admits, caps and audits each one, and the e-stop (`robotd estop`, the
//! dashboard, the MCP tool) stops it, exactly as for any other motion.
//!
//! Two ways to reach the arm, chosen by [`Session::start`]:
//!
//! - **Fresh**: no robotd serves the configured bus namespace. Commissioning starts robotd's
//!   arm, gripper and camera actors on the configured driver in this process. The WidowX
//!   gripper runs with a widened tick range and a low PWM, for the gripper step (see
//!   `gripper.rs`).
//! - **Attached**: a robotd already drives the arm there (a Ned2 serves one client, a servo
//!   bus one master, so commissioning must not connect to it too). Commissioning sends its
//!   motions to that robotd and asks it what the robot is (`system/hardware`: intrinsics,
//!   versions, e-stop). Its driver must be the configured one, and it must not be another
//!   `robotd commission` run. The WidowX gripper step, which needs the fingers driven past
//!   the configured ends, is refused there.
//!
//! Either way the speed is capped low: every request asks the policy for the `--speed` cap
//! (the origin's `speed_cap_mm_s`, which lowers the configured cap and never raises it), and
//! a fresh session also lowers `safety.max_tcp_speed_m_s` to it.

use anyhow::{bail, Context, Result};
use robotd_config::Config;
use robotd_protocol::arm::{ArmCommand, ArmReply, ArmState};
use robotd_protocol::camera::CameraIntrinsics;
use robotd_protocol::geometry::Pose;
use robotd_protocol::gripper::{GripperCommand, GripperReply};
use robotd_protocol::hardware::{HardwareInfo, HardwareQuery, HardwareReport};
use robotd_protocol::health::{EStopRelease, EmergencyStop};
use robotd_protocol::safety::{Origin, OriginKind};
use robotd_robot::Hardware;
use robotd_runtime::bus::{Bus, BusOptions, FrameSubscriber, Subscriber};
use robotd_topics::{
    ARM_COMMAND, ARM_STATE, CAMERA_FRAMES, GRIPPER_COMMAND, SAFETY_ESTOP, SAFETY_RELEASE,
    SYSTEM_HARDWARE,
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
    /// The actors this process started; `None` when attached to a running robotd.
    hardware: Option<Hardware>,
    /// The camera's intrinsics (from the driver, or the running robotd).
    intrinsics: CameraIntrinsics,
    /// Who every request comes from: the CLI, with the commissioning speed cap.
    origin: Origin,
    states: Subscriber<ArmState>,
    frames: FrameSubscriber,
    last_state: Option<ArmState>,
    /// How long one motion may take before commissioning gives up on it.
    pub motion_timeout: Duration,
}

impl Session {
    /// Reaches the arm of `config`'s driver, its speed capped at `speed_m_s`: attached to the
    /// robotd that serves the configured bus namespace, or with actors started here.
    pub async fn start(config: &Config, speed_m_s: f64) -> Result<Session> {
        let namespace = &config.bus.namespace;
        let bus = Bus::open(BusOptions::new(namespace, "robotd-commission"))
            .with_context(|| format!("joining the bus '{namespace}'"))?;
        let origin = Origin::new(OriginKind::Cli)
            .session("robotd commission")
            .speed_cap((speed_m_s * 1000.0).floor().max(1.0) as u32);
        let (hardware, intrinsics) = if bus.client(&ARM_COMMAND)?.has_server() {
            (None, attach(&bus, config).await?.intrinsics)
        } else {
            let hardware = start_actors(&bus, config, speed_m_s).await?;
            let intrinsics = hardware.camera_intrinsics.clone();
            (Some(hardware), intrinsics)
        };
        let states = bus.subscriber(&ARM_STATE)?;
        let frames = bus.frame_subscriber(&CAMERA_FRAMES)?;
        Ok(Session {
            bus,
            hardware,
            intrinsics,
            origin,
            states,
            frames,
            last_state: None,
            motion_timeout: Duration::from_secs(60),
        })
    }

    /// Whether commissioning works through a robotd that was already running.
    pub fn attached(&self) -> bool {
        self.hardware.is_none()
    }

    /// What the running robotd says about its robot (attached sessions).
    async fn report(&self) -> Result<HardwareReport> {
        ask_hardware(&self.bus).await
    }

    /// The robot's versions as its arm driver reads them.
    pub async fn hardware_info(&self) -> Result<HardwareInfo, String> {
        match &self.hardware {
            Some(hardware) => hardware
                .arm_context
                .driver
                .hardware_info()
                .await
                .map_err(|e| e.to_string()),
            None => self.report().await.map_err(|e| format!("{e:#}"))?.versions,
        }
    }

    /// Where the gripper's fingers stopped on its last close and the load there.
    pub fn last_close(&self) -> Result<robotd_driver::CloseStop, String> {
        match &self.hardware {
            Some(hardware) => hardware
                .gripper_driver
                .last_close()
                .map_err(|e| e.to_string()),
            None => Err(ATTACHED_GRIPPER.into()),
        }
    }

    /// The camera's intrinsics as the driver reports them.
    pub fn intrinsics(&self) -> CameraIntrinsics {
        self.intrinsics.clone()
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
        let origin = self.origin.clone();
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
        let origin = self.origin.clone();
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
        let origin = self.origin.clone();
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
    pub async fn estop_reason(&self) -> Result<Option<String>> {
        match &self.hardware {
            Some(hardware) => Ok(hardware.safety.estop()),
            None => Ok(self.report().await?.estop),
        }
    }

    /// Releases the e-stop through the motion policy's `safety/release` (origin `cli`), only
    /// if its reason is still exactly `own_reason` (the policy checks it as it releases).
    pub async fn release_estop(&self, by: &str, own_reason: &str) -> Result<()> {
        let client = self.bus.client(&SAFETY_RELEASE)?;
        let origin = self.origin.clone();
        let request = EStopRelease {
            confirm: "release".into(),
            by: by.into(),
            only_if_reason: Some(own_reason.to_owned()),
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

/// Why the gripper step does not run on a robotd that was already running.
pub const ATTACHED_GRIPPER: &str = "the gripper step drives the fingers past the configured \
    ends at a low PWM to find their stops, which a running robotd does not allow: stop robotd \
    and run `robotd commission --only gripper`; nothing moved";

/// Asks the robotd on `bus` what its robot is.
async fn ask_hardware(bus: &Bus) -> Result<HardwareReport> {
    let client = bus.client(&SYSTEM_HARDWARE)?;
    if !client.wait_for_server(Duration::from_secs(2)).await {
        bail!(
            "the running robotd does not answer system/hardware (a robotd older than this \
             one?): stop it and run robotd commission on its own"
        );
    }
    client
        .request(&HardwareQuery {}, Duration::from_secs(10))
        .await
        .context("asking the running robotd about its robot (system/hardware)")
}

/// Checks that the robotd already on the bus drives the configured robot, and returns what it
/// says about it.
async fn attach(bus: &Bus, config: &Config) -> Result<HardwareReport> {
    let report = ask_hardware(bus).await?;
    if report.commissioning {
        bail!(
            "another robotd commission is working with the robot on bus namespace '{}': wait \
             for it to finish",
            config.bus.namespace
        );
    }
    let configured = config.robot.driver.name();
    if report.driver != configured {
        bail!(
            "the robotd running on bus namespace '{}' drives '{}', but this configuration \
             names robot.driver = \"{configured}\": commission with the configuration that \
             robotd runs with (--config), or stop it",
            config.bus.namespace,
            report.driver
        );
    }
    tracing::info!(driver = configured, "attached to the running robotd");
    Ok(report)
}

/// Starts robotd's arm, gripper and camera actors on `config`'s driver in this process, the
/// speed capped at `speed_m_s` and the WidowX gripper free to find its stops.
async fn start_actors(bus: &Bus, config: &Config, speed_m_s: f64) -> Result<Hardware> {
    let mut config = config.clone();
    let safety = &mut config.safety;
    safety.max_tcp_speed_m_s = safety.max_tcp_speed_m_s.min(speed_m_s);
    safety.motions_per_minute = 0;
    // The gripper step finds the fingers' real stops: let them go past the configured ends.
    let widowx = &mut config.robot.widowx;
    (widowx.gripper_closed_ticks, widowx.gripper_open_ticks) =
        super::gripper::widened(widowx.gripper_closed_ticks, widowx.gripper_open_ticks);
    widowx.gripper_pwm = widowx.gripper_pwm.min(super::gripper::LOW_PWM);
    let mut sections = config.robot_sections();
    sections.commissioning = true;
    Hardware::start(bus, &sections, |_| {
        robotd_runtime::supervision::observer_fn(
            |_: &robotd_runtime::supervision::SupervisionEvent| {},
        )
    })
    .await
    .context("starting robotd's arm, gripper and camera on the configured driver")
}
