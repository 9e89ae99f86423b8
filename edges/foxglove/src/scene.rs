//! robotd's state as Foxglove messages: transforms of the arm's links, the objects and the
//! workspace as 3D scene entities, texts as log lines. All in the robot's base frame
//! (`base_link`), metres, with `world` = `base_link`.

use foxglove::messages::{
    Color, CubePrimitive, FrameTransform, FrameTransforms, LinePrimitive, Log, Point3, Pose,
    Quaternion, SceneEntity, SceneUpdate, TextPrimitive, Timestamp, Vector3,
};
use nalgebra::Isometry3;
use robotd_protocol::objects::DetectedObject;
use robotd_protocol::workspace::WorkspaceInfo;

/// The frame everything is expressed in.
pub const BASE_FRAME: &str = "base_link";

/// `ns` (since the Unix epoch) as a Foxglove timestamp.
pub fn timestamp(ns: u64) -> Timestamp {
    Timestamp::new((ns / 1_000_000_000) as u32, (ns % 1_000_000_000) as u32)
}

fn vector(x: f64, y: f64, z: f64) -> Vector3 {
    Vector3 { x, y, z }
}

fn quaternion(iso: &Isometry3<f64>) -> Quaternion {
    let q = iso.rotation.quaternion();
    Quaternion {
        x: q.i,
        y: q.j,
        z: q.k,
        w: q.w,
    }
}

fn pose_at(x: f64, y: f64, z: f64, yaw: f64) -> Pose {
    let (s, c) = (yaw / 2.0).sin_cos();
    Pose {
        position: Some(vector(x, y, z)),
        orientation: Some(Quaternion {
            x: 0.0,
            y: 0.0,
            z: s,
            w: c,
        }),
    }
}

const fn colour(r: f64, g: f64, b: f64, a: f64) -> Color {
    Color { r, g, b, a }
}

/// The pose of every link of a chain (`(name, pose in the base frame)`, base first, each link
/// the parent of the next, as the kinematics list them) as transforms from each link's parent:
/// the tree of the URDF, so the transforms agree with the joints Foxglove's URDF layer reads
/// from `/robot_description` (a frame given two different parents would be re-parented back and
/// forth). A first link other than the base frame is placed from the base frame.
pub fn link_transforms(links: &[(String, Isometry3<f64>)], ns: u64) -> FrameTransforms {
    let mut parent: (&str, Isometry3<f64>) = (BASE_FRAME, Isometry3::identity());
    let mut transforms = Vec::with_capacity(links.len());
    for (name, pose) in links {
        if name != BASE_FRAME {
            let relative = parent.1.inverse() * pose;
            transforms.push(FrameTransform {
                timestamp: Some(timestamp(ns)),
                parent_frame_id: parent.0.to_owned(),
                child_frame_id: name.clone(),
                translation: Some(vector(
                    relative.translation.x,
                    relative.translation.y,
                    relative.translation.z,
                )),
                rotation: Some(quaternion(&relative)),
            });
        }
        parent = (name, *pose);
    }
    FrameTransforms { transforms }
}

/// The arm drawn as a line through its link origins (for views without the URDF layer).
pub fn arm_scene(links: &[(String, Isometry3<f64>)], ns: u64) -> SceneUpdate {
    let points = links
        .iter()
        .map(|(_, iso)| Point3 {
            x: iso.translation.x,
            y: iso.translation.y,
            z: iso.translation.z,
        })
        .collect();
    let line = LinePrimitive {
        r#type: foxglove::messages::line_primitive::Type::LineStrip as i32,
        pose: Some(pose_at(0.0, 0.0, 0.0, 0.0)),
        thickness: 0.02,
        scale_invariant: false,
        points,
        color: Some(colour(0.95, 0.55, 0.1, 1.0)),
        ..Default::default()
    };
    SceneUpdate {
        deletions: vec![],
        entities: vec![SceneEntity {
            timestamp: Some(timestamp(ns)),
            frame_id: BASE_FRAME.to_owned(),
            id: "arm".to_owned(),
            lines: vec![line],
            ..Default::default()
        }],
    }
}

/// The tracked objects as boxes on the table with their label and id above them. Objects no
/// longer tracked disappear: the update replaces all entities of the `objects/` namespace.
pub fn objects_scene(objects: &[DetectedObject], previous: &[String], ns: u64) -> SceneUpdate {
    let entities: Vec<SceneEntity> = objects
        .iter()
        .map(|o| {
            let c = &o.position.center_of_mass;
            let height = (2.0 * c.z_m).max(0.005);
            SceneEntity {
                timestamp: Some(timestamp(ns)),
                frame_id: BASE_FRAME.to_owned(),
                id: format!("objects/{}", o.id),
                cubes: vec![CubePrimitive {
                    pose: Some(pose_at(c.x_m, c.y_m, height / 2.0, 0.0)),
                    // `height_m` lies along x (away from the robot), `width_m` along y.
                    size: Some(vector(o.dimensions.height_m, o.dimensions.width_m, height)),
                    color: Some(colour(0.1, 0.6, 0.25, 0.7)),
                }],
                texts: vec![TextPrimitive {
                    pose: Some(pose_at(c.x_m, c.y_m, height + 0.02, 0.0)),
                    billboard: true,
                    font_size: 14.0,
                    scale_invariant: true,
                    color: Some(colour(1.0, 1.0, 1.0, 1.0)),
                    text: format!("{} ({})", o.label, o.id),
                }],
                ..Default::default()
            }
        })
        .collect();
    let current: Vec<&str> = entities.iter().map(|e| e.id.as_str()).collect();
    let deletions = previous
        .iter()
        .filter(|id| !current.contains(&id.as_str()))
        .map(|id| foxglove::messages::SceneEntityDeletion {
            timestamp: Some(timestamp(ns)),
            r#type: foxglove::messages::scene_entity_deletion::Type::MatchingId as i32,
            id: id.clone(),
        })
        .collect();
    SceneUpdate {
        deletions,
        entities,
    }
}

/// An axis-aligned box, metres in the base frame: the geofence or a keep-out zone.
#[derive(Debug, Clone, PartialEq)]
pub struct Box3 {
    /// What it is (`geofence`, or the keep-out zone's name).
    pub name: String,
    /// Lowest corner.
    pub min: [f64; 3],
    /// Highest corner.
    pub max: [f64; 3],
}

/// The twelve edges of `b` as a line list.
fn box_edges(b: &Box3) -> Vec<Point3> {
    let corner = |i: usize| Point3 {
        x: if i & 1 == 0 { b.min[0] } else { b.max[0] },
        y: if i & 2 == 0 { b.min[1] } else { b.max[1] },
        z: if i & 4 == 0 { b.min[2] } else { b.max[2] },
    };
    // Pairs of corners differing in one bit.
    let mut points = Vec::with_capacity(24);
    for i in 0..8usize {
        for bit in [1, 2, 4] {
            if i & bit == 0 {
                points.push(corner(i));
                points.push(corner(i | bit));
            }
        }
    }
    points
}

/// The geofence (red edges) and keep-out zones (translucent red boxes with their names).
fn fence_entities(fence: &Box3, keep_out: &[Box3], ns: u64) -> Vec<SceneEntity> {
    let mut entities = vec![SceneEntity {
        timestamp: Some(timestamp(ns)),
        frame_id: BASE_FRAME.to_owned(),
        id: "geofence".to_owned(),
        lines: vec![LinePrimitive {
            r#type: foxglove::messages::line_primitive::Type::LineList as i32,
            pose: Some(pose_at(0.0, 0.0, 0.0, 0.0)),
            thickness: 2.0,
            scale_invariant: true,
            points: box_edges(fence),
            color: Some(colour(0.85, 0.15, 0.15, 1.0)),
            ..Default::default()
        }],
        ..Default::default()
    }];
    for zone in keep_out {
        let centre = |axis: usize| (zone.min[axis] + zone.max[axis]) / 2.0;
        let size = |axis: usize| (zone.max[axis] - zone.min[axis]).abs();
        entities.push(SceneEntity {
            timestamp: Some(timestamp(ns)),
            frame_id: BASE_FRAME.to_owned(),
            id: format!("keep_out/{}", zone.name),
            cubes: vec![CubePrimitive {
                pose: Some(pose_at(centre(0), centre(1), centre(2), 0.0)),
                size: Some(vector(size(0), size(1), size(2))),
                color: Some(colour(0.85, 0.15, 0.15, 0.25)),
            }],
            texts: vec![TextPrimitive {
                pose: Some(pose_at(centre(0), centre(1), zone.max[2] + 0.02, 0.0)),
                billboard: true,
                font_size: 12.0,
                scale_invariant: true,
                color: Some(colour(0.85, 0.15, 0.15, 1.0)),
                text: zone.name.clone(),
            }],
            ..Default::default()
        });
    }
    entities
}

/// The workspaces' sheets as flat boxes with their ids, and the geofence with its keep-out
/// zones when given.
pub fn workspace_scene(
    workspaces: &[WorkspaceInfo],
    geofence: Option<&(Box3, Vec<Box3>)>,
    ns: u64,
) -> SceneUpdate {
    let mut entities: Vec<SceneEntity> = workspaces
        .iter()
        .map(|w| {
            let (a, b) = (w.upper_left, w.lower_right);
            let (cx, cy) = ((a.x_m + b.x_m) / 2.0, (a.y_m + b.y_m) / 2.0);
            SceneEntity {
                timestamp: Some(timestamp(ns)),
                frame_id: BASE_FRAME.to_owned(),
                id: format!("workspaces/{}", w.id),
                cubes: vec![CubePrimitive {
                    pose: Some(pose_at(cx, cy, -0.001, 0.0)),
                    size: Some(vector((a.x_m - b.x_m).abs(), (a.y_m - b.y_m).abs(), 0.002)),
                    color: Some(colour(0.95, 0.95, 0.95, 0.9)),
                }],
                texts: vec![TextPrimitive {
                    pose: Some(pose_at(a.x_m.max(b.x_m) + 0.02, cy, 0.0, 0.0)),
                    billboard: true,
                    font_size: 12.0,
                    scale_invariant: true,
                    color: Some(colour(0.2, 0.2, 0.2, 1.0)),
                    text: w.id.clone(),
                }],
                ..Default::default()
            }
        })
        .collect();
    if let Some((fence, keep_out)) = geofence {
        entities.extend(fence_entities(fence, keep_out, ns));
    }
    SceneUpdate {
        deletions: vec![],
        entities,
    }
}

/// A log line of `level` from `name` (an actor, `speech`, `agent`).
pub fn log(level: foxglove::messages::log::Level, name: &str, message: String, ns: u64) -> Log {
    Log {
        timestamp: Some(timestamp(ns)),
        level: level as i32,
        message,
        name: name.to_owned(),
        ..Default::default()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Translation3, UnitQuaternion};
    use robotd_kinematics::{Kinematics, RobotModel};

    fn isometry(t: &FrameTransform) -> Isometry3<f64> {
        let (p, q) = (
            t.translation.as_ref().unwrap(),
            t.rotation.as_ref().unwrap(),
        );
        Isometry3::from_parts(
            Translation3::new(p.x, p.y, p.z),
            UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(q.w, q.x, q.y, q.z)),
        )
    }

    #[test]
    fn transforms_follow_the_urdf_tree_and_compose_to_the_link_poses() {
        for model in [RobotModel::Ned2, RobotModel::WidowX250] {
            let kinematics = Kinematics::new(model);
            let q = [0.3, -0.4, 0.5, 0.2, 0.6, -0.7];
            let links = kinematics.link_poses(&q).unwrap();
            let tf = link_transforms(&links, 7);
            let joints = crate::urdf::parse(kinematics.urdf()).joints;
            let mut in_base: std::collections::HashMap<&str, Isometry3<f64>> =
                [(BASE_FRAME, Isometry3::identity())].into();
            for t in &tf.transforms {
                // Each transform is one joint of the URDF, from its parent link to its child.
                assert!(
                    joints
                        .iter()
                        .any(|j| j.parent == t.parent_frame_id && j.child == t.child_frame_id),
                    "{model:?}: {} -> {} is no joint",
                    t.parent_frame_id,
                    t.child_frame_id
                );
                let parent = in_base[t.parent_frame_id.as_str()];
                in_base.insert(&t.child_frame_id, parent * isometry(t));
            }
            assert_eq!(tf.transforms.len(), links.len() - 1, "{model:?}");
            for (name, pose) in &links {
                let composed = in_base[name.as_str()];
                assert!(
                    (composed.translation.vector - pose.translation.vector).norm() < 1e-9
                        && composed.rotation.angle_to(&pose.rotation) < 1e-9,
                    "{model:?}: {name}"
                );
            }
        }
    }
}
