//! # robotd-driver-replay: a recording played as the robot
//!
//! `robot.driver = "replay"` makes a recording (`robotd record`, or `robotd serve`'s
//! `[record]`) the robot: robotd's own perception, workspace model, dashboard and tools work
//! on a lab's session without the lab's robot, and nothing else publishes camera frames or arm
//! states on the bus, so recorded and live data never mix.
//!
//! ```toml
//! [robot]
//! driver = "replay"
//! [robot.replay]
//! file = "session.mcap"
//! speed = 1.0    # 1.0 = the recorded pace
//! loop = false   # at the end: stop (false) or start again
//! model = "ned2" # the robot it was recorded on
//! ```
//!
//! What each driver does:
//!
//! - the **camera** serves the recorded frames (JPEG decoded with robotd's decoder), at their
//!   recorded pace times `speed`, posed where the recording says the camera was and dated
//!   with their capture time on the replay's clock; at the end of the file it reports "the
//!   recording … ended" (or, with `loop`, starts again);
//! - the **arm** reports the recorded joints and flags at the recorded times, so the tool pose
//!   and the observation-pose checks match the original run, and the recorded instants at
//!   which it came to rest, so perception's "arm at rest" rule judges every frame as it did
//!   then. It refuses every motion, calibration and collision clearing with [`REFUSAL`];
//! - the **gripper** reports the recorded states and refuses every command.
//!
//! The file is checked before anything starts ([`check::inspect`]): a missing file, one that
//! is not MCAP, a recording without camera frames or arm states, of another robot model, or
//! whose frames do not fit the intrinsics are refused with the file's name and what to do.
//! The file is read as it plays ([`source`]), never whole into memory.
//!
//! The replay starts when [`Replay::start`] is called (`robotd serve` calls it once
//! perception and the workspace model are up, so they see the recording from its first frame);
//! until then the arm stands where the recording begins.
//!
//! | module | job |
//! |---|---|
//! | [`check`] | is the recording playable; the intrinsics its frames are served with |
//! | [`source`] | the reader thread: file → decoded messages |
//! | [`player`] | the pace: each message applied at its recorded time, in time order |
//! | [`robot`] | the replayed arm and gripper, and their refusals |

pub mod check;
pub mod player;
pub mod robot;
pub mod source;

pub use check::{inspect, Checked, ReplayError};
pub use robot::REFUSAL;

use player::{Clock, Player};
use robot::{RecordedRobot, ReplayArm, ReplayGripper};
use robotd_driver::camera_feed::{CameraFeed, FedCamera};
use robotd_driver::{ReplayConfig, RobotDrivers};
use std::sync::Arc;
use std::time::Duration;
use tokio::sync::Notify;

/// Messages the reader thread may be ahead of the player.
const READ_AHEAD: usize = 4;

/// The replayed camera: frames come through its feed.
struct ReplayCamera(Arc<CameraFeed>);

impl FedCamera for ReplayCamera {
    fn feed(&self) -> &CameraFeed {
        &self.0
    }
}

/// An opened replay: the drivers, the player's task, and the switch that starts it.
pub struct Replay {
    /// The drivers for robotd's arm, gripper and camera actors.
    pub drivers: RobotDrivers,
    /// The player (aborted when the robot shuts down; its reader thread then stops).
    pub tasks: Vec<tokio::task::JoinHandle<()>>,
    /// What the file holds and how it is served.
    pub checked: Checked,
    go: Arc<Notify>,
}

impl std::fmt::Debug for Replay {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Replay")
            .field("file", &self.checked.contents.path)
            .finish_non_exhaustive()
    }
}

impl Replay {
    /// Starts the replay (again calling it does nothing more).
    pub fn start(&self) {
        self.go.notify_one();
    }
}

/// Checks the recording `[robot.replay]` names and opens it as a robot. Call from within a
/// tokio runtime (the player is a task on it).
pub fn open(config: &ReplayConfig) -> Result<Replay, ReplayError> {
    let checked = inspect(config)?;
    let contents = &checked.contents;
    let path = contents.path.clone();
    let (t0, t_end) = contents.span.unwrap_or_default();
    let clock = Clock::new(t0, config.speed, robotd_protocol::envelope::unix_now_ns());
    let max_width_m = contents.widest_gripper_m.unwrap_or(0.0).max(0.001);
    let robot = Arc::new(RecordedRobot::new(
        config.model,
        &checked.first_arm_state,
        t0,
        &clock,
        contents.first_gripper_state.as_ref(),
        max_width_m,
    ));
    let camera = Arc::new(CameraFeed::new(
        &path.display().to_string(),
        checked.intrinsics.clone(),
        Duration::ZERO,
        Arc::new(|| None),
        format!(
            "the replay of {} has not started yet (robotd starts it once it is up)",
            path.display()
        ),
    ));
    let go = Arc::new(Notify::new());
    let (items_tx, items_rx) = tokio::sync::mpsc::channel(READ_AHEAD);
    source::spawn(path.clone(), config.looping, items_tx)
        .map_err(|e| ReplayError::Thread(e.to_string()))?;
    let player = Player {
        clock,
        lap: Duration::from_nanos(t_end - t0).div_f64(config.speed),
        looping: config.looping,
        robot: robot.clone(),
        first_arm_state: (checked.first_arm_state.clone(), t0),
        camera: camera.clone(),
        ended: format!(
            "the recording {} ended after {:.1} s (robot.replay.loop = false); restart robotd \
             to replay it again, or set robot.replay.loop = true",
            path.display(),
            contents.seconds()
        ),
        go: go.clone(),
    };
    tracing::info!(
        file = %path.display(),
        contents = %contents.describe(),
        intrinsics = checked.intrinsics_from,
        speed = config.speed,
        looping = config.looping,
        "replaying a recording as the robot"
    );
    let task = tokio::spawn(player.run(items_rx));
    Ok(Replay {
        drivers: RobotDrivers {
            model: config.model,
            arm: Arc::new(ReplayArm(robot.clone())),
            gripper: Arc::new(ReplayGripper(robot)),
            camera: Arc::new(ReplayCamera(camera)),
        },
        tasks: vec![task],
        checked,
        go,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use robotd_recording::fixture::{write_recording, Recorded};

    #[tokio::test]
    async fn an_opened_recording_waits_for_its_start_then_plays_to_its_end() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("s.mcap");
        write_recording(&path, &Recorded::short_session());
        let config = ReplayConfig {
            file: Some(path),
            speed: 10.0,
            ..ReplayConfig::default()
        };
        let replay = open(&config).unwrap();
        let camera = replay.drivers.camera.clone();
        assert_eq!(camera.size(), (16, 12));
        let waiting = camera.frame_ready().await.unwrap_err().to_string();
        assert!(waiting.contains("has not started"), "{waiting}");
        assert_eq!(replay.drivers.arm.joints().unwrap()[0], 0.0);

        replay.start();
        let mut out = vec![0; 16 * 12 * 3];
        let mut frames = 0;
        let ended = loop {
            match camera.frame_ready().await {
                Ok(()) => {
                    camera.capture_into(&mut out).unwrap();
                    frames += 1;
                }
                Err(error) => break error.to_string(),
            }
        };
        assert!(ended.contains("ended after 3.0 s"), "{ended}");
        assert!(frames >= 1, "at least the last frame is always taken");
        assert!((replay.drivers.arm.joints().unwrap()[0] - 0.6).abs() < 1e-9);
        assert!(replay.drivers.gripper.status().unwrap().holding);
    }
}
