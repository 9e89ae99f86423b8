//! Solids as convex polyhedra: world vertices, outward faces, and the directions the
//! separating-axis test needs.

use crate::scene::{Shape, Solid};
use nalgebra::{Isometry3, Point3, Vector3};
use std::ops::Range;

/// Sides of the prism a cylinder is drawn as (a multiple of 4, see [`push_solid`]).
pub(crate) const CYLINDER_SIDES: usize = 32;

/// One face of a mesh: indices into the vertex buffer, counter-clockwise seen from outside.
#[derive(Debug, Clone)]
pub(crate) struct MeshFace {
    pub(crate) indices: Range<usize>,
    /// Outward unit normal, world frame.
    pub(crate) normal: Vector3<f64>,
}

/// A solid's part of the [`MeshBuffers`].
#[derive(Debug, Clone)]
pub(crate) struct SolidMesh {
    pub(crate) verts: Range<usize>,
    pub(crate) faces: Range<usize>,
    pub(crate) axes: Range<usize>,
}

/// Meshes of all solids of a frame, reused from frame to frame.
#[derive(Debug, Default)]
pub(crate) struct MeshBuffers {
    pub(crate) verts: Vec<Point3<f64>>,
    pub(crate) indices: Vec<usize>,
    pub(crate) faces: Vec<MeshFace>,
    /// Unit face normals and edge directions, up to sign, world frame.
    pub(crate) axes: Vec<Vector3<f64>>,
}

impl MeshBuffers {
    pub(crate) fn clear(&mut self) {
        self.verts.clear();
        self.indices.clear();
        self.faces.clear();
        self.axes.clear();
    }
}

fn finite_pose(pose: &Isometry3<f64>) -> bool {
    pose.translation.vector.iter().all(|v| v.is_finite())
        && pose.rotation.coords.iter().all(|v| v.is_finite())
}

/// Newell's normal of a polygon, normalised; `None` when degenerate.
pub(crate) fn polygon_normal(
    points: impl Iterator<Item = Point3<f64>> + Clone,
) -> Option<Vector3<f64>> {
    let mut n = Vector3::<f64>::zeros();
    let mut iter = points.clone().cycle().skip(1);
    for p in points {
        let q = iter.next()?;
        n.x += (p.y - q.y) * (p.z + q.z);
        n.y += (p.z - q.z) * (p.x + q.x);
        n.z += (p.x - q.x) * (p.y + q.y);
    }
    let len = n.norm();
    (len.is_finite() && len > 1e-300).then(|| n / len)
}

/// Appends the mesh of `solid`; `None` (and nothing appended) when the solid has non-finite or
/// non-positive dimensions or a non-finite pose.
///
/// For a prism with a multiple of 4 sides, the rim edge directions are side normals of other
/// facets, so face normals and edge directions share one set of axes.
pub(crate) fn push_solid(buf: &mut MeshBuffers, solid: &Solid) -> Option<SolidMesh> {
    if !finite_pose(&solid.pose) {
        return None;
    }
    let v0 = buf.verts.len();
    let i0 = buf.indices.len();
    let f0 = buf.faces.len();
    let a0 = buf.axes.len();
    let rot = solid.pose.rotation;
    let faces_ok = match solid.shape {
        Shape::Box { size_m } => {
            if !size_m.iter().all(|s| s.is_finite() && *s > 0.0) {
                return None;
            }
            let h = size_m / 2.0;
            for i in 0..8 {
                let sx = if i & 1 == 0 { -h.x } else { h.x };
                let sy = if i & 2 == 0 { -h.y } else { h.y };
                let sz = if i & 4 == 0 { -h.z } else { h.z };
                buf.verts.push(solid.pose * Point3::new(sx, sy, sz));
            }
            // Corner i has bit 0 = +x, bit 1 = +y, bit 2 = +z. CCW seen from outside.
            const FACES: [[usize; 4]; 6] = [
                [0, 2, 3, 1], // -z
                [4, 5, 7, 6], // +z
                [0, 1, 5, 4], // -y
                [2, 6, 7, 3], // +y
                [0, 4, 6, 2], // -x
                [1, 3, 7, 5], // +x
            ];
            let mut ok = true;
            for face in FACES {
                ok &= push_face(buf, v0, face.iter().copied());
            }
            for axis in [Vector3::x(), Vector3::y(), Vector3::z()] {
                buf.axes.push(rot * axis);
            }
            ok
        }
        Shape::Cylinder { radius_m, height_m } => {
            if !(radius_m.is_finite() && radius_m > 0.0 && height_m.is_finite() && height_m > 0.0) {
                return None;
            }
            let n = CYLINDER_SIDES;
            let step = std::f64::consts::TAU / n as f64;
            for z in [-height_m / 2.0, height_m / 2.0] {
                for i in 0..n {
                    let (s, c) = (step * i as f64).sin_cos();
                    buf.verts
                        .push(solid.pose * Point3::new(radius_m * c, radius_m * s, z));
                }
            }
            // Bottom ring 0..n, top ring n..2n.
            let mut ok = push_face(buf, v0, (0..n).rev());
            ok &= push_face(buf, v0, n..2 * n);
            for i in 0..n {
                let j = (i + 1) % n;
                ok &= push_face(buf, v0, [i, j, n + j, n + i].into_iter());
            }
            buf.axes.push(rot * Vector3::z());
            for i in 0..n / 2 {
                let (s, c) = (step * (i as f64 + 0.5)).sin_cos();
                buf.axes.push(rot * Vector3::new(c, s, 0.0));
            }
            ok
        }
    };
    let axes_ok = buf.axes[a0..]
        .iter()
        .all(|a| a.iter().all(|v| v.is_finite()));
    let verts_ok = buf.verts[v0..]
        .iter()
        .all(|p| p.iter().all(|v| v.is_finite()));
    if !(faces_ok && axes_ok && verts_ok) {
        buf.verts.truncate(v0);
        buf.faces.truncate(f0);
        buf.axes.truncate(a0);
        buf.indices.truncate(i0);
        return None;
    }
    Some(SolidMesh {
        verts: v0..buf.verts.len(),
        faces: f0..buf.faces.len(),
        axes: a0..buf.axes.len(),
    })
}

/// Appends a face of vertices `v0 + i`; false when it is degenerate.
fn push_face(buf: &mut MeshBuffers, v0: usize, local: impl Iterator<Item = usize>) -> bool {
    let start = buf.indices.len();
    buf.indices.extend(local.map(|i| v0 + i));
    let end = buf.indices.len();
    let verts = &buf.verts;
    let normal = polygon_normal(buf.indices[start..end].iter().map(|&i| verts[i]));
    match normal {
        Some(normal) => {
            buf.faces.push(MeshFace {
                indices: start..end,
                normal,
            });
            true
        }
        None => false,
    }
}

/// How two disjoint convex solids are ordered as seen from the camera.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Relation {
    /// The first may hide the second; the second never hides the first.
    FirstInFront,
    /// The second may hide the first; the first never hides the second.
    SecondInFront,
    /// Neither can hide the other.
    Unrelated,
    /// No separating plane found (they touch or interpenetrate).
    Unknown,
}

/// Orders two convex solids by a separating plane: the solid on the camera's side of it is in
/// front (a ray from the camera crosses the plane at most once).
pub(crate) fn relation(
    a_verts: &[Point3<f64>],
    a_axes: &[Vector3<f64>],
    b_verts: &[Point3<f64>],
    b_axes: &[Vector3<f64>],
    camera: &Point3<f64>,
) -> Relation {
    let test = |axis: &Vector3<f64>| -> Option<Relation> {
        let range = |verts: &[Point3<f64>]| {
            verts
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| {
                    let d = axis.dot(&p.coords);
                    (lo.min(d), hi.max(d))
                })
        };
        let (a_lo, a_hi) = range(a_verts);
        let (b_lo, b_hi) = range(b_verts);
        let c = axis.dot(&camera.coords);
        const TOUCH: f64 = 1e-7;
        if a_hi <= b_lo + TOUCH {
            Some(if c <= a_hi {
                Relation::FirstInFront
            } else if c >= b_lo {
                Relation::SecondInFront
            } else {
                Relation::Unrelated
            })
        } else if b_hi <= a_lo + TOUCH {
            Some(if c <= b_hi {
                Relation::SecondInFront
            } else if c >= a_lo {
                Relation::FirstInFront
            } else {
                Relation::Unrelated
            })
        } else {
            None
        }
    };
    for axis in a_axes.iter().chain(b_axes) {
        if let Some(r) = test(axis) {
            return r;
        }
    }
    for a in a_axes {
        for b in b_axes {
            let axis = a.cross(b);
            let len = axis.norm();
            if len > 1e-9 {
                if let Some(r) = test(&(axis / len)) {
                    return r;
                }
            }
        }
    }
    Relation::Unknown
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Translation3, UnitQuaternion};

    fn solid(shape: Shape, x: f64, y: f64, z: f64) -> Solid {
        Solid {
            shape,
            pose: Isometry3::from_parts(
                Translation3::new(x, y, z),
                UnitQuaternion::from_euler_angles(0.1, -0.2, 0.7),
            ),
            color: [0, 0, 0],
        }
    }

    #[test]
    fn faces_point_outwards() {
        let mut buf = MeshBuffers::default();
        for shape in [
            Shape::Box {
                size_m: Vector3::new(0.02, 0.03, 0.05),
            },
            Shape::Cylinder {
                radius_m: 0.02,
                height_m: 0.04,
            },
        ] {
            buf.clear();
            let s = solid(shape, 0.3, 0.1, 0.02);
            let mesh = push_solid(&mut buf, &s).unwrap();
            let centre = s.pose.translation.vector;
            for face in &buf.faces[mesh.faces.clone()] {
                let p = buf.verts[buf.indices[face.indices.start]];
                assert!(face.normal.dot(&(p.coords - centre)) > 0.0);
            }
            let expected = match shape {
                Shape::Box { .. } => 6,
                Shape::Cylinder { .. } => CYLINDER_SIDES + 2,
            };
            assert_eq!(mesh.faces.len(), expected);
        }
    }

    #[test]
    fn bad_solids_are_refused_without_leftovers() {
        let mut buf = MeshBuffers::default();
        let bad = [
            solid(
                Shape::Box {
                    size_m: Vector3::new(0.0, 1.0, 1.0),
                },
                0.0,
                0.0,
                0.0,
            ),
            solid(
                Shape::Cylinder {
                    radius_m: f64::NAN,
                    height_m: 1.0,
                },
                0.0,
                0.0,
                0.0,
            ),
            solid(
                Shape::Cylinder {
                    radius_m: 1.0,
                    height_m: 1.0,
                },
                f64::INFINITY,
                0.0,
                0.0,
            ),
        ];
        for s in &bad {
            assert!(push_solid(&mut buf, s).is_none());
        }
        assert!(buf.verts.is_empty() && buf.faces.is_empty() && buf.indices.is_empty());
    }

    #[test]
    fn the_solid_nearer_the_camera_is_in_front() {
        let mut buf = MeshBuffers::default();
        let cube = Shape::Box {
            size_m: Vector3::new(0.02, 0.02, 0.02),
        };
        let a = push_solid(&mut buf, &solid(cube, 0.2, 0.0, 0.01)).unwrap();
        let b = push_solid(&mut buf, &solid(cube, 0.3, 0.0, 0.01)).unwrap();
        let rel = |cam: Point3<f64>| {
            relation(
                &buf.verts[a.verts.clone()],
                &buf.axes[a.axes.clone()],
                &buf.verts[b.verts.clone()],
                &buf.axes[b.axes.clone()],
                &cam,
            )
        };
        assert_eq!(rel(Point3::new(0.0, 0.0, 0.2)), Relation::FirstInFront);
        assert_eq!(rel(Point3::new(0.5, 0.0, 0.2)), Relation::SecondInFront);
        assert_eq!(rel(Point3::new(0.25, 0.0, 0.01)), Relation::Unrelated);
    }
}
