//! Convex geometry for the world: separating-axis tests between boxes and upright prisms (a
//! cylinder is a 16-sided prism, within 0.3 mm of the true surface for a 30 mm cylinder), how
//! far a shape must be shoved along a direction to clear another, and 2-D footprints.

use nalgebra::{Isometry3, Point3, Rotation2, Vector2, Vector3};
use std::f64::consts::PI;

/// Sides of the prism that stands in for a cylinder.
pub(crate) const CYLINDER_SIDES: usize = 16;

/// A convex polyhedron with what the separating-axis test needs.
#[derive(Debug, Clone)]
pub(crate) struct Hull {
    verts: Vec<Point3<f64>>,
    /// Unit face normals, one per family of parallel faces.
    normals: Vec<Vector3<f64>>,
    /// Unit edge directions, one per family of parallel edges.
    edges: Vec<Vector3<f64>>,
    centre: Point3<f64>,
    radius: f64,
}

impl Hull {
    /// A box of half extents `half` centred at `pose`.
    pub fn cuboid(pose: &Isometry3<f64>, half: &Vector3<f64>) -> Hull {
        let mut verts = Vec::with_capacity(8);
        for sx in [-1.0, 1.0] {
            for sy in [-1.0, 1.0] {
                for sz in [-1.0, 1.0] {
                    verts.push(pose * Point3::new(sx * half.x, sy * half.y, sz * half.z));
                }
            }
        }
        let r = pose.rotation;
        let axes = vec![r * Vector3::x(), r * Vector3::y(), r * Vector3::z()];
        Hull {
            verts,
            normals: axes.clone(),
            edges: axes,
            centre: pose * Point3::origin(),
            radius: half.norm(),
        }
    }

    /// A regular prism standing for a cylinder of `radius` and half height `half_h` along the
    /// local z axis of `pose`, centred at `pose`.
    pub fn prism(pose: &Isometry3<f64>, radius: f64, half_h: f64) -> Hull {
        let n = CYLINDER_SIDES;
        let mut verts = Vec::with_capacity(2 * n);
        for i in 0..n {
            let a = 2.0 * PI * i as f64 / n as f64;
            let (s, c) = a.sin_cos();
            verts.push(pose * Point3::new(radius * c, radius * s, -half_h));
            verts.push(pose * Point3::new(radius * c, radius * s, half_h));
        }
        let r = pose.rotation;
        let mut normals = vec![r * Vector3::z()];
        let mut edges = vec![r * Vector3::z()];
        for i in 0..n / 2 {
            let a = 2.0 * PI * (i as f64 + 0.5) / n as f64;
            let (s, c) = a.sin_cos();
            normals.push(r * Vector3::new(c, s, 0.0));
            edges.push(r * Vector3::new(-s, c, 0.0));
        }
        Hull {
            verts,
            normals,
            edges,
            centre: pose * Point3::origin(),
            radius: radius.hypot(half_h),
        }
    }

    fn project(&self, axis: &Vector3<f64>) -> (f64, f64) {
        let mut lo = f64::INFINITY;
        let mut hi = f64::NEG_INFINITY;
        for v in &self.verts {
            let p = axis.dot(&v.coords);
            lo = lo.min(p);
            hi = hi.max(p);
        }
        (lo, hi)
    }

    /// Lowest z of the hull.
    pub fn min_z(&self) -> f64 {
        self.verts.iter().map(|v| v.z).fold(f64::INFINITY, f64::min)
    }

    /// Whether the bounding spheres are apart by more than `margin`.
    fn far_from(&self, other: &Hull, margin: f64) -> bool {
        (self.centre - other.centre).norm() > self.radius + other.radius + margin
    }
}

/// Candidate separating axes of two convex polyhedra (unit vectors).
fn axes(a: &Hull, b: &Hull) -> Vec<Vector3<f64>> {
    let mut out =
        Vec::with_capacity(a.normals.len() + b.normals.len() + a.edges.len() * b.edges.len());
    out.extend(a.normals.iter().copied());
    out.extend(b.normals.iter().copied());
    for ea in &a.edges {
        for eb in &b.edges {
            let c = ea.cross(eb);
            let n = c.norm();
            if n > 1e-9 {
                out.push(c / n);
            }
        }
    }
    out
}

/// How deeply `a` and `b` interpenetrate: the smallest overlap over all separating axes
/// (exact for convex polyhedra). Zero or negative when they are apart or just touching.
pub(crate) fn penetration(a: &Hull, b: &Hull) -> f64 {
    if a.far_from(b, 0.0) {
        return -1.0;
    }
    let mut depth = f64::INFINITY;
    for axis in axes(a, b) {
        let (alo, ahi) = a.project(&axis);
        let (blo, bhi) = b.project(&axis);
        let overlap = ahi.min(bhi) - alo.max(blo);
        if overlap <= 0.0 {
            return overlap;
        }
        depth = depth.min(overlap);
    }
    depth
}

/// How far `moving` must travel along the unit direction `dir` to stop overlapping `fixed`:
/// the first translation at which some axis separates them. Zero when they are apart;
/// infinite when no translation along `dir` separates them.
pub(crate) fn push_out(fixed: &Hull, moving: &Hull, dir: &Vector3<f64>) -> f64 {
    if fixed.far_from(moving, 0.0) {
        return 0.0;
    }
    let mut best = f64::INFINITY;
    for axis in axes(fixed, moving) {
        let (flo, fhi) = fixed.project(&axis);
        let (mlo, mhi) = moving.project(&axis);
        if fhi.min(mhi) - flo.max(mlo) <= 0.0 {
            return 0.0;
        }
        let s = axis.dot(dir);
        let t = if s > 1e-9 {
            (fhi - mlo) / s
        } else if s < -1e-9 {
            (mhi - flo) / -s
        } else {
            continue;
        };
        best = best.min(t.max(0.0));
    }
    best
}

/// The outline of an upright object on the table.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Footprint {
    /// A rectangle of half extents `half` (along its own x, y) rotated by `yaw` about `c`.
    Rect {
        c: Vector2<f64>,
        half: Vector2<f64>,
        yaw: f64,
    },
    /// A disc.
    Circle { c: Vector2<f64>, r: f64 },
}

impl Footprint {
    fn corners(c: &Vector2<f64>, half: &Vector2<f64>, yaw: f64) -> [Vector2<f64>; 4] {
        let r = Rotation2::new(yaw);
        [
            c + r * Vector2::new(half.x, half.y),
            c + r * Vector2::new(-half.x, half.y),
            c + r * Vector2::new(-half.x, -half.y),
            c + r * Vector2::new(half.x, -half.y),
        ]
    }
}

/// `p` in the frame of a rectangle centred at `c` rotated by `yaw`.
fn to_rect_frame(p: &Vector2<f64>, c: &Vector2<f64>, yaw: f64) -> Vector2<f64> {
    Rotation2::new(-yaw) * (p - c)
}

/// How deeply two footprints overlap (positive), or ≤ 0 when they are apart or touching.
pub(crate) fn footprint_overlap(a: &Footprint, b: &Footprint) -> f64 {
    match (a, b) {
        (Footprint::Circle { c: ca, r: ra }, Footprint::Circle { c: cb, r: rb }) => {
            ra + rb - (ca - cb).norm()
        }
        (Footprint::Circle { c: cc, r }, Footprint::Rect { c, half, yaw })
        | (Footprint::Rect { c, half, yaw }, Footprint::Circle { c: cc, r }) => {
            let q = to_rect_frame(cc, c, *yaw);
            let clamped = Vector2::new(q.x.clamp(-half.x, half.x), q.y.clamp(-half.y, half.y));
            if q.x.abs() <= half.x && q.y.abs() <= half.y {
                r + (half.x - q.x.abs()).min(half.y - q.y.abs())
            } else {
                r - (q - clamped).norm()
            }
        }
        (
            Footprint::Rect {
                c: ca,
                half: ha,
                yaw: ya,
            },
            Footprint::Rect {
                c: cb,
                half: hb,
                yaw: yb,
            },
        ) => {
            let pa = Footprint::corners(ca, ha, *ya);
            let pb = Footprint::corners(cb, hb, *yb);
            let mut depth = f64::INFINITY;
            for yaw in [*ya, *yb] {
                let (s, c) = yaw.sin_cos();
                for axis in [Vector2::new(c, s), Vector2::new(-s, c)] {
                    let proj = |pts: &[Vector2<f64>; 4]| {
                        pts.iter()
                            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| {
                                let d = axis.dot(p);
                                (lo.min(d), hi.max(d))
                            })
                    };
                    let (alo, ahi) = proj(&pa);
                    let (blo, bhi) = proj(&pb);
                    let overlap = ahi.min(bhi) - alo.max(blo);
                    if overlap <= 0.0 {
                        return overlap;
                    }
                    depth = depth.min(overlap);
                }
            }
            depth
        }
    }
}

/// Whether footprint `a` lies inside the rectangle centred at `c` with half extents `half`
/// rotated by `yaw`, with `tol` to spare.
pub(crate) fn footprint_inside_rect(
    a: &Footprint,
    c: &Vector2<f64>,
    half: &Vector2<f64>,
    yaw: f64,
    tol: f64,
) -> bool {
    match a {
        Footprint::Circle { c: cc, r } => {
            let q = to_rect_frame(cc, c, yaw);
            q.x.abs() + r <= half.x + tol && q.y.abs() + r <= half.y + tol
        }
        Footprint::Rect {
            c: ca,
            half: ha,
            yaw: ya,
        } => Footprint::corners(ca, ha, *ya).iter().all(|p| {
            let q = to_rect_frame(p, c, yaw);
            q.x.abs() <= half.x + tol && q.y.abs() <= half.y + tol
        }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Translation3, UnitQuaternion};

    fn at(x: f64, y: f64, z: f64, yaw: f64) -> Isometry3<f64> {
        Isometry3::from_parts(
            Translation3::new(x, y, z),
            UnitQuaternion::from_euler_angles(0.0, 0.0, yaw),
        )
    }

    #[test]
    fn boxes_overlap_and_separate() {
        let h = Vector3::new(0.01, 0.01, 0.01);
        let a = Hull::cuboid(&at(0.0, 0.0, 0.0, 0.0), &h);
        let b = Hull::cuboid(&at(0.015, 0.0, 0.0, 0.0), &h);
        assert!((penetration(&a, &b) - 0.005).abs() < 1e-12);
        let c = Hull::cuboid(&at(0.021, 0.0, 0.0, 0.0), &h);
        assert!(penetration(&a, &c) <= 0.0);
        // A rotated box whose corner pokes 1 mm into the other.
        let d = Hull::cuboid(
            &at(0.01 + 0.01 * 2f64.sqrt() - 0.001, 0.0, 0.0, PI / 4.0),
            &h,
        );
        assert!((penetration(&a, &d) - 0.001).abs() < 1e-9);
        // Push b out along +x: 5 mm; along +y: 20 mm.
        assert!((push_out(&a, &b, &Vector3::x()) - 0.005).abs() < 1e-12);
        assert!((push_out(&a, &b, &Vector3::y()) - 0.02).abs() < 1e-12);
    }

    #[test]
    fn prism_approximates_a_cylinder() {
        let p = Hull::prism(&at(0.0, 0.0, 0.0, 0.0), 0.015, 0.02);
        let b = Hull::cuboid(&at(0.0, 0.0245, 0.0, 0.0), &Vector3::new(0.01, 0.01, 0.01));
        let d = penetration(&p, &b);
        assert!((d - 0.0005).abs() < 0.0003, "{d}");
        assert!((p.min_z() + 0.02).abs() < 1e-12);
    }

    #[test]
    fn footprints() {
        let rect = |x: f64, y: f64, hx: f64, hy: f64, yaw: f64| Footprint::Rect {
            c: Vector2::new(x, y),
            half: Vector2::new(hx, hy),
            yaw,
        };
        let circle = |x: f64, y: f64, r: f64| Footprint::Circle {
            c: Vector2::new(x, y),
            r,
        };
        assert!(
            footprint_overlap(
                &rect(0.0, 0.0, 0.01, 0.01, 0.0),
                &rect(0.021, 0.0, 0.01, 0.01, 0.0)
            ) < 0.0
        );
        assert!(
            footprint_overlap(
                &rect(0.0, 0.0, 0.01, 0.01, 0.0),
                &rect(0.019, 0.0, 0.01, 0.01, 0.3)
            ) > 0.0
        );
        assert!(
            (footprint_overlap(&circle(0.0, 0.0, 0.01), &circle(0.015, 0.0, 0.01)) - 0.005).abs()
                < 1e-12
        );
        assert!(
            footprint_overlap(&circle(0.0, 0.0, 0.01), &rect(0.0, 0.0205, 0.01, 0.01, 0.0)) < 0.0
        );
        assert!(
            footprint_overlap(&circle(0.0, 0.0, 0.01), &rect(0.0, 0.019, 0.01, 0.01, 0.0)) > 0.0
        );
        assert!(footprint_inside_rect(
            &circle(0.0, 0.0, 0.01),
            &Vector2::zeros(),
            &Vector2::new(0.02, 0.02),
            0.0,
            0.0
        ));
        assert!(!footprint_inside_rect(
            &rect(0.0, 0.0, 0.03, 0.01, 0.0),
            &Vector2::zeros(),
            &Vector2::new(0.02, 0.02),
            0.0,
            0.0
        ));
    }
}
