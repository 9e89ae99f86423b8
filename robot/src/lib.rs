//! The robot: chooses the driver `[robot] driver` names and starts the arm, gripper and
//! camera actors on it.
//!
//! The actors (`actors/arm`, `actors/gripper`, `actors/camera`) plan, check and report; the
//! driver (`drivers/*`) only executes. This crate is the one place that joins them:
//!
//! | actor | serves / publishes | catalogue |
//! |---|---|---|
//! | arm | `arm/command` (motions, stop, queries), `arm/state`, listens to `safety/estop` | [`ARM_COMMAND`](robotd_topics::ARM_COMMAND) |
//! | gripper | `gripper/command`, `gripper/state` | [`GRIPPER_COMMAND`](robotd_topics::GRIPPER_COMMAND) |
//! | camera | `camera/frames` (640×480 RGB, zero-copy) | [`CAMERA_FRAMES`](robotd_topics::CAMERA_FRAMES) |
//!
//! Drivers: `sim-ned2` (the default) and `sim-widowx` run the simulator of `drivers/sim`;
//! `niryo` drives a real Ned2 over TCP (`drivers/niryo`); `widowx` a real WidowX 250 s over
//! its DYNAMIXEL servo bus (`drivers/widowx`); `replay` plays a recording as the robot
//! (`drivers/replay`: it never moves). A new driver is a crate in `drivers/` plus one arm of the `match` in
//! [`Hardware::start`].
//!
//! The robot reads only its own sections of the configuration, [`RobotSections`]; the binary
//! hands them over from the composed configuration (`robotd_config::Config::robot_sections`).
//!
//! ```no_run
//! # async fn demo(sections: robotd_robot::RobotSections) -> anyhow::Result<()> {
//! use robotd_runtime::bus::{Bus, BusOptions};
//! use robotd_robot::Hardware;
//!
//! let bus = Bus::open(BusOptions::new("robotd", "robotd"))?;
//! let hardware = Hardware::start(&bus, &sections, |_actor| {
//!     robotd_runtime::supervision::observer_fn(|event: &robotd_runtime::supervision::SupervisionEvent| {
//!         eprintln!("{event}")
//!     })
//! })
//! .await?;
//! // ... arm/command, gripper/command and camera/frames are on the bus now.
//! hardware.shutdown().await;
//! # Ok(()) }
//! ```

mod info_service;

use robotd_arm::{ArmActor, ArmContext, RunningArm};
use robotd_camera::CameraActor;
use robotd_driver::{MotionControl, ObservationPose, RobotConfig, RobotDriver, RobotDrivers};
use robotd_driver_sim::SimRobot;
use robotd_gripper::GripperActor;
use robotd_runtime::bus::Bus;
use robotd_runtime::config::SupervisionConfig;
use robotd_runtime::host::ActorStartError;
use robotd_runtime::supervision::{Supervised, SupervisionObserver, Supervisor};
use robotd_safety::{Safety, SafetyConfig};
use std::collections::BTreeMap;
use std::path::PathBuf;

/// The robot's supervised actors, by the names their supervisors, `[actors.<name>]` and the
/// observer know them by.
pub const ACTORS: [&str; 3] = ["arm", "gripper", "camera"];

/// What the robot reads of robotd's configuration: its own sections, handed over by the
/// binary (`robotd_config::Config::robot_sections` makes them from the composed
/// configuration), so that this crate depends on neither that configuration nor the edges and
/// agent whose sections it is made of.
#[derive(Debug, Clone, PartialEq)]
pub struct RobotSections {
    /// `[robot]`: the driver and its settings, the workspaces.
    pub robot: RobotConfig,
    /// `[safety]`: the motion policy.
    pub safety: SafetyConfig,
    /// `[telemetry] log_dir`: where the audit log is written when `safety.audit.path` is empty.
    pub log_dir: PathBuf,
    /// `[supervision]`: the restart policy of each of the robot's [`ACTORS`] without an entry
    /// in [`RobotSections::actor_supervision`].
    pub supervision: SupervisionConfig,
    /// The effective restart policy of those of the robot's [`ACTORS`] that override
    /// `[supervision]` (`[actors.<name>]`), by actor name.
    pub actor_supervision: BTreeMap<String, SupervisionConfig>,
    /// Whether this process is a `robotd commission` run: `system/hardware` says so, so that
    /// another commissioning does not work through it at the same time.
    pub commissioning: bool,
}

impl RobotSections {
    /// The restart policy of `actor`: its own if it has one, else `[supervision]`.
    pub fn supervision_for(&self, actor: &str) -> &SupervisionConfig {
        self.actor_supervision
            .get(actor)
            .unwrap_or(&self.supervision)
    }
}

/// Why the robot's actors could not start.
#[derive(Debug, thiserror::Error)]
pub enum StartError {
    /// The simulator's scene is missing, malformed or for another robot.
    #[error(transparent)]
    Scene(#[from] robotd_driver_sim::SceneError),
    /// The recording of the replay driver is missing or cannot be played.
    #[error(transparent)]
    Replay(#[from] robotd_driver_replay::ReplayError),
    /// The audit log could not be opened (the motion policy refuses to run without it).
    #[error("safety.audit: {0}; fix the path or set safety.audit.enabled = false")]
    Audit(robotd_safety::AuditError),
    /// An actor could not be put on the bus.
    #[error("starting the {actor} actor: {source}")]
    Actor {
        /// Actor name.
        actor: &'static str,
        /// Why.
        source: ActorStartError,
    },
    /// A bus port of the driver could not be created.
    #[error("bus: {0}")]
    Bus(#[from] robotd_runtime::bus::BusError),
}

/// The running arm, gripper and camera actors and their bus tasks.
pub struct Hardware {
    /// The simulated robot (ground truth, for tests and benchmarks); `None` on real hardware.
    pub sim: Option<SimRobot>,
    /// The supervised arm actor.
    pub arm: Supervised<ArmActor>,
    /// The supervised gripper actor.
    pub gripper: Supervised<GripperActor>,
    /// The gripper's driver, for what only commissioning asks of it (the load at its stop).
    pub gripper_driver: std::sync::Arc<dyn robotd_driver::GripperDriver>,
    /// The supervised camera actor.
    pub camera: Supervised<CameraActor>,
    /// Shared arm state (driver, kinematics, stop signals).
    pub arm_context: ArmContext,
    /// The motion policy every arm and gripper motion passes (e-stop state, approvals).
    pub safety: Safety,
    /// The camera's intrinsics as its driver reports them (zero distortion when the image is
    /// already an ideal pinhole image), for the perception actor.
    pub camera_intrinsics: robotd_protocol::camera::CameraIntrinsics,
    /// The replay driver's recording, which plays once [`Hardware::start_playback`] is called.
    pub replay: Option<robotd_driver_replay::Replay>,
    tasks: Vec<tokio::task::JoinHandle<()>>,
}

impl std::fmt::Debug for Hardware {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Hardware")
            .field("simulated", &self.sim.is_some())
            .finish_non_exhaustive()
    }
}

impl Hardware {
    /// Opens the configured driver and starts the arm, gripper and camera actors on `bus`,
    /// each under its supervisor with the observer `observer(actor name)` gives.
    pub async fn start<O: SupervisionObserver>(
        bus: &Bus,
        sections: &RobotSections,
        observer: impl Fn(&'static str) -> O,
    ) -> Result<Hardware, StartError> {
        match sections.robot.driver {
            RobotDriver::SimNed2 | RobotDriver::SimWidowx => {
                let sim = robotd_driver_sim::open(&sections.robot)?;
                let ground_truth = robotd_driver_sim::serve_ground_truth(bus, sim.robot.clone())?;
                let mut hardware = Self::start_with(bus, sections, sim.drivers, observer).await?;
                hardware.tasks.push(ground_truth);
                hardware.sim = Some(sim.robot);
                Ok(hardware)
            }
            RobotDriver::Niryo => {
                // The policy first: the driver's automatic calibration on connecting asks it.
                let safety = Self::policy(sections, robotd_protocol::RobotModel::Ned2)?;
                let niryo = robotd_driver_niryo::open(
                    &sections.robot,
                    std::time::Duration::from_secs(3),
                    safety.clone(),
                )
                .await;
                let mut hardware =
                    Self::start_on(bus, sections, niryo.drivers, safety, observer).await?;
                hardware.tasks.extend(niryo.tasks);
                Ok(hardware)
            }
            RobotDriver::Replay => {
                // Checks the file on the blocking pool. Should the actors not start, `replay`
                // is dropped here and aborts its player (and so its reader thread).
                let mut replay = robotd_driver_replay::open(&sections.robot.replay).await?;
                let drivers = replay.drivers.clone();
                let mut hardware = Self::start_with(bus, sections, drivers, observer).await?;
                hardware.tasks.append(&mut replay.tasks);
                hardware.replay = Some(replay);
                Ok(hardware)
            }
            RobotDriver::Widowx => {
                let widowx = robotd_driver_widowx::open(&sections.robot);
                // Give the servos a moment, so the arm's first state is real; a bus that is
                // not there yet is not an error (the drivers say why until it answers).
                let deadline = std::time::Instant::now() + std::time::Duration::from_secs(3);
                while widowx.drivers.arm.joints().is_err() && std::time::Instant::now() < deadline {
                    tokio::time::sleep(std::time::Duration::from_millis(20)).await;
                }
                if let Err(reason) = widowx.bus.connection() {
                    tracing::warn!(%reason, "the WidowX is not connected yet; robotd keeps trying");
                }
                let mut hardware =
                    Self::start_with(bus, sections, widowx.drivers, observer).await?;
                hardware.tasks.extend(widowx.tasks);
                Ok(hardware)
            }
        }
    }

    /// The motion policy of a `model` robot under `sections` (`[safety]`, the workspaces), on
    /// fresh stop signals, with its audit log opened.
    pub fn policy(
        sections: &RobotSections,
        model: robotd_protocol::RobotModel,
    ) -> Result<Safety, StartError> {
        let audit =
            Safety::open_audit(&sections.safety, &sections.log_dir).map_err(StartError::Audit)?;
        Ok(Safety::new(
            sections.safety.clone(),
            robotd_kinematics::Kinematics::new(model),
            MotionControl::default(),
            &sections.robot.workspaces(),
            audit,
        ))
    }

    /// Starts the three actors on the given drivers (any driver, simulated or real), under a
    /// new motion policy ([`Hardware::policy`]).
    pub async fn start_with<O: SupervisionObserver>(
        bus: &Bus,
        sections: &RobotSections,
        drivers: RobotDrivers,
        observer: impl Fn(&'static str) -> O,
    ) -> Result<Hardware, StartError> {
        let safety = Self::policy(sections, drivers.model)?;
        Self::start_on(bus, sections, drivers, safety, observer).await
    }

    /// Starts the three actors on the given drivers under the motion policy `safety`, whose
    /// stop signals become the arm's.
    pub async fn start_on<O: SupervisionObserver>(
        bus: &Bus,
        sections: &RobotSections,
        drivers: RobotDrivers,
        safety: Safety,
        observer: impl Fn(&'static str) -> O,
    ) -> Result<Hardware, StartError> {
        let supervisor = |actor: &'static str| {
            Supervisor::new(actor)
                .policy(sections.supervision_for(actor).policy())
                .observer(observer(actor))
        };
        let failed = |actor: &'static str| move |source| StartError::Actor { actor, source };
        let camera_intrinsics = drivers.camera.intrinsics();
        // Bound first, so a service that cannot be bound leaves no actor behind; it answers
        // once the actors run.
        let info = info_service::bind(
            bus,
            info_service::RobotFacts {
                driver_name: sections.robot.driver.name().to_owned(),
                commissioning: sections.commissioning,
                arm: drivers.arm.clone(),
                camera: drivers.camera.clone(),
                safety: safety.clone(),
            },
        )?;
        let kinematics = robotd_kinematics::Kinematics::new(drivers.model);
        let control = safety.control().clone();
        let context = ArmContext {
            kinematics,
            driver: drivers.arm,
            control,
            safety: safety.clone(),
            shared: Default::default(),
            observation_poses: sections
                .robot
                .workspaces()
                .iter()
                .map(|w| ObservationPose {
                    workspace_id: w.id.clone(),
                    pose: robotd_protocol::geometry::Pose::from_array(w.observation_pose),
                })
                .collect(),
        };
        let RunningArm {
            actor: arm,
            mut tasks,
        } = robotd_arm::start(
            bus,
            supervisor("arm"),
            context.clone(),
            sections.robot.control_period(),
        )
        .await
        .map_err(failed("arm"))?;
        let gripper_driver = drivers.gripper.clone();
        let (gripper, task) =
            robotd_gripper::start(bus, supervisor("gripper"), drivers.gripper, safety.clone())
                .await
                .map_err(failed("gripper"))?;
        tasks.push(task);
        let (camera, task) = robotd_camera::start(
            bus,
            supervisor("camera"),
            drivers.camera,
            sections.robot.camera.fps,
        )
        .await
        .map_err(failed("camera"))?;
        tasks.push(task);
        tasks.push(info.spawn());
        Ok(Hardware {
            sim: None,
            arm,
            gripper,
            gripper_driver,
            camera,
            arm_context: context,
            safety,
            camera_intrinsics,
            replay: None,
            tasks,
        })
    }

    /// Starts what the robot plays by itself: the replay driver's recording (nothing for
    /// other drivers). Call once the actors that consume the robot's data (perception, the
    /// workspace model) are up, so they see it from its start.
    pub fn start_playback(&self) {
        if let Some(replay) = &self.replay {
            replay.start();
        }
    }

    /// Stops the bus tasks and the actors (halting the arm first).
    pub async fn shutdown(self) {
        let _ = self.arm_context.driver.halt();
        for task in &self.tasks {
            task.abort();
        }
        for result in [
            self.camera.shutdown().await,
            self.gripper.shutdown().await,
            self.arm.shutdown().await,
        ] {
            if let Err(error) = result {
                tracing::warn!(%error, "stopping a hardware actor");
            }
        }
    }
}
