//! For tests of drivers (feature `testing`, enabled only by dev-dependencies): a real policy
//! with limits wide enough for a driver's own tests, and the few lines that turn a command
//! into a permit through it.
//!
//! A driver's tests call its actuator methods directly (a motion into the table to see the
//! collision, a target near a joint's end), so they need permits the production limits would
//! refuse. They still get them from the policy — [`Safety::admit`] then the `permit_*` call,
//! e-stop included — only under a configuration no robotd configuration file can set (the
//! loader bounds every limit). The feature is off in every build that is not a test.

use crate::control::{Motion, MotionControl};
use crate::permit::{ArmMotion, Calibration, ClearCollision, GripperAct, Permit};
use crate::{AuditLog, Safety, SafetyConfig};
use robotd_kinematics::Kinematics;
use robotd_protocol::safety::{Origin, OriginKind};
use robotd_protocol::RobotModel;

/// Limits wide enough for any motion a driver test makes: fence, floor, ceiling and reach
/// 10 m away, no joint margin, no rate limit, no approval; speed caps at `speed_m_s` (m/s and
/// ten times that in m/s²).
pub fn wide_config(speed_m_s: f64) -> SafetyConfig {
    SafetyConfig {
        fence_margin_m: 10.0,
        floor_z_m: -10.0,
        ceiling_z_m: 10.0,
        max_reach_m: 10.0,
        joint_margin_rad: 0.0,
        max_tcp_speed_m_s: speed_m_s,
        llm_max_tcp_speed_m_s: speed_m_s,
        max_tcp_acceleration_m_s2: speed_m_s * 10.0,
        llm_max_tcp_acceleration_m_s2: speed_m_s * 10.0,
        motions_per_minute: 0,
        llm_motions_per_minute: 0,
        ..SafetyConfig::default()
    }
}

/// A policy for `model` with [`wide_config`] at 100 m/s (so motions run at full speed), on
/// its own stop signals, without an audit log.
pub fn wide_policy(model: RobotModel) -> Safety {
    policy(model, wide_config(100.0), MotionControl::default())
}

/// A policy for `model` with `config`, on `control`, without an audit log.
pub fn policy(model: RobotModel, config: SafetyConfig, control: MotionControl) -> Safety {
    Safety::new(
        config,
        Kinematics::new(model),
        control,
        &[],
        AuditLog::disabled(),
    )
}

fn origin() -> Origin {
    Origin::new(OriginKind::Internal).session("driver test")
}

/// The permit for `motion` from joints `start`; panics when the policy refuses it.
pub async fn motion(policy: &Safety, start: &[f64], motion: Motion) -> Permit<ArmMotion> {
    let admission = policy
        .admit(&origin(), "arm", "test_motion", serde_json::Value::Null)
        .await
        .expect("the test policy admits the motion");
    policy
        .permit_motion(&admission, start, motion)
        .expect("the test policy permits the motion")
}

/// The permit for a calibration from joints `start`; panics when the policy refuses it.
pub async fn calibration(policy: &Safety, start: &[f64]) -> Permit<Calibration> {
    let admission = policy
        .admit(&origin(), "arm", "test_calibrate", serde_json::Value::Null)
        .await
        .expect("the test policy admits the calibration");
    policy
        .permit_calibration(&admission, start)
        .expect("the test policy permits the calibration")
}

/// The permit for clearing the collision flag.
pub async fn clear_collision(policy: &Safety) -> Permit<ClearCollision> {
    let admission = policy
        .admit_clear_collision(&origin(), serde_json::Value::Null)
        .await
        .expect("the test policy admits clearing the collision flag");
    policy
        .permit_clear_collision(&admission)
        .expect("the test policy permits clearing the collision flag")
}

/// The permit for a gripper act; panics when the policy refuses it.
pub async fn gripper<A: GripperAct>(policy: &Safety, act: A) -> Permit<A> {
    let admission = policy
        .admit(
            &origin(),
            "gripper",
            "test_gripper",
            serde_json::Value::Null,
        )
        .await
        .expect("the test policy admits the gripper act");
    policy
        .permit_gripper(&admission, act)
        .expect("the test policy permits the gripper act")
}
