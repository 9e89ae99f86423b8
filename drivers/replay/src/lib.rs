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
//! [`open`] runs that check (one pass over the file) on tokio's blocking pool, never on a
//! runtime worker. The file is read as it plays ([`source`]), never whole into memory.
//!
//! A [`Replay`] dropped before its tasks were handed on (its robot failed to start) aborts its
//! player, and the reader thread ends with it, letting go of the file.
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
///
/// Dropping it aborts the tasks still in [`Replay::tasks`] (take them to keep them running).
pub struct Replay {
    /// The drivers for robotd's arm, gripper and camera actors.
    pub drivers: RobotDrivers,
    /// The player (aborted when the robot shuts down, or when the `Replay` is dropped while
    /// it still holds it; its reader thread then stops).
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

impl Drop for Replay {
    /// A player that never gets its start would wait forever, and its reader thread with it,
    /// blocked on a full channel holding the file and decoded frames: abort it (the reader
    /// thread then finds the channel closed and ends).
    fn drop(&mut self) {
        for task in &self.tasks {
            task.abort();
        }
    }
}

/// The paces the replay plays at (`robot.replay.speed`).
pub const SPEEDS: std::ops::RangeInclusive<f64> = 0.1..=10.0;

/// `speed` when it is one the replay plays at.
fn check_speed(speed: f64) -> Result<f64, ReplayError> {
    if SPEEDS.contains(&speed) {
        Ok(speed)
    } else {
        Err(ReplayError::Speed(speed))
    }
}

/// Checks the recording `[robot.replay]` names and opens it as a robot. The check reads the
/// whole file once, on tokio's blocking pool; the player is a task on the current runtime.
pub async fn open(config: &ReplayConfig) -> Result<Replay, ReplayError> {
    check_speed(config.speed)?;
    let owned = config.clone();
    let checked = tokio::task::spawn_blocking(move || inspect(&owned))
        .await
        .map_err(|e| ReplayError::Recording {
            path: config.file.clone().unwrap_or_default(),
            problem: format!("checking the file failed ({e})"),
        })??;
    open_checked(config, checked)
}

/// Opens a recording [`inspect`] found playable as a robot, without reading the file here.
/// Call from within a tokio runtime (the player is a task on it).
pub fn open_checked(config: &ReplayConfig, checked: Checked) -> Result<Replay, ReplayError> {
    check_speed(config.speed)?;
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

/// The warnings logged on this thread while `f` runs, one string each.
#[cfg(test)]
pub(crate) fn warnings_of<T>(f: impl FnOnce() -> T) -> (T, Vec<String>) {
    use std::sync::Mutex;
    #[derive(Clone, Default)]
    struct Lines(Arc<Mutex<Vec<u8>>>);
    impl std::io::Write for Lines {
        fn write(&mut self, bytes: &[u8]) -> std::io::Result<usize> {
            self.0.lock().unwrap().extend_from_slice(bytes);
            Ok(bytes.len())
        }
        fn flush(&mut self) -> std::io::Result<()> {
            Ok(())
        }
    }
    let lines = Lines::default();
    let writer = lines.clone();
    let subscriber = tracing_subscriber::fmt()
        .with_max_level(tracing::Level::WARN)
        .with_ansi(false)
        .with_writer(move || writer.clone())
        .finish();
    let result = tracing::subscriber::with_default(subscriber, f);
    let text = String::from_utf8(lines.0.lock().unwrap().clone()).unwrap();
    // A reason may hold a line break: a warning starts with its time and level.
    let mut warnings: Vec<String> = Vec::new();
    for line in text.lines() {
        match warnings.last_mut() {
            Some(last) if !line.contains(" WARN ") => last.push_str(line),
            _ => warnings.push(line.to_owned()),
        }
    }
    (result, warnings)
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
        let replay = open(&config).await.unwrap();
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

    fn recording(dir: &std::path::Path) -> std::path::PathBuf {
        let path = dir.join("s.mcap");
        write_recording(&path, &Recorded::short_session());
        path
    }

    /// Descriptors of this process open on `path`.
    fn open_on(path: &std::path::Path) -> usize {
        std::fs::read_dir("/proc/self/fd")
            .unwrap()
            .filter_map(|fd| std::fs::read_link(fd.ok()?.path()).ok())
            .filter(|target| target == path)
            .count()
    }

    #[tokio::test]
    async fn the_check_reads_the_file_off_the_runtime() {
        // The recording comes through a FIFO, which a second thread fills only once a task
        // on this (single-threaded) runtime ran: a check that blocks the runtime's thread
        // waits for the fallback after 5 s instead.
        let dir = tempfile::tempdir().unwrap();
        let bytes = std::fs::read(recording(dir.path())).unwrap();
        let fifo = dir.path().join("fifo.mcap");
        let made = std::process::Command::new("mkfifo")
            .arg(&fifo)
            .status()
            .unwrap();
        assert!(made.success());
        let (ran_tx, ran_rx) = std::sync::mpsc::channel::<()>();
        let writer = {
            let (fifo, bytes) = (fifo.clone(), bytes.clone());
            std::thread::spawn(move || {
                let ran = ran_rx.recv_timeout(Duration::from_secs(5)).is_ok();
                std::fs::write(&fifo, &bytes).unwrap();
                ran
            })
        };
        tokio::spawn(async move {
            let _ = ran_tx.send(());
        });
        let config = ReplayConfig {
            file: Some(fifo.clone()),
            ..ReplayConfig::default()
        };
        let replay = open(&config).await.unwrap();
        assert!(
            writer.join().unwrap(),
            "the runtime ran nothing while the recording was checked"
        );
        assert_eq!(replay.checked.contents.camera_frames(), 13);
        // The reader thread opens the FIFO again: let it read, then stop it.
        std::fs::write(&fifo, &bytes).unwrap();
        drop(replay);
    }

    #[tokio::test]
    async fn a_replay_dropped_before_it_started_lets_go_of_its_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = recording(dir.path());
        let config = ReplayConfig {
            file: Some(path.clone()),
            ..ReplayConfig::default()
        };
        let replay = open(&config).await.unwrap();
        // The reader thread holds the file, blocked on the full channel.
        let deadline = std::time::Instant::now() + Duration::from_secs(10);
        while open_on(&path) == 0 && std::time::Instant::now() < deadline {
            tokio::time::sleep(Duration::from_millis(10)).await;
        }
        assert_eq!(open_on(&path), 1, "the reader thread reads the file");
        let player = replay.tasks[0].abort_handle();
        // What robotd does when the actors fail to start after the replay was opened.
        drop(replay);
        while open_on(&path) > 0 && std::time::Instant::now() < deadline {
            tokio::time::sleep(Duration::from_millis(10)).await;
        }
        assert_eq!(open_on(&path), 0, "the reader thread still holds the file");
        assert!(player.is_finished());
    }

    #[tokio::test]
    async fn a_pace_the_replay_cannot_play_is_refused_with_the_setting() {
        let dir = tempfile::tempdir().unwrap();
        let path = recording(dir.path());
        let good = ReplayConfig {
            file: Some(path),
            ..ReplayConfig::default()
        };
        let checked = inspect(&good).unwrap();
        for speed in [0.0, -1.0, f64::NAN, f64::INFINITY, 0.01, 100.0] {
            let config = ReplayConfig {
                speed,
                ..good.clone()
            };
            let error = open(&config).await.unwrap_err();
            assert!(matches!(error, ReplayError::Speed(_)), "{error}");
            let text = error.to_string();
            assert!(text.contains("robot.replay.speed"), "{text}");
            assert!(text.contains("0.1 to 10"), "{text}");
            let error = open_checked(&config, checked.clone()).unwrap_err();
            assert!(matches!(error, ReplayError::Speed(_)), "{error}");
        }
        for speed in [0.1, 10.0] {
            let config = ReplayConfig {
                speed,
                ..good.clone()
            };
            assert!(open_checked(&config, checked.clone()).is_ok(), "{speed}");
        }
    }
}
