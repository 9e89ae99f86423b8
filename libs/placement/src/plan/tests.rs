//! The planner's decisions on small hand-made tables: which grasp, which place, which push,
//! and the reason when there is none.

use super::*;
use robotd_protocol::objects::{Dimensions, ObjectPosition};
use robotd_protocol::{Point3, Pose, RobotModel};

/// The Ned2's sheet: markers at x 0.163 … 0.337, y -0.087 … 0.087.
fn settings() -> SkillsSettings {
    SkillsSettings::new(
        RobotModel::Ned2,
        vec![WorkspaceInfo {
            id: "niryo_ws".into(),
            robot: RobotModel::Ned2,
            upper_left: Point2::new(0.337, 0.087),
            lower_right: Point2::new(0.163, -0.087),
            observation_pose: Pose::default(),
        }],
    )
}

/// An object `along_x` × `along_y` metres and `tall` high, standing on the table at (x, y)
/// (footprints lie along their long side, turned by the gripper rotation: a quarter turn when
/// the long side is along y).
pub(crate) fn object(
    id: &str,
    label: &str,
    x: f64,
    y: f64,
    along_x: f64,
    along_y: f64,
    tall: f64,
) -> DetectedObject {
    DetectedObject {
        id: id.into(),
        label: label.into(),
        workspace_id: "niryo_ws".into(),
        position: ObjectPosition {
            center_of_mass: Point3::new(x, y, tall / 2.0),
            center: Point3::new(x, y, tall / 2.0),
        },
        dimensions: Dimensions {
            width_m: along_y,
            height_m: along_x,
            size_m2: along_x * along_y,
        },
        gripper_rotation_rad: if along_y > along_x { FRAC_PI_2 } else { 0.0 },
        ..Default::default()
    }
}

fn held(o: &DetectedObject) -> HeldPlan<'_> {
    HeldPlan {
        object: o,
        yaw_rad: o.gripper_rotation_rad,
        tcp_above_base_m: 0.01,
    }
}

#[test]
fn a_grasp_takes_the_yaw_with_room_and_names_what_blocks_every_yaw() {
    let s = settings();
    let cube = object("obj-1", "red cube", 0.25, 0.0, 0.03, 0.03, 0.03);
    // Alone: its own yaw.
    assert_eq!(
        grasp_yaw(&s, &cube, std::slice::from_ref(&cube), 0.015).unwrap(),
        0.0
    );
    // A tall neighbour where the fingers open at yaw 0 (they close along y): the turned grasp.
    let left = object("obj-2", "blue cylinder", 0.25, 0.035, 0.02, 0.02, 0.04);
    let yaw = grasp_yaw(&s, &cube, &[cube.clone(), left.clone()], 0.015).unwrap();
    assert!((yaw - FRAC_PI_2).abs() < 1e-9, "{yaw}");
    // Neighbours on both axes: refused, naming one of them.
    let front = object("obj-3", "green cylinder", 0.285, 0.0, 0.02, 0.02, 0.04);
    let error = grasp_yaw(&s, &cube, &[cube.clone(), left, front], 0.015).unwrap_err();
    let text = error.to_string();
    assert!(
        text.contains("fingers would hit") && text.contains("cylinder"),
        "{text}"
    );
    // A flat neighbour below the finger tips does not block.
    let pad = object("obj-4", "blue square", 0.25, 0.035, 0.02, 0.02, 0.002);
    assert_eq!(
        grasp_yaw(&s, &cube, &[cube.clone(), pad], 0.015).unwrap(),
        0.0
    );
}

#[test]
fn a_tall_neighbour_beside_the_palm_blocks_a_grasp_the_fingers_would_clear() {
    // A 12 mm cube and, 11 mm beyond its edge, a tall bottle: the fingers (9 mm each side
    // across the closing axis) pass it, the palm above them (15 mm each side) does not.
    let s = settings();
    let small = object("obj-1", "small cube", 0.25, 0.0, 0.012, 0.012, 0.012);
    let bottle = object("obj-2", "bottle", 0.271, 0.0, 0.02, 0.02, 0.08);
    let text = grasp_yaw(&s, &small, &[small.clone(), bottle.clone()], 0.006)
        .unwrap_err()
        .to_string();
    assert!(text.contains("bottle"), "{text}");
    // A short one at the same place stays below the palm: allowed.
    let cup = object("obj-3", "cup", 0.271, 0.0, 0.02, 0.02, 0.03);
    assert_eq!(
        grasp_yaw(&s, &small, &[small.clone(), cup], 0.006).unwrap(),
        0.0
    );
}

#[test]
fn a_place_must_be_on_the_sheet_clear_of_objects_and_markers() {
    let s = settings();
    let pencil = object("obj-1", "pencil", 0.0, 0.0, 0.01, 0.115, 0.01);
    let cube = object("obj-2", "red cube", 0.25, 0.0, 0.03, 0.03, 0.03);
    let others = [cube.clone()];
    let plan = held(&pencil);
    // A free spot: there, on the table.
    let (at, z) = place_target(&s, &others, &plan, Point2::new(0.30, 0.0), Location::None).unwrap();
    assert_eq!((at, z), (Point2::new(0.30, 0.0), 0.0));
    // On the cube: refused, naming it.
    let text = place_target(&s, &others, &plan, Point2::new(0.25, 0.0), Location::None)
        .unwrap_err()
        .to_string();
    assert!(text.contains("red cube"), "{text}");
    // Over a corner marker.
    let text = place_target(
        &s,
        &[],
        &held(&cube),
        Point2::new(0.17, 0.08),
        Location::None,
    )
    .unwrap_err()
    .to_string();
    assert!(text.contains("would cover the marker"), "{text}");
    // Off the sheet (the pencil's length reaches past the edge at y 0.099).
    let text = place_target(&s, &[], &plan, Point2::new(0.25, 0.07), Location::None)
        .unwrap_err()
        .to_string();
    assert!(text.contains("stick out of the sheet"), "{text}");
    // Outside every workspace.
    assert!(matches!(
        place_target(&s, &[], &plan, Point2::new(0.6, 0.0), Location::None),
        Err(SkillError::OutsideWorkspace { .. })
    ));
}

#[test]
fn stacking_needs_a_larger_support_and_side_places_step_outwards() {
    let s = settings();
    let cube = object("obj-1", "red cube", 0.25, -0.04, 0.03, 0.03, 0.03);
    let square = object("obj-2", "blue square", 0.25, 0.03, 0.045, 0.045, 0.01);
    // The cube onto the larger square: at the square's centre, on its top.
    let (at, z) = place_target(
        &s,
        std::slice::from_ref(&square),
        &held(&cube),
        square.xy(),
        Location::OnTopOf,
    )
    .unwrap();
    assert_eq!(at, square.xy());
    assert!((z - 0.01).abs() < 1e-9, "{z}");
    // The square onto the smaller cube: refused, it would overhang.
    let text = place_target(
        &s,
        std::slice::from_ref(&cube),
        &held(&square),
        cube.xy(),
        Location::OnTopOf,
    )
    .unwrap_err()
    .to_string();
    assert!(text.contains("overhang"), "{text}");
    // Beside the square with something in the contract's spot: further out, never on it.
    let pencil = object("obj-3", "pencil", 0.0, 0.0, 0.115, 0.01, 0.01);
    let beside = geometry::beside(&square, Location::Above, extents(&cube)).unwrap();
    let blocker = object(
        "obj-4",
        "tray",
        beside.x_m - 0.005,
        0.03,
        0.012,
        0.012,
        0.005,
    );
    let others = [square.clone(), blocker.clone()];
    let (at, _) = place_target(&s, &others, &held(&cube), square.xy(), Location::Above).unwrap();
    assert!(
        at.x_m > beside.x_m,
        "stepped outwards: {at:?} beyond {beside:?}"
    );
    assert!(placement_problem(
        &s,
        &others,
        &held(&cube),
        at,
        0.0,
        release_height(&s, &held(&cube), 0.0)
    )
    .is_none());
    // Nowhere to go: the reason names the reference and the search.
    let text = place_target(
        &s,
        std::slice::from_ref(&square),
        &held(&pencil),
        square.xy(),
        Location::Below,
    )
    .unwrap_err()
    .to_string();
    assert!(
        text.contains("no room") && text.contains("blue square"),
        "{text}"
    );
}

#[test]
fn pushes_refuse_to_shove_another_object_or_leave_the_sheet() {
    let s = settings();
    let cube = object("obj-1", "red cube", 0.25, 0.0, 0.03, 0.03, 0.03);
    let square = object("obj-2", "blue square", 0.30, 0.0, 0.045, 0.045, 0.01);
    let others = [cube.clone(), square.clone()];
    assert!(push_problem(&s, &cube, &others, Point2::new(0.25, 0.03)).is_none());
    let text = push_problem(&s, &cube, &others, Point2::new(0.28, 0.0)).unwrap();
    assert!(text.contains("would shove 'blue square'"), "{text}");
    let text = push_problem(
        &s,
        &cube,
        std::slice::from_ref(&cube),
        Point2::new(0.25, 0.095),
    )
    .unwrap();
    assert!(text.contains("stick out of the sheet"), "{text}");
}

#[test]
fn a_free_spot_is_free_and_nearest_the_centre() {
    let s = settings();
    let cube = object("obj-1", "red cube", 0.0, 0.0, 0.03, 0.03, 0.03);
    let plan = held(&cube);
    // The search grid's point nearest the centre (0.25, 0.0), 5 mm apart from x 0.163.
    let centre = Point2::new(0.25, 0.0);
    let alone = free_spot(&s, &[], &plan).unwrap();
    assert!(alone.distance_to(&centre) < 0.0036, "{alone:?}");
    let square = object("obj-2", "blue square", 0.25, 0.0, 0.045, 0.045, 0.01);
    let spot = free_spot(&s, std::slice::from_ref(&square), &plan).unwrap();
    let release = release_height(&s, &plan, 0.0);
    assert!(placement_problem(&s, &[square], &plan, spot, 0.0, release).is_none());
    assert!(
        spot.distance_to(&centre) > 0.03,
        "not on the square: {spot:?}"
    );
    assert!(spot.distance_to(&centre) < 0.06, "but near it: {spot:?}");
    // Stacked releases are higher by the stacking margin.
    let on_table = release_height(&s, &plan, 0.0);
    let on_top = release_height(&s, &plan, 0.03);
    assert!((on_top - on_table - 0.03 - s.stack_height_margin_m).abs() < 1e-9);
}
