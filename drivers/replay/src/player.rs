//! The pace of a replay: each recorded message handed to the robot at its recorded time.
//!
//! A [`Clock`] maps recorded time onto the replay's: the recording's first instant `t0` falls
//! at the replay's start, and later instants `speed` times sooner. The [`Player`] takes the
//! messages the reader thread decoded (in file order) and applies each when its time comes:
//! arm and gripper states into the [`RecordedRobot`], frames into the camera's feed, dated
//! with their mapped capture time and posed where the recording says the camera was.
//!
//! Two details keep the replay's timing faithful:
//!
//! - a recorder writes a frame after it encoded it, so the file can hold a frame after arm
//!   states sent later than the frame was taken. The player reads [`REORDER`] of recorded
//!   time ahead (at most [`MAX_PENDING`] messages) and hands messages out in time order;
//! - frames are handed out [`FRAME_DELAY`] after their capture time, as a real camera's arrive
//!   late. The arm actor samples the arm once per control tick, so by then it has published
//!   every state up to the frame, and perception sees the arm move before it sees a frame
//!   taken during the motion, as it did in the original run.
//!
//! At the end of the file the player stops (the camera then reports that the recording ended;
//! the arm stays where it was) or, with `loop`, starts the next lap on a clock moved on by the
//! recording's length.

use crate::robot::RecordedRobot;
use robotd_driver::camera_feed::CameraFeed;
use robotd_driver::CaptureInfo;
use robotd_protocol::arm::ArmState;
use robotd_protocol::geometry::Pose;
use robotd_protocol::gripper::GripperState;
use robotd_recording::camera::FrameMeta;
use std::cmp::Reverse;
use std::collections::BinaryHeap;
use std::sync::Arc;
use std::time::Duration;
use tokio::sync::{mpsc, Notify};
use tokio::time::Instant;

/// How far ahead, in recorded time, the player reads to put messages in time order.
pub const REORDER: Duration = Duration::from_millis(300);
/// Most messages held for ordering, however the file's times jump (a recorder's clock that
/// jumped ahead would otherwise make the player read on and on).
pub const MAX_PENDING: usize = 64;
/// How long after its capture time a frame is handed to the camera.
pub const FRAME_DELAY: Duration = Duration::from_millis(50);
/// How long the last frame waits for the camera to take it before the end is reported (the
/// camera asks at `robot.camera.fps`, at least 0.1 a second).
pub const LAST_FRAME_WAIT: Duration = Duration::from_secs(10);
/// The pause between the end of one lap and the start of the next.
pub const LAP_GAP: Duration = Duration::from_millis(100);
/// When a message whose recorded time is beyond any replay is due: after about 30 years.
pub const FAR_FUTURE: Duration = Duration::from_secs(30 * 365 * 86_400);

/// A message of the recording, decoded by the reader thread.
#[derive(Debug)]
pub enum Item {
    /// A camera frame: its header and its image (RGB8).
    Frame {
        /// Log (capture) time.
        log_time: u64,
        /// Its header.
        meta: FrameMeta,
        /// RGB8, `meta.width × meta.height × 3` bytes.
        rgb: Vec<u8>,
    },
    /// An arm state.
    Arm {
        /// Send time.
        log_time: u64,
        /// The state.
        state: ArmState,
    },
    /// A gripper state.
    Gripper {
        /// Send time.
        log_time: u64,
        /// The state.
        state: GripperState,
    },
    /// The end of the file: this lap is over.
    End,
    /// The file cannot be read any more (deleted while looping, unreadable).
    Failed(String),
}

impl Item {
    fn log_time(&self) -> u64 {
        match self {
            Item::Frame { log_time, .. }
            | Item::Arm { log_time, .. }
            | Item::Gripper { log_time, .. } => *log_time,
            Item::End | Item::Failed(_) => 0,
        }
    }
}

/// Recorded time onto the replay's time.
#[derive(Debug, Clone, Copy)]
pub struct Clock {
    t0: u64,
    speed: f64,
    start: Instant,
    start_unix_ns: u64,
}

impl Clock {
    /// Recorded instant `t0` falls now (Unix time `start_unix_ns`); later ones `speed` times
    /// sooner than recorded.
    pub fn new(t0: u64, speed: f64, start_unix_ns: u64) -> Clock {
        Clock {
            t0,
            speed,
            start: Instant::now(),
            start_unix_ns,
        }
    }

    /// When recorded instant `t` is due on the replay's (tokio) clock. The file's times are
    /// not trusted: one centuries after `t0` (or a pace that is not positive) is due in
    /// [`FAR_FUTURE`], never an overflow.
    pub fn due(&self, t: u64) -> Instant {
        let far = self.start + FAR_FUTURE;
        let seconds = Duration::from_nanos(t.saturating_sub(self.t0)).as_secs_f64() / self.speed;
        Duration::try_from_secs_f64(seconds)
            .ok()
            .and_then(|after| self.start.checked_add(after))
            .map_or(far, |due| due.min(far))
    }

    /// Recorded instant `t` on the replay's Unix clock (before its start for `t < t0`; clamped
    /// to what a `u64` of nanoseconds holds).
    pub fn unix_at(&self, t: u64) -> u64 {
        let offset = (i128::from(t) - i128::from(self.t0)) as f64 / self.speed;
        i128::from(self.start_unix_ns)
            .saturating_add(offset as i128)
            .clamp(0, i128::from(u64::MAX)) as u64
    }

    fn next_lap(&mut self, length: Duration) {
        self.start = self
            .start
            .checked_add(length)
            .unwrap_or(self.start + FAR_FUTURE);
        let nanos = u64::try_from(length.as_nanos()).unwrap_or(u64::MAX);
        self.start_unix_ns = self.start_unix_ns.saturating_add(nanos);
    }
}

struct Pending {
    due: Instant,
    seq: u64,
    log_time: u64,
    item: Item,
}

impl PartialEq for Pending {
    fn eq(&self, other: &Self) -> bool {
        (self.due, self.seq) == (other.due, other.seq)
    }
}
impl Eq for Pending {}
impl PartialOrd for Pending {
    fn partial_cmp(&self, other: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(other))
    }
}
impl Ord for Pending {
    fn cmp(&self, other: &Self) -> std::cmp::Ordering {
        (self.due, self.seq).cmp(&(other.due, other.seq))
    }
}

/// Plays the reader's messages onto the robot and the camera.
pub struct Player {
    /// The recording's first instant and pace; re-started when the replay starts.
    pub clock: Clock,
    /// Length of one lap on the replay's clock (the recording's span / speed).
    pub lap: Duration,
    /// Start again at the end.
    pub looping: bool,
    /// The arm and gripper the states go to.
    pub robot: Arc<RecordedRobot>,
    /// The first arm state, applied again when the replay starts, and its log time.
    pub first_arm_state: (ArmState, u64),
    /// The camera's feed the frames go to.
    pub camera: Arc<CameraFeed>,
    /// What the camera says once the recording ended.
    pub ended: String,
    /// Notified when the replay may start (robotd's consumers are up).
    pub go: Arc<Notify>,
}

impl Player {
    /// Waits for the go, then plays `items` until the recording ends (or, looping, forever).
    pub async fn run(mut self, mut items: mpsc::Receiver<Item>) {
        self.go.notified().await;
        self.clock.start = Instant::now();
        self.clock.start_unix_ns = robotd_protocol::envelope::unix_now_ns();
        let (first, first_time) = &self.first_arm_state;
        self.robot.set_arm(first, *first_time, &self.clock);
        let mut pending: BinaryHeap<Reverse<Pending>> = BinaryHeap::new();
        let mut seq = 0u64;
        let mut newest = 0u64;
        let mut lap_over = false;
        let mut warned_size = false;
        loop {
            while !lap_over {
                let read_enough = pending.len() >= MAX_PENDING
                    || pending.peek().is_some_and(|Reverse(p)| {
                        newest >= p.log_time.saturating_add(REORDER.as_nanos() as u64)
                    });
                if read_enough {
                    break;
                }
                match items.recv().await {
                    Some(Item::End) => lap_over = true,
                    Some(Item::Failed(reason)) => {
                        self.camera.set_problem(reason);
                        return;
                    }
                    None => {
                        self.camera
                            .set_problem("the replay's reader thread stopped".into());
                        return;
                    }
                    Some(item) => {
                        let log_time = item.log_time();
                        newest = newest.max(log_time);
                        let mut due = self.clock.due(log_time);
                        if matches!(item, Item::Frame { .. }) {
                            due += FRAME_DELAY;
                        }
                        pending.push(Reverse(Pending {
                            due,
                            seq,
                            log_time,
                            item,
                        }));
                        seq += 1;
                    }
                }
            }
            let Some(Reverse(next)) = pending.pop() else {
                if !self.looping {
                    self.wait_for_the_last_frame().await;
                    self.camera.set_problem(self.ended.clone());
                    return;
                }
                self.clock.next_lap(self.lap.saturating_add(LAP_GAP));
                newest = 0;
                lap_over = false;
                continue;
            };
            tokio::time::sleep_until(next.due).await;
            match next.item {
                Item::Frame {
                    meta,
                    rgb,
                    log_time,
                } => self.show(meta, rgb, log_time, &mut warned_size),
                Item::Arm { log_time, state } => self.robot.set_arm(&state, log_time, &self.clock),
                Item::Gripper { state, .. } => self.robot.set_gripper(&state),
                Item::End | Item::Failed(_) => {}
            }
        }
    }

    /// Lets the camera take the last frame before it is told the recording ended (which
    /// replaces the frame), for at most [`LAST_FRAME_WAIT`].
    async fn wait_for_the_last_frame(&self) {
        let deadline = Instant::now() + LAST_FRAME_WAIT;
        while self.camera.has_unread() && Instant::now() < deadline {
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
    }

    fn show(&self, meta: FrameMeta, rgb: Vec<u8>, log_time: u64, warned_size: &mut bool) {
        let intrinsics = self.camera.intrinsics();
        if (meta.width, meta.height) != (intrinsics.width, intrinsics.height) {
            if !*warned_size {
                *warned_size = true;
                tracing::warn!(
                    frame_id = meta.frame_id,
                    width = meta.width,
                    height = meta.height,
                    "replay: a frame of another size than the first; such frames are skipped"
                );
            }
            return;
        }
        let camera_pose = robotd_kinematics::pose_to_isometry(&Pose::from_array(meta.camera_pose));
        let taken = if meta.timestamp_unix_ns > 0 {
            meta.timestamp_unix_ns
        } else {
            log_time
        };
        self.camera.publish_taken(
            rgb,
            CaptureInfo {
                camera_pose,
                timestamp_unix_ns: self.clock.unix_at(taken),
            },
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use robotd_driver::{ArmDriver, CameraDriver};
    use robotd_protocol::geometry::RobotModel;
    use robotd_recording::fixture::{arm_state, at, intrinsics, meta, T0};

    struct Rig {
        robot: Arc<RecordedRobot>,
        camera: Arc<CameraFeed>,
        go: Arc<Notify>,
        items: mpsc::Sender<Item>,
    }

    fn rig(speed: f64, looping: bool, lap_s: f64) -> (Rig, Player, mpsc::Receiver<Item>) {
        let clock = Clock::new(T0, speed, 0);
        let first = arm_state(0.0, T0 - 1_000_000_000);
        let robot = Arc::new(RecordedRobot::new(
            RobotModel::Ned2,
            &first,
            T0,
            &clock,
            None,
            0.04,
        ));
        let camera = Arc::new(CameraFeed::new(
            "test.mcap",
            intrinsics(4, 2),
            Duration::ZERO,
            Arc::new(|| None),
            "waiting for the start".into(),
        ));
        let go = Arc::new(Notify::new());
        let (tx, rx) = mpsc::channel(256);
        let player = Player {
            clock,
            lap: Duration::from_secs_f64(lap_s / speed),
            looping,
            robot: robot.clone(),
            first_arm_state: (first, T0),
            camera: camera.clone(),
            ended: "the recording ended".into(),
            go: go.clone(),
        };
        (
            Rig {
                robot,
                camera,
                go,
                items: tx,
            },
            player,
            rx,
        )
    }

    fn frame(id: u64, t: u64) -> Item {
        Item::Frame {
            log_time: t,
            meta: meta(id, t, 4, 2),
            rgb: vec![id as u8; 4 * 2 * 3],
        }
    }

    fn arm(j1: f64, still_since: u64, t: u64) -> Item {
        Item::Arm {
            log_time: t,
            state: arm_state(j1, still_since),
        }
    }

    struct Camera(Arc<CameraFeed>);
    impl robotd_driver::camera_feed::FedCamera for Camera {
        fn feed(&self) -> &CameraFeed {
            &self.0
        }
    }

    #[tokio::test(start_paused = true)]
    async fn messages_come_at_their_recorded_times_scaled_by_speed_in_time_order() {
        let (rig, player, rx) = rig(2.0, false, 2.0);
        let arm_driver = crate::robot::ReplayArm(rig.robot.clone());
        let camera = Camera(rig.camera.clone());
        // File order: the frame taken at 1.0 s is written after the state sent at 1.1 s.
        for item in [
            arm(0.2, 0, at(0.4)),
            arm(0.3, 0, at(1.1)),
            frame(1, at(1.0)),
            arm(0.4, at(1.6), at(1.7)),
            frame(2, at(2.0)),
            Item::End,
        ] {
            rig.items.try_send(item).unwrap();
        }
        tokio::spawn(player.run(rx));
        // Nothing happens before the go.
        tokio::time::sleep(Duration::from_secs(5)).await;
        assert_eq!(arm_driver.joints().unwrap()[0], 0.0);
        assert!(rig.camera.problem().is_some());
        let start = Instant::now();
        rig.go.notify_one();

        // At speed 2 the state of 0.4 s comes at 0.2 s.
        tokio::time::sleep(Duration::from_millis(199)).await;
        assert_eq!(arm_driver.joints().unwrap()[0], 0.0);
        tokio::time::sleep(Duration::from_millis(2)).await;
        assert_eq!(arm_driver.joints().unwrap()[0], 0.2);
        assert!(arm_driver.flags().moving);

        // The frame of 1.0 s comes at 0.5 s + FRAME_DELAY, after the state of 1.1 s (0.55 s).
        camera.frame_ready().await.unwrap();
        let waited = start.elapsed();
        assert_eq!(waited, Duration::from_millis(500) + FRAME_DELAY);
        assert_eq!(arm_driver.joints().unwrap()[0], 0.3);
        let mut out = vec![0; 24];
        let info = camera.capture_into(&mut out).unwrap();
        assert_eq!(out, vec![1; 24]);
        assert!((info.camera_pose.translation.vector.z - 0.3).abs() < 1e-12);
        // Dated at its mapped capture time (0.5 s after the start), not its arrival.
        let replay_start = info.timestamp_unix_ns - 500_000_000;
        let wall = robotd_protocol::envelope::unix_now_ns();
        assert!(
            replay_start.abs_diff(wall) < 10_000_000_000,
            "on the Unix clock"
        );

        // At rest since 1.6 s, mapped to 0.8 s.
        tokio::time::sleep_until(start + Duration::from_millis(851)).await;
        assert_eq!(
            arm_driver.still_since_unix_ns(),
            Some(replay_start + 800_000_000)
        );
        assert!(!arm_driver.flags().moving);

        camera.frame_ready().await.unwrap();
        assert_eq!(start.elapsed(), Duration::from_secs(1) + FRAME_DELAY);
        let info = camera.capture_into(&mut out).unwrap();
        assert_eq!(info.timestamp_unix_ns, replay_start + 1_000_000_000);

        // The end: the camera says so; the arm stays.
        let error = camera.frame_ready().await.unwrap_err();
        assert!(error.to_string().contains("the recording ended"), "{error}");
        assert_eq!(arm_driver.joints().unwrap()[0], 0.4);
    }

    #[tokio::test(start_paused = true)]
    async fn a_loop_starts_again_one_lap_later_with_the_same_rest() {
        let (rig, player, rx) = rig(1.0, true, 1.0);
        let camera = Camera(rig.camera.clone());
        let arm_driver = crate::robot::ReplayArm(rig.robot.clone());
        for _ in 0..2 {
            for item in [frame(7, at(0.5)), arm(0.1, at(0.6), at(1.0)), Item::End] {
                rig.items.try_send(item).unwrap();
            }
        }
        tokio::spawn(player.run(rx));
        let start = Instant::now();
        rig.go.notify_one();
        let mut out = vec![0; 24];
        camera.frame_ready().await.unwrap();
        let first = camera.capture_into(&mut out).unwrap();
        assert_eq!(start.elapsed(), Duration::from_millis(500) + FRAME_DELAY);
        tokio::time::sleep_until(start + Duration::from_millis(1001)).await;
        let rest = arm_driver.still_since_unix_ns().unwrap();
        camera.frame_ready().await.unwrap();
        let second = camera.capture_into(&mut out).unwrap();
        let lap = Duration::from_secs(1) + LAP_GAP;
        assert_eq!(
            start.elapsed(),
            lap + Duration::from_millis(500) + FRAME_DELAY
        );
        assert_eq!(
            second.timestamp_unix_ns - first.timestamp_unix_ns,
            lap.as_nanos() as u64
        );
        tokio::time::sleep_until(start + lap + Duration::from_millis(1001)).await;
        assert_eq!(
            arm_driver.still_since_unix_ns().unwrap() - rest,
            lap.as_nanos() as u64
        );
    }

    #[tokio::test(start_paused = true)]
    async fn a_time_jump_in_the_file_does_not_make_the_player_read_it_all() {
        let (rig, player, rx) = rig(1.0, false, 20.0);
        let arm_driver = crate::robot::ReplayArm(rig.robot.clone());
        rig.items.try_send(frame(1, at(20.0))).unwrap();
        for k in 0..150 {
            rig.items
                .try_send(arm(0.001 * f64::from(k), 0, at(0.01 * f64::from(k))))
                .unwrap();
        }
        tokio::spawn(player.run(rx));
        rig.go.notify_one();
        tokio::time::sleep(Duration::from_millis(55)).await;
        let unread = 256 - rig.items.capacity();
        assert!(
            unread >= 150 - MAX_PENDING - 10,
            "{unread} messages left unread"
        );
        // The states still come in time order.
        assert!((arm_driver.joints().unwrap()[0] - 0.005).abs() < 1e-9);
    }

    #[tokio::test(start_paused = true)]
    async fn log_times_at_the_end_of_time_neither_overflow_nor_stop_the_replay() {
        let (rig, player, rx) = rig(1.0, false, 1.0);
        let arm_driver = crate::robot::ReplayArm(rig.robot.clone());
        for item in [
            arm(0.2, 0, at(0.1)),
            arm(0.3, 0, u64::MAX - 5),
            frame(1, u64::MAX),
            Item::End,
        ] {
            rig.items.try_send(item).unwrap();
        }
        let player = tokio::spawn(player.run(rx));
        rig.go.notify_one();
        tokio::time::sleep(Duration::from_millis(101)).await;
        assert_eq!(arm_driver.joints().unwrap()[0], 0.2);
        // The rest is due centuries later: far in the future, not an overflow.
        player.await.expect("the player does not panic");
        assert_eq!(arm_driver.joints().unwrap()[0], 0.3);
        assert_eq!(rig.camera.problem().as_deref(), Some("the recording ended"));
    }

    #[test]
    fn the_clock_takes_any_recorded_time_and_any_pace_without_overflowing() {
        for speed in [1.0, 0.1, 10.0, 1e-12, 0.0, -1.0, f64::NAN, f64::INFINITY] {
            let mut clock = Clock::new(T0, speed, 1_000);
            let now = clock.start;
            for t in [0, T0, T0 + 1, u64::MAX - 1, u64::MAX] {
                let due = clock.due(t);
                assert!(due >= now && due <= now + FAR_FUTURE, "{speed} {t}");
                let _ = clock.unix_at(t);
            }
            clock.next_lap(Duration::MAX);
            assert_eq!(clock.start_unix_ns, u64::MAX);
        }
        let clock = Clock::new(T0, 1e-12, u64::MAX - 10);
        assert_eq!(clock.unix_at(u64::MAX), u64::MAX);
        assert_eq!(Clock::new(T0, 1e-12, 10).unix_at(0), 0);
        let clock = Clock::new(T0, 2.0, 1_000);
        assert_eq!(clock.due(at(1.0)), clock.start + Duration::from_millis(500));
        assert_eq!(clock.unix_at(at(1.0)), 500_001_000);
    }

    #[tokio::test(start_paused = true)]
    async fn a_reader_that_fails_is_reported_by_the_camera() {
        let (rig, player, rx) = rig(1.0, true, 1.0);
        rig.items
            .try_send(Item::Failed("cannot read s.mcap: no such file".into()))
            .unwrap();
        rig.go.notify_one();
        player.run(rx).await;
        assert_eq!(
            rig.camera.problem().as_deref(),
            Some("cannot read s.mcap: no such file")
        );
    }
}
