//! The arm's stop signals and the shape of a motion: what the policy and every driver share.
//!
//! These types sit here, under the drivers, because the policy needs them to decide
//! ([`MotionControl`] holds the e-stop latch the policy reads; [`Motion`] is what it checks)
//! and the drivers need them to run what was decided. `robotd-driver` re-exports them, so a
//! driver writes `robotd_driver::MotionControl` as before.
//!
//! - [`MotionControl`]: the `Stop` command and the emergency stop, checked by a running
//!   motion at every control tick ([`MotionControl::check`]); a motion received before a stop
//!   never starts ([`MotionControl::begin_motion`]).
//! - [`Motion`]: a joint target, or a dense joint path the arm actor planned.
//! - [`nominal_travel_time_s`]: the drivers' timing contract, which the policy uses to predict
//!   tool speeds.

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;

/// A motion must stop (or must not start): a stop command or the emergency stop. A driver
/// turns it into its own error (`robotd_driver::DriverError::Stopped`).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("motion stopped: {reason}")]
pub struct Stopped {
    /// A stop command, or the e-stop's reason.
    pub reason: String,
}

/// Shared stop signals of one arm: the `Stop` command and the emergency stop. A running motion
/// checks them at every control tick.
#[derive(Debug, Clone, Default)]
pub struct MotionControl {
    inner: Arc<ControlFlags>,
}

#[derive(Debug, Default)]
struct ControlFlags {
    stop: AtomicBool,
    stop_generation: AtomicU64,
    estop: AtomicBool,
    estop_reason: std::sync::Mutex<String>,
}

impl MotionControl {
    /// Asks the running motion (if any) to stop at its next control tick.
    ///
    /// Every motion received before the stop is cancelled too: see [`Self::begin_motion`].
    pub fn request_stop(&self) {
        self.inner.stop_generation.fetch_add(1, Ordering::SeqCst);
        self.inner.stop.store(true, Ordering::SeqCst);
    }

    /// How many stops were requested so far; a motion notes it when it is received.
    pub fn stop_generation(&self) -> u64 {
        self.inner.stop_generation.load(Ordering::SeqCst)
    }

    /// Starts a motion received at stop generation `received_at`: refused with [`Stopped`]
    /// when a stop came in since (a motion queued behind the one a stop interrupted never runs
    /// later), else clears the stop flag for it.
    pub fn begin_motion(&self, received_at: u64) -> Result<(), Stopped> {
        if self.stop_generation() != received_at {
            return Err(Stopped {
                reason: "a stop command came after the motion was requested".into(),
            });
        }
        self.inner.stop.store(false, Ordering::SeqCst);
        Ok(())
    }

    /// Engages (`true`) or releases the emergency stop.
    pub fn set_estop(&self, engaged: bool, reason: &str) {
        if let Ok(mut r) = self.inner.estop_reason.lock() {
            *r = reason.to_owned();
        }
        self.inner.estop.store(engaged, Ordering::SeqCst);
    }

    /// Whether the emergency stop is engaged.
    pub fn estop_engaged(&self) -> bool {
        self.inner.estop.load(Ordering::SeqCst)
    }

    /// Why the emergency stop was engaged.
    pub fn estop_reason(&self) -> String {
        self.inner
            .estop_reason
            .lock()
            .map(|r| r.clone())
            .unwrap_or_default()
    }

    /// `Err(Stopped)` when the motion must stop now (stop requested or e-stop engaged).
    pub fn check(&self) -> Result<(), Stopped> {
        if self.estop_engaged() {
            return Err(Stopped {
                reason: format!("emergency stop: {}", self.estop_reason()),
            });
        }
        if self.inner.stop.load(Ordering::SeqCst) {
            return Err(Stopped {
                reason: "stop command".into(),
            });
        }
        Ok(())
    }
}

/// One arm motion: what the policy checks and the driver executes.
#[derive(Debug, Clone, PartialEq)]
pub enum Motion {
    /// Joint-space motion to these positions (radians, base to wrist); all joints start and
    /// end together.
    Joints(Vec<f64>),
    /// A straight tool path, given as dense joint waypoints the arm actor computed (and
    /// checked) with inverse kinematics; the last one is the target.
    JointPath(Vec<Vec<f64>>),
}

/// Nominal time, seconds, to travel from joints `a` to `b` at full speed: the slowest joint
/// at its velocity limit (`max_velocity_rad_s`, one per joint), times 1.5 for a smooth start
/// and stop (a cubic profile peaks at 1.5 × its average speed). Drivers time a motion run at
/// `speed_scale` as this divided by the scale; the safety policy predicts tool speeds with it.
pub fn nominal_travel_time_s(a: &[f64], b: &[f64], max_velocity_rad_s: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .zip(max_velocity_rad_s)
        .map(|((from, to), limit)| (to - from).abs() / limit.max(1e-6))
        .fold(0.0, f64::max)
        * 1.5
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_stop_cancels_the_motions_received_before_it() {
        let control = MotionControl::default();
        let received = control.stop_generation();
        control.request_stop();
        assert!(control.check().is_err());
        assert!(control.begin_motion(received).is_err());
        let next = control.stop_generation();
        assert!(control.begin_motion(next).is_ok());
        assert!(control.check().is_ok());
        control.set_estop(true, "test");
        assert_eq!(
            control.check().unwrap_err().reason,
            "emergency stop: test".to_owned()
        );
    }
}
