//! Checking a planned motion point by point, and the speed it may run at.
//!
//! The arm actor plans every motion as joint positions (one target, or dense waypoints for a
//! straight tool path). This module follows the tool centre through that plan — joint
//! targets sampled every [`SAMPLE_STEP_RAD`] of the fastest-moving joint — and checks every
//! sample against the [`Fence`]: the tool centre point against the whole fence, and the box
//! of every link (elbow, forearm, wrist, gripper housing, camera) against the floor, the
//! ceiling and the keep-out boxes ([`Fence::check_body`]). Every joint target is checked
//! against its limits minus the margin.
//! So approach, push and retreat points are checked wherever they come from, not just a
//! skill's target.
//!
//! It also predicts the tool's peak speed and acceleration at full speed from the drivers'
//! timing contract ([`crate::control::nominal_travel_time_s`]) and returns the speed scale that
//! keeps both under the caps.

use crate::control::{nominal_travel_time_s, Motion};
use crate::fence::{BodyDepth, Fence, Violation};
use nalgebra::Vector3;
use robotd_kinematics::Kinematics;

/// Largest joint change between two checked samples, radians (≈ 9 mm of tool travel at
/// 0.45 m from the base).
pub const SAMPLE_STEP_RAD: f64 = 0.02;

/// What the check found in a motion that may run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MotionCheck {
    /// Fraction of the joint velocity limits the motion may use (0 < scale ≤ 1).
    pub speed_scale: f64,
    /// Predicted peak tool speed at full speed, m/s.
    pub peak_speed_m_s: f64,
    /// Predicted peak tool acceleration at full speed, m/s².
    pub peak_acceleration_m_s2: f64,
    /// Tool positions checked.
    pub samples: usize,
}

/// The speed and acceleration caps of one origin.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Caps {
    /// m/s.
    pub speed_m_s: f64,
    /// m/s².
    pub acceleration_m_s2: f64,
}

/// Checks `motion` from joints `start`: every joint target within the limits minus
/// `joint_margin_rad`, every sampled tool position inside `fence`; returns the speed scale
/// under `caps`.
///
/// An arm that starts outside the fence (moved by hand, say) may only move back towards it:
/// samples may be outside as long as they are no farther out than the start.
pub fn check_motion(
    kinematics: &Kinematics,
    fence: &Fence,
    joint_margin_rad: f64,
    start: &[f64],
    motion: &Motion,
    caps: Caps,
) -> Result<MotionCheck, Violation> {
    let (targets, smooth): (&[Vec<f64>], bool) = match motion {
        Motion::Joints(target) => (std::slice::from_ref(target), true),
        Motion::JointPath(path) => (path.as_slice(), false),
    };
    if targets.is_empty() {
        return Err(Violation {
            limit: "plan",
            reason: "the motion has no target".into(),
        });
    }
    let limits = kinematics.joint_limits();
    for target in targets {
        check_joints(target, limits, joint_margin_rad)?;
    }
    let velocities: Vec<f64> = limits.iter().map(|l| l.max_velocity_rad_s).collect();
    let tcp = |q: &[f64]| -> Result<Vector3<f64>, Violation> {
        kinematics
            .tool_pose(q)
            .map(|iso| iso.translation.vector)
            .map_err(|e| Violation {
                limit: "kinematics",
                reason: format!("the tool position of a planned joint target is unknown: {e}"),
            })
    };
    let body = |q: &[f64]| {
        kinematics.body(q).map_err(|e| Violation {
            limit: "kinematics",
            reason: format!("the arm's links for a planned joint target are unknown: {e}"),
        })
    };
    let start_tcp = tcp(start)?;
    let start_outside = fence.check(&start_tcp).is_err();
    let start_distance = distance_outside(fence, &start_tcp);
    // An arm whose links are already past the floor or the ceiling may not go deeper.
    let start_depth: BodyDepth = fence.body_depth(&body(start)?);
    let allowed = |p: &Vector3<f64>| -> Result<(), Violation> {
        match fence.check(p) {
            Ok(()) => Ok(()),
            // Moving back towards the fence from outside it.
            Err(v)
                if start_outside
                    && v.limit != "keep_out"
                    && distance_outside(fence, p) <= start_distance + 1e-3 =>
            {
                Ok(())
            }
            Err(v) => Err(v),
        }
    };
    let allowed_at = |q: &[f64]| -> Result<Vector3<f64>, Violation> {
        let (tool, links) = kinematics.tool_and_body(q).map_err(|e| Violation {
            limit: "kinematics",
            reason: format!("the arm's links for a planned joint target are unknown: {e}"),
        })?;
        let p = tool.translation.vector;
        allowed(&p)?;
        fence.check_body(&links, start_depth)?;
        Ok(p)
    };
    // The target first, so a refusal names it rather than the first point on the way there.
    if let Some(target) = targets.last() {
        allowed_at(target)?;
    }
    let mut samples = 0;
    let (mut peak_speed, mut peak_acceleration) = (0.0_f64, 0.0_f64);
    let mut from = start.to_vec();
    let mut previous = start_tcp;
    for target in targets {
        let largest_step = from
            .iter()
            .zip(target)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        let steps = ((largest_step / SAMPLE_STEP_RAD).ceil() as usize).clamp(1, 500);
        let mut length = 0.0;
        for i in 1..=steps {
            let t = i as f64 / steps as f64;
            let q: Vec<f64> = from
                .iter()
                .zip(target)
                .map(|(a, b)| a + (b - a) * t)
                .collect();
            let p = allowed_at(&q)?;
            samples += 1;
            length += (p - previous).norm();
            previous = p;
        }
        let duration = nominal_travel_time_s(&from, target, &velocities);
        if duration > 0.0 {
            if smooth {
                // Cubic profile: peak speed 1.5 L/T, peak acceleration 6 L/T².
                peak_speed = peak_speed.max(1.5 * length / duration);
                peak_acceleration = peak_acceleration.max(6.0 * length / (duration * duration));
            } else {
                peak_speed = peak_speed.max(length / duration);
            }
        }
        from.clone_from(target);
    }
    let mut scale: f64 = 1.0;
    if peak_speed > caps.speed_m_s {
        scale = scale.min(caps.speed_m_s / peak_speed);
    }
    if peak_acceleration > caps.acceleration_m_s2 {
        scale = scale.min((caps.acceleration_m_s2 / peak_acceleration).sqrt());
    }
    Ok(MotionCheck {
        speed_scale: scale.clamp(1e-3, 1.0),
        peak_speed_m_s: peak_speed,
        peak_acceleration_m_s2: peak_acceleration,
        samples,
    })
}

fn check_joints(
    q: &[f64],
    limits: &[robotd_kinematics::JointLimit],
    margin: f64,
) -> Result<(), Violation> {
    if q.len() != limits.len() {
        return Err(Violation {
            limit: "joints",
            reason: format!(
                "{} joint values given; this arm has {}",
                q.len(),
                limits.len()
            ),
        });
    }
    for (joint, (value, limit)) in q.iter().zip(limits).enumerate() {
        let (low, high) = (limit.min_rad + margin, limit.max_rad - margin);
        if !value.is_finite() || *value < low || *value > high {
            return Err(Violation {
                limit: "joint_limit",
                reason: format!(
                    "joint {joint} target {value:.4} rad is outside its limits with the safety margin [{low:.4}, {high:.4}] rad"
                ),
            });
        }
    }
    Ok(())
}

/// How far `p` lies outside the fence's box (0 inside), metres.
fn distance_outside(fence: &Fence, p: &Vector3<f64>) -> f64 {
    let mut d2 = 0.0;
    for axis in 0..3 {
        let below = fence.min[axis] - p[axis];
        let above = p[axis] - fence.max[axis];
        let out = below.max(above).max(0.0);
        d2 += out * out;
    }
    let reach_out = (p.xy().norm() - fence.max_reach_m).max(0.0);
    d2.sqrt().max(reach_out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::SafetyConfig;
    use robotd_kinematics::pose_to_isometry;
    use robotd_protocol::geometry::{Pose, RobotModel};

    const FAST: Caps = Caps {
        speed_m_s: 100.0,
        acceleration_m_s2: 1000.0,
    };

    fn setup() -> (Kinematics, Fence, Vec<f64>) {
        let kin = Kinematics::new(RobotModel::Ned2);
        let fence = Fence::around(
            &[[0.337, 0.087], [0.163, -0.087]],
            &SafetyConfig::default(),
            0.44,
        );
        let start = joints_at(&kin, 0.25, 0.0, 0.15);
        (kin, fence, start)
    }

    fn joints_at(kin: &Kinematics, x: f64, y: f64, z: f64) -> Vec<f64> {
        let pose = Pose::new(x, y, z, 0.0, std::f64::consts::FRAC_PI_2, 0.0);
        kin.inverse(&pose_to_isometry(&pose), None).unwrap()
    }

    #[test]
    fn a_refusal_names_the_target_not_a_point_on_the_way() {
        let (kin, fence, start) = setup();
        let target = joints_at(&kin, 0.25, 0.0, -0.03);
        let v =
            check_motion(&kin, &fence, 0.01, &start, &Motion::Joints(target), FAST).unwrap_err();
        assert_eq!(
            v.reason,
            "the tool centre would go to z -0.030 m, below the table floor 0.000 m"
        );
    }

    #[test]
    fn every_waypoint_is_checked_not_just_the_target() {
        let (kin, fence, start) = setup();
        // Out past the fence's far side and back: the target is fine, the middle is not.
        let out = joints_at(&kin, 0.40, 0.0, 0.15);
        let back = start.clone();
        let path = Motion::JointPath(vec![out, back]);
        let v = check_motion(&kin, &fence, 0.01, &start, &path, FAST).unwrap_err();
        assert_eq!(v.limit, "fence", "{v}");
    }

    #[test]
    fn joint_targets_keep_the_margin() {
        let (kin, fence, start) = setup();
        let mut q = start.clone();
        q[0] = kin.joint_limits()[0].max_rad - 0.001;
        let v = check_motion(&kin, &fence, 0.01, &start, &Motion::Joints(q), FAST).unwrap_err();
        assert_eq!(v.limit, "joint_limit");
        let v = check_motion(
            &kin,
            &fence,
            0.01,
            &start,
            &Motion::Joints(vec![0.0; 3]),
            FAST,
        )
        .unwrap_err();
        assert_eq!(v.reason, "3 joint values given; this arm has 6");
    }

    #[test]
    fn lower_caps_slow_the_motion_down() {
        let (kin, fence, start) = setup();
        let target = joints_at(&kin, 0.18, -0.08, 0.05);
        let motion = Motion::Joints(target);
        let free = check_motion(&kin, &fence, 0.01, &start, &motion, FAST).unwrap();
        assert_eq!(free.speed_scale, 1.0);
        assert!(free.peak_speed_m_s > 0.0 && free.samples > 1);
        let cap = Caps {
            speed_m_s: free.peak_speed_m_s / 4.0,
            acceleration_m_s2: 1000.0,
        };
        let slow = check_motion(&kin, &fence, 0.01, &start, &motion, cap).unwrap();
        assert!((slow.speed_scale - 0.25).abs() < 1e-9, "{slow:?}");
        let cap = Caps {
            speed_m_s: 100.0,
            acceleration_m_s2: free.peak_acceleration_m_s2 / 4.0,
        };
        let gentle = check_motion(&kin, &fence, 0.01, &start, &motion, cap).unwrap();
        assert!((gentle.speed_scale - 0.5).abs() < 1e-9, "{gentle:?}");
    }

    #[test]
    fn a_link_in_a_keep_out_box_is_refused_where_the_tool_centre_is_not() {
        let (kin, mut fence, start) = setup();
        let target = joints_at(&kin, 0.25, 0.05, 0.06);
        let forearm = kin
            .body(&target)
            .unwrap()
            .into_iter()
            .find(|b| &*b.link == "forearm_link")
            .unwrap();
        let c = forearm.pose.translation.vector;
        let tcp = kin.tool_pose(&target).unwrap().translation.vector;
        assert!(
            (c - tcp).norm() > 0.1,
            "the forearm is far from the tool centre"
        );
        fence.keep_out.push(crate::config::KeepOutBox {
            name: "camera mast".into(),
            min: [c.x - 0.005, c.y - 0.005, c.z - 0.005],
            max: [c.x + 0.005, c.y + 0.005, c.z + 0.005],
        });
        assert!(fence.check(&tcp).is_ok());
        let v =
            check_motion(&kin, &fence, 0.01, &start, &Motion::Joints(target), FAST).unwrap_err();
        assert_eq!(v.limit, "keep_out", "{v}");
        assert!(
            v.reason
                .starts_with("the arm's forearm_link would enter the keep-out box 'camera mast'"),
            "{v}"
        );
    }

    #[test]
    fn the_gripper_housing_may_not_dip_into_the_table() {
        // Tool level, 2 cm above the table: the tool centre is fine, the hand and the
        // gripper housing around it reach below the table.
        let (kin, fence, start) = setup();
        let level = Pose::new(0.30, 0.0, 0.02, 0.0, 0.0, 0.0);
        let target = kin.inverse(&pose_to_isometry(&level), None).unwrap();
        assert!(fence
            .check(&kin.tool_pose(&target).unwrap().translation.vector)
            .is_ok());
        let v =
            check_motion(&kin, &fence, 0.01, &start, &Motion::Joints(target), FAST).unwrap_err();
        assert_eq!(v.limit, "floor", "{v}");
        assert!(v.reason.starts_with("the arm's "), "{v}");
        // Pointing down at the same height it is allowed: the fingertips end at the tool
        // centre.
        let down = joints_at(&kin, 0.30, 0.0, 0.02);
        assert!(check_motion(&kin, &fence, 0.01, &start, &Motion::Joints(down), FAST).is_ok());
    }

    #[test]
    fn an_arm_with_a_link_past_the_floor_may_only_rise() {
        let (kin, fence, _) = setup();
        let low = kin
            .inverse(
                &pose_to_isometry(&Pose::new(0.30, 0.0, 0.015, 0.0, 0.0, 0.0)),
                None,
            )
            .unwrap();
        let lower = kin
            .inverse(
                &pose_to_isometry(&Pose::new(0.30, 0.0, 0.005, 0.0, 0.0, 0.0)),
                None,
            )
            .unwrap();
        let up = joints_at(&kin, 0.25, 0.0, 0.15);
        assert!(check_motion(&kin, &fence, 0.01, &low, &Motion::Joints(up), FAST).is_ok());
        assert_eq!(
            check_motion(&kin, &fence, 0.01, &low, &Motion::Joints(lower), FAST)
                .unwrap_err()
                .limit,
            "floor"
        );
    }

    #[test]
    fn an_arm_outside_the_fence_may_only_come_back() {
        let (kin, fence, _) = setup();
        let outside = joints_at(&kin, 0.40, 0.0, 0.15);
        let inside = joints_at(&kin, 0.25, 0.0, 0.15);
        let further = joints_at(&kin, 0.41, 0.0, 0.15);
        assert!(check_motion(&kin, &fence, 0.01, &outside, &Motion::Joints(inside), FAST).is_ok());
        assert!(
            check_motion(&kin, &fence, 0.01, &outside, &Motion::Joints(further), FAST).is_err()
        );
    }
}
