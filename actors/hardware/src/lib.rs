//! robotd's hardware actors — arm, gripper, wrist camera — and the simulated robot they drive
//! when there is no hardware.
//!
//! Each actor owns one driver ([`driver::ArmDriver`], [`driver::GripperDriver`],
//! [`driver::CameraDriver`]), runs under a supervisor whose safe-state hook halts the arm
//! before any restart, and talks only through the bus:
//!
//! | actor | serves / publishes | catalogue |
//! |---|---|---|
//! | arm | `arm/command` (motions, stop, queries), `arm/state`, listens to `safety/estop` | [`ARM_COMMAND`](robotd_runtime::catalog::ARM_COMMAND) |
//! | gripper | `gripper/command`, `gripper/state` | [`GRIPPER_COMMAND`](robotd_runtime::catalog::GRIPPER_COMMAND) |
//! | camera | `camera/frames` (640×480 RGB, zero-copy) | [`CAMERA_FRAMES`](robotd_runtime::catalog::CAMERA_FRAMES) |
//!
//! The drivers are chosen by `[robot] driver`: `sim-ned2` (the default) and `sim-widowx` run
//! the simulator of [`sim`]; the real `niryo` and `widowx` drivers are not in this build and
//! are refused at start-up with a message saying so.
//!
//! ```no_run
//! # async fn demo() -> anyhow::Result<()> {
//! use robotd_runtime::bus::{Bus, BusOptions};
//! use robotd_runtime::config::{Config, LoadOptions};
//! use robotd_hardware::Hardware;
//!
//! let config = Config::load(LoadOptions::default())?;
//! let bus = Bus::open(BusOptions::new(&config.bus.namespace, "robotd"))?;
//! let hardware = Hardware::start(&bus, &config, |_actor| {
//!     robotd_runtime::supervision::observer_fn(|event: &robotd_runtime::supervision::SupervisionEvent| {
//!         eprintln!("{event}")
//!     })
//! })
//! .await?;
//! // ... arm/command, gripper/command and camera/frames are on the bus now.
//! hardware.shutdown().await;
//! # Ok(()) }
//! ```

pub mod arm;
pub mod camera;
pub mod driver;
pub mod faults;
pub mod gripper;
pub mod sim;

use arm::{ArmActor, ArmContext, ObservationPose};
use camera::CameraActor;
use driver::{ArmDriver, CameraDriver, GripperDriver, MotionControl};
use faults::FaultInjector;
use gripper::GripperActor;
use robotd_protocol::geometry::Pose;
use robotd_runtime::bus::Bus;
use robotd_runtime::catalog::{
    ARM_COMMAND, ARM_STATE, CAMERA_FRAMES, GRIPPER_COMMAND, GRIPPER_STATE, SAFETY_ESTOP,
};
use robotd_runtime::config::{Config, RobotDriver};
use robotd_runtime::supervision::{safe_state_fn, Supervised, SupervisionObserver, Supervisor};
use robotd_sim::Scene;
use sim::{SimRobot, SimSettings};
use std::path::Path;
use std::sync::atomic::AtomicU64;
use std::sync::Arc;
use std::time::Duration;

/// Why the hardware actors could not start.
#[derive(Debug, thiserror::Error)]
pub enum StartError {
    /// The configured driver is not part of this build.
    #[error("robot.driver = \"{driver}\" is not available in this build yet (only \"sim-ned2\" and \"sim-widowx\" are); use a simulator or wait for the hardware drivers")]
    DriverNotAvailable {
        /// The configured driver.
        driver: String,
    },
    /// The scene file is missing, malformed or describes an impossible scene.
    #[error("scene: {0}")]
    Scene(String),
    /// The scene is for another robot than the configured driver.
    #[error("scene '{scene}' is for the {scene_robot}, but robot.driver is \"{driver}\"")]
    SceneRobotMismatch {
        /// Scene name.
        scene: String,
        /// The scene's robot.
        scene_robot: String,
        /// The configured driver.
        driver: String,
    },
    /// A bus port could not be created.
    #[error("bus: {0}")]
    Bus(#[from] robotd_runtime::bus::BusError),
    /// An actor failed its first start.
    #[error("starting the {actor} actor: {reason}")]
    Actor {
        /// Actor name.
        actor: &'static str,
        /// Why.
        reason: String,
    },
}

/// The running hardware actors and their bus tasks.
pub struct Hardware {
    /// The simulated robot (ground truth, for tests and benchmarks); `None` on real hardware.
    pub sim: Option<SimRobot>,
    /// The supervised arm actor.
    pub arm: Supervised<ArmActor>,
    /// The supervised gripper actor.
    pub gripper: Supervised<GripperActor>,
    /// The supervised camera actor.
    pub camera: Supervised<CameraActor>,
    /// Shared arm state (driver, kinematics, stop signals).
    pub arm_context: ArmContext,
    /// The camera's intrinsics as its driver reports them (zero distortion when the image is
    /// already an ideal pinhole image), for the perception actor.
    pub camera_intrinsics: robotd_protocol::camera::CameraIntrinsics,
    tasks: Vec<tokio::task::JoinHandle<()>>,
}

impl std::fmt::Debug for Hardware {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Hardware")
            .field("simulated", &self.sim.is_some())
            .finish_non_exhaustive()
    }
}

/// Serves `sim/world`: the simulator's ground truth, for tests and dashboards.
fn serve_ground_truth(
    bus: &Bus,
    robot: SimRobot,
) -> Result<tokio::task::JoinHandle<()>, StartError> {
    use robotd_protocol::diagnostics::{SimObjectState, SimWorldReply};
    let mut server = bus
        .server(&robotd_runtime::catalog::SIM_WORLD)
        .map_err(StartError::Bus)?;
    Ok(tokio::spawn(async move {
        let served = server
            .serve(move |_request| {
                let reply = robot.with_world(|world| SimWorldReply {
                    scene: world.scene_name().to_owned(),
                    objects: world
                        .objects()
                        .iter()
                        .map(|o| SimObjectState {
                            label: o.spec.label.clone(),
                            x_m: o.pose.translation.x,
                            y_m: o.pose.translation.y,
                            z_m: o.pose.translation.z,
                            yaw_rad: o.yaw_rad(),
                            bottom_z_m: o.bottom_z(),
                            top_z_m: o.top_z(),
                            held: o.held,
                        })
                        .collect(),
                });
                async move { Ok(reply) }
            })
            .await;
        if let Err(error) = served {
            tracing::warn!(%error, "the sim/world service stopped");
        }
    }))
}

/// Loads the scene the configuration asks for (the built-in one by default) and checks it
/// against the robot's reach.
pub fn load_scene(config: &Config) -> Result<Scene, StartError> {
    let driver = config.robot.driver;
    let scene = match &config.robot.scene {
        Some(path) => Scene::load(Path::new(path)).map_err(|e| StartError::Scene(e.to_string()))?,
        None => match driver {
            RobotDriver::SimWidowx => Scene::default_widowx(),
            _ => Scene::default_ned2(),
        },
    };
    let expected = match driver {
        RobotDriver::SimWidowx | RobotDriver::Widowx => {
            robotd_protocol::geometry::RobotModel::WidowX250
        }
        RobotDriver::SimNed2 | RobotDriver::Niryo => robotd_protocol::geometry::RobotModel::Ned2,
    };
    if scene.robot != expected {
        return Err(StartError::SceneRobotMismatch {
            scene: scene.name.clone(),
            scene_robot: scene.robot.display_name().to_owned(),
            driver: format!("{driver:?}"),
        });
    }
    let kinematics = robotd_kinematics::Kinematics::new(scene.robot);
    scene
        .validate(&|x, y, z| reachable_from_above(&kinematics, x, y, z))
        .map_err(|e| StartError::Scene(e.to_string()))?;
    Ok(scene)
}

/// Whether the tool can reach (x, y, z) pointing down, at some yaw.
pub fn reachable_from_above(
    kinematics: &robotd_kinematics::Kinematics,
    x: f64,
    y: f64,
    z: f64,
) -> bool {
    let yaw0 = y.atan2(x);
    [
        0.0,
        std::f64::consts::FRAC_PI_2,
        yaw0,
        -std::f64::consts::FRAC_PI_2,
    ]
    .iter()
    .any(|yaw| {
        let pose = Pose::new(x, y, z, 0.0, std::f64::consts::FRAC_PI_2, *yaw);
        kinematics
            .inverse(&robotd_kinematics::pose_to_isometry(&pose), None)
            .is_ok()
    })
}

impl Hardware {
    /// Starts the arm, gripper and camera actors of the configured robot on `bus`, each under
    /// its supervisor with the observer `observer(actor name)` gives.
    pub async fn start<O: SupervisionObserver>(
        bus: &Bus,
        config: &Config,
        observer: impl Fn(&'static str) -> O,
    ) -> Result<Hardware, StartError> {
        if !config.robot.driver.is_simulated() {
            return Err(StartError::DriverNotAvailable {
                driver: format!("{:?}", config.robot.driver).to_lowercase(),
            });
        }
        let scene = load_scene(config)?;
        let settings = SimSettings {
            time_scale: config.robot.time_scale,
            control_period: config.robot.control_period(),
            noise_stddev: config.robot.camera.noise_stddev,
            lens_distortion: config.robot.camera.lens_distortion,
        };
        let robot = SimRobot::new(&scene, settings);
        let faults = &config.robot.faults;
        let arm_driver: Arc<dyn ArmDriver> =
            Arc::new(robot.arm(FaultInjector::new("arm", faults.arm.clone())));
        let gripper_driver: Arc<dyn GripperDriver> =
            Arc::new(robot.gripper(FaultInjector::new("gripper", faults.gripper.clone())));
        let camera_driver: Arc<dyn CameraDriver> =
            Arc::new(robot.camera(FaultInjector::new("camera", faults.camera.clone())));
        let observation_poses = scene
            .workspaces
            .iter()
            .map(|w| ObservationPose {
                workspace_id: w.id.clone(),
                pose: Pose::from_array(w.observation_pose),
            })
            .collect();
        let context = ArmContext {
            driver: arm_driver,
            kinematics: robot.kinematics().clone(),
            control: MotionControl::default(),
            observation_poses,
        };
        let mut hardware = Self::start_with(
            bus,
            config,
            context,
            gripper_driver,
            camera_driver,
            observer,
        )
        .await?;
        hardware.tasks.push(serve_ground_truth(bus, robot.clone())?);
        hardware.sim = Some(robot);
        Ok(hardware)
    }

    /// Starts the three actors on the given drivers (any driver, simulated or real).
    pub async fn start_with<O: SupervisionObserver>(
        bus: &Bus,
        config: &Config,
        context: ArmContext,
        gripper_driver: Arc<dyn GripperDriver>,
        camera_driver: Arc<dyn CameraDriver>,
        observer: impl Fn(&'static str) -> O,
    ) -> Result<Hardware, StartError> {
        let mut tasks = Vec::new();
        let camera_intrinsics = camera_driver.intrinsics();

        // The arm: the safe state halts it through the driver, not through the dead actor.
        let halt_driver = context.driver.clone();
        let actor_context = context.clone();
        let arm = Supervisor::new("arm")
            .policy(config.supervision_for("arm").policy())
            .observer(observer("arm"))
            .safe_state(safe_state_fn(
                Duration::from_secs(1),
                move |reason: String| {
                    let driver = halt_driver.clone();
                    async move {
                        tracing::warn!(%reason, "arm actor failed: halting the arm");
                        driver.halt().map_err(|e| e.to_string())
                    }
                },
            ))
            .spawn_actor::<ArmActor>(move || ArmActor::new(actor_context.clone()))
            .await
            .map_err(|e| StartError::Actor {
                actor: "arm",
                reason: e.to_string(),
            })?;
        let server = bus.server(&ARM_COMMAND)?;
        let (serve_actor, serve_context) = (arm.clone(), context.clone());
        tasks.push(tokio::spawn(async move {
            if let Err(error) = arm::serve_arm(server, serve_actor, serve_context).await {
                tracing::error!(%error, "arm/command stopped serving");
            }
        }));
        let state_publisher = bus.publisher(&ARM_STATE)?;
        let (state_context, period) = (context.clone(), config.robot.control_period());
        tasks.push(tokio::spawn(async move {
            if let Err(error) = arm::publish_arm_state(state_publisher, state_context, period).await
            {
                tracing::error!(%error, "arm/state stopped publishing");
            }
        }));
        let estop = bus.subscriber(&SAFETY_ESTOP)?;
        let estop_context = context.clone();
        tasks.push(tokio::spawn(async move {
            if let Err(error) = arm::watch_estop(estop, estop_context).await {
                tracing::error!(%error, "safety/estop stopped being watched");
            }
        }));

        // The gripper: its safe state is to hold still (a real gripper keeps its grip).
        let gripper_state = Arc::new(bus.publisher(&GRIPPER_STATE)?);
        let gripper = Supervisor::new("gripper")
            .policy(config.supervision_for("gripper").policy())
            .observer(observer("gripper"))
            .spawn_actor::<GripperActor>(move || {
                GripperActor::new(gripper_driver.clone(), Some(gripper_state.clone()))
            })
            .await
            .map_err(|e| StartError::Actor {
                actor: "gripper",
                reason: e.to_string(),
            })?;
        let server = bus.server(&GRIPPER_COMMAND)?;
        let serve_gripper = gripper.clone();
        tasks.push(tokio::spawn(async move {
            if let Err(error) = robotd_runtime::host::serve_supervised(server, serve_gripper).await
            {
                tracing::error!(%error, "gripper/command stopped serving");
            }
        }));

        // The camera.
        let frames = Arc::new(bus.frame_publisher(&CAMERA_FRAMES)?);
        let frame_ids = Arc::new(AtomicU64::new(1));
        let camera = Supervisor::new("camera")
            .policy(config.supervision_for("camera").policy())
            .observer(observer("camera"))
            .spawn_actor::<CameraActor>(move || {
                CameraActor::new(camera_driver.clone(), frames.clone(), frame_ids.clone())
            })
            .await
            .map_err(|e| StartError::Actor {
                actor: "camera",
                reason: e.to_string(),
            })?;
        let (tick_camera, fps) = (camera.clone(), config.robot.camera.fps);
        tasks.push(tokio::spawn(camera::run_camera(tick_camera, fps)));

        Ok(Hardware {
            sim: None,
            arm,
            gripper,
            camera,
            arm_context: context,
            camera_intrinsics,
            tasks,
        })
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
