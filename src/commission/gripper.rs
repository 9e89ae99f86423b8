//! The gripper step of `robotd commission`: where the WidowX gripper's mechanical stops are, in
//! servo ticks (`robot.widowx.gripper_closed_ticks` and `gripper_open_ticks`, whose defaults
//! are a guess).
//!
//! For the whole commissioning run the driver is started with the configured tick range
//! widened by [`WIDEN_TICKS`] on each side and a low PWM (at most [`LOW_PWM`]): opening and
//! closing then drive the fingers until they stall at the real stops instead of stopping at
//! the configured ends, and the width the driver reports there, read back through the widened
//! range, is the stop's tick. The step opens, closes on nothing (the fingers must be empty)
//! and opens again, each through `gripper/command` from the origin `cli`, admitted by the
//! motion policy; it leaves the gripper open.
//!
//! **Grasp threshold.** The driver says "holding something" when the fingers stopped more than
//! 25 ticks short of closed with a Present Load of at least `robot.widowx.gripper_holding_load`
//! (`drivers/widowx/src/gripper.rs`). On the empty close the driver reads the load at the
//! closed stop: the servo stalled there at the commissioning PWM, as it stalls on an object.
//! A stalled motor's load follows its drive, so the stall load at the configured
//! `gripper_pwm` is that load × `gripper_pwm` / the commissioning PWM; the threshold is half
//! of it: well under what fingers stalled on an object report, well over the few percent of
//! fingers that move freely. (The load while moving freely is not measured.)
//!
//! Attached to a robotd that was already running, the step is refused before anything moves:
//! that robotd holds the gripper to its configured range.
//!
//! The Ned2's TCP protocol reports no finger position: its gripper step is `ned2_tool.rs`.

use super::session::Session;
use anyhow::{bail, Result};
use robotd_config::Config;
use robotd_protocol::geometry::RobotModel;
use robotd_protocol::gripper::{GripperCommand, GripperReply};
use serde::Serialize;

/// How far past each configured end the driver may drive the fingers while commissioning.
pub const WIDEN_TICKS: i32 = 400;

/// The PWM the fingers are driven with while commissioning (of 885).
pub const LOW_PWM: u16 = 250;

/// What the gripper step measured.
#[derive(Debug, Clone, Serialize)]
pub struct GripperReport {
    /// Ticks at the closed stop.
    pub closed_ticks: i32,
    /// Ticks at the open stop.
    pub open_ticks: i32,
    /// The configured closed ticks.
    pub configured_closed_ticks: u16,
    /// The configured open ticks.
    pub configured_open_ticks: u16,
    /// Present Load (0.1 % units) at the closed stop on the empty close.
    pub empty_close_load: u16,
    /// The PWM the empty close drove the fingers with.
    pub empty_close_pwm: u16,
    /// The derived `gripper_holding_load`: half the stall load at the configured PWM.
    pub holding_load: u16,
    /// The configured `gripper_holding_load`.
    pub configured_holding_load: u16,
}

/// The load below which a stall at the closed stop is no measurement: the fingers did not
/// push there (the driver gave up after 300 ms still without load).
const MIN_STALL_LOAD: u16 = 20;

/// `gripper_holding_load` from the load `load` at the closed stop when driven with `pwm`:
/// half of the stall load at the operating PWM `operating_pwm`, within 1..=1000.
pub fn holding_threshold(load: u16, pwm: u16, operating_pwm: u16) -> u16 {
    let stall = f64::from(load) * f64::from(operating_pwm) / f64::from(pwm.max(1));
    (stall / 2.0).round().clamp(1.0, 1000.0) as u16
}

/// The tick range the driver runs with while commissioning: the configured one widened.
pub fn widened(closed: u16, open: u16) -> (u16, u16) {
    let (closed, open) = (i32::from(closed), i32::from(open));
    let sign = (open - closed).signum();
    let clamp = |t: i32| t.clamp(0, 4095) as u16;
    (
        clamp(closed - sign * WIDEN_TICKS),
        clamp(open + sign * WIDEN_TICKS),
    )
}

/// Runs the step on a WidowX.
pub async fn run(session: &Session, config: &Config) -> Result<GripperReport> {
    if config.robot.model() != RobotModel::WidowX250 {
        bail!(
            "the gripper's ticks are a WidowX's; this robot is a {:?}",
            config.robot.model()
        );
    }
    if session.attached() {
        bail!(super::session::ATTACHED_GRIPPER);
    }
    let widowx = &config.robot.widowx;
    let (closed_w, open_w) = widened(widowx.gripper_closed_ticks, widowx.gripper_open_ticks);
    let max = robotd_driver::hardware::gripper_max_width(RobotModel::WidowX250);
    let ticks = |width_m: f64| {
        (f64::from(closed_w) + width_m / max * (f64::from(open_w) - f64::from(closed_w))).round()
            as i32
    };
    let width = |reply: GripperReply, what: &str| -> Result<f64> {
        match reply {
            GripperReply::State { width_m, .. } => Ok(width_m),
            GripperReply::Error { error } => bail!("{what}: {error}"),
        }
    };
    let open = width(session.gripper(GripperCommand::Open).await?, "opening")?;
    let closed = width(session.gripper(GripperCommand::Close).await?, "closing")?;
    let stop = session
        .last_close()
        .map_err(|e| anyhow::anyhow!("the load at the closed stop: {e}"))?;
    if stop.load < MIN_STALL_LOAD {
        bail!(
            "the fingers stopped at the closed stop with a load of {} (0.1 %), under {}: they \
             did not push there, so no grasp threshold can be derived",
            stop.load,
            MIN_STALL_LOAD
        );
    }
    width(
        session.gripper(GripperCommand::Open).await?,
        "opening again",
    )?;
    let (closed_ticks, open_ticks) = (ticks(closed), ticks(open));
    let at_limit = |t: i32| t == i32::from(closed_w) || t == i32::from(open_w);
    if at_limit(closed_ticks) || at_limit(open_ticks) {
        bail!(
            "the fingers reached the widened range's end ({closed_w}..{open_w} ticks) without \
             stalling: the configured ticks are more than {WIDEN_TICKS} ticks off, or the \
             servo is not the gripper; nothing was measured"
        );
    }
    if (open_ticks - closed_ticks).abs() < 200 {
        bail!(
            "the fingers moved only {} ticks between closed and open: is something between \
             them? The gripper step closes on nothing",
            (open_ticks - closed_ticks).abs()
        );
    }
    Ok(GripperReport {
        closed_ticks,
        open_ticks,
        configured_closed_ticks: widowx.gripper_closed_ticks,
        configured_open_ticks: widowx.gripper_open_ticks,
        empty_close_load: stop.load,
        empty_close_pwm: stop.pwm,
        holding_load: holding_threshold(stop.load, stop.pwm, widowx.gripper_pwm),
        configured_holding_load: widowx.gripper_holding_load,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_range_widens_outwards_either_way_round() {
        assert_eq!(widened(1600, 2600), (1200, 3000));
        assert_eq!(widened(2600, 1600), (3000, 1200));
        assert_eq!(widened(100, 4000), (0, 4095));
    }

    #[test]
    fn the_threshold_is_half_the_stall_load_at_the_operating_pwm() {
        // Stalled with 282 at PWM 250: 395 at PWM 350, so 197.
        assert_eq!(holding_threshold(282, 250, 350), 197);
        assert_eq!(holding_threshold(300, 300, 300), 150);
        assert_eq!(holding_threshold(1000, 100, 885), 1000);
        assert_eq!(holding_threshold(1, 885, 100), 1);
    }
}
