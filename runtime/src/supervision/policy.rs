//! Restart policy, restart budget and backoff: the numbers a supervisor decides with.

use std::collections::VecDeque;
use std::time::Duration;

use serde::{Deserialize, Serialize};
use tokio::time::Instant;

/// When a supervised actor or process is restarted after it stopped on its own.
///
/// | policy | after a failure (panic, error, non-zero exit, signal) | after a normal exit |
/// |---|---|---|
/// | [`Permanent`](Self::Permanent) | restart | restart |
/// | [`Transient`](Self::Transient) | restart | stay stopped |
/// | [`Never`](Self::Never) | stay stopped (reported as an escalation) | stay stopped |
///
/// The safe-state hook runs in every case: a stop is a stop, whatever comes next.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum RestartPolicy {
    /// Always restart: hardware drivers that must be there while robotd runs (the default).
    #[default]
    Permanent,
    /// Restart after failures only; a normal exit (an actor calling `ctx.stop()`, a process
    /// exiting with status 0) means the work is done.
    Transient,
    /// Never restart; the failure is escalated straight away.
    Never,
}

impl RestartPolicy {
    /// Whether this policy restarts after a stop that was a failure (`failed`) or a normal exit.
    pub fn restarts_after(self, failed: bool) -> bool {
        match self {
            RestartPolicy::Permanent => true,
            RestartPolicy::Transient => failed,
            RestartPolicy::Never => false,
        }
    }
}

impl From<RestartPolicy> for kameo::supervision::RestartPolicy {
    fn from(policy: RestartPolicy) -> Self {
        match policy {
            RestartPolicy::Permanent => kameo::supervision::RestartPolicy::Permanent,
            RestartPolicy::Transient => kameo::supervision::RestartPolicy::Transient,
            RestartPolicy::Never => kameo::supervision::RestartPolicy::Never,
        }
    }
}

/// How one supervisor restarts its child: policy, restart budget and backoff.
///
/// The default allows 5 restarts within 60 s, waiting 10 ms before the first restart and
/// doubling up to 5 s: a glitch is fixed in milliseconds, a crash loop gives up within a
/// minute instead of hammering the hardware.
///
/// ```
/// use std::time::Duration;
/// use robotd_runtime::supervision::SupervisionPolicy;
///
/// let policy = SupervisionPolicy::default();
/// assert_eq!(policy.backoff_for(1), Duration::from_millis(10));
/// assert_eq!(policy.backoff_for(2), Duration::from_millis(20));
/// assert_eq!(policy.backoff_for(30), Duration::from_secs(5)); // capped at backoff_max
/// ```
#[derive(Clone, Debug, PartialEq)]
pub struct SupervisionPolicy {
    /// Restarts allowed within [`window`](Self::window); one more failure exhausts the budget
    /// and the supervisor gives up. `0` means: never restart, escalate the first failure.
    pub max_restarts: u32,
    /// Length of the sliding window the restarts are counted in (a zero window never fills
    /// up: restarts are then unlimited).
    pub window: Duration,
    /// Delay before the first restart of a burst.
    pub backoff_initial: Duration,
    /// Upper bound of the delay.
    pub backoff_max: Duration,
    /// Factor between consecutive delays (values below 1, NaN or infinite count as 1).
    pub backoff_multiplier: f64,
    /// When to restart at all.
    pub restart: RestartPolicy,
}

impl Default for SupervisionPolicy {
    fn default() -> Self {
        SupervisionPolicy {
            max_restarts: 5,
            window: Duration::from_secs(60),
            backoff_initial: Duration::from_millis(10),
            backoff_max: Duration::from_secs(5),
            backoff_multiplier: 2.0,
            restart: RestartPolicy::Permanent,
        }
    }
}

impl SupervisionPolicy {
    /// The delay before restart number `attempt` of the current burst, where a burst is the
    /// restarts still inside the sliding [`window`](Self::window): `attempt` 1 waits
    /// `backoff_initial`, each further attempt `backoff_multiplier` times longer, never more
    /// than `backoff_max`. `attempt` 0 (the first start) is not delayed.
    ///
    /// Once a child has run without failing for a whole window, the burst is over and the next
    /// restart waits `backoff_initial` again.
    pub fn backoff_for(&self, attempt: u32) -> Duration {
        if attempt == 0 {
            return Duration::ZERO;
        }
        let max = self.backoff_max;
        let initial = self.backoff_initial.min(max);
        let multiplier = if self.backoff_multiplier.is_finite() && self.backoff_multiplier >= 1.0 {
            self.backoff_multiplier
        } else {
            1.0
        };
        let exponent = i32::try_from(attempt - 1).unwrap_or(i32::MAX);
        // Nanoseconds in f64 are exact up to ~104 days, so the usual values come out exact.
        let nanos = (initial.as_nanos() as f64 * multiplier.powi(exponent)).round();
        if !nanos.is_finite() || nanos >= max.as_nanos() as f64 {
            max
        } else {
            Duration::from_nanos(nanos as u64)
        }
    }
}

/// The sliding-window restart budget of one supervisor.
#[derive(Debug)]
pub(crate) struct RestartBudget {
    max_restarts: u32,
    window: Duration,
    restarts: VecDeque<Instant>,
}

impl RestartBudget {
    pub(crate) fn new(policy: &SupervisionPolicy) -> Self {
        RestartBudget {
            max_restarts: policy.max_restarts,
            window: policy.window,
            restarts: VecDeque::new(),
        }
    }

    /// Takes one restart from the budget at `now`. `Ok(n)`: allowed, and it is the `n`th
    /// restart inside the window (the backoff attempt). `Err(n)`: exhausted, `n` restarts
    /// already happened inside the window.
    pub(crate) fn take(&mut self, now: Instant) -> Result<u32, u32> {
        while let Some(&oldest) = self.restarts.front() {
            if now.saturating_duration_since(oldest) >= self.window {
                self.restarts.pop_front();
            } else {
                break;
            }
        }
        let used = u32::try_from(self.restarts.len()).unwrap_or(u32::MAX);
        if used >= self.max_restarts {
            return Err(used);
        }
        self.restarts.push_back(now);
        Ok(used + 1)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ms(n: u64) -> Duration {
        Duration::from_millis(n)
    }

    #[test]
    fn default_policy_matches_the_config_defaults() {
        let p = SupervisionPolicy::default();
        assert_eq!(p.max_restarts, 5);
        assert_eq!(p.window, Duration::from_secs(60));
        assert_eq!(p.backoff_initial, ms(10));
        assert_eq!(p.backoff_max, Duration::from_secs(5));
        assert_eq!(p.backoff_multiplier, 2.0);
        assert_eq!(p.restart, RestartPolicy::Permanent);
    }

    #[test]
    fn backoff_doubles_from_initial_and_caps_at_max() {
        let p = SupervisionPolicy::default();
        let got: Vec<_> = (0..=12).map(|a| p.backoff_for(a)).collect();
        let want = [
            0, 10, 20, 40, 80, 160, 320, 640, 1280, 2560, 5000, 5000, 5000,
        ]
        .map(ms);
        assert_eq!(got, want);
        assert_eq!(p.backoff_for(u32::MAX), p.backoff_max);
    }

    #[test]
    fn backoff_handles_odd_multipliers_and_initial_above_max() {
        let mut p = SupervisionPolicy {
            backoff_multiplier: 1.5,
            ..SupervisionPolicy::default()
        };
        assert_eq!(p.backoff_for(3), Duration::from_micros(22_500));
        p.backoff_multiplier = 0.5;
        assert_eq!(p.backoff_for(4), ms(10), "multiplier < 1 counts as 1");
        p.backoff_multiplier = f64::NAN;
        assert_eq!(p.backoff_for(4), ms(10));
        p.backoff_initial = Duration::from_secs(9);
        assert_eq!(p.backoff_for(1), Duration::from_secs(5));
        p.backoff_initial = Duration::ZERO;
        p.backoff_multiplier = 2.0;
        assert_eq!(p.backoff_for(7), Duration::ZERO);
    }

    #[test]
    fn budget_slides_with_the_window() {
        let policy = SupervisionPolicy {
            max_restarts: 2,
            window: ms(100),
            ..SupervisionPolicy::default()
        };
        let mut budget = RestartBudget::new(&policy);
        let t0 = Instant::now();
        assert_eq!(budget.take(t0), Ok(1));
        assert_eq!(budget.take(t0 + ms(10)), Ok(2));
        assert_eq!(budget.take(t0 + ms(20)), Err(2));
        // the first restart leaves the window at t0 + 100 ms
        assert_eq!(budget.take(t0 + ms(100)), Ok(2));
        assert_eq!(budget.take(t0 + ms(300)), Ok(1));
    }

    #[test]
    fn zero_budget_never_restarts() {
        let policy = SupervisionPolicy {
            max_restarts: 0,
            ..SupervisionPolicy::default()
        };
        assert_eq!(RestartBudget::new(&policy).take(Instant::now()), Err(0));
    }

    #[test]
    fn restart_policy_decides_by_failure() {
        assert!(RestartPolicy::Permanent.restarts_after(false));
        assert!(RestartPolicy::Transient.restarts_after(true));
        assert!(!RestartPolicy::Transient.restarts_after(false));
        assert!(!RestartPolicy::Never.restarts_after(true));
    }
}
