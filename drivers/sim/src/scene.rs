//! The simulator's scene: which one to load, and whether the arm can reach what is on it.

use robotd_driver::RobotConfig;
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

/// Loads the scene the configuration asks for (the model's built-in one by default), puts the
/// configured workspaces (`[robot] workspaces`, the same a real robot uses) on its table and
/// checks it against the robot's reach.
pub fn load_scene(robot: &RobotConfig) -> Result<Scene, SceneError> {
    let driver = robot.driver;
    let mut scene = match &robot.scene {
        Some(path) => {
            Scene::load(Path::new(path)).map_err(|e| SceneError::Invalid(e.to_string()))?
        }
        None => match robot.model() {
            RobotModel::WidowX250 => Scene::default_widowx(),
            RobotModel::Ned2 => Scene::default_ned2(),
        },
    };
    if scene.robot != robot.model() {
        return Err(SceneError::RobotMismatch {
            scene: scene.name.clone(),
            scene_robot: scene.robot.display_name().to_owned(),
            driver: format!("{driver:?}"),
        });
    }
    if scene.own_workspaces {
        return Err(SceneError::Invalid(format!(
            "scene file {} lists its own [[workspaces]]; workspaces are configured once, in \
             [[robot.workspaces]] (see config/default.toml), so the simulator and a real robot \
             use the same ones: move them there and remove them from the scene",
            scene.origin
        )));
    }
    scene.workspaces = robot.workspaces();
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

#[cfg(test)]
mod tests {
    use super::*;

    fn robot(toml_text: &str) -> RobotConfig {
        toml::from_str(toml_text).expect("a [robot] table")
    }

    #[test]
    fn the_configured_workspaces_are_the_simulators_table() {
        let config = robot(
            "driver = \"sim-ned2\"\n[[workspaces]]\nid = \"lab_ws\"\nupper_left = [0.337, 0.087]\n\
             lower_right = [0.163, -0.087]\nobservation_pose = [0.173, -0.002, 0.277, -3.042, 1.327, -3.027]\n",
        );
        let scene = load_scene(&config).expect("the default scene on the configured sheet");
        let ids: Vec<&str> = scene.workspaces.iter().map(|w| w.id.as_str()).collect();
        assert_eq!(ids, ["lab_ws"]);
    }

    #[test]
    fn a_scene_with_its_own_workspaces_is_refused() {
        let dir = std::env::temp_dir().join(format!("robotd-scene-ws-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("own.toml");
        std::fs::write(
            &path,
            "name = \"own\"\nrobot = \"ned2\"\n[[workspaces]]\nid = \"x\"\nupper_left = [0.3, 0.1]\n\
             lower_right = [0.2, -0.1]\nobservation_pose = [0.2, 0.0, 0.3, 0.0, 1.57, 0.0]\n",
        )
        .unwrap();
        let config = robot(&format!("driver = \"sim-ned2\"\nscene = {:?}\n", path));
        let error = load_scene(&config).unwrap_err().to_string();
        std::fs::remove_dir_all(&dir).ok();
        assert!(error.contains("[[robot.workspaces]]"), "{error}");
        assert!(error.contains("own.toml"), "{error}");
    }
}
