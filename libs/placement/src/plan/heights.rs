//! The planner's heights and refusals, one rule per test: the grasp height (the caller's
//! offset, the palm over a tall object, never below the lowest height), the release height
//! on the table and on a support, which workspace a target is in (the margin, the nearest one
//! named), the place inside a container and close to an object, and the pushing tool's path.

use crate::plan::{
    grasp_height, place_target, push_tool_problem, release_height, workspace_of, HeldPlan,
};
use crate::SkillsSettings;
use robotd_protocol::objects::DetectedObject;
use robotd_protocol::skills::SkillError;
use robotd_protocol::workspace::WorkspaceInfo;
use robotd_protocol::{Location, Point2, Pose, RobotModel};

fn sheet(id: &str, upper_left: Point2, lower_right: Point2) -> WorkspaceInfo {
    WorkspaceInfo {
        id: id.into(),
        robot: RobotModel::Ned2,
        upper_left,
        lower_right,
        observation_pose: Pose::default(),
    }
}

/// The Ned2's sheet (x 0.163 … 0.337, y -0.087 … 0.087) and a second one to its left
/// (y 0.15 … 0.25).
fn settings() -> SkillsSettings {
    SkillsSettings::new(
        RobotModel::Ned2,
        vec![
            sheet(
                "niryo_ws",
                Point2::new(0.337, 0.087),
                Point2::new(0.163, -0.087),
            ),
            sheet("left_ws", Point2::new(0.30, 0.25), Point2::new(0.20, 0.15)),
        ],
    )
}

/// A box `side` × `side` and `tall` high, standing on the table at (x, y).
fn object(id: &str, label: &str, x: f64, y: f64, side: f64, tall: f64) -> DetectedObject {
    crate::plan::tests::object(id, label, x, y, side, side, tall)
}

fn held(o: &DetectedObject, tcp_above_base_m: f64) -> HeldPlan<'_> {
    HeldPlan {
        object: o,
        yaw_rad: 0.0,
        tcp_above_base_m,
    }
}

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() < 1e-9
}

#[test]
fn a_grasp_is_at_the_centre_plus_the_offset_never_below_the_lowest_height() {
    let s = settings();
    let cube = object("obj-1", "red cube", 0.25, 0.0, 0.03, 0.03);
    assert!(close(grasp_height(&s, &cube, 0.0), 0.015));
    assert!(close(grasp_height(&s, &cube, 0.005), 0.020));
    // An offset that would put the fingers into the table: the lowest height instead.
    assert!(close(grasp_height(&s, &cube, -0.05), s.min_tcp_z_m));
    let coin = object("obj-2", "coin", 0.25, 0.0, 0.02, 0.002);
    assert!(close(grasp_height(&s, &coin, 0.0), s.min_tcp_z_m));
}

#[test]
fn a_tall_object_is_grasped_high_enough_for_the_palm_to_clear_its_top() {
    let s = settings();
    // 120 mm tall: its centre (60 mm) would put the palm, 35 mm above the tool centre, into
    // it; grasped with the palm 3 mm over its top instead.
    let bottle = object("obj-1", "bottle", 0.25, 0.0, 0.03, 0.12);
    let z = grasp_height(&s, &bottle, 0.0);
    assert!(close(z, 0.12 - s.finger_length_m + 0.003), "{z}");
    assert!(z > bottle.position.center_of_mass.z_m);
}

#[test]
fn a_release_is_just_above_the_surface_and_higher_onto_a_measured_support() {
    let s = settings();
    let cube = object("obj-1", "red cube", 0.25, 0.0, 0.03, 0.03);
    let plan = held(&cube, 0.015);
    // On the table: the gap below the object.
    assert!(close(
        release_height(&s, &plan, 0.0),
        0.015 + s.release_gap_m
    ));
    // Onto a support 10 mm high: its top, the gap and the stacking margin.
    assert!(close(
        release_height(&s, &plan, 0.01),
        0.01 + 0.015 + s.release_gap_m + s.stack_height_margin_m
    ));
    // Never below the lowest height.
    assert!(close(
        release_height(&s, &held(&cube, -0.05), 0.0),
        s.min_tcp_z_m
    ));
}

#[test]
fn a_target_beyond_the_margin_is_refused_naming_the_nearest_workspace() {
    let s = settings();
    // Within the margin beyond the markers: that workspace.
    let ws = workspace_of(
        &s,
        "pick",
        Point2::new(0.337 + s.workspace_margin_m - 0.002, 0.0),
    );
    assert_eq!(ws.unwrap().id, "niryo_ws");
    assert_eq!(
        workspace_of(&s, "pick", Point2::new(0.25, 0.2)).unwrap().id,
        "left_ws"
    );
    // Beyond it: refused, naming what, where and the nearest workspace.
    let far = Point2::new(0.337 + s.workspace_margin_m + 0.002, 0.0);
    let Err(SkillError::OutsideWorkspace {
        what,
        at,
        workspace_id,
    }) = workspace_of(&s, "pick", far)
    else {
        panic!("accepted");
    };
    assert_eq!(
        (what.as_str(), at, workspace_id.as_str()),
        ("pick", far, "niryo_ws")
    );
    let Err(SkillError::OutsideWorkspace { workspace_id, .. }) =
        workspace_of(&s, "place", Point2::new(0.25, 0.3))
    else {
        panic!("accepted");
    };
    assert_eq!(workspace_id, "left_ws");
}

#[test]
fn inside_goes_to_the_container_floor_and_close_to_the_nearest_free_side() {
    let s = settings();
    let cube = object("obj-1", "red cube", 0.0, 0.0, 0.02, 0.02);
    // A flat tray (its rim below the opening fingers).
    let tray = object("obj-2", "tray", 0.25, 0.0, 0.08, 0.008);
    let others = [tray.clone()];
    let plan = held(&cube, 0.01);
    let (at, surface) = place_target(&s, &others, &plan, tray.xy(), Location::Inside).unwrap();
    assert_eq!(at, tray.xy());
    assert!(close(surface, s.container_floor_m));
    // Close to the tray, asked for a spot on its right (lower y): the right side.
    let asked = Point2::new(0.25, -0.07);
    let (at, surface) = place_target(&s, &others, &plan, asked, Location::CloseTo).unwrap();
    assert!(close(at.x_m, 0.25) && at.y_m < -0.05, "{at:?}");
    assert_eq!(surface, 0.0);
    // And asked in front of it (higher x): that side.
    let asked = Point2::new(0.32, 0.0);
    let (at, _) = place_target(&s, &others, &plan, asked, Location::CloseTo).unwrap();
    assert!(close(at.y_m, 0.0) && at.x_m > 0.30, "{at:?}");
}

#[test]
fn the_pushing_tool_must_not_meet_a_neighbour_taller_than_its_path() {
    let s = settings();
    let cube = object("obj-1", "red cube", 0.25, 0.0, 0.03, 0.03);
    let (start, end) = (Point2::new(0.22, 0.0), Point2::new(0.25, 0.0));
    let low_z = 0.012;
    // A tall neighbour where the tool comes down behind the cube: named.
    let bottle = object("obj-2", "bottle", 0.205, 0.0, 0.02, 0.08);
    let problem = push_tool_problem(&s, &cube, &[cube.clone(), bottle], start, end, 0.0, low_z)
        .expect("the bottle is in the way");
    assert!(problem.contains("would hit 'bottle'"), "{problem}");
    // A flat one there stays under the tool; one beside the path is not touched; the pushed
    // cube itself never counts.
    let coaster = object("obj-3", "coaster", 0.205, 0.0, 0.02, 0.005);
    let beside = object("obj-4", "cup", 0.23, 0.06, 0.03, 0.08);
    assert_eq!(
        push_tool_problem(
            &s,
            &cube,
            &[cube.clone(), coaster, beside],
            start,
            end,
            0.0,
            low_z
        ),
        None
    );
}
