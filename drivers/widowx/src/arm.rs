//! The WidowX arm driver: robotd's own trajectories streamed to the servos, one goal per tick.
//!
//! A motion is interpolated in joint space (a smooth cubic for a joint motion, linear between
//! the dense waypoints of a straight tool path), timed by the joints' velocity limits and the
//! policy's speed scale, and handed to the bus thread one goal per control tick: where the path
//! is at that moment ([`robotd_driver::TimedPath`]), so a straight path of many short
//! segments takes the time its speed gives it, not a tick per waypoint. At every
//! tick the stop and e-stop are checked (a stop holds the arm where it is at once, within one
//! tick), the servos' positions are compared with what was sent, and a new servo fault ends
//! the motion. X-series servos cannot feel a collision; a joint that lags its goal by more than
//! `tracking_tolerance_rad` for two ticks is one, and the arm is held there. At the end the arm
//! must have arrived within `arrival_tolerance_rad`.

use crate::bus::ServoBus;
use crate::control_table::{rad_to_ticks, ticks_to_rad};
use robotd_driver::{
    ArmDriver, ArmFlags, ArmMotion, Calibration, ClearCollision, DriverError, DriverFuture,
    HardwareInfo, Motion, MotionControl, MotorInfo, Permit,
};
use robotd_kinematics::Kinematics;
use robotd_protocol::geometry::RobotModel;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};

/// How the arm driver moves.
#[derive(Debug, Clone)]
pub struct ArmSettings {
    /// Velocity limit per joint, rad/s.
    pub max_velocity_rad_s: Vec<f64>,
    /// Lag that counts as blocked, rad.
    pub tracking_tolerance_rad: f64,
    /// Allowed final error, rad.
    pub arrival_tolerance_rad: f64,
}

/// How many ticks old the goal is that the servos are compared with.
const LAG_TICKS: usize = 3;
/// How long a joint must lag before it counts as blocked.
const BLOCKED_AFTER: std::time::Duration = std::time::Duration::from_millis(100);
/// Ticks allowed for the servos to settle on the final goal.
const SETTLE_TICKS: u32 = 50;

/// The WidowX arm.
pub struct WidowxArm {
    bus: Arc<ServoBus>,
    kinematics: Kinematics,
    settings: ArmSettings,
    moving: AtomicBool,
    collision: Mutex<Option<String>>,
    halts: AtomicU64,
}

impl WidowxArm {
    /// An arm on `bus`.
    pub fn new(bus: Arc<ServoBus>, settings: ArmSettings) -> Self {
        Self {
            bus,
            kinematics: Kinematics::new(RobotModel::WidowX250),
            settings,
            moving: AtomicBool::new(false),
            collision: Mutex::new(None),
            halts: AtomicU64::new(0),
        }
    }

    fn present(&self) -> Result<Vec<f64>, DriverError> {
        self.bus
            .connection()
            .map_err(|r| DriverError::Hardware(format!("robot not connected: {r}")))?;
        let ticks = self
            .bus
            .snapshot()
            .and_then(|s| s.joint_ticks())
            .ok_or_else(|| {
                DriverError::Hardware("no joint positions from the servos yet".into())
            })?;
        Ok(ticks.iter().map(|t| ticks_to_rad(*t)).collect())
    }

    fn collision_pending(&self) -> bool {
        self.collision.lock().map(|c| c.is_some()).unwrap_or(true)
    }

    fn hold_after(&self, error: DriverError) -> DriverError {
        self.bus.hold();
        error
    }

    async fn run(
        &self,
        motion: Motion,
        speed_scale: f64,
        control: &MotionControl,
    ) -> Result<(), DriverError> {
        robotd_driver::check_speed_scale(speed_scale)?;
        if self.collision_pending() {
            return Err(DriverError::CollisionPending);
        }
        let (waypoints, smooth) = match motion {
            Motion::Joints(q) => (vec![q], true),
            Motion::JointPath(path) => (path, false),
        };
        for q in &waypoints {
            self.kinematics
                .check_joints(q)
                .map_err(|e| DriverError::OutOfRange(e.to_string()))?;
        }
        let Some(target) = waypoints.last().cloned() else {
            return Ok(());
        };
        let halts = self.halts.load(Ordering::SeqCst);
        let faults = self.bus.last_fault().map_or(0, |f| f.generation);
        let velocities = self.settings.max_velocity_rad_s.clone();
        let mut path =
            robotd_driver::TimedPath::new(self.present()?, waypoints, smooth, move |a, b| {
                robotd_driver::nominal_travel_time_s(a, b, &velocities) / speed_scale
            });
        // Goals sent, newest last; the servos are compared with one a few ticks old, so that
        // the bus's own delay is not taken for a blocked joint.
        let mut sent: std::collections::VecDeque<Vec<f64>> = std::collections::VecDeque::new();
        let mut lagging_since: Option<tokio::time::Instant> = None;
        let started = tokio::time::Instant::now();
        loop {
            self.bus.next_tick().await?;
            self.check_interrupts(control, halts, faults)?;
            let present = self.present()?;
            if sent.len() > LAG_TICKS {
                sent.pop_front();
            }
            if let Some(reference) = sent.front() {
                let (joint, lag) = worst(&present, reference);
                if lag <= self.settings.tracking_tolerance_rad {
                    lagging_since = None;
                } else if lagging_since
                    .get_or_insert_with(tokio::time::Instant::now)
                    .elapsed()
                    >= BLOCKED_AFTER
                {
                    return Err(self.blocked(joint, lag));
                }
            }
            // The goal of this tick: where the path is now (waypoints passed within the tick
            // are not sent one by one; time, not the number of waypoints, sets the pace).
            let sample = path.sample(started.elapsed().as_secs_f64());
            self.bus.set_joint_goal(to_ticks(&sample.now));
            sent.push_back(sample.now);
            if sample.finished {
                break;
            }
        }
        let mut blocked_since: Option<tokio::time::Instant> = None;
        for _ in 0..SETTLE_TICKS {
            self.bus.next_tick().await?;
            self.check_interrupts(control, halts, faults)?;
            let (joint, error) = worst(&self.present()?, &target);
            if error <= self.settings.arrival_tolerance_rad {
                return Ok(());
            }
            // Still far from the goal the servos have had for a while: something holds it.
            if error > self.settings.tracking_tolerance_rad
                && blocked_since
                    .get_or_insert_with(tokio::time::Instant::now)
                    .elapsed()
                    >= BLOCKED_AFTER
            {
                return Err(self.blocked(joint, error));
            }
        }
        let (joint, error) = worst(&self.present()?, &target);
        Err(self.hold_after(DriverError::Hardware(format!(
            "the arm did not arrive: joint {} is {error:.3} rad from its target",
            joint + 1
        ))))
    }

    /// Records a blocked joint as a collision and holds the arm.
    fn blocked(&self, joint: usize, lag: f64) -> DriverError {
        let what = format!(
            "an obstacle (joint {} stopped {lag:.2} rad short of its goal)",
            joint + 1
        );
        tracing::warn!(%what, "the WidowX arm is blocked: holding it");
        *self.collision.lock().unwrap_or_else(|p| p.into_inner()) = Some(what.clone());
        self.hold_after(DriverError::Collision { what })
    }

    fn check_interrupts(
        &self,
        control: &MotionControl,
        halts: u64,
        faults: u64,
    ) -> Result<(), DriverError> {
        if let Err(stop) = control.check() {
            return Err(self.hold_after(stop.into()));
        }
        if self.halts.load(Ordering::SeqCst) != halts {
            return Err(DriverError::Stopped {
                reason: "the arm was halted".into(),
            });
        }
        if let Some(fault) = self.bus.last_fault().filter(|f| f.generation != faults) {
            return Err(DriverError::Hardware(fault.to_string()));
        }
        Ok(())
    }
}

/// The joint with the largest |a − b| and that difference.
fn worst(a: &[f64], b: &[f64]) -> (usize, f64) {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .enumerate()
        .fold(
            (0, 0.0),
            |best, (i, d)| if d > best.1 { (i, d) } else { best },
        )
}

fn to_ticks(q: &[f64]) -> [i32; 6] {
    let mut out = [2048; 6];
    for (slot, rad) in out.iter_mut().zip(q) {
        *slot = rad_to_ticks(*rad);
    }
    out
}

impl ArmDriver for WidowxArm {
    fn model(&self) -> RobotModel {
        RobotModel::WidowX250
    }

    fn joints(&self) -> Result<Vec<f64>, DriverError> {
        self.present()
    }

    fn flags(&self) -> ArmFlags {
        ArmFlags {
            moving: self.moving.load(Ordering::SeqCst),
            collision_detected: self.collision_pending(),
            // Absolute encoders: a WidowX never needs calibrating.
            calibrated: true,
        }
    }

    fn execute<'a>(
        &'a self,
        permit: Permit<ArmMotion>,
        control: &'a MotionControl,
    ) -> DriverFuture<'a, ()> {
        let ArmMotion {
            motion,
            speed_scale,
        } = permit.into_act();
        Box::pin(async move {
            self.moving.store(true, Ordering::SeqCst);
            let result = self.run(motion, speed_scale, control).await;
            self.moving.store(false, Ordering::SeqCst);
            result
        })
    }

    fn calibrate(&self, _permit: Permit<Calibration>) -> DriverFuture<'_, ()> {
        Box::pin(async {
            // The servos' encoders are absolute: there is nothing to calibrate, only to check.
            self.present().map(|_| ())
        })
    }

    fn clear_collision(&self, _permit: Permit<ClearCollision>) -> DriverFuture<'_, ()> {
        Box::pin(async {
            *self.collision.lock().unwrap_or_else(|p| p.into_inner()) = None;
            Ok(())
        })
    }

    fn halt(&self) -> Result<(), DriverError> {
        self.halts.fetch_add(1, Ordering::SeqCst);
        self.bus.hold();
        Ok(())
    }

    fn connection(&self) -> Result<(), String> {
        self.bus.connection()
    }

    fn hardware_info(&self) -> DriverFuture<'_, HardwareInfo> {
        Box::pin(async move {
            let motors = self.bus.call(read_versions).await?;
            Ok(HardwareInfo {
                hardware_version: None,
                software_version: None,
                motors,
                // The gripper is the ninth servo, listed with the motors.
                tool: None,
                not_reported: vec![
                    "hardware and software versions: a WidowX is servos on a bus, each reports \
                     its own model and firmware only"
                        .into(),
                ],
            })
        })
    }
}

/// Each servo's Model Number (address 0) and Firmware Version (address 6), in ID order.
fn read_versions(bus: &mut crate::DxlBus) -> Result<Vec<MotorInfo>, String> {
    use crate::control_table::{address, model_name, servo_name, ALL_IDS};
    ALL_IDS
        .iter()
        .map(|&id| {
            let what = || format!("servo {id} ({})", servo_name(id));
            let model = bus
                .read_u16(id, address::MODEL_NUMBER)
                .map_err(|e| format!("reading {}'s model number: {e}", what()))?
                .data;
            let firmware = bus
                .read_u8(id, address::FIRMWARE_VERSION)
                .map_err(|e| format!("reading {}'s firmware version: {e}", what()))?
                .data;
            Ok(MotorInfo {
                name: format!("{id} {}", servo_name(id)),
                model: format!("{} ({model})", model_name(model)),
                firmware: Some(firmware.to_string()),
            })
        })
        .collect()
}
