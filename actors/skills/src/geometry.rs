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

/// `close to` placement: beside the reference on the free side nearest `wanted`, never on
/// it. `None` when every side is taken or outside the workspaces.
pub fn close_to(
    reference: &DetectedObject,
    held_extents: (f64, f64),
    wanted: Point2,
    others: &[DetectedObject],
    fits: impl Fn(Point2) -> bool,
) -> Option<Point2> {
    let mut sides: Vec<Point2> = [
        Location::LeftNextTo,
        Location::RightNextTo,
        Location::Above,
        Location::Below,
    ]
    .iter()
    .filter_map(|side| beside(reference, *side, held_extents))
    .collect();
    sides.sort_by(|a, b| a.distance_to(&wanted).total_cmp(&b.distance_to(&wanted)));
    let neighbours: Vec<DetectedObject> = others
        .iter()
        .filter(|o| o.id != reference.id)
        .cloned()
        .collect();
    sides
        .into_iter()
        .find(|p| fits(*p) && !overlaps(*p, held_extents, &neighbours, 0.005))
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
    fn close_to_takes_the_free_side_nearest_the_wish() {
        let r = object("obj-1", 0.25, 0.0, 0.04, 0.04, 0.015);
        let blocker = object("obj-2", 0.25, 0.05, 0.03, 0.03, 0.015);
        // Wanted left of the reference, but the left side is taken.
        let p = close_to(
            &r,
            (0.02, 0.02),
            Point2::new(0.25, 0.06),
            &[r.clone(), blocker],
            |_| true,
        )
        .unwrap();
        assert!(p.distance_to(&r.xy()) > 0.02, "never on top: {p}");
        assert!(
            p.y_m <= 0.0 || p.x_m != 0.25,
            "not the blocked left side: {p}"
        );
        assert!(close_to(&r, (0.02, 0.02), Point2::new(0.25, 0.06), &[], |_| false).is_none());
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
