//! Shapes: the geometry of one object at one pose, and small pose helpers.
//!
//! An object is a box (a container is a floor and four walls [`CONTAINER_WALL_M`] thick) or an
//! upright cylinder; [`object_hulls`] gives its solid parts for the contact tests,
//! [`footprint_at`] its outline on the table, [`support_height`] the height at which something
//! above it comes to rest (its top, or a container's floor), [`extent_along`] its size along a
//! direction. [`upright_yaw`] reads the yaw back out of a rotation.

use crate::geom::{footprint_inside_rect, footprint_overlap, Footprint, Hull};
use crate::scene::{footprint_of, ObjectShape, ObjectSpec, CONTAINER_WALL_M};
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector2, Vector3};
use std::f64::consts::{FRAC_PI_2, PI};

/// Two footprints must overlap this much for one to support the other.
const SUPPORT_OVERLAP_M: f64 = 0.0005;

/// Pose of an object standing on the table as its spec says.
pub(super) fn standing_pose(spec: &ObjectSpec) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::new(spec.x_m, spec.y_m, spec.shape.height_m() / 2.0),
        UnitQuaternion::from_euler_angles(0.0, 0.0, spec.yaw_rad),
    )
}

/// The solid parts of an object at `pose`: one hull, or floor and four walls of a container.
pub(super) fn object_hulls(spec: &ObjectSpec, pose: &Isometry3<f64>) -> Vec<Hull> {
    match spec.shape {
        ObjectShape::Box {
            length_x_m: l,
            width_y_m: w,
            height_z_m: h,
        } => {
            if !spec.container {
                return vec![Hull::cuboid(pose, &Vector3::new(l / 2.0, w / 2.0, h / 2.0))];
            }
            let t = CONTAINER_WALL_M;
            let part = |x: f64, y: f64, z: f64, half: Vector3<f64>| {
                Hull::cuboid(
                    &(pose * Isometry3::from_parts(Translation3::new(x, y, z), Default::default())),
                    &half,
                )
            };
            let wall_h = (h - t) / 2.0;
            vec![
                part(
                    0.0,
                    0.0,
                    -h / 2.0 + t / 2.0,
                    Vector3::new(l / 2.0, w / 2.0, t / 2.0),
                ),
                part(
                    l / 2.0 - t / 2.0,
                    0.0,
                    t / 2.0,
                    Vector3::new(t / 2.0, w / 2.0, wall_h),
                ),
                part(
                    -l / 2.0 + t / 2.0,
                    0.0,
                    t / 2.0,
                    Vector3::new(t / 2.0, w / 2.0, wall_h),
                ),
                part(
                    0.0,
                    w / 2.0 - t / 2.0,
                    t / 2.0,
                    Vector3::new(l / 2.0 - t, t / 2.0, wall_h),
                ),
                part(
                    0.0,
                    -w / 2.0 + t / 2.0,
                    t / 2.0,
                    Vector3::new(l / 2.0 - t, t / 2.0, wall_h),
                ),
            ]
        }
        ObjectShape::Cylinder {
            diameter_m,
            height_m,
        } => vec![Hull::prism(pose, diameter_m / 2.0, height_m / 2.0)],
    }
}

/// Footprint of an (upright) object at `pose`.
pub(super) fn footprint_at(spec: &ObjectSpec, pose: &Isometry3<f64>) -> Footprint {
    footprint_of(
        &spec.shape,
        Vector2::new(pose.translation.x, pose.translation.y),
        upright_yaw(&pose.rotation),
    )
}

/// The height at which something with footprint `fp` rests on object `spec` at `pose`: its
/// top, or its floor if it is a container and `fp` fits inside; `None` when the footprints do
/// not overlap.
pub(super) fn support_height(
    spec: &ObjectSpec,
    pose: &Isometry3<f64>,
    fp: &Footprint,
) -> Option<f64> {
    let own = footprint_at(spec, pose);
    if footprint_overlap(&own, fp) <= SUPPORT_OVERLAP_M {
        return None;
    }
    let h = spec.shape.height_m();
    let bottom = pose.translation.z - h / 2.0;
    if let (
        true,
        ObjectShape::Box {
            length_x_m,
            width_y_m,
            ..
        },
    ) = (spec.container, spec.shape)
    {
        let inner = Vector2::new(
            length_x_m / 2.0 - CONTAINER_WALL_M,
            width_y_m / 2.0 - CONTAINER_WALL_M,
        );
        let c = Vector2::new(pose.translation.x, pose.translation.y);
        if footprint_inside_rect(fp, &c, &inner, upright_yaw(&pose.rotation), 0.0005) {
            return Some(bottom + CONTAINER_WALL_M);
        }
    }
    Some(bottom + h)
}

/// Extent of an object of `shape` rotated by `rot` along the unit direction `u`.
pub(super) fn extent_along(
    shape: &ObjectShape,
    rot: &UnitQuaternion<f64>,
    u: &Vector3<f64>,
) -> f64 {
    let local = rot.inverse() * u;
    match *shape {
        ObjectShape::Box {
            length_x_m,
            width_y_m,
            height_z_m,
        } => local.x.abs() * length_x_m + local.y.abs() * width_y_m + local.z.abs() * height_z_m,
        ObjectShape::Cylinder {
            diameter_m,
            height_m,
        } => diameter_m * (1.0 - local.z * local.z).max(0.0).sqrt() + height_m * local.z.abs(),
    }
}

/// Yaw of an upright-ish rotation: the heading of its x axis (of its y axis − 90° when x is
/// nearly vertical), in (−π, π].
pub(super) fn upright_yaw(rot: &UnitQuaternion<f64>) -> f64 {
    let x = rot * Vector3::x();
    if x.z.abs() < 0.9 {
        x.y.atan2(x.x)
    } else {
        let y = rot * Vector3::y();
        let yaw = y.y.atan2(y.x) - FRAC_PI_2;
        if yaw <= -PI {
            yaw + 2.0 * PI
        } else {
            yaw
        }
    }
}

/// Whether every coordinate of `p` is finite.
pub(super) fn isometry_finite(p: &Isometry3<f64>) -> bool {
    p.translation.vector.iter().all(|v| v.is_finite())
        && p.rotation.coords.iter().all(|v| v.is_finite())
}
