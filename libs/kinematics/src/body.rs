//! The arm's body: every link's shapes, placed for given joints, as oriented boxes.
//!
//! Fencing only the tool centre point leaves the elbow, the wrist and the gripper housing
//! free to hit the table or a keep-out box. This module reads the shapes of every link from
//! the built-in URDF (its `<collision>` elements, or its `<visual>` ones when a link has
//! none) and turns each into an oriented box that contains it: a box is itself, a cylinder
//! or capsule the box around it, a sphere the cube around it. Boxes over-cover round shapes
//! by a few millimetres, on the safe side; they make the checks exact and cheap (the
//! lowest point of a box is one dot product, box against box is a separating-axis test).
//!
//! [`Kinematics::body`] places the boxes for joints `q`. Each carries its link's name (for
//! refusals a user can read) and how many actuated joints lie between it and the base: a
//! link moved only by the first joint (a vertical axis) never changes height, so the base
//! and shoulder — which stand on the table — are not checked against it.
//!
//! The tool centre point's own link is left out: the fence checks that point itself, and
//! its marker shape in the URDF is not hardware.

use crate::{Kinematics, KinematicsError};
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};

/// One shape of a link, in the link's frame.
#[derive(Debug, Clone)]
pub(crate) struct LinkShape {
    link: std::sync::Arc<str>,
    /// Shape centre and axes in the link frame.
    origin: Isometry3<f64>,
    half_extents: Vector3<f64>,
}

/// One box of the arm's body, placed in the base frame.
#[derive(Debug, Clone, PartialEq)]
pub struct BodyBox {
    /// The URDF link the box belongs to (`forearm_link`, `wrist_link`, …).
    pub link: std::sync::Arc<str>,
    /// Box centre and axes in the base frame.
    pub pose: Isometry3<f64>,
    /// Half the box's size along its own x, y and z axes, metres.
    pub half_extents: Vector3<f64>,
    /// Actuated joints between the base and this link (0 for the base).
    pub joints_from_base: usize,
}

impl BodyBox {
    /// Lowest and highest z of the box in the base frame, metres.
    pub fn z_range(&self) -> (f64, f64) {
        let r = self.pose.rotation.to_rotation_matrix();
        let reach: f64 = (0..3).map(|i| r[(2, i)].abs() * self.half_extents[i]).sum();
        let z = self.pose.translation.vector.z;
        (z - reach, z + reach)
    }

    /// Whether the box overlaps the axis-aligned box `min`–`max` (base frame), by the
    /// separating-axis test.
    pub fn overlaps_aligned_box(&self, min: &Vector3<f64>, max: &Vector3<f64>) -> bool {
        let centre = (min + max) / 2.0;
        let half = (max - min) / 2.0;
        let r = self.pose.rotation.to_rotation_matrix();
        let axes_a = [Vector3::x(), Vector3::y(), Vector3::z()];
        let axes_b = [r * Vector3::x(), r * Vector3::y(), r * Vector3::z()];
        let gap = self.pose.translation.vector - centre;
        let extent_a = |axis: &Vector3<f64>| -> f64 {
            (0..3).map(|i| axes_a[i].dot(axis).abs() * half[i]).sum()
        };
        let extent_b = |axis: &Vector3<f64>| -> f64 {
            (0..3)
                .map(|i| axes_b[i].dot(axis).abs() * self.half_extents[i])
                .sum()
        };
        let separated = |axis: Vector3<f64>| -> bool {
            if axis.norm_squared() < 1e-12 {
                return false; // parallel edges: covered by the face axes
            }
            gap.dot(&axis).abs() > extent_a(&axis) + extent_b(&axis)
        };
        let face_axes = axes_a.iter().chain(&axes_b).copied();
        if face_axes.clone().any(separated) {
            return false;
        }
        for a in &axes_a {
            for b in &axes_b {
                if separated(a.cross(b)) {
                    return false;
                }
            }
        }
        true
    }
}

/// The shapes of every link of `robot` except `tcp_link`'s, as boxes in their link frames.
pub(crate) fn link_shapes(robot: &urdf_rs::Robot, tcp_link: &str) -> Vec<LinkShape> {
    let mut shapes = Vec::new();
    for link in robot.links.iter().filter(|l| l.name != tcp_link) {
        let geometry: Vec<(&urdf_rs::Pose, &urdf_rs::Geometry)> = if link.collision.is_empty() {
            link.visual
                .iter()
                .map(|v| (&v.origin, &v.geometry))
                .collect()
        } else {
            link.collision
                .iter()
                .map(|c| (&c.origin, &c.geometry))
                .collect()
        };
        for (origin, geometry) in geometry {
            let half_extents = match geometry {
                urdf_rs::Geometry::Box { size } => Vector3::new(size[0], size[1], size[2]) / 2.0,
                urdf_rs::Geometry::Cylinder { radius, length } => {
                    Vector3::new(*radius, *radius, length / 2.0)
                }
                urdf_rs::Geometry::Capsule { radius, length } => {
                    Vector3::new(*radius, *radius, length / 2.0 + radius)
                }
                urdf_rs::Geometry::Sphere { radius } => Vector3::repeat(*radius),
                // The built-in models have no meshes; a mesh has no size without its file.
                urdf_rs::Geometry::Mesh { .. } => continue,
            };
            let (xyz, rpy) = (&origin.xyz, &origin.rpy);
            shapes.push(LinkShape {
                link: link.name.as_str().into(),
                origin: Isometry3::from_parts(
                    Translation3::new(xyz[0], xyz[1], xyz[2]),
                    UnitQuaternion::from_euler_angles(rpy[0], rpy[1], rpy[2]),
                ),
                half_extents,
            });
        }
    }
    shapes
}

impl Kinematics {
    /// The boxes of the arm's body for joints `q`, base to tool, in the base frame (see the
    /// [module documentation](self)).
    pub fn body(&self, q: &[f64]) -> Result<Vec<BodyBox>, KinematicsError> {
        Ok(self.tool_and_body(q)?.1)
    }

    /// The tool centre point's pose and the body's boxes for joints `q`, from one pass
    /// through the chain (what a path check needs at every sample).
    pub fn tool_and_body(
        &self,
        q: &[f64],
    ) -> Result<(Isometry3<f64>, Vec<BodyBox>), KinematicsError> {
        self.check_joints(q)?;
        let chains = self.lock();
        chains.tcp.set_joint_positions_unchecked(q);
        let poses = chains.tcp.update_transforms();
        let tool = poses.last().copied().unwrap_or_else(Isometry3::identity);
        let mut joints_from_base = 0;
        let mut boxes = Vec::with_capacity(self.body.len());
        for (node, pose) in chains.tcp.iter().zip(poses) {
            if node.joint().is_movable() {
                joints_from_base += 1;
            }
            let link = node.link();
            let Some(link) = link.as_ref() else {
                continue;
            };
            for shape in self.body.iter().filter(|s| *s.link == *link.name) {
                boxes.push(BodyBox {
                    link: shape.link.clone(),
                    pose: pose * shape.origin,
                    half_extents: shape.half_extents,
                    joints_from_base,
                });
            }
        }
        Ok((tool, boxes))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::RobotModel;

    #[test]
    fn every_moving_link_of_both_arms_has_a_box() {
        for model in [RobotModel::Ned2, RobotModel::WidowX250] {
            let kinematics = Kinematics::new(model);
            let body = kinematics.body(&kinematics.home_joints()).unwrap();
            let links: std::collections::BTreeSet<&str> = body.iter().map(|b| &*b.link).collect();
            assert!(links.len() >= 7, "{model:?}: {links:?}");
            assert!(
                body.iter().any(|b| b.joints_from_base >= 5),
                "{model:?}: the wrist's boxes are counted after five joints"
            );
            assert!(
                body.iter().any(|b| b.joints_from_base == 0),
                "{model:?}: the base has a box"
            );
            assert!(!links.contains("tcp_link") && !links.contains("ee_gripper_link"));
        }
    }

    #[test]
    fn the_fingers_end_at_the_tool_centre() {
        // Tool pointing straight down: the lowest point of the body is the fingertips, at
        // the tool centre's height, not below it.
        for model in [RobotModel::Ned2, RobotModel::WidowX250] {
            let kinematics = Kinematics::new(model);
            let target = robotd_protocol::geometry::Pose::new(
                0.25,
                0.0,
                0.05,
                0.0,
                std::f64::consts::FRAC_PI_2,
                0.0,
            );
            let q = kinematics
                .inverse(&crate::pose_to_isometry(&target), None)
                .unwrap();
            let lowest = kinematics
                .body(&q)
                .unwrap()
                .iter()
                .filter(|b| b.joints_from_base >= 2)
                .map(|b| b.z_range().0)
                .fold(f64::INFINITY, f64::min);
            assert!((lowest - 0.05).abs() < 1e-3, "{model:?}: lowest {lowest}");
        }
    }

    #[test]
    fn a_box_overlaps_only_what_it_touches() {
        let tilted = BodyBox {
            link: "test".into(),
            pose: Isometry3::from_parts(
                Translation3::new(0.0, 0.0, 0.0),
                UnitQuaternion::from_euler_angles(0.0, 0.0, std::f64::consts::FRAC_PI_4),
            ),
            half_extents: Vector3::new(0.1, 0.01, 0.01),
            joints_from_base: 3,
        };
        // Along its diagonal it reaches (0.07, 0.07); an aligned box there is hit...
        let hit = (Vector3::new(0.06, 0.06, -0.1), Vector3::new(0.1, 0.1, 0.1));
        assert!(tilted.overlaps_aligned_box(&hit.0, &hit.1));
        // ...one in the corner its axis-aligned bounds would cover is not.
        let miss = (
            Vector3::new(0.06, -0.1, -0.1),
            Vector3::new(0.1, -0.06, 0.1),
        );
        assert!(!tilted.overlaps_aligned_box(&miss.0, &miss.1));
        let (low, high) = tilted.z_range();
        assert!((low + 0.01).abs() < 1e-12 && (high - 0.01).abs() < 1e-12);
    }
}
