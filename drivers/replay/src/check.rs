//! Is the configured recording one the replay driver can play? Checked before anything
//! starts, so `robotd serve` refuses a bad file with the file's name and what is wrong, instead
//! of starting a robot that never sends a frame.
//!
//! A recording is playable when it is an MCAP file with camera frames and arm states, made on
//! the configured robot model, whose frames fit the camera intrinsics in use. The intrinsics
//! are `[robot.replay] camera_intrinsics` when given, else the recording's own (`robotd serve`'s
//! `[record]` files have them), else the simulated wrist camera's, undistorted (what the
//! simulator and a WidowX without configured intrinsics use).

use robotd_driver::ReplayConfig;
use robotd_protocol::arm::ArmState;
use robotd_protocol::camera::CameraIntrinsics;
use robotd_recording::camera::FrameMeta;
use robotd_recording::contents::Contents;
use robotd_recording::reader::ReadError;
use robotd_runtime::bus::{FRAME_HEIGHT, FRAME_WIDTH};
use std::path::PathBuf;

/// Why the replay driver cannot start.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ReplayError {
    /// `robot.replay.file` is not set.
    #[error(
        "robot.replay.file is not set: the replay driver needs a recording, e.g. \
         robot.replay.file = \"session.mcap\""
    )]
    NoFile,
    /// The recording cannot be played, because of `problem`.
    #[error("robot.replay.file = {}: {problem}", path.display())]
    Recording {
        /// The file.
        path: PathBuf,
        /// What is wrong with it, and what to do.
        problem: String,
    },
    /// The reader thread did not start.
    #[error("cannot start the replay's reader thread: {0}")]
    Thread(String),
    /// `robot.replay.speed` is not a pace the replay plays at.
    #[error(
        "robot.replay.speed = {0}: must be from 0.1 to 10 (1.0 = the recorded pace, 2.0 = \
         twice as fast)"
    )]
    Speed(f64),
}

/// A playable recording: what it holds and the camera intrinsics its frames are served with.
#[derive(Debug, Clone, PartialEq)]
pub struct Checked {
    /// The file's contents.
    pub contents: Contents,
    /// The first arm state: where the arm is before the replay starts.
    pub first_arm_state: ArmState,
    /// The first camera frame's header.
    pub first_frame: FrameMeta,
    /// The intrinsics the camera reports.
    pub intrinsics: CameraIntrinsics,
    /// Where [`Self::intrinsics`] come from, in words.
    pub intrinsics_from: &'static str,
}

/// The simulated wrist camera's intrinsics, undistorted.
pub fn default_intrinsics() -> CameraIntrinsics {
    let mut intrinsics = CameraIntrinsics::from(robotd_render::Intrinsics::ned2());
    intrinsics.distortion = [0.0; 5];
    intrinsics
}

/// Reads the configured recording once and checks that it can be played.
pub fn inspect(config: &ReplayConfig) -> Result<Checked, ReplayError> {
    let path = config.file.clone().ok_or(ReplayError::NoFile)?;
    let bad = |problem: String| ReplayError::Recording {
        path: path.clone(),
        problem,
    };
    let contents = Contents::inspect(&path).map_err(|error| match error {
        ReadError::Open { reason, .. } => bad(reason),
        ReadError::NotMcap { reason, .. } => bad(format!(
            "not an MCAP recording ({reason}); give a file written by `robotd record` or \
             robotd serve's [record]"
        )),
        other => bad(other.to_string()),
    })?;
    if contents.camera_frames() == 0 {
        return Err(bad(format!(
            "it holds no camera frames (no {} messages); the replay driver needs them: record \
             with the camera (robotd record without --topics, or with camera/frames among them)",
            robotd_recording::CAMERA_META
        )));
    }
    if contents.arm_states() == 0 {
        return Err(bad(format!(
            "it holds no arm states (no {} messages); the replay driver needs them: record \
             with arm/state among the topics",
            robotd_recording::ARM_STATE
        )));
    }
    match (contents.model, &contents.urdf_robot) {
        (Some(recorded), _) if recorded != config.model => {
            return Err(bad(format!(
                "it was recorded on a {} (its {}), but robot.replay.model is \"{}\": set \
                 robot.replay.model = \"{recorded}\"",
                recorded.display_name(),
                robotd_recording::ROBOT_DESCRIPTION,
                config.model,
            )))
        }
        (None, Some(name)) => {
            return Err(bad(format!(
                "it was recorded on a robot robotd does not drive ('{name}' in its {})",
                robotd_recording::ROBOT_DESCRIPTION
            )))
        }
        (None, None) => tracing::warn!(
            file = %path.display(),
            model = %config.model,
            "the recording does not say which robot it was made on; replaying it as robot.replay.model"
        ),
        _ => {}
    }
    let Some(first_arm_state) = contents.first_arm_state.clone() else {
        return Err(bad(
            "its arm states do not read as arm.state messages (written by an incompatible \
             robotd?)"
                .into(),
        ));
    };
    let joints = first_arm_state.joints.positions_rad.len();
    if joints != config.model.joint_count() {
        return Err(bad(format!(
            "its arm states have {joints} joints; a {} has {}",
            config.model.display_name(),
            config.model.joint_count()
        )));
    }
    let Some(first_frame) = contents.first_frame.clone() else {
        return Err(bad(format!(
            "its camera headers ({}) do not read as frame headers (written by an incompatible \
             robotd?)",
            robotd_recording::CAMERA_META
        )));
    };
    let (width, height) = (first_frame.width, first_frame.height);
    if width as usize > FRAME_WIDTH || height as usize > FRAME_HEIGHT || width == 0 || height == 0 {
        return Err(bad(format!(
            "its camera frames are {width}×{height}; the bus carries frames up to \
             {FRAME_WIDTH}×{FRAME_HEIGHT}"
        )));
    }
    let (intrinsics, intrinsics_from) = match (&config.camera_intrinsics, &first_frame.intrinsics) {
        (Some(given), _) => (given.clone(), "robot.replay.camera_intrinsics"),
        (None, Some(recorded)) => (recorded.clone(), "the recording's"),
        (None, None) => (
            default_intrinsics(),
            "the simulated wrist camera's (the recording has none)",
        ),
    };
    if (intrinsics.width, intrinsics.height) != (width, height) {
        return Err(bad(format!(
            "its camera frames are {width}×{height}, but the intrinsics in use ({intrinsics_from}) \
             are for {}×{}: set robot.replay.camera_intrinsics for {width}×{height}",
            intrinsics.width, intrinsics.height
        )));
    }
    if let Some(reason) = &contents.damaged {
        tracing::warn!(
            file = %path.display(),
            %reason,
            "the recording breaks off; replaying the messages before"
        );
    }
    Ok(Checked {
        contents,
        first_arm_state,
        first_frame,
        intrinsics,
        intrinsics_from,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use robotd_protocol::geometry::RobotModel;
    use robotd_recording::fixture::{write_recording, Entry, Recorded};

    fn config(path: PathBuf) -> ReplayConfig {
        ReplayConfig {
            file: Some(path),
            ..ReplayConfig::default()
        }
    }

    fn problem(config: &ReplayConfig) -> String {
        let error = inspect(config).unwrap_err();
        let text = error.to_string();
        if let Some(file) = &config.file {
            assert!(text.contains(&file.display().to_string()), "{text}");
        }
        text
    }

    #[test]
    fn a_session_of_the_configured_robot_plays_with_its_own_intrinsics() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("s.mcap");
        write_recording(&path, &Recorded::short_session());
        let checked = inspect(&config(path)).unwrap();
        assert_eq!(checked.intrinsics.width, 16);
        assert_eq!(checked.intrinsics_from, "the recording's");
        assert_eq!(checked.contents.model, Some(RobotModel::Ned2));
    }

    #[test]
    fn missing_file_other_format_and_no_file_are_refused_by_name() {
        let dir = tempfile::tempdir().unwrap();
        assert_eq!(
            inspect(&ReplayConfig::default()).unwrap_err(),
            ReplayError::NoFile
        );
        let missing = problem(&config(dir.path().join("none.mcap")));
        assert!(missing.ends_with("no such file"), "{missing}");
        let text = dir.path().join("notes.txt");
        std::fs::write(&text, "hello").unwrap();
        let other = problem(&config(text));
        assert!(other.contains("not an MCAP recording"), "{other}");
    }

    #[test]
    fn a_recording_without_frames_or_arm_states_is_refused_with_what_to_record() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("no-camera.mcap");
        write_recording(
            &path,
            &Recorded::short_session().without(|e| !matches!(e, Entry::Frame { .. })),
        );
        let text = problem(&config(path));
        assert!(text.contains("no camera frames"), "{text}");
        assert!(text.contains("camera/frames"), "{text}");

        let path = dir.path().join("no-arm.mcap");
        write_recording(
            &path,
            &Recorded::short_session().without(|e| !matches!(e, Entry::Arm(_))),
        );
        let text = problem(&config(path));
        assert!(text.contains("no arm states"), "{text}");
    }

    #[test]
    fn a_recording_of_another_robot_names_the_setting_to_change() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("s.mcap");
        write_recording(&path, &Recorded::short_session());
        let widowx = ReplayConfig {
            model: RobotModel::WidowX250,
            ..config(path.clone())
        };
        let text = problem(&widowx);
        assert!(text.contains("recorded on a Niryo Ned2"), "{text}");
        assert!(text.contains("robot.replay.model = \"ned2\""), "{text}");

        let unknown = Recorded::short_session().without(|e| !matches!(e, Entry::Description(_)));
        let mut unknown = unknown;
        unknown.entries.insert(
            0,
            (
                robotd_recording::fixture::T0,
                Entry::Description("<robot name=\"ur5\"></robot>".into()),
            ),
        );
        write_recording(&path, &unknown);
        assert!(problem(&config(path)).contains("'ur5'"));
    }

    #[test]
    fn frames_must_fit_the_intrinsics_in_use() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("s.mcap");
        write_recording(&path, &Recorded::short_session());
        let given = ReplayConfig {
            camera_intrinsics: Some(default_intrinsics()),
            ..config(path.clone())
        };
        let text = problem(&given);
        assert!(text.contains("16×12"), "{text}");
        assert!(text.contains("robot.replay.camera_intrinsics"), "{text}");

        // Without recorded intrinsics the default (640×480) is used, and 16×12 does not fit.
        let mut session = Recorded::short_session();
        for (_, entry) in &mut session.entries {
            if let Entry::Frame { meta, .. } = entry {
                meta.intrinsics = None;
            }
        }
        write_recording(&path, &session);
        let text = problem(&config(path));
        assert!(text.contains("the simulated wrist camera's"), "{text}");
    }
}
