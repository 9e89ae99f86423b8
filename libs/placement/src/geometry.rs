//! The skills' table geometry, pure functions: which workspace a point lies in, where a
//! placement puts the held object relative to a reference (the Location table of the tool
//! contract), where a push starts, and whether a grasp fits the gripper.

use robotd_protocol::location::PLACE_GAP_M;
use robotd_protocol::objects::DetectedObject;
use robotd_protocol::workspace::WorkspaceInfo;
use robotd_protocol::{Direction, Location, Point2};

/// The workspace `p` lies in (within `margin_m` of its rectangle), if any.
pub fn workspace_of(
    workspaces: &[WorkspaceInfo],
    p: Point2,
    margin_m: f64,
) -> Option<&WorkspaceInfo> {
    workspaces.iter().find(|w| w.contains(p, margin_m))
}

/// Extent of an object along y (width) and x (height), metres.
pub fn extents(o: &DetectedObject) -> (f64, f64) {
    (o.dimensions.width_m, o.dimensions.height_m)
}

/// Height of an object's top above the table, metres (perception puts the centre of mass at
/// half the object's height).
pub fn top_z(o: &DetectedObject) -> f64 {
    (o.position.center_of_mass.z_m * 2.0).max(0.0)
}

/// How far a stacked object's centre may lie outside the footprint of the object it rests on
/// (the camera's measurement of either), metres.
pub const STACK_SUPPORT_TOLERANCE_M: f64 = 0.005;

/// Whether `upper` rests on `lower`: its centre of mass is higher and lies on `lower`'s
/// footprint (within [`STACK_SUPPORT_TOLERANCE_M`]). Objects on the table never overlap, so an
/// object whose centre lies on another's footprint stands on it.
pub fn rests_on(upper: &DetectedObject, lower: &DetectedObject) -> bool {
    upper.id != lower.id
        && lower.position.center_of_mass.z_m < upper.position.center_of_mass.z_m - 0.001
        && Rect::of_object(lower)
            .grown(STACK_SUPPORT_TOLERANCE_M)
            .contains(&Rect::footprint(upper.xy(), (0.0, 0.0)))
}

/// Height of the surface `o` stands on among `objects`: the top of the highest object it rests
/// on ([`rests_on`]; the workspace model reports a stacked object at its true height), else the
/// table, 0.
pub fn base_z(o: &DetectedObject, objects: &[DetectedObject]) -> f64 {
    objects
        .iter()
        .filter(|lower| rests_on(o, lower))
        .map(|lower| top_among(lower, objects))
        .fold(0.0, f64::max)
}

/// Height of `o`'s top among `objects`: its base ([`base_z`]) plus its own height (twice its
/// centre of mass above the base).
pub fn top_among(o: &DetectedObject, objects: &[DetectedObject]) -> f64 {
    let base = base_z(o, objects);
    (2.0 * o.position.center_of_mass.z_m - base).max(base)
}

/// The skills' own check of a table placement (`place_object` with no location) of `object` at
/// `at` among `others` (the objects on the table without it), held at gripper yaw `yaw_rad`
/// by the grasp the skills take of it on the table: `None` when the skills would place it
/// there, else why not. The workspace model answers free space with it.
pub fn table_place_problem(
    settings: &crate::SkillsSettings,
    others: &[DetectedObject],
    object: &DetectedObject,
    yaw_rad: f64,
    at: Point2,
) -> Option<String> {
    let held = crate::plan::HeldPlan {
        object,
        yaw_rad,
        tcp_above_base_m: crate::plan::grasp_height_on(settings, object, 0.0, 0.0),
    };
    crate::plan::place_target(settings, others, &held, at, Location::None)
        .err()
        .map(|e| e.to_string())
}

/// Where a placement with `location` relative to `reference` puts the centre of the held
/// object (`held_extents` = its width along y, height along x), for the four side-by-side
/// locations of the contract.
pub fn beside(
    reference: &DetectedObject,
    side: Location,
    held_extents: (f64, f64),
) -> Option<Point2> {
    let r = reference.xy();
    let (rw, rh) = extents(reference);
    let (hw, hh) = held_extents;
    let dy = rw / 2.0 + PLACE_GAP_M + hw / 2.0;
    let dx = rh / 2.0 + PLACE_GAP_M + hh / 2.0;
    Some(match side {
        Location::LeftNextTo => Point2::new(r.x_m, r.y_m + dy),
        Location::RightNextTo => Point2::new(r.x_m, r.y_m - dy),
        Location::Above => Point2::new(r.x_m + dx, r.y_m),
        Location::Below => Point2::new(r.x_m - dx, r.y_m),
        _ => return None,
    })
}

/// Whether a rectangle of `extents` centred at `at` overlaps any of `others` (footprints
/// grown by `gap_m`).
pub fn overlaps(at: Point2, extents: (f64, f64), others: &[DetectedObject], gap_m: f64) -> bool {
    others.iter().any(|o| {
        let (ow, oh) = self::extents(o);
        let c = o.xy();
        (at.y_m - c.y_m).abs() < (extents.0 + ow) / 2.0 + gap_m
            && (at.x_m - c.x_m).abs() < (extents.1 + oh) / 2.0 + gap_m
    })
}

/// Where the tool starts a push of `object` in `direction`: `clearance_m` behind its edge.
pub fn push_start(object: &DetectedObject, direction: Direction, clearance_m: f64) -> Point2 {
    let c = object.xy();
    let (w, h) = extents(object);
    match direction {
        Direction::Up => Point2::new(c.x_m - h / 2.0 - clearance_m, c.y_m),
        Direction::Down => Point2::new(c.x_m + h / 2.0 + clearance_m, c.y_m),
        Direction::Left => Point2::new(c.x_m, c.y_m - w / 2.0 - clearance_m),
        Direction::Right => Point2::new(c.x_m, c.y_m + w / 2.0 + clearance_m),
    }
}

/// A rectangle on the table, turned by `yaw_rad` about the vertical: `half_x_m` along its own
/// x axis, `half_y_m` along its y axis.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Rect {
    /// Centre on the table.
    pub centre: Point2,
    /// Half its extent along its own x axis, metres.
    pub half_x_m: f64,
    /// Half its extent along its own y axis, metres.
    pub half_y_m: f64,
    /// Its turn about the vertical, radians (0: its x axis is the world's).
    pub yaw_rad: f64,
}

impl Rect {
    /// An object's footprint: its long side along its grasp yaw's x axis (the detector turns
    /// the gripper across the narrow side), its short side across.
    pub fn of_object(o: &DetectedObject) -> Rect {
        Rect::of_object_at(o, o.xy())
    }

    /// `o`'s footprint moved to `at`, turned as it is now.
    pub fn of_object_at(o: &DetectedObject, at: Point2) -> Rect {
        let (w, h) = extents(o);
        Rect {
            centre: at,
            half_x_m: w.max(h) / 2.0,
            half_y_m: w.min(h) / 2.0,
            yaw_rad: o.gripper_rotation_rad,
        }
    }

    /// The four corners.
    pub fn corners(&self) -> [Point2; 4] {
        let [u, v] = self.axes();
        let c = self.centre;
        [(1.0, 1.0), (1.0, -1.0), (-1.0, -1.0), (-1.0, 1.0)].map(|(a, b)| {
            Point2::new(
                c.x_m + a * self.half_x_m * u.0 + b * self.half_y_m * v.0,
                c.y_m + a * self.half_x_m * u.1 + b * self.half_y_m * v.1,
            )
        })
    }

    /// Whether `other` lies wholly inside this rectangle.
    pub fn contains(&self, other: &Rect) -> bool {
        let [u, v] = self.axes();
        other.corners().iter().all(|p| {
            let d = (p.x_m - self.centre.x_m, p.y_m - self.centre.y_m);
            (d.0 * u.0 + d.1 * u.1).abs() <= self.half_x_m + 1e-9
                && (d.0 * v.0 + d.1 * v.1).abs() <= self.half_y_m + 1e-9
        })
    }

    /// Half the rectangle's extent along the world's x axis.
    pub fn half_extent_x(&self) -> f64 {
        self.radius_along((1.0, 0.0))
    }

    /// Half the rectangle's extent along the world's y axis.
    pub fn half_extent_y(&self) -> f64 {
        self.radius_along((0.0, 1.0))
    }

    /// An axis-aligned footprint of `extents` (width along y, height along x) at `centre`.
    pub fn footprint(centre: Point2, extents: (f64, f64)) -> Rect {
        Rect {
            centre,
            half_x_m: extents.1 / 2.0,
            half_y_m: extents.0 / 2.0,
            yaw_rad: 0.0,
        }
    }

    /// The same rectangle grown by `gap_m` on every side.
    pub fn grown(self, gap_m: f64) -> Rect {
        Rect {
            half_x_m: self.half_x_m + gap_m,
            half_y_m: self.half_y_m + gap_m,
            ..self
        }
    }

    fn axes(&self) -> [(f64, f64); 2] {
        let (s, c) = self.yaw_rad.sin_cos();
        [(c, s), (-s, c)]
    }

    /// Half the rectangle's extent along the unit direction `axis`.
    fn radius_along(&self, axis: (f64, f64)) -> f64 {
        let [u, v] = self.axes();
        self.half_x_m * (u.0 * axis.0 + u.1 * axis.1).abs()
            + self.half_y_m * (v.0 * axis.0 + v.1 * axis.1).abs()
    }

    /// Whether the two rectangles overlap (separating axis test; touching is not overlapping).
    pub fn overlaps(&self, other: &Rect) -> bool {
        let d = (
            other.centre.x_m - self.centre.x_m,
            other.centre.y_m - self.centre.y_m,
        );
        self.axes().into_iter().chain(other.axes()).all(|axis| {
            let distance = (d.0 * axis.0 + d.1 * axis.1).abs();
            distance < self.radius_along(axis) + other.radius_along(axis)
        })
    }
}

/// What the open fingers sweep on the table around a tool centre at `at` turned by `yaw_rad`
/// (a tool pointing down): along the closing axis, `reach_m` each side of the centre (half the
/// opening plus a finger's thickness); across it, `half_width_m` each side.
pub fn finger_sweep(at: Point2, yaw_rad: f64, reach_m: f64, half_width_m: f64) -> Rect {
    // The closing axis of a tool pointing down with yaw ψ is (−sin ψ, cos ψ): the rectangle's
    // y axis.
    Rect {
        centre: at,
        half_x_m: half_width_m,
        half_y_m: reach_m,
        yaw_rad,
    }
}

/// The squares around a workspace's four corner markers that placed or pushed objects must
/// keep clear of, so that the camera keeps seeing every marker: `keep_out_m` each side of the
/// marker's centre.
pub fn marker_zones(workspace: &WorkspaceInfo, keep_out_m: f64) -> [Rect; 4] {
    let (ul, lr) = (workspace.upper_left, workspace.lower_right);
    [
        Point2::new(ul.x_m, ul.y_m),
        Point2::new(ul.x_m, lr.y_m),
        Point2::new(lr.x_m, ul.y_m),
        Point2::new(lr.x_m, lr.y_m),
    ]
    .map(|corner| Rect {
        centre: corner,
        half_x_m: keep_out_m,
        half_y_m: keep_out_m,
        yaw_rad: 0.0,
    })
}

/// The object's extent across the fingers when grasped across its narrow side, metres.
pub fn grasp_width(o: &DetectedObject) -> f64 {
    let (w, h) = extents(o);
    w.min(h)
}

#[cfg(test)]
mod tests {
    use super::*;
    use robotd_protocol::objects::{Dimensions, ObjectPosition};
    use robotd_protocol::Point3;

    fn object(id: &str, x: f64, y: f64, w: f64, h: f64, z: f64) -> DetectedObject {
        DetectedObject {
            id: id.into(),
            label: "box".into(),
            position: ObjectPosition {
                center_of_mass: Point3::new(x, y, z),
                center: Point3::new(x, y, z),
            },
            dimensions: Dimensions {
                width_m: w,
                height_m: h,
                size_m2: w * h,
            },
            ..Default::default()
        }
    }

    #[test]
    fn placements_follow_the_location_table() {
        let r = object("obj-1", 0.25, 0.0, 0.04, 0.06, 0.015);
        let held = (0.02, 0.03);
        let p = beside(&r, Location::RightNextTo, held).unwrap();
        assert!((p.y_m - (0.0 - 0.02 - 0.02 - 0.01)).abs() < 1e-12);
        assert_eq!(p.x_m, 0.25);
        let p = beside(&r, Location::Above, held).unwrap();
        assert!((p.x_m - (0.25 + 0.03 + 0.02 + 0.015)).abs() < 1e-12);
        assert!(beside(&r, Location::OnTopOf, held).is_none());
        assert!((top_z(&r) - 0.03).abs() < 1e-12);
    }

    #[test]
    fn a_stacked_object_stands_on_the_top_of_the_one_below() {
        let cube = object("obj-1", 0.28, 0.04, 0.03, 0.03, 0.015);
        // A 40 mm cylinder on the cube: its centre 20 mm above the cube's top, 4 mm off centre.
        let cylinder = object("obj-2", 0.284, 0.04, 0.03, 0.03, 0.05);
        let beside = object("obj-3", 0.22, 0.04, 0.03, 0.03, 0.02);
        let all = [cube.clone(), cylinder.clone(), beside.clone()];
        assert!(rests_on(&cylinder, &cube) && !rests_on(&cube, &cylinder));
        assert!((base_z(&cylinder, &all) - 0.03).abs() < 1e-12);
        assert!((top_among(&cylinder, &all) - 0.07).abs() < 1e-12);
        assert_eq!(base_z(&cube, &all), 0.0);
        assert!((top_among(&beside, &all) - 0.04).abs() < 1e-12);
        // A third on top: on the cylinder's top.
        let third = object("obj-4", 0.28, 0.04, 0.02, 0.02, 0.08);
        let all = [cube, cylinder, beside, third.clone()];
        assert!((base_z(&third, &all) - 0.07).abs() < 1e-12);
    }

    #[test]
    fn rectangles_overlap_only_when_they_do() {
        let a = Rect::footprint(Point2::new(0.0, 0.0), (0.02, 0.02));
        let touching = Rect::footprint(Point2::new(0.02, 0.0), (0.02, 0.02));
        assert!(!a.overlaps(&touching));
        assert!(a.overlaps(&touching.grown(0.001)));
        // A long thin rectangle turned 45° reaches a square its axis-aligned box would not.
        let diagonal = Rect {
            centre: Point2::new(0.0, 0.0),
            half_x_m: 0.05,
            half_y_m: 0.002,
            yaw_rad: std::f64::consts::FRAC_PI_4,
        };
        assert!(diagonal.overlaps(&Rect::footprint(Point2::new(0.03, 0.03), (0.01, 0.01))));
        assert!(!diagonal.overlaps(&Rect::footprint(Point2::new(0.03, -0.03), (0.01, 0.01))));
    }

    #[test]
    fn an_object_footprint_is_turned_by_its_grasp_yaw() {
        // A pencil lying along y: 120 mm wide (along y), 12 mm high (along x), grasped at 90°.
        let mut pencil = object("obj-1", 0.25, 0.0, 0.12, 0.012, 0.005);
        pencil.gripper_rotation_rad = std::f64::consts::FRAC_PI_2;
        let r = Rect::of_object(&pencil);
        assert!((r.half_extent_y() - 0.06).abs() < 1e-9);
        assert!((r.half_extent_x() - 0.006).abs() < 1e-9);
        assert!(r.overlaps(&Rect::footprint(Point2::new(0.25, 0.05), (0.01, 0.01))));
        assert!(!r.overlaps(&Rect::footprint(Point2::new(0.27, 0.0), (0.01, 0.01))));
        // Turned 45°, its axis-aligned box would hide a cube its real footprint misses.
        pencil.gripper_rotation_rad = std::f64::consts::FRAC_PI_4;
        let r = Rect::of_object(&pencil);
        assert!(!r.overlaps(&Rect::footprint(Point2::new(0.29, -0.03), (0.02, 0.02))));
        assert!(r.overlaps(&Rect::footprint(Point2::new(0.29, 0.04), (0.02, 0.02))));
    }

    #[test]
    fn open_fingers_sweep_across_the_closing_axis() {
        // Yaw 0: the fingers close along y.
        let sweep = finger_sweep(Point2::new(0.25, 0.0), 0.0, 0.028, 0.009);
        let beside_in_y = Rect::footprint(Point2::new(0.25, 0.04), (0.03, 0.03));
        assert!(
            sweep.overlaps(&beside_in_y),
            "a finger reaches y = 0.028 > 0.025"
        );
        let beside_in_x = Rect::footprint(Point2::new(0.28, 0.0), (0.03, 0.03));
        assert!(
            !sweep.overlaps(&beside_in_x),
            "across the fingers only 9 mm"
        );
        // Turned a quarter: the other way round.
        let turned = finger_sweep(
            Point2::new(0.25, 0.0),
            std::f64::consts::FRAC_PI_2,
            0.028,
            0.009,
        );
        assert!(!turned.overlaps(&beside_in_y));
        assert!(turned.overlaps(&beside_in_x));
    }

    #[test]
    fn pushes_start_behind_the_object() {
        let o = object("obj-1", 0.25, -0.02, 0.07, 0.09, 0.025);
        let s = push_start(&o, Direction::Right, 0.025);
        assert!((s.y_m - (-0.02 + 0.035 + 0.025)).abs() < 1e-12);
        let s = push_start(&o, Direction::Up, 0.025);
        assert!((s.x_m - (0.25 - 0.045 - 0.025)).abs() < 1e-12);
        assert!((grasp_width(&o) - 0.07).abs() < 1e-12);
    }
}
