//! Pushing and settling: what happens to objects the empty gripper runs into sideways.
//!
//! [`World::push`] shoves each touched object along the step's horizontal direction just far
//! enough to clear the gripper, carries along whatever stands on it or inside it
//! ([`World::riders`]), shoves in turn the objects it then runs into, and finally lets every
//! object that lost its support drop ([`World::settle`]). [`World::rest_height`] — where an
//! object lands when it drops straight down — is also what a released object uses
//! ([`open_gripper`](World::open_gripper)).
//!
//! Not modelled: friction, toppling, objects turning when pushed off-centre.

use super::contact::{max_penetration, CONTACT_TOLERANCE_M};
use super::shapes::{footprint_at, object_hulls, support_height};
use super::World;
use crate::geom::{penetration, push_out, Hull};
use nalgebra::{Isometry3, Vector3};
use std::collections::VecDeque;

/// A pushed object may be shoved at most this much further than the pushing step.
const PUSH_SLACK_M: f64 = 0.003;

/// A released object may start this far below the top of what it lands on.
const DROP_TOLERANCE_M: f64 = 0.003;

impl World {
    /// Shoves the objects `first` out of the gripper at `tcp` along `dir`, and whatever they
    /// run into, then lets everything settle. Returns the new poses and the moved indices, or
    /// the label of an object that could not be moved out of the way.
    pub(super) fn push(
        &self,
        tcp: &Isometry3<f64>,
        first: &[usize],
        dir: &Vector3<f64>,
        run: f64,
        poses: &[Isometry3<f64>],
    ) -> Result<(Vec<Isometry3<f64>>, Vec<usize>), String> {
        let n = self.objects.len();
        let held_index = self.held_index();
        let grip = self.gripper_hulls(tcp);
        let mut poses = poses.to_vec();
        let riders = self.riders(&poses);
        let cap = run + PUSH_SLACK_M;
        let mut moved = vec![false; n];
        let mut queue = VecDeque::new();
        let label = |i: usize| self.objects[i].spec.label.clone();
        for &i in first {
            let hulls = object_hulls(&self.objects[i].spec, &poses[i]);
            let t = shove_distance(&grip, &hulls, dir);
            if t.is_nan() || t > cap {
                return Err(label(i));
            }
            if t > 0.0 {
                for j in shift(&mut poses, &riders, i, None, dir * (t + 1e-6)) {
                    moved[j] = true;
                    queue.push_back(j);
                }
            }
        }
        let mut budget = 64 * n.max(1);
        while let Some(m) = queue.pop_front() {
            budget -= 1;
            if budget == 0 {
                return Err(label(m));
            }
            let hm = object_hulls(&self.objects[m].spec, &poses[m]);
            for k in 0..n {
                if k == m || Some(k) == held_index {
                    continue;
                }
                let hk = object_hulls(&self.objects[k].spec, &poses[k]);
                if max_penetration(&hm, &hk) <= CONTACT_TOLERANCE_M {
                    continue;
                }
                let t = shove_distance(&hm, &hk, dir);
                if t.is_nan() || t > cap {
                    return Err(label(k));
                }
                for j in shift(&mut poses, &riders, k, Some(m), dir * (t + 1e-6)) {
                    moved[j] = true;
                    queue.push_back(j);
                }
            }
        }
        self.settle(&mut poses);
        let moved = (0..n).filter(|&i| moved[i]).collect();
        Ok((poses, moved))
    }

    /// For each object, the objects standing directly on it or inside it.
    fn riders(&self, poses: &[Isometry3<f64>]) -> Vec<Vec<usize>> {
        let held_index = self.held_index();
        let n = self.objects.len();
        let mut out = vec![Vec::new(); n];
        for (j, a) in self.objects.iter().enumerate() {
            if Some(j) == held_index {
                continue;
            }
            let fp = footprint_at(&a.spec, &poses[j]);
            let bottom = poses[j].translation.z - a.spec.shape.height_m() / 2.0;
            if bottom < 0.0005 {
                continue;
            }
            for (i, b) in self.objects.iter().enumerate() {
                if i == j || Some(i) == held_index {
                    continue;
                }
                if let Some(s) = support_height(&b.spec, &poses[i], &fp) {
                    if (s - bottom).abs() <= 0.001 {
                        out[i].push(j);
                    }
                }
            }
        }
        out
    }

    /// Height of what object `i` (footprint from `pose`, base at `bottom`) comes to rest on
    /// when it drops straight down: the table or the highest support below it.
    pub(super) fn rest_height(
        &self,
        i: usize,
        pose: &Isometry3<f64>,
        bottom: f64,
        poses: &[Isometry3<f64>],
    ) -> f64 {
        let fp = footprint_at(&self.objects[i].spec, pose);
        let held_index = self.held_index();
        let mut rest: f64 = 0.0;
        for (k, o) in self.objects.iter().enumerate() {
            if k == i || Some(k) == held_index {
                continue;
            }
            if let Some(s) = support_height(&o.spec, &poses[k], &fp) {
                if s <= bottom + DROP_TOLERANCE_M {
                    rest = rest.max(s);
                }
            }
        }
        rest
    }

    /// Lets unsupported objects drop, lowest first.
    fn settle(&self, poses: &mut [Isometry3<f64>]) {
        let held_index = self.held_index();
        let half = |i: usize| self.objects[i].spec.shape.height_m() / 2.0;
        let mut order: Vec<usize> = (0..self.objects.len())
            .filter(|&i| Some(i) != held_index)
            .collect();
        order.sort_by(|&a, &b| {
            let za = poses[a].translation.z - half(a);
            let zb = poses[b].translation.z - half(b);
            za.total_cmp(&zb)
        });
        for i in order {
            let bottom = poses[i].translation.z - half(i);
            let pose = poses[i];
            let rest = self.rest_height(i, &pose, bottom, poses);
            if rest < bottom - 1e-5 {
                poses[i].translation.z = rest + half(i);
            }
        }
    }
}

/// Moves object `i` and (recursively) what rides on it, except `except`, by `v`; returns the
/// moved indices.
fn shift(
    poses: &mut [Isometry3<f64>],
    riders: &[Vec<usize>],
    i: usize,
    except: Option<usize>,
    v: Vector3<f64>,
) -> Vec<usize> {
    let mut done = vec![false; poses.len()];
    let mut stack = vec![i];
    let mut out = Vec::new();
    while let Some(j) = stack.pop() {
        if done[j] || Some(j) == except {
            continue;
        }
        done[j] = true;
        poses[j].translation.vector += v;
        out.push(j);
        stack.extend(riders[j].iter().copied());
    }
    out
}

/// How far `moving` (several hulls, rigidly joined) must go along `dir` to clear `fixed`.
fn shove_distance(fixed: &[Hull], moving: &[Hull], dir: &Vector3<f64>) -> f64 {
    let mut t: f64 = 0.0;
    for f in fixed {
        for m in moving {
            if penetration(f, m) > 0.0 {
                t = t.max(push_out(f, m, dir));
            }
        }
    }
    t
}
