//! Contacts: how deep the gripper — and the object it carries — sinks into the table and into
//! each object at one tool pose, and which of those contacts count.
//!
//! A motion is checked sub-step by sub-step: [`World::probe`] measures the penetration depths
//! at the next pose ([`Probe`]), [`World::hits`] compares them with the depths at the previous
//! pose. Only a contact that is new or got deeper counts ([`Hit`]), so a tool that starts
//! inside something can still move out of it. The gripper itself may touch things by
//! [`CONTACT_TOLERANCE_M`]; a carried object may sink [`HELD_TOLERANCE_M`] into what it is set
//! down on. What a counted hit then means — a push or a collision — is decided in
//! [`motion`](super::motion).

use super::shapes::object_hulls;
use super::World;
use crate::geom::{penetration, Hull};
use nalgebra::Isometry3;

/// The gripper may touch things: only a penetration deeper than this is a contact.
pub const CONTACT_TOLERANCE_M: f64 = 0.0001;

/// A contact that already exists counts again only when a step makes it deeper by more than
/// this, metres: an arm leaving a contact along a joint-space path wobbles by a few microns,
/// and must not be stopped by it (a straight push into an object deepens by far more).
pub const DEEPER_M: f64 = 0.00005;

/// A carried object may sink this far into another (or the table) before it is a collision,
/// so that placing it on top of something, or down on the table, works.
pub const HELD_TOLERANCE_M: f64 = 0.002;

/// Something the gripper ran into.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Contact {
    /// The gripper (or what it carries) would have entered something solid.
    Collision {
        /// `"table"` or the label of the object.
        what: String,
    },
}

/// Penetration depths of the gripper (and of what it carries) at one tool pose.
#[derive(Debug, Clone)]
pub(super) struct Probe {
    pub(super) table: f64,
    pub(super) held_table: f64,
    /// Per object index: gripper vs object.
    pub(super) grip: Vec<f64>,
    /// Per object index: carried object vs object.
    pub(super) held: Vec<f64>,
}

/// A contact that counts: the table, or object `i` touched by the gripper or by the carried
/// object.
pub(super) enum Hit {
    Table,
    Grip(usize),
    Held(usize),
}

impl World {
    /// Penetrations of the gripper and the carried object at `tcp`, objects at `poses`.
    pub(super) fn probe(&self, tcp: &Isometry3<f64>, poses: &[Isometry3<f64>]) -> Probe {
        let grip = self.gripper_hulls(tcp);
        let table = grip.iter().map(Hull::min_z).fold(f64::INFINITY, f64::min);
        let held_index = self.held_index();
        let carried = match (self.held, held_index) {
            (Some(h), Some(i)) => object_hulls(&self.objects[i].spec, &(tcp * h.rel)),
            _ => Vec::new(),
        };
        let held_table = carried
            .iter()
            .map(Hull::min_z)
            .fold(f64::INFINITY, f64::min);
        let mut probe = Probe {
            table: (-table).max(0.0),
            held_table: (-held_table).max(0.0),
            grip: vec![0.0; self.objects.len()],
            held: vec![0.0; self.objects.len()],
        };
        for (i, (o, pose)) in self.objects.iter().zip(poses).enumerate() {
            if Some(i) == held_index {
                continue;
            }
            let hulls = object_hulls(&o.spec, pose);
            probe.grip[i] = max_penetration(&grip, &hulls).max(0.0);
            if !carried.is_empty() {
                probe.held[i] = max_penetration(&carried, &hulls).max(0.0);
            }
        }
        probe
    }

    /// Contacts that are new or deeper in `after` than in `before` (by more than
    /// [`DEEPER_M`]: an arm leaving a contact along a joint-space path wobbles by microns).
    pub(super) fn hits(&self, before: &Probe, after: &Probe) -> Vec<Hit> {
        let deeper = |a: f64, b: f64, tol: f64| a > tol && a > b + DEEPER_M;
        let mut out = Vec::new();
        if deeper(after.table, before.table, CONTACT_TOLERANCE_M)
            || deeper(after.held_table, before.held_table, HELD_TOLERANCE_M)
        {
            out.push(Hit::Table);
        }
        for i in 0..after.grip.len().min(before.grip.len()) {
            if deeper(after.held[i], before.held[i], HELD_TOLERANCE_M) {
                out.push(Hit::Held(i));
            }
            if deeper(after.grip[i], before.grip[i], CONTACT_TOLERANCE_M) {
                out.push(Hit::Grip(i));
            }
        }
        out
    }
}

/// The deepest penetration between any hull of `a` and any of `b` (≤ 0: apart).
pub(super) fn max_penetration(a: &[Hull], b: &[Hull]) -> f64 {
    let mut depth = f64::NEG_INFINITY;
    for x in a {
        for y in b {
            depth = depth.max(penetration(x, y));
        }
    }
    depth
}
