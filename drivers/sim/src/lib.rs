//! The simulated robot as a driver: a kinematic Niryo Ned2 or WidowX 250 in a simulated world,
//! behind the same driver traits ([`robotd_driver`]) a real robot implements.
//!
//! `robot.driver = "sim-ned2"` (the default) or `"sim-widowx"` selects it. [`open`] loads the
//! scene (`robot.scene`, or the model's built-in one), checks every object against the arm's
//! reach, and builds one [`SimRobot`] whose arm, gripper and camera drivers share one world:
//!
//! - [`robot`]: the simulated arm, gripper and wrist camera (motions in time, collisions,
//!   grasps, rendered frames);
//! - [`faults`]: fault injection (`[robot.faults.<actor>]`), so supervision is exercised
//!   without hardware;
//! - [`serve_ground_truth`]: `sim/world`, where every object really is, for tests.
//!
//! ```no_run
//! # fn demo() -> Result<(), Box<dyn std::error::Error>> {
//! let robot: robotd_driver::RobotConfig = toml::from_str("driver = \"sim-ned2\"")?;
//! let sim = robotd_driver_sim::open(&robot)?;
//! println!("{} objects on the table", sim.robot.with_world(|w| w.objects().len()));
//! # Ok(()) }
//! ```

pub mod faults;
mod ground_truth;
pub mod robot;
mod scene;

pub use ground_truth::serve_ground_truth;
pub use robot::{
    gripper_max_width, solid_of, SimArm, SimCamera, SimGripper, SimRobot, SimSettings,
};
pub use scene::{load_scene, reachable_from_above, SceneError};

use faults::FaultInjector;
use robotd_driver::RobotConfig;
use robotd_driver::RobotDrivers;
use robotd_sim::Scene;
use std::sync::Arc;

/// A started simulated robot: its drivers, and the simulator behind them.
pub struct SimDriver {
    /// The simulator (ground truth, teleport), shared by the three drivers.
    pub robot: SimRobot,
    /// The scene it was built from.
    pub scene: Scene,
    /// The drivers for the arm, gripper and camera actors.
    pub drivers: RobotDrivers,
}

/// Builds the simulated robot `[robot]` asks for.
pub fn open(config: &RobotConfig) -> Result<SimDriver, SceneError> {
    let scene = load_scene(config)?;
    let settings = SimSettings {
        time_scale: config.time_scale,
        control_period: config.control_period(),
        noise_stddev: config.camera.noise_stddev,
        lens_distortion: config.camera.lens_distortion,
    };
    let mount = config
        .camera_mount()
        .map_err(|e| SceneError::Invalid(format!("robot.camera.mount: {e}")))?;
    let robot = SimRobot::new(&scene, settings).with_camera_mount(mount);
    let faults = &config.faults;
    let drivers = RobotDrivers {
        model: scene.robot,
        arm: Arc::new(robot.arm(FaultInjector::new("arm", faults.arm.clone()))),
        gripper: Arc::new(robot.gripper(FaultInjector::new("gripper", faults.gripper.clone()))),
        camera: Arc::new(robot.camera(FaultInjector::new("camera", faults.camera.clone()))),
    };
    Ok(SimDriver {
        robot,
        scene,
        drivers,
    })
}
