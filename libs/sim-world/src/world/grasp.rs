//! Grasping and releasing: [`World::close_gripper`] and [`World::open_gripper`].
//!
//! Closing grasps an object only when it is really between the fingers — reached into by at
//! least [`GRASP_MIN_ENGAGEMENT_M`], centred within [`GRASP_CENTRE_TOLERANCE_M`], the jaw within
//! [`GRASP_ANGLE_TOLERANCE_DEG`] of a side that fits the opening (`grip_axis`); otherwise the
//! fingers close on nothing and the [`GraspOutcome`] says why, naming the nearest object.
//! Opening stalls against objects in the way (`free_opening`) and, past the held object's
//! width, releases it: it drops straight down ([`rest_height`](World::rest_height)).

use super::shapes::{extent_along, object_hulls, upright_yaw};
use super::{Held, World};
use crate::geom::Hull;
use crate::scene::ObjectShape;
use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector2, Vector3};
use std::f64::consts::{FRAC_PI_2, PI};

/// An object's centre must be this close to the TCP (perpendicular to the tool axis) to be
/// grasped.
pub const GRASP_CENTRE_TOLERANCE_M: f64 = 0.005;

/// The closing axis must be within this angle of the object's side to grasp, degrees.
pub const GRASP_ANGLE_TOLERANCE_DEG: f64 = 15.0;

/// The fingers must reach this far into an object along the tool axis (or 30 % of its extent,
/// if less) to grasp it.
pub const GRASP_MIN_ENGAGEMENT_M: f64 = 0.003;

/// What [`World::close_gripper`] got.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum GraspOutcome {
    /// The object is now held; the fingers rest on it.
    Grasped {
        /// The object's id.
        id: u32,
        /// The object's label.
        label: String,
    },
    /// Nothing was grasped; the fingers closed fully.
    Empty {
        /// Why, e.g. "no object between the fingers".
        reason: String,
    },
}

impl World {
    /// Closes the fingers. An object is grasped only if it is really between them:
    /// - the fingers reach into it along the tool axis by at least [`GRASP_MIN_ENGAGEMENT_M`]
    ///   (or 30 % of its extent, if less) — i.e. the TCP is inside its vertical extent, not
    ///   above it;
    /// - its centre is within [`GRASP_CENTRE_TOLERANCE_M`] of the TCP, measured perpendicular
    ///   to the tool axis;
    /// - the closing axis is within [`GRASP_ANGLE_TOLERANCE_DEG`] of one of its sides that fits
    ///   in the current opening (for a box: across its short side, or across a longer side
    ///   that also fits; a cylinder at any angle), and that side is no wider than the opening.
    ///
    /// On success the object is held and the fingers stop on it (the opening becomes its
    /// width); the fingers square it up (turn it by up to 15° about the vertical so its side is
    /// across the jaw) and centre it between them. Otherwise the fingers close fully (opening
    /// 0) and the reason names the nearest object and what was wrong. Closing while already
    /// holding something keeps holding it.
    pub fn close_gripper(&mut self) -> GraspOutcome {
        if let Some(h) = self.held {
            let label = self
                .object(h.id)
                .map(|o| o.spec.label.clone())
                .unwrap_or_default();
            return GraspOutcome::Grasped { id: h.id, label };
        }
        let tcp = self.tool.tcp;
        let opening = self.tool.opening_m;
        let inv = tcp.inverse();
        let tool_axis = tcp.rotation * Vector3::x();
        let closing = tcp.rotation * Vector3::y();
        // (score, reason) of the best failure; (distance, index, width, gripped axis) of the best success.
        let mut failure: Option<(f64, String)> = None;
        let mut success: Option<(f64, usize, f64, Vector3<f64>)> = None;
        for (i, o) in self.objects.iter().enumerate() {
            let label = &o.spec.label;
            let c = inv * Point3::from(o.pose.translation.vector);
            let perp = c.y.hypot(c.z);
            if perp > 0.03 {
                continue;
            }
            let e = extent_along(&o.spec.shape, &o.pose.rotation, &tool_axis) / 2.0;
            let (lo, hi) = (c.x - e, c.x + e);
            let engaged = hi.min(0.0) - lo.max(-self.gripper.finger_length_m);
            let need = GRASP_MIN_ENGAGEMENT_M.min(0.3 * 2.0 * e);
            let mut fail = |score: f64, reason: String| {
                if failure.as_ref().is_none_or(|(s, _)| score < *s) {
                    failure = Some((score, reason));
                }
            };
            if engaged < need {
                let reason = if lo > 0.0 {
                    format!(
                        "the fingertips are {:.1} mm short of '{label}' (above its top)",
                        lo * 1000.0
                    )
                } else if hi < -self.gripper.finger_length_m {
                    format!("'{label}' is behind the fingers")
                } else {
                    format!(
                        "the fingers reach only {:.1} mm into '{label}' (at least {:.1} mm needed)",
                        engaged.max(0.0) * 1000.0,
                        need * 1000.0
                    )
                };
                fail(perp + (need - engaged), reason);
                continue;
            }
            if perp > GRASP_CENTRE_TOLERANCE_M {
                fail(
                    perp,
                    format!(
                        "'{label}' is not centred between the fingers: its centre is {:.1} mm \
                         from the tool centre (at most {:.1} mm)",
                        perp * 1000.0,
                        GRASP_CENTRE_TOLERANCE_M * 1000.0
                    ),
                );
                continue;
            }
            match grip_axis(
                &o.spec.shape,
                &o.pose.rotation,
                &tool_axis,
                &closing,
                opening,
            ) {
                Ok((width, axis)) => {
                    if success.as_ref().is_none_or(|(d, ..)| perp < *d) {
                        success = Some((perp, i, width, axis));
                    }
                }
                Err(GripError::TooWide(w)) => fail(
                    perp,
                    format!("'{label}' is {w:.3} m wide, wider than the {opening:.3} m opening"),
                ),
                Err(GripError::Angle(deg)) => fail(
                    perp,
                    format!(
                        "jaw not across the short side of '{label}' (off by {deg:.0}°, at most \
                         {GRASP_ANGLE_TOLERANCE_DEG:.0}°)"
                    ),
                ),
                Err(GripError::NoSide) => {
                    fail(perp, format!("no side of '{label}' lies across the jaw"))
                }
            }
        }
        let Some((_, i, width, axis)) = success else {
            self.tool.opening_m = 0.0;
            let reason = failure
                .map(|(_, r)| r)
                .unwrap_or_else(|| "no object between the fingers".to_owned());
            return GraspOutcome::Empty { reason };
        };
        // Square the object up and centre it between the fingers.
        let mut pose = self.objects[i].pose;
        if tool_axis.z < -(10f64.to_radians().cos()) && axis.z.abs() < 0.2 {
            let a = Vector2::new(axis.x, axis.y);
            let c = Vector2::new(closing.x, closing.y);
            if a.norm() > 1e-9 && c.norm() > 1e-9 {
                let mut turn = (a.x * c.y - a.y * c.x).atan2(a.dot(&c));
                if turn > FRAC_PI_2 {
                    turn -= PI;
                } else if turn < -FRAC_PI_2 {
                    turn += PI;
                }
                pose.rotation = UnitQuaternion::from_euler_angles(0.0, 0.0, turn) * pose.rotation;
            }
        }
        let off = (pose.translation.vector - tcp.translation.vector).dot(&closing);
        pose.translation.vector -= closing * off;
        let id = self.objects[i].id;
        self.objects[i].pose = pose;
        self.objects[i].held = true;
        self.held = Some(Held {
            id,
            rel: inv * pose,
            width_m: width,
        });
        self.tool.opening_m = width;
        GraspOutcome::Grasped {
            id,
            label: self.objects[i].spec.label.clone(),
        }
    }

    /// Opens the fingers to `opening_m` (clamped to the gripper's range; non-finite = fully
    /// open). Fingers that meet an object on the way stall against it, as a real gripper's do:
    /// the opening stops at the contact. A held object is released if the fingers open beyond
    /// its width: it drops
    /// straight down from where it is, upright, keeping its yaw, onto whatever is below its
    /// footprint — the table, the top of another object (stacking), or the floor of an open
    /// container it fits into (inside; else it rests on the rim). Returns the released
    /// object's id. Asking for less than the held object's width keeps holding it.
    pub fn open_gripper(&mut self, opening_m: f64) -> Option<u32> {
        let max = self.gripper.max_opening_m;
        let wanted = if opening_m.is_finite() {
            opening_m.clamp(0.0, max)
        } else {
            max
        };
        let opening = self.free_opening(wanted);
        let Some(held) = self.held else {
            self.tool.opening_m = opening;
            return None;
        };
        if opening < held.width_m - 1e-9 {
            return None;
        }
        self.tool.opening_m = opening;
        self.held = None;
        let i = self.index_of(held.id)?;
        let carried = self.tool.tcp * held.rel;
        let spec = &self.objects[i].spec;
        let bottom = object_hulls(spec, &carried)
            .iter()
            .map(Hull::min_z)
            .fold(f64::INFINITY, f64::min);
        let yaw = upright_yaw(&carried.rotation);
        let mut pose = Isometry3::from_parts(
            Translation3::new(carried.translation.x, carried.translation.y, 0.0),
            UnitQuaternion::from_euler_angles(0.0, 0.0, yaw),
        );
        let poses = self.poses();
        let rest = self.rest_height(i, &pose, bottom, &poses);
        pose.translation.z = rest + spec.shape.height_m() / 2.0;
        self.objects[i].pose = pose;
        self.objects[i].held = false;
        Some(held.id)
    }

    /// The widest opening up to `wanted` the fingers reach from the current one before a
    /// finger presses into an object (found to ~0.01 mm). Closing further is never blocked
    /// here: closing goes through [`close_gripper`](Self::close_gripper).
    fn free_opening(&mut self, wanted: f64) -> f64 {
        let current = self.tool.opening_m;
        if wanted <= current {
            return wanted;
        }
        let tcp = self.tool.tcp;
        let poses = self.poses();
        let before = self.probe(&tcp, &poses);
        // Touching is the limit (not the contact tolerance), so the arm can leave afterwards.
        let free = |world: &mut World, opening: f64| {
            world.tool.opening_m = opening;
            let after = world.probe(&tcp, &poses);
            after
                .grip
                .iter()
                .zip(&before.grip)
                .all(|(a, b)| *a <= b + 1e-6)
        };
        let reached = if free(self, wanted) {
            wanted
        } else {
            let (mut lo, mut hi) = (current, wanted);
            for _ in 0..12 {
                let mid = (lo + hi) / 2.0;
                if free(self, mid) {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            lo
        };
        self.tool.opening_m = current;
        reached
    }
}

/// Why no side of an object can be gripped: the nearest side is too wide (its width), the
/// fitting side is too far off the closing axis (degrees), or no side lies across the jaw.
enum GripError {
    TooWide(f64),
    Angle(f64),
    NoSide,
}

/// The side of the object the jaw closes across: its width and world direction.
fn grip_axis(
    shape: &ObjectShape,
    rot: &UnitQuaternion<f64>,
    tool_axis: &Vector3<f64>,
    closing: &Vector3<f64>,
    opening: f64,
) -> Result<(f64, Vector3<f64>), GripError> {
    let fit = opening + 0.0005;
    // (width, world direction, angle to the closing axis in degrees)
    let mut sides: Vec<(f64, Vector3<f64>, f64)> = Vec::new();
    let angle = |a: &Vector3<f64>| a.dot(closing).abs().min(1.0).acos().to_degrees();
    let z = rot * Vector3::z();
    match *shape {
        ObjectShape::Box {
            length_x_m,
            width_y_m,
            height_z_m,
        } => {
            for (w, a) in [
                (length_x_m, rot * Vector3::x()),
                (width_y_m, rot * Vector3::y()),
                (height_z_m, z),
            ] {
                sides.push((w, a, angle(&a)));
            }
        }
        ObjectShape::Cylinder {
            diameter_m,
            height_m,
        } => {
            // Radial: the closing axis projected onto the cylinder's cross-section.
            let radial = closing - z * closing.dot(&z);
            if radial.norm() > 1e-9 {
                let r = radial.normalize();
                sides.push((diameter_m, r, angle(&r)));
            }
            sides.push((height_m, z, angle(&z)));
        }
    }
    // A side along the tool axis cannot be gripped across.
    sides.retain(|(_, a, _)| a.dot(tool_axis).abs() < 0.7);
    let nearest = sides
        .iter()
        .min_by(|a, b| a.2.total_cmp(&b.2))
        .copied()
        .ok_or(GripError::NoSide)?;
    let fitting = sides
        .iter()
        .filter(|s| s.0 <= fit)
        .min_by(|a, b| a.2.total_cmp(&b.2))
        .copied();
    match fitting {
        None => Err(GripError::TooWide(nearest.0)),
        Some((w, a, deg)) if deg <= GRASP_ANGLE_TOLERANCE_DEG => Ok((w, a)),
        Some((_, _, deg)) => Err(GripError::Angle(deg)),
    }
}
