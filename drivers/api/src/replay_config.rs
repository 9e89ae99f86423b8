//! `[robot.replay]`: a recording played as the robot (`robot.driver = "replay"`).
//!
//! The replay driver (`drivers/replay`) serves the camera frames, arm states and gripper states
//! of an MCAP recording (`robotd record`, or `robotd serve`'s `[record]`) as if the robot
//! produced them, so perception, the workspace model, the dashboard and the tools work on a
//! lab's session without the robot. It never moves: every motion and gripper command is
//! refused.
//!
//! The robot model is configured ([`ReplayConfig::model`]), not read from the file, because
//! everything that depends on it (the built-in workspaces, the kinematics, the tools) is set
//! up from the configuration; the driver checks at start that the recording was made on that
//! model and says what to set when it was not.

use robotd_protocol::camera::CameraIntrinsics;
use robotd_protocol::geometry::RobotModel;
use robotd_runtime::config::Checks;
use serde::{Deserialize, Serialize};
use std::path::PathBuf;

/// `[robot.replay]`
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ReplayConfig {
    /// The recording (an `.mcap` file); required by the replay driver.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub file: Option<PathBuf>,
    /// Pace relative to the recording: 1.0 = as recorded, 2.0 = twice as fast (0.1 to 10).
    #[serde(default = "defaults::speed")]
    pub speed: f64,
    /// Start again from the beginning at the end of the file (false: the camera reports that
    /// the recording ended, the arm stays where the recording left it).
    #[serde(default, rename = "loop")]
    pub looping: bool,
    /// The robot the recording was made on (`"ned2"` or `"widowx250"`); the driver refuses a
    /// recording of another robot.
    #[serde(default = "defaults::model")]
    pub model: RobotModel,
    /// The camera's intrinsics, when the recording's are missing (`robotd record` cannot know
    /// them; `robotd serve`'s `[record]` files have them) or wrong; default: the recorded
    /// ones, else the simulated wrist camera's, undistorted.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub camera_intrinsics: Option<CameraIntrinsics>,
}

impl Default for ReplayConfig {
    fn default() -> Self {
        Self {
            file: None,
            speed: defaults::speed(),
            looping: false,
            model: defaults::model(),
            camera_intrinsics: None,
        }
    }
}

impl ReplayConfig {
    /// Adds the problems of these settings to `checks` (keys under `replay.`); `in_use` when
    /// `robot.driver = "replay"` (only then is the file required).
    pub fn check(&self, checks: &mut Checks, in_use: bool) {
        match &self.file {
            None if in_use => checks.problem(
                "replay.file",
                "the replay driver needs a recording, e.g. robot.replay.file = \"session.mcap\"",
            ),
            Some(file) if file.as_os_str().is_empty() => checks.problem(
                "replay.file",
                "must name a recording (an .mcap file of `robotd record` or [record])",
            ),
            _ => {}
        }
        checks.range_f64("replay.speed", self.speed, 0.1..=10.0, "");
        if let Some(intrinsics) = &self.camera_intrinsics {
            use robotd_protocol::validate::Validate;
            if let Err(problem) = intrinsics.validate() {
                checks.problem("replay.camera_intrinsics", problem.to_string());
            }
            if intrinsics.width == 0 || intrinsics.height == 0 {
                checks.problem(
                    "replay.camera_intrinsics",
                    "width and height must be the recorded frames' size in pixels",
                );
            }
        }
    }
}

mod defaults {
    use robotd_protocol::geometry::RobotModel;

    pub fn speed() -> f64 {
        1.0
    }
    pub fn model() -> RobotModel {
        RobotModel::Ned2
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn problems(config: &ReplayConfig, in_use: bool) -> Vec<(String, String)> {
        let mut out = Vec::new();
        config.check(&mut Checks::new("robot", &mut out), in_use);
        out
    }

    #[test]
    fn the_file_is_required_only_by_the_replay_driver_and_the_speed_is_bounded() {
        let config = ReplayConfig::default();
        assert!(problems(&config, false).is_empty());
        let found = problems(&config, true);
        assert_eq!(found.len(), 1, "{found:?}");
        assert_eq!(found[0].0, "robot.replay.file");
        assert!(found[0].1.contains("needs a recording"), "{found:?}");

        let config = ReplayConfig {
            file: Some(PathBuf::new()),
            speed: 0.0,
            ..ReplayConfig::default()
        };
        let keys: Vec<String> = problems(&config, true).into_iter().map(|p| p.0).collect();
        assert_eq!(keys, ["robot.replay.file", "robot.replay.speed"]);
        for bad in [f64::NAN, f64::INFINITY, -1.0, 10.5] {
            let config = ReplayConfig {
                file: Some("a.mcap".into()),
                speed: bad,
                ..ReplayConfig::default()
            };
            assert_eq!(problems(&config, true).len(), 1, "{bad}");
        }
    }

    #[test]
    fn intrinsics_given_must_be_usable() {
        let config = ReplayConfig {
            file: Some("a.mcap".into()),
            camera_intrinsics: Some(CameraIntrinsics {
                width: 0,
                height: 480,
                fx: -1.0,
                fy: 500.0,
                cx: 320.0,
                cy: 240.0,
                distortion: [0.0; 5],
            }),
            ..ReplayConfig::default()
        };
        let found = problems(&config, true);
        assert_eq!(found.len(), 2, "{found:?}");
        assert!(found
            .iter()
            .all(|(key, _)| key == "robot.replay.camera_intrinsics"));
    }

    #[test]
    fn loop_is_spelled_as_in_the_file() {
        let config: ReplayConfig =
            toml::from_str("file = \"s.mcap\"\nloop = true\nmodel = \"widowx250\"").unwrap();
        assert!(config.looping);
        assert_eq!(config.model, RobotModel::WidowX250);
        assert!(toml::from_str::<ReplayConfig>("speed = 2\nrepeat = true").is_err());
    }
}
