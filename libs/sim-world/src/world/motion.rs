//! Moving the tool: [`World::move_tool`] cuts a straight-line motion (and shortest rotation)
//! into sub-steps of at most [`SUB_STEP_M`] and decides at each one whether the gripper moves
//! freely, pushes what it ran into, or is blocked.
//!
//! A blocked motion is refined by bisection to the last free pose and reports what it hit in
//! a [`StepOutcome`]; a push hands over to [`push`](super::push). The contact measurements come
//! from [`contact`](super::contact).

use super::contact::{Contact, Hit, Probe};
use super::shapes::{extent_along, isometry_finite};
use super::{ToolState, World};
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};

/// Longest sub-step of a tool motion, metres (also for points 0.1 m from the TCP when the
/// tool turns).
pub const SUB_STEP_M: f64 = 0.001;

/// Lever arm used to turn a rotation into a sub-step length, metres.
const LEVER_M: f64 = 0.1;

/// Upper bound on the sub-steps of one motion (100 m of travel).
const MAX_SUB_STEPS: f64 = 100_000.0;

/// A sub-step pushes (rather than collides) when |dz| ≤ this × its horizontal length.
const PUSH_MAX_SLOPE: f64 = 0.5;

/// What happened during one [`World::move_tool`].
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct StepOutcome {
    /// Set when the motion stopped at a collision: `"table"` or the object's label.
    pub collision: Option<String>,
    /// Ids of the objects pushed during the motion (each once).
    pub pushed: Vec<u32>,
}

impl StepOutcome {
    /// The collision as a [`Contact`], if there was one.
    pub fn contact(&self) -> Option<Contact> {
        self.collision
            .as_ref()
            .map(|what| Contact::Collision { what: what.clone() })
    }
}

/// What one sub-step of a motion does.
enum Step {
    Free(Probe),
    Pushed(Vec<Isometry3<f64>>, Vec<usize>, Probe),
    Blocked(String),
}

impl World {
    /// Moves the tool in a straight line (and a shortest rotation) from where it is to
    /// `to.tcp`, in sub-steps of at most 1 mm (also at 0.1 m from the TCP when it turns).
    ///
    /// At each sub-step:
    /// - a finger or the palm that would sink into the table, or a carried object that would
    ///   sink more than [`HELD_TOLERANCE_M`](super::HELD_TOLERANCE_M) into the table or another
    ///   object, stops the motion: the tool stays at the last free position (refined to within
    ///   ~0.01 mm of the contact) and the outcome names what was hit;
    /// - a finger or the palm that would enter an object either **pushes** it — when the
    ///   gripper is empty, the sub-step is mostly horizontal (|dz| ≤ 0.5 × horizontal travel)
    ///   and the object is wider along the closing axis than the opening (it cannot slip
    ///   between the fingers; always so for a closed gripper) — or else is a collision, as
    ///   above;
    /// - a pushed object is shoved along the step's horizontal direction just far enough to
    ///   clear the gripper (so it travels the remaining distance of the push, without
    ///   turning); whatever stands on it or inside it moves along; an object it then runs
    ///   into is shoved the same way, and so on; objects that lost their support drop;
    /// - a held object follows the tool rigidly.
    ///
    /// Contacts only count when they get deeper, so a tool that starts inside something (after
    /// [`set_tool`](Self::set_tool)) can move out of it. `to.opening_m` is ignored: the fingers
    /// move only through [`close_gripper`](Self::close_gripper) and
    /// [`open_gripper`](Self::open_gripper). A non-finite target does nothing.
    ///
    /// Returns the state reached and what happened.
    pub fn move_tool(&mut self, to: &ToolState) -> (ToolState, StepOutcome) {
        let mut outcome = StepOutcome::default();
        if !isometry_finite(&to.tcp) {
            return (self.tool, outcome);
        }
        let start = self.tool.tcp;
        let dist = (to.tcp.translation.vector - start.translation.vector).norm();
        let angle = start.rotation.angle_to(&to.tcp.rotation);
        let n = (dist.max(angle * LEVER_M) / SUB_STEP_M)
            .ceil()
            .clamp(1.0, MAX_SUB_STEPS) as usize;
        let mut poses = self.poses();
        let mut before = self.probe(&start, &poses);
        let mut prev = start;
        for i in 1..=n {
            let next = interpolate(&start, &to.tcp, i as f64 / n as f64);
            match self.step(&prev, &next, &before, &poses) {
                Step::Free(after) => {
                    before = after;
                    prev = next;
                }
                Step::Pushed(new_poses, moved, after) => {
                    poses = new_poses;
                    for (o, p) in self.objects.iter_mut().zip(&poses) {
                        o.pose = *p;
                    }
                    for i in moved {
                        let id = self.objects[i].id;
                        if !outcome.pushed.contains(&id) {
                            outcome.pushed.push(id);
                        }
                    }
                    before = after;
                    prev = next;
                }
                Step::Blocked(what) => {
                    let (mut lo, mut hi) = (0.0, 1.0);
                    for _ in 0..10 {
                        let mid = (lo + hi) / 2.0;
                        let probe = self.probe(&interpolate(&prev, &next, mid), &poses);
                        if self.hits(&before, &probe).is_empty() {
                            lo = mid;
                        } else {
                            hi = mid;
                        }
                    }
                    prev = interpolate(&prev, &next, lo);
                    outcome.collision = Some(what);
                    break;
                }
            }
        }
        self.tool.tcp = prev;
        self.update_held_pose();
        (self.tool, outcome)
    }

    /// One sub-step from `prev` to `next`: free, pushing the objects the gripper ran into
    /// (new object poses, moved indices, contacts after the push), or blocked (by what).
    fn step(
        &self,
        prev: &Isometry3<f64>,
        next: &Isometry3<f64>,
        before: &Probe,
        poses: &[Isometry3<f64>],
    ) -> Step {
        let after = self.probe(next, poses);
        let hits = self.hits(before, &after);
        if hits.is_empty() {
            return Step::Free(after);
        }
        let d = next.translation.vector - prev.translation.vector;
        let horizontal = Vector3::new(d.x, d.y, 0.0);
        let run = horizontal.norm();
        let can_push = self.held.is_none() && run > 1e-9 && d.z.abs() <= PUSH_MAX_SLOPE * run;
        let closing = next.rotation * Vector3::y();
        let mut pushed = Vec::new();
        for hit in &hits {
            match *hit {
                Hit::Table => return Step::Blocked("table".to_owned()),
                Hit::Held(i) => return Step::Blocked(self.objects[i].spec.label.clone()),
                Hit::Grip(i) => {
                    let o = &self.objects[i];
                    let across = extent_along(&o.spec.shape, &poses[i].rotation, &closing);
                    if !can_push || self.tool.opening_m >= across {
                        return Step::Blocked(o.spec.label.clone());
                    }
                    pushed.push(i);
                }
            }
        }
        let dir = horizontal / run;
        match self.push(next, &pushed, &dir, run, poses) {
            Ok((new_poses, moved)) => {
                let after = self.probe(next, &new_poses);
                match self.hits(before, &after).first() {
                    None => Step::Pushed(new_poses, moved, after),
                    Some(Hit::Table) => Step::Blocked("table".to_owned()),
                    Some(Hit::Grip(i) | Hit::Held(i)) => {
                        Step::Blocked(self.objects[*i].spec.label.clone())
                    }
                }
            }
            Err(label) => Step::Blocked(label),
        }
    }
}

/// Straight-line position and shortest-path rotation between `a` and `b` at `t` ∈ [0, 1].
fn interpolate(a: &Isometry3<f64>, b: &Isometry3<f64>, t: f64) -> Isometry3<f64> {
    let position = a.translation.vector.lerp(&b.translation.vector, t);
    let delta = a.rotation.inverse() * b.rotation;
    let rotation = match delta.axis_angle() {
        Some((axis, angle)) => a.rotation * UnitQuaternion::from_axis_angle(&axis, angle * t),
        None => a.rotation,
    };
    Isometry3::from_parts(Translation3::from(position), rotation)
}
