//! The WidowX gripper (servo 9 in PWM mode): a grasp that stops on contact and knows whether it
//! holds something.
//!
//! Closing drives the fingers with `gripper_pwm` until they stop moving: still for a few ticks
//! while pushing (Present Load at least `gripper_holding_load`), or still for
//! 300 ms whatever the load. Stopped short of
//! closed with a Present Load of at least `gripper_holding_load` means an object is between
//! them: the PWM drops to `gripper_hold_pwm`, enough to hold it without overheating the servo.
//! Stopped at closed means nothing was caught: the PWM goes to 0. Opening drives them the
//! other way until they reach open (or stop), then the PWM goes to 0. Finger width is linear in
//! the servo's ticks between `gripper_closed_ticks` (0 m) and `gripper_open_ticks` (widest).

use crate::bus::ServoBus;
use crate::control_table::{address, GRIPPER_ID};
use robotd_driver::{
    Close, CloseStop, DriverError, DriverFuture, GripperDriver, GripperStatus, Open, Permit,
    SetWidth,
};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

/// How the gripper moves.
#[derive(Debug, Clone)]
pub struct GripperSettings {
    /// Ticks with the fingers closed.
    pub closed_ticks: i32,
    /// Ticks with the fingers open.
    pub open_ticks: i32,
    /// PWM while moving.
    pub pwm: i16,
    /// PWM while holding an object.
    pub hold_pwm: i16,
    /// Load that counts as holding.
    pub holding_load: i16,
    /// Widest opening, metres.
    pub max_width_m: f64,
}

/// Ticks from an end that count as being there.
const AT_END_TICKS: i32 = 25;
/// Ticks without movement after which the fingers may have stopped.
const STILL_TICKS: u32 = 4;
/// How long the fingers must stay still to count as stopped when the servo does not push
/// (a load under `gripper_holding_load`): a few ticks without movement and without load can
/// also be a servo that has not started yet, or a late position on a busy bus.
const STILL_WITHOUT_LOAD: Duration = Duration::from_millis(300);
/// Longest a finger motion may take.
const MOTION_DEADLINE: Duration = Duration::from_secs(3);

/// The WidowX gripper.
pub struct WidowxGripper {
    bus: Arc<ServoBus>,
    settings: GripperSettings,
    holding: AtomicBool,
    last_close: Mutex<Option<CloseStop>>,
}

impl WidowxGripper {
    /// A gripper on `bus`.
    pub fn new(bus: Arc<ServoBus>, settings: GripperSettings) -> Self {
        Self {
            bus,
            settings,
            holding: AtomicBool::new(false),
            last_close: Mutex::new(None),
        }
    }

    fn closing_sign(&self) -> i16 {
        if self.settings.closed_ticks < self.settings.open_ticks {
            -1
        } else {
            1
        }
    }

    fn width_m(&self, ticks: i32) -> f64 {
        let s = &self.settings;
        let fraction = f64::from(ticks - s.closed_ticks) / f64::from(s.open_ticks - s.closed_ticks);
        (fraction * s.max_width_m).clamp(0.0, s.max_width_m)
    }

    fn ticks_now(&self) -> Result<i32, DriverError> {
        self.bus
            .connection()
            .map_err(|r| DriverError::Hardware(format!("robot not connected: {r}")))?;
        self.bus
            .snapshot()
            .and_then(|s| s.gripper_ticks())
            .ok_or_else(|| DriverError::Hardware("no position from the gripper servo yet".into()))
    }

    fn status_now(&self) -> Result<GripperStatus, DriverError> {
        Ok(GripperStatus {
            holding: self.holding.load(Ordering::SeqCst),
            width_m: self.width_m(self.ticks_now()?),
        })
    }

    /// Drives the fingers with `pwm` until they reach `end` or stop; the ticks they stopped at.
    async fn drive(&self, pwm: i16, end: i32) -> Result<i32, DriverError> {
        self.bus.set_gripper_pwm(pwm);
        let deadline = tokio::time::Instant::now() + MOTION_DEADLINE;
        let mut last = self.ticks_now()?;
        let mut still = 0;
        let mut still_since = tokio::time::Instant::now();
        while tokio::time::Instant::now() < deadline {
            self.bus.next_tick().await?;
            let now = self.ticks_now()?;
            if (now - end).abs() <= AT_END_TICKS {
                return Ok(now);
            }
            if (now - last).abs() <= 1 {
                still += 1;
            } else {
                still = 0;
                still_since = tokio::time::Instant::now();
            }
            if still >= STILL_TICKS
                && (still_since.elapsed() >= STILL_WITHOUT_LOAD
                    || self.present_load().await?.unsigned_abs()
                        >= self.settings.holding_load.unsigned_abs())
            {
                return Ok(now);
            }
            last = now;
        }
        self.bus.set_gripper_pwm(0);
        Err(DriverError::Hardware(format!(
            "the gripper did not stop within {} s",
            MOTION_DEADLINE.as_secs()
        )))
    }

    async fn present_load(&self) -> Result<i16, DriverError> {
        self.bus
            .call(|bus| {
                bus.read_u16(GRIPPER_ID, address::PRESENT_LOAD)
                    .map(|r| r.data as i16)
                    .map_err(|e| format!("reading the gripper's load: {e}"))
            })
            .await
    }
}

impl GripperDriver for WidowxGripper {
    fn max_width_m(&self) -> f64 {
        self.settings.max_width_m
    }

    fn open(&self, _permit: Permit<Open>) -> DriverFuture<'_, GripperStatus> {
        Box::pin(async move {
            let pwm = -self.closing_sign() * self.settings.pwm;
            let result = self.drive(pwm, self.settings.open_ticks).await;
            self.bus.set_gripper_pwm(0);
            self.holding.store(false, Ordering::SeqCst);
            result?;
            self.status_now()
        })
    }

    fn close(&self, _permit: Permit<Close>) -> DriverFuture<'_, GripperStatus> {
        Box::pin(async move {
            let pwm = self.closing_sign() * self.settings.pwm;
            let stopped_at = self.drive(pwm, self.settings.closed_ticks).await?;
            let short_of_closed = (stopped_at - self.settings.closed_ticks).abs() > AT_END_TICKS;
            // Read at every stop (not only short of closed): commissioning derives the
            // threshold from the load at the closed stop.
            let load = self.present_load().await?.unsigned_abs();
            let holding = short_of_closed && load >= self.settings.holding_load.unsigned_abs();
            *self.last_close.lock().unwrap_or_else(|p| p.into_inner()) = Some(CloseStop {
                ticks: stopped_at,
                load,
                pwm: self.settings.pwm.unsigned_abs(),
                holding,
            });
            let keep = if holding {
                self.closing_sign() * self.settings.hold_pwm
            } else {
                0
            };
            self.bus.set_gripper_pwm(keep);
            self.holding.store(holding, Ordering::SeqCst);
            self.status_now()
        })
    }

    fn set_width(&self, permit: Permit<SetWidth>) -> DriverFuture<'_, GripperStatus> {
        let width_m = permit.act().width_m;
        Box::pin(async move {
            Err(DriverError::Hardware(format!(
                "the WidowX gripper runs in PWM mode (so it can squeeze an object): it opens and \
                 closes, it cannot go to {width_m:.3} m"
            )))
        })
    }

    fn status(&self) -> Result<GripperStatus, DriverError> {
        self.status_now()
    }

    fn last_close(&self) -> Result<CloseStop, DriverError> {
        self.last_close
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .ok_or_else(|| DriverError::Hardware("the gripper has not closed yet".into()))
    }
}
