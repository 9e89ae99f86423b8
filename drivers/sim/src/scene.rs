//! The simulator's scene: which one to load, and whether the arm can reach what is on it.

use robotd_driver::{RobotConfig, RobotDriver};
use robotd_kinematics::Kinematics;
use robotd_protocol::geometry::{Pose, RobotModel};
use robotd_sim::Scene;
use std::path::Path;

/// Why the simulated robot cannot be built from its scene.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// The scene file is missing, malformed or describes an impossible scene.
    #[error("scene: {0}")]
    Invalid(String),
    /// The scene is for another robot than the configured driver.
    #[error("scene '{scene}' is for the {scene_robot}, but robot.driver is \"{driver}\"")]
    RobotMismatch {
        /// Scene name.
        scene: String,
        /// The scene's robot.
        scene_robot: String,
        /// The configured driver.
        driver: String,
    },
}

/// Loads the scene the configuration asks for (the model's built-in one by default) and checks
/// it against the robot's reach.
pub fn load_scene(robot: &RobotConfig) -> Result<Scene, SceneError> {
    let driver = robot.driver;
    let scene = match &robot.scene {
        Some(path) => {
            Scene::load(Path::new(path)).map_err(|e| SceneError::Invalid(e.to_string()))?
        }
        None => match driver {
            RobotDriver::SimWidowx => Scene::default_widowx(),
            _ => Scene::default_ned2(),
        },
    };
    let expected = match driver {
        RobotDriver::SimWidowx | RobotDriver::Widowx => RobotModel::WidowX250,
        RobotDriver::SimNed2 | RobotDriver::Niryo => RobotModel::Ned2,
    };
    if scene.robot != expected {
        return Err(SceneError::RobotMismatch {
            scene: scene.name.clone(),
            scene_robot: scene.robot.display_name().to_owned(),
            driver: format!("{driver:?}"),
        });
    }
    let kinematics = Kinematics::new(scene.robot);
    scene
        .validate(&|x, y, z| reachable_from_above(&kinematics, x, y, z))
        .map_err(|e| SceneError::Invalid(e.to_string()))?;
    Ok(scene)
}

/// Whether the tool can reach (x, y, z) pointing down, at some yaw.
pub fn reachable_from_above(kinematics: &Kinematics, x: f64, y: f64, z: f64) -> bool {
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
