//! The servos' motion, backed by the simulated world.
//!
//! Before every reply the fake advances time: each joint master with torque on moves toward its
//! Goal Position at the servo's top speed; the six joints then move the simulated arm one
//! step through the world ([`SimRobot::step_arm`]), which refuses a step into an object or the
//! table, so the servos stay where they were, as blocked servos do (robotd sees the joint lag
//! behind its goal). The shadows report their master's position. The gripper (PWM mode) moves
//! its fingers in the direction of its Goal PWM until they meet an object or their end, where
//! its Present Load rises.

use crate::servo::Servo;
use robotd_driver_sim::SimRobot;
use robotd_driver_widowx::control_table::{
    rad_to_ticks, ticks_to_rad, GRIPPER_ID, JOINT_IDS, SHADOWS,
};
use robotd_sim::GraspOutcome;
use std::collections::VecDeque;
use std::time::{Duration, Instant};

/// Top speed of an arm servo in the fake, ticks per second (≈ 6 rad/s).
const JOINT_TICKS_PER_S: f64 = 4000.0;
/// Gripper finger travel at full PWM, ticks per second.
const GRIPPER_TICKS_PER_S: f64 = 4000.0;

/// Where the gripper is heading.
#[derive(Debug, Clone, Copy, PartialEq)]
enum FingerMotion {
    Still,
    Closing { stop_at: i32 },
    Opening,
}

/// The servos' physical side.
pub struct FakeWorld {
    sim: SimRobot,
    last: Instant,
    gripper_closed_ticks: i32,
    gripper_open_ticks: i32,
    gripper_max_width_m: f64,
    fingers: FingerMotion,
    /// How late the joints obey goal positions, a stop included (0: at once): an arm that
    /// keeps going a while after it was told to stop, for `robotd commission` to measure.
    stopping_lag: Duration,
    /// Goals written and not yet obeyed, oldest first (only with a lag).
    written: VecDeque<(Instant, Vec<i32>)>,
    /// The goals the joints obey now (only with a lag; empty: where they stand).
    obeyed: Vec<i32>,
}

impl FakeWorld {
    /// Servos as the simulated arm stands now; the gripper's tick range maps linearly onto
    /// the simulated fingers' opening (closed → 0 m, open → widest).
    pub fn new(sim: SimRobot, gripper_closed_ticks: u16, gripper_open_ticks: u16) -> Self {
        Self {
            gripper_max_width_m: robotd_driver_sim::gripper_max_width(sim.kinematics().model()),
            sim,
            last: Instant::now(),
            gripper_closed_ticks: gripper_closed_ticks.into(),
            gripper_open_ticks: gripper_open_ticks.into(),
            fingers: FingerMotion::Still,
            stopping_lag: Duration::ZERO,
            written: VecDeque::new(),
            obeyed: Vec::new(),
        }
    }

    /// Makes the joints obey every goal position `lag` late, a stop included.
    pub fn set_stopping_lag(&mut self, lag: Duration) {
        self.stopping_lag = lag;
        self.written.clear();
        self.obeyed.clear();
    }

    /// The goals the joints follow now: with a lag, the last ones written at least the lag
    /// ago (a delay line), else those written.
    fn lagged_goals(&mut self, written: Vec<i32>, present: &[i32], now: Instant) -> Vec<i32> {
        if self.stopping_lag.is_zero() {
            return written;
        }
        if self.written.back().is_none_or(|(_, last)| *last != written) {
            self.written.push_back((now, written));
        }
        while let Some((at, goals)) = self.written.front() {
            if now.duration_since(*at) < self.stopping_lag {
                break;
            }
            self.obeyed = goals.clone();
            self.written.pop_front();
        }
        if self.obeyed.is_empty() {
            self.obeyed = present.to_vec();
        }
        self.obeyed.clone()
    }

    /// The simulator behind the servos.
    pub fn sim(&self) -> &SimRobot {
        &self.sim
    }

    /// Servos matching the simulated arm's posture.
    pub fn initial_positions(&self) -> Vec<(u8, i32)> {
        let joints = self.sim.joints();
        let mut out: Vec<(u8, i32)> = JOINT_IDS
            .iter()
            .zip(&joints)
            .map(|(id, q)| (*id, rad_to_ticks(*q)))
            .collect();
        for (shadow, master) in SHADOWS {
            let ticks = out
                .iter()
                .find(|(id, _)| *id == master)
                .map_or(2048, |p| p.1);
            out.push((shadow, ticks));
        }
        let width = self.sim.with_world(|w| w.gripper_width_m());
        out.push((GRIPPER_ID, self.width_to_ticks(width)));
        out.sort_by_key(|(id, _)| *id);
        out
    }

    fn width_to_ticks(&self, width_m: f64) -> i32 {
        let span = f64::from(self.gripper_open_ticks - self.gripper_closed_ticks);
        self.gripper_closed_ticks + (width_m / self.gripper_max_width_m * span).round() as i32
    }

    /// Advances the servos to now.
    pub fn advance(&mut self, servos: &mut [Servo]) {
        let now = Instant::now();
        let dt = now.duration_since(self.last).as_secs_f64().min(0.2);
        self.last = now;
        self.advance_arm(servos, dt);
        self.advance_gripper(servos, dt);
    }

    fn advance_arm(&mut self, servos: &mut [Servo], dt: f64) {
        let step = (JOINT_TICKS_PER_S * dt).ceil() as i32;
        let (mut written, mut present) = (Vec::with_capacity(6), Vec::with_capacity(6));
        for id in JOINT_IDS {
            let Some(servo) = servos.iter().find(|s| s.id == id) else {
                return;
            };
            written.push(servo.goal_position());
            present.push(servo.present_position());
        }
        let goals = self.lagged_goals(written, &present, Instant::now());
        let mut next = Vec::with_capacity(6);
        let mut moved = false;
        for (id, goal) in JOINT_IDS.iter().zip(goals) {
            let Some(servo) = servos.iter().find(|s| s.id == *id) else {
                return;
            };
            let here = servo.present_position();
            let to = if servo.torque_on() {
                here + (goal - here).clamp(-step, step)
            } else {
                here
            };
            moved |= to != here;
            next.push(to);
        }
        if !moved {
            return;
        }
        let q: Vec<f64> = next.iter().map(|t| ticks_to_rad(*t)).collect();
        if self.sim.step_arm(&q).is_err() {
            // Blocked: the servos stay where they are.
            return;
        }
        for (id, ticks) in JOINT_IDS.iter().zip(&next) {
            for servo in servos.iter_mut() {
                let follows = SHADOWS.iter().any(|(s, m)| *s == servo.id && m == id);
                if servo.id == *id || (follows && servo.torque_on()) {
                    servo.set_present_position(*ticks);
                }
            }
        }
    }

    fn advance_gripper(&mut self, servos: &mut [Servo], dt: f64) {
        let Some(servo) = servos.iter_mut().find(|s| s.id == GRIPPER_ID) else {
            return;
        };
        let pwm = if servo.torque_on() && servo.operating_mode() == 16 {
            servo.goal_pwm()
        } else {
            0
        };
        let closing_sign = (self.gripper_closed_ticks - self.gripper_open_ticks).signum();
        let direction = i32::from(pwm.signum());
        if pwm == 0 {
            self.fingers = FingerMotion::Still;
        } else if direction == closing_sign {
            if !matches!(self.fingers, FingerMotion::Closing { .. }) {
                let outcome = self.sim.with_world(|w| w.close_gripper());
                let width = match outcome {
                    GraspOutcome::Grasped { .. } => self.sim.with_world(|w| w.gripper_width_m()),
                    _ => 0.0,
                };
                self.fingers = FingerMotion::Closing {
                    stop_at: self.width_to_ticks(width),
                };
            }
        } else if self.fingers != FingerMotion::Opening {
            let max = self.gripper_max_width_m;
            self.sim.with_world(|w| w.open_gripper(max));
            self.fingers = FingerMotion::Opening;
        }
        let target = match self.fingers {
            FingerMotion::Still => servo.present_position(),
            FingerMotion::Closing { stop_at } => stop_at,
            FingerMotion::Opening => self.gripper_open_ticks,
        };
        let speed = GRIPPER_TICKS_PER_S * f64::from(pwm.unsigned_abs()) / 885.0;
        let step = (speed * dt).ceil() as i32;
        let here = servo.present_position();
        let next = here + (target - here).clamp(-step, step);
        servo.set_present_position(next);
        // Pushing against something (an object or the end): load follows the PWM.
        let blocked = pwm != 0 && next == target;
        let load = if blocked {
            (i32::from(pwm) * 1000 / 885) as i16
        } else {
            pwm.signum() * 20
        };
        servo.set_present_load(load);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// With a lag the joints obey a goal only once it is that old; until then the goals
    /// before it (at first: where the joints stand).
    #[test]
    fn a_lag_is_a_delay_line_for_the_goals() {
        let config: robotd_driver::RobotConfig = toml::from_str("driver = \"sim-widowx\"").unwrap();
        let sim = robotd_driver_sim::open(&config).unwrap().robot;
        let mut world = FakeWorld::new(sim, 1600, 2600);
        let t0 = Instant::now();
        let at = |ms: u64| t0 + Duration::from_millis(ms);
        assert_eq!(world.lagged_goals(vec![5; 6], &[1; 6], at(0)), vec![5; 6]);
        world.set_stopping_lag(Duration::from_millis(50));
        let here = [1; 6];
        assert_eq!(world.lagged_goals(vec![7; 6], &here, at(0)), vec![1; 6]);
        assert_eq!(world.lagged_goals(vec![7; 6], &here, at(49)), vec![1; 6]);
        // The stop, written at 60 ms, is not obeyed yet; the goal of 0 ms is.
        assert_eq!(world.lagged_goals(vec![2; 6], &here, at(60)), vec![7; 6]);
        assert_eq!(world.lagged_goals(vec![2; 6], &here, at(109)), vec![7; 6]);
        assert_eq!(world.lagged_goals(vec![2; 6], &here, at(110)), vec![2; 6]);
    }
}
