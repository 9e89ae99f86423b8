//! The replayed arm and gripper: what the recording says they did, and a refusal for every
//! command that would move them.
//!
//! [`RecordedRobot`] holds the arm's joints and flags, when it came to rest and the gripper's
//! state as of the replay's current instant; the player updates it at the recorded times. The
//! arm's rest instant is the recorded one mapped onto the replay's clock, so perception's
//! "arm at rest" rule ([`robotd_protocol::arm::ArmMotion`]) judges each replayed frame as it
//! judged the original.
//!
//! A motion, a calibration, a gripper command: each is refused with [`REFUSAL`], never
//! pretended. `halt` succeeds (nothing moves, so the arm is halted), so supervision's safe
//! state works as on any robot.

use crate::player::Clock;
use robotd_driver::{
    ArmDriver, ArmFlags, ArmMotion, Calibration, ClearCollision, Close, DriverError, DriverFuture,
    GripperDriver, GripperStatus, MotionControl, Open, Permit, SetWidth,
};
use robotd_protocol::arm::ArmState;
use robotd_protocol::geometry::RobotModel;
use robotd_protocol::gripper::GripperState;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};

/// Why every command that would move the replayed robot is refused.
pub const REFUSAL: &str =
    "this robot is a recording being replayed (robot.driver = \"replay\"); it cannot move";

fn refused() -> DriverError {
    DriverError::Hardware(REFUSAL.to_owned())
}

#[derive(Debug, Clone)]
struct ArmNow {
    joints: Vec<f64>,
    flags: ArmFlags,
    /// When the arm came to rest on the replay's clock; 0 while it moves.
    still_since_unix_ns: u64,
}

/// The recorded robot as of the replay's current instant.
#[derive(Debug)]
pub struct RecordedRobot {
    model: RobotModel,
    arm: Mutex<ArmNow>,
    gripper: Mutex<GripperStatus>,
    max_width_m: f64,
    /// Arm states skipped for not being this model's finite joints.
    skipped_arm_states: AtomicU64,
}

/// Whether the `n`th of a kind of problem is worth a log line: the 1st, 10th, 100th, … (a
/// recording full of them costs a few lines, not one per message).
pub fn worth_a_line(n: u64) -> bool {
    let mut m = n;
    while m >= 10 && m.is_multiple_of(10) {
        m /= 10;
    }
    m == 1
}

fn lock<T>(mutex: &Mutex<T>) -> MutexGuard<'_, T> {
    mutex.lock().unwrap_or_else(|p| p.into_inner())
}

impl RecordedRobot {
    /// A `model` standing as `first` says (its rest mapped with `clock`), its gripper as
    /// `gripper` says (open at `max_width_m` when nothing was recorded).
    pub fn new(
        model: RobotModel,
        first: &ArmState,
        first_log_time: u64,
        clock: &Clock,
        gripper: Option<&GripperState>,
        max_width_m: f64,
    ) -> Self {
        let robot = Self {
            model,
            arm: Mutex::new(ArmNow {
                joints: first.joints.positions_rad.clone(),
                flags: ArmFlags::default(),
                still_since_unix_ns: 0,
            }),
            gripper: Mutex::new(GripperStatus {
                holding: false,
                width_m: max_width_m,
            }),
            max_width_m,
            skipped_arm_states: AtomicU64::new(0),
        };
        robot.set_arm(first, first_log_time, clock);
        if let Some(state) = gripper {
            robot.set_gripper(state);
        }
        robot
    }

    /// The arm as recorded state `state` (logged at `log_time`) says, on `clock`.
    pub fn set_arm(&self, state: &ArmState, log_time: u64, clock: &Clock) {
        let joints = &state.joints.positions_rad;
        if joints.len() != self.model.joint_count() || joints.iter().any(|q| !q.is_finite()) {
            let skipped = self.skipped_arm_states.fetch_add(1, Ordering::Relaxed) + 1;
            if worth_a_line(skipped) {
                tracing::warn!(
                    joints = joints.len(),
                    skipped,
                    "replay: an arm state without {} finite joints; skipped ({skipped} so far, \
                     logged at the 1st, 10th, 100th, …)",
                    self.model.joint_count()
                );
            }
            return;
        }
        let mut arm = lock(&self.arm);
        let moving = state.moving;
        arm.still_since_unix_ns = if moving {
            0
        } else if state.still_since_unix_ns > 0 {
            clock.unix_at(state.still_since_unix_ns)
        } else if arm.still_since_unix_ns > 0 {
            // Older recorders did not send it: at rest since the first state that said so.
            arm.still_since_unix_ns
        } else {
            clock.unix_at(log_time)
        };
        arm.joints = joints.clone();
        arm.flags = ArmFlags {
            moving,
            collision_detected: state.collision_detected,
            calibrated: state.calibrated,
        };
    }

    /// Arm states skipped so far for not being this model's finite joints.
    pub fn skipped_arm_states(&self) -> u64 {
        self.skipped_arm_states.load(Ordering::Relaxed)
    }

    /// The gripper as recorded state `state` says.
    pub fn set_gripper(&self, state: &GripperState) {
        if !state.width_m.is_finite() {
            return;
        }
        *lock(&self.gripper) = GripperStatus {
            holding: state.holding,
            width_m: state.width_m,
        };
    }
}

/// The replayed arm.
#[derive(Debug, Clone)]
pub struct ReplayArm(pub Arc<RecordedRobot>);

impl ArmDriver for ReplayArm {
    fn model(&self) -> RobotModel {
        self.0.model
    }

    fn joints(&self) -> Result<Vec<f64>, DriverError> {
        Ok(lock(&self.0.arm).joints.clone())
    }

    fn flags(&self) -> ArmFlags {
        lock(&self.0.arm).flags
    }

    fn still_since_unix_ns(&self) -> Option<u64> {
        Some(lock(&self.0.arm).still_since_unix_ns)
    }

    fn execute<'a>(
        &'a self,
        _permit: Permit<ArmMotion>,
        _control: &'a MotionControl,
    ) -> DriverFuture<'a, ()> {
        Box::pin(async { Err(refused()) })
    }

    fn calibrate(&self, _permit: Permit<Calibration>) -> DriverFuture<'_, ()> {
        Box::pin(async { Err(refused()) })
    }

    fn clear_collision(&self, _permit: Permit<ClearCollision>) -> DriverFuture<'_, ()> {
        Box::pin(async { Err(refused()) })
    }

    fn halt(&self) -> Result<(), DriverError> {
        Ok(())
    }
}

/// The replayed gripper.
#[derive(Debug, Clone)]
pub struct ReplayGripper(pub Arc<RecordedRobot>);

impl GripperDriver for ReplayGripper {
    fn max_width_m(&self) -> f64 {
        self.0.max_width_m
    }

    fn open(&self, _permit: Permit<Open>) -> DriverFuture<'_, GripperStatus> {
        Box::pin(async { Err(refused()) })
    }

    fn close(&self, _permit: Permit<Close>) -> DriverFuture<'_, GripperStatus> {
        Box::pin(async { Err(refused()) })
    }

    fn set_width(&self, _permit: Permit<SetWidth>) -> DriverFuture<'_, GripperStatus> {
        Box::pin(async { Err(refused()) })
    }

    fn status(&self) -> Result<GripperStatus, DriverError> {
        Ok(*lock(&self.0.gripper))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use robotd_driver::Motion;
    use robotd_recording::fixture::{arm_state, at, T0};
    use robotd_safety::testing;

    fn robot(clock: &Clock) -> Arc<RecordedRobot> {
        Arc::new(RecordedRobot::new(
            RobotModel::Ned2,
            &arm_state(0.5, T0 - 2_000_000_000),
            T0,
            clock,
            None,
            0.04,
        ))
    }

    #[tokio::test]
    async fn every_command_that_would_move_is_refused_and_nothing_changes() {
        let clock = Clock::new(T0, 1.0, 5_000_000_000_000);
        let robot = robot(&clock);
        let (arm, gripper) = (ReplayArm(robot.clone()), ReplayGripper(robot));
        let control = MotionControl::default();
        let policy = testing::wide_policy(RobotModel::Ned2);
        let before = arm.joints().unwrap();
        let refusals = [
            arm.execute(
                testing::motion(&policy, &before, Motion::Joints(vec![0.0; 6])).await,
                &control,
            )
            .await
            .unwrap_err(),
            arm.calibrate(testing::calibration(&policy, &before).await)
                .await
                .unwrap_err(),
            arm.clear_collision(testing::clear_collision(&policy).await)
                .await
                .unwrap_err(),
            gripper
                .open(testing::gripper(&policy, Open).await)
                .await
                .unwrap_err(),
            gripper
                .close(testing::gripper(&policy, Close).await)
                .await
                .unwrap_err(),
            gripper
                .set_width(testing::gripper(&policy, SetWidth { width_m: 0.01 }).await)
                .await
                .unwrap_err(),
        ];
        for refusal in refusals {
            assert_eq!(refusal.to_string(), REFUSAL);
        }
        assert_eq!(arm.joints().unwrap(), before);
        assert!(!arm.flags().moving);
        assert!(arm.halt().is_ok(), "halting a robot that never moves works");
        assert_eq!(gripper.status().unwrap().width_m, 0.04);
        assert!(REFUSAL.contains("robot.driver = \"replay\""));
    }

    #[test]
    fn rest_and_motion_follow_the_recording_on_the_replay_clock() {
        // The replay started at Unix time 5000 s, twice as fast as recorded.
        let clock = Clock::new(T0, 2.0, 5_000_000_000_000);
        let robot = robot(&clock);
        let arm = ReplayArm(robot.clone());
        // At rest since 2 s before the recording began: 1 s before the replay began.
        assert_eq!(arm.still_since_unix_ns(), Some(4_999_000_000_000));
        robot.set_arm(&arm_state(0.7, 0), at(1.0), &clock);
        assert_eq!(arm.still_since_unix_ns(), Some(0));
        assert!(arm.flags().moving);
        assert_eq!(arm.joints().unwrap()[0], 0.7);
        robot.set_arm(&arm_state(0.9, at(1.8)), at(2.0), &clock);
        assert_eq!(arm.still_since_unix_ns(), Some(5_000_900_000_000));
        assert!(!arm.flags().moving);

        // A sender without still_since: at rest since the first state that says so.
        robot.set_arm(&arm_state(0.9, 0), at(2.5), &clock);
        let mut old = arm_state(0.9, 0);
        old.moving = false;
        robot.set_arm(&old, at(3.0), &clock);
        assert_eq!(arm.still_since_unix_ns(), Some(5_001_500_000_000));
        robot.set_arm(&old, at(4.0), &clock);
        assert_eq!(arm.still_since_unix_ns(), Some(5_001_500_000_000));

        // A state of the wrong robot changes nothing.
        let mut short = arm_state(2.0, at(1.0));
        short.joints.positions_rad.pop();
        robot.set_arm(&short, at(5.0), &clock);
        assert_eq!(arm.joints().unwrap()[0], 0.9);
    }

    #[test]
    fn malformed_arm_states_are_counted_and_logged_at_the_1st_10th_100th() {
        let clock = Clock::new(T0, 1.0, 5_000_000_000_000);
        let robot = robot(&clock);
        let mut bad = arm_state(0.3, 0);
        bad.joints.positions_rad[2] = f64::NAN;
        let ((), warnings) = crate::warnings_of(|| {
            for k in 0..1_000 {
                robot.set_arm(&bad, at(0.001 * f64::from(k)), &clock);
            }
        });
        assert_eq!(robot.skipped_arm_states(), 1_000);
        assert_eq!(warnings.len(), 4, "{warnings:#?}");
        assert!(warnings[3].contains("1000 so far"), "{}", warnings[3]);
        assert_eq!(ReplayArm(robot).joints().unwrap()[0], 0.5, "none applied");
        let logged: Vec<u64> = (1..=10_000).filter(|n| worth_a_line(*n)).collect();
        assert_eq!(logged, [1, 10, 100, 1_000, 10_000]);
    }
}
