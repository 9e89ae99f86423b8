//! Fault injection for the simulated drivers, so supervision is exercised without hardware.
//!
//! A real driver fails in ways a simulator never would on its own: a servo reports garbage,
//! a connection drops mid-command, a camera stalls. [`FaultInjector`] makes the simulated
//! drivers fail on purpose, as configured in `[robot.faults.<actor>]`: every Nth command, or
//! at random with a probability and a seed (so a failing run can be repeated), optionally
//! after hanging for a while. A failing command **panics**, exactly like a driver bug would:
//! the actor dies with the request in hand, the caller gets an "actor failed, not retried"
//! error, the supervisor drives the hardware to its safe state and restarts the actor.
//!
//! The injector's counter lives outside the actor, so it keeps counting across restarts.

use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};
use robotd_driver::FaultConfig;
use std::sync::Mutex;
use std::time::Duration;

/// Decides, command by command, whether a simulated driver fails.
#[derive(Debug)]
pub struct FaultInjector {
    actor: &'static str,
    config: FaultConfig,
    state: Mutex<(u64, SmallRng)>,
}

impl FaultInjector {
    /// An injector for `actor` with `config` (all zero = never fails).
    pub fn new(actor: &'static str, config: FaultConfig) -> Self {
        let rng = SmallRng::seed_from_u64(config.seed);
        Self {
            actor,
            config,
            state: Mutex::new((0, rng)),
        }
    }

    /// An injector that never fails.
    pub fn none(actor: &'static str) -> Self {
        Self::new(actor, FaultConfig::default())
    }

    /// Counts one command of kind `command` and returns `Some(message)` when it must fail.
    pub fn next_fault(&self, command: &str) -> Option<String> {
        if !self.config.is_active() {
            return None;
        }
        let mut state = self.state.lock().unwrap_or_else(|p| p.into_inner());
        state.0 += 1;
        let n = state.0;
        let every = self.config.fail_every_n;
        if every > 0 && n.is_multiple_of(u64::from(every)) {
            return Some(format!(
                "injected fault in the {} driver: command #{n} ({command}) fails (fail_every_n = {every})",
                self.actor
            ));
        }
        let p = self.config.fail_probability;
        if p > 0.0 && state.1.random_bool(p.clamp(0.0, 1.0)) {
            return Some(format!(
                "injected fault in the {} driver: command #{n} ({command}) fails (fail_probability = {p})",
                self.actor
            ));
        }
        None
    }

    /// How long a failing command hangs before it fails.
    pub fn hang(&self) -> Duration {
        Duration::from_millis(self.config.hang_ms)
    }

    /// Fails the current command if it is its turn: hangs (async) as configured, then panics.
    pub async fn maybe_fail(&self, command: &str) {
        if let Some(message) = self.next_fault(command) {
            let hang = self.hang();
            if !hang.is_zero() {
                tokio::time::sleep(hang).await;
            }
            panic!("{message}");
        }
    }

    /// Like [`maybe_fail`](Self::maybe_fail) for synchronous calls (hangs by blocking).
    pub fn maybe_fail_blocking(&self, command: &str) {
        if let Some(message) = self.next_fault(command) {
            let hang = self.hang();
            if !hang.is_zero() {
                std::thread::sleep(hang);
            }
            panic!("{message}");
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_nth_command_fails() {
        let faults = FaultInjector::new(
            "arm",
            FaultConfig {
                fail_every_n: 3,
                ..FaultConfig::default()
            },
        );
        let failed: Vec<bool> = (0..9)
            .map(|_| faults.next_fault("move").is_some())
            .collect();
        assert_eq!(
            failed,
            [false, false, true, false, false, true, false, false, true]
        );
    }

    #[test]
    fn random_faults_repeat_with_the_same_seed() {
        let config = FaultConfig {
            fail_probability: 0.3,
            seed: 7,
            ..FaultConfig::default()
        };
        let a = FaultInjector::new("gripper", config.clone());
        let b = FaultInjector::new("gripper", config);
        let run_a: Vec<bool> = (0..200).map(|_| a.next_fault("close").is_some()).collect();
        let run_b: Vec<bool> = (0..200).map(|_| b.next_fault("close").is_some()).collect();
        assert_eq!(run_a, run_b);
        let failures = run_a.iter().filter(|f| **f).count();
        assert!((30..=90).contains(&failures), "{failures} of 200 failed");
    }

    #[test]
    fn no_config_never_fails() {
        let faults = FaultInjector::none("camera");
        assert!((0..1000).all(|_| faults.next_fault("capture").is_none()));
    }
}
