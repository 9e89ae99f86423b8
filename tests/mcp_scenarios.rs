//! Scenarios on the simulator, as an LLM would script them: tool calls over MCP against a served
//! robotd, using only what the tools say (positions from `get_detected_objects`), and then
//! the world checked against the simulator's ground truth (`sim/world` on the bus).

mod common;
#[path = "common/lab.rs"]
mod lab;

use lab::{assert_near, lab_on, lab_with, runtime, scene, Driver, Lab};

/// Runs the scenario `$name(lab)` three times: as `$name::sim` on the built-in simulator, as
/// `$name::niryo` through the niryo driver against `robotd fake-niryo` (the same simulator
/// behind the Ned2's TCP protocol) and as `$name::widowx` through the widowx driver against
/// `robotd fake-widowx` (a WidowX behind its servo bus, on the same sheet): one scenario list,
/// three drivers.
macro_rules! on_both_drivers {
    ($name:ident, $scene:expr) => {
        mod $name {
            use super::*;
            #[test]
            fn sim() {
                run(Driver::Sim, $scene, super::$name);
            }
            #[test]
            fn niryo() {
                run(Driver::Niryo, $scene, super::$name);
            }
            #[test]
            fn widowx() {
                run(Driver::Widowx, $scene, super::$name);
            }
        }
    };
}

/// Starts a lab on `driver` with `scene` and runs `scenario` in it.
fn run<F: std::future::Future<Output = ()>>(
    driver: Driver,
    scene: Option<String>,
    scenario: fn(Lab) -> F,
) {
    runtime().block_on(async {
        let extra: Vec<String> = scene.into_iter().collect();
        let lab = lab_on(driver, 0.05, &extra).await;
        scenario(lab).await;
    });
}
use serde_json::{json, Value};

on_both_drivers!(sort_by_size_in_a_line, Some(scene("sort.toml")));
async fn sort_by_size_in_a_line(lab: Lab) {
    let mut seen = lab.seen().await;
    assert_eq!(seen.len(), 3, "{seen:?}");
    // Sort all objects by size in a line across the sheet at x = 0.25, 6 cm apart.
    seen.sort_by(|a, b| a.2.total_cmp(&b.2));
    let line: Vec<[f64; 2]> = (0..3).map(|i| [0.25, -0.07 + 0.06 * i as f64]).collect();
    for ((label, at, _), to) in seen.iter().zip(&line) {
        lab.move_object(label, *at, *to).await;
    }
    for ((label, _, _), to) in seen.iter().zip(&line) {
        assert_near(&lab.truth_of(label).await, *to, 0.005);
    }
    assert_eq!(
        seen.iter().map(|s| s.0.as_str()).collect::<Vec<_>>(),
        ["red cube", "green cylinder", "pencil"]
    );
}

on_both_drivers!(a_triangle_at_three_corners, Some(scene("sort.toml")));
async fn a_triangle_at_three_corners(lab: Lab) {
    // A triangle at [0.175, 0.0], [0.25, −0.08], [0.25, 0.08]; the long pencil goes to a
    // corner where it stays on the sheet, and each move goes to a free spot.
    let corners = [
        ("pencil", [0.25, -0.08]),
        ("green cylinder", [0.175, 0.0]),
        ("red cube", [0.25, 0.08]),
    ];
    for (label, to) in corners {
        let seen = lab.seen().await;
        let (_, at, _) = seen
            .iter()
            .find(|s| s.0 == label)
            .unwrap_or_else(|| panic!("{label} not seen: {seen:?}"));
        lab.move_object(label, *at, to).await;
    }
    for (label, to) in corners {
        assert_near(&lab.truth_of(label).await, to, 0.005);
    }
}

on_both_drivers!(
    swap_the_two_largest_through_the_largest_free_space,
    Some(scene("sort.toml"))
);
async fn swap_the_two_largest_through_the_largest_free_space(lab: Lab) {
    let (_, data) = lab
        .call("get_detected_objects_sorted", json!({"ascending": false}))
        .await;
    let objects = data.as_array().unwrap();
    let pos = |o: &Value| {
        let c = &o["position"]["center_of_mass"];
        [c["x"].as_f64().unwrap(), c["y"].as_f64().unwrap()]
    };
    let (a, a_at) = (
        objects[0]["label"].as_str().unwrap().to_owned(),
        pos(&objects[0]),
    );
    let (b, b_at) = (
        objects[1]["label"].as_str().unwrap().to_owned(),
        pos(&objects[1]),
    );
    assert_eq!((a.as_str(), b.as_str()), ("pencil", "green cylinder"));
    let free = lab
        .ok("get_largest_free_space_with_center", json!({}))
        .await;
    let park = [
        free["center"][0].as_f64().unwrap(),
        free["center"][1].as_f64().unwrap(),
    ];
    lab.move_object(&a, a_at, park).await;
    lab.move_object(&b, b_at, a_at).await;
    // Pick the first one up where the camera now sees it.
    let parked = lab
        .seen()
        .await
        .into_iter()
        .find(|s| s.0 == a)
        .expect("the parked object is seen");
    lab.move_object(&a, parked.1, b_at).await;
    assert_near(&lab.truth_of(&a).await, b_at, 0.006);
    assert_near(&lab.truth_of(&b).await, a_at, 0.006);
}

on_both_drivers!(
    push_the_too_wide_box_right_but_never_off_the_sheet,
    Some(scene_file("push.toml"))
);
async fn push_the_too_wide_box_right_but_never_off_the_sheet(lab: Lab) {
    let before = lab.truth_of("large box").await;
    let seen = lab.seen().await;
    let (_, at, _) = seen.iter().find(|s| s.0 == "large box").expect("box seen");
    // Too wide to pick: the tool says so and nothing moves.
    let (text, _) = lab
        .call(
            "pick_object",
            json!({"object_name": "large box", "pick_coordinate": at}),
        )
        .await;
    assert!(
        text.starts_with("❌ Failed to pick 'large box': "),
        "{text}"
    );
    assert!(text.contains("push it instead"), "{text}");
    // 50 mm would put 2 cm of it beyond the sheet, where the camera would see it cut.
    let (text, _) = lab
        .call(
            "push_object",
            json!({"object_name": "large box", "push_coordinate": at,
                       "direction": "right", "distance": 50.0}),
        )
        .await;
    assert!(text.contains("would stick out of the sheet"), "{text}");
    assert_eq!(lab.truth_of("large box").await.y_m, before.y_m);
    let (text, _) = lab
        .call(
            "push_object",
            json!({"object_name": "large box", "push_coordinate": at,
                       "direction": "right", "distance": 30.0}),
        )
        .await;
    assert_eq!(
        text,
        format!(
            "✓ Successfully pushed 'large box' from [{:.3}, {:.3}] right by 30.0mm",
            at[0], at[1]
        )
    );
    // The camera sees one box where it went, not a new one beside a stale one.
    let boxes: Vec<_> = lab
        .seen()
        .await
        .into_iter()
        .filter(|s| s.0 == "large box")
        .collect();
    assert_eq!(boxes.len(), 1, "{boxes:?}");
    assert!((boxes[0].1[1] - (at[1] - 0.03)).abs() < 0.005, "{boxes:?}");
    let after = lab.truth_of("large box").await;
    let moved_y = after.y_m - before.y_m;
    assert!(
        (moved_y + 0.030).abs() <= 0.005 && (after.x_m - before.x_m).abs() <= 0.005,
        "box moved ({:.1}, {:.1}) mm",
        (after.x_m - before.x_m) * 1000.0,
        moved_y * 1000.0
    );
}

fn scene_file(name: &str) -> String {
    format!(
        "robot.scene={}/config/scenes/{name}",
        env!("CARGO_MANIFEST_DIR")
    )
}

on_both_drivers!(
    stack_the_small_cube_on_the_large_one_and_recover_from_errors,
    Some(scene("stack.toml"))
);
async fn stack_the_small_cube_on_the_large_one_and_recover_from_errors(lab: Lab) {
    let mut cubes = lab.seen().await;
    assert_eq!(cubes.len(), 2, "{cubes:?}");
    cubes.sort_by(|a, b| a.2.total_cmp(&b.2));
    let (small_at, large_at) = (cubes[0].1, cubes[1].1);

    // Error recovery: an unknown object, a target far outside; nothing moves.
    let (text, _) = lab
        .call(
            "pick_object",
            json!({"object_name": "unicorn", "pick_coordinate": small_at}),
        )
        .await;
    assert_eq!(
            text,
            format!(
                "❌ Failed to pick 'unicorn': no 'unicorn' within 5 cm of [{:.3}, {:.3}]; seen there: red cube",
                small_at[0], small_at[1]
            )
        );
    let (text, _) = lab
        .call(
            "pick_place_object",
            json!({"object_name": "red cube", "pick_coordinate": small_at,
                       "place_coordinate": [99.9, 99.9]}),
        )
        .await;
    assert_eq!(
            text,
            "❌ Failed to pick and place 'red cube': place coordinate [99.900, 99.900] is outside workspace 'niryo_ws'"
        );
    let small = lab.truth_of("small cube").await;
    assert!(!small.held && small.bottom_z_m < 0.002, "{small:?}");

    // Stack.
    let (text, _) = lab
        .call(
            "pick_place_object",
            json!({"object_name": "red cube", "pick_coordinate": small_at,
                       "place_coordinate": large_at, "location": "on top of"}),
        )
        .await;
    assert_eq!(
            text,
            format!(
                "✓ Successfully picked 'red cube' from [{:.3}, {:.3}] and placed it on top of coordinate [{:.3}, {:.3}]",
                small_at[0], small_at[1], large_at[0], large_at[1]
            )
        );
    let small = lab.truth_of("small cube").await;
    let large = lab.truth_of("large cube").await;
    assert!(!small.held, "{small:?}");
    assert!(
        (small.bottom_z_m - large.top_z_m).abs() < 0.003,
        "small cube's bottom at {:.4} m, large cube's top at {:.4} m",
        small.bottom_z_m,
        large.top_z_m
    );
    assert_near(&small, [large.x_m, large.y_m], 0.006);
}

on_both_drivers!(
    move2by_places_at_the_pick_coordinate_moved_by_the_distance,
    None
);
async fn move2by_places_at_the_pick_coordinate_moved_by_the_distance(lab: Lab) {
    let cube = lab.truth_of("red cube").await;
    // A pick coordinate 1 cm off the cube's centre: the contract moves the coordinate,
    // so the cube ends 2 cm left of the coordinate, 3 cm left of where it was.
    let pick = [cube.x_m, cube.y_m - 0.01];
    let (text, _) = lab
        .call(
            "move2by",
            json!({"object_name": "red cube", "pick_coordinate": pick,
                       "direction": "left", "distance": 0.02}),
        )
        .await;
    let target = [pick[0], pick[1] + 0.02];
    assert_eq!(
            text,
            format!(
                "✓ Successfully picked 'red cube' from [{:.3}, {:.3}] and placed it 2.0 centimeters leftwards at [{:.3}, {:.3}]",
                pick[0], pick[1], target[0], target[1]
            )
        );
    assert_near(&lab.truth_of("red cube").await, target, 0.006);
}

/// Whether the simulated gripper holds `label`.
async fn held(lab: &Lab, label: &str) -> bool {
    lab.truth_of(label).await.held
}

// Issue 17, failure 1: the 12 cm pencil "left next to" the red cube would cover a corner
// marker (and its fingers would touch the cube): refused before moving, pencil still held.
on_both_drivers!(
    a_place_that_would_hide_a_marker_is_refused_and_says_what_is_held,
    None
);
async fn a_place_that_would_hide_a_marker_is_refused_and_says_what_is_held(lab: Lab) {
    let pencil = lab.truth_of("pencil").await;
    lab.ok(
        "pick_object",
        json!({"object_name": "pencil", "pick_coordinate": [pencil.x_m, pencil.y_m]}),
    )
    .await;
    let (text, _) = lab
        .call(
            "place_object",
            json!({"place_coordinate": [0.25, 0.0], "location": "left next to"}),
        )
        .await;
    assert!(
        text.starts_with("❌ Failed to place object: no room left next to 'red cube'")
            && text.contains("would cover the marker at [0.337, 0.087]")
            && text.contains("; 'pencil' is still held: put it down with place_object, e.g. at ["),
        "{text}"
    );
    assert!(held(&lab, "pencil").await);
    lab.ok(
        "place_object",
        json!({"place_coordinate": [0.22, -0.05], "location": "none"}),
    )
    .await;
    assert_near(&lab.truth_of("pencil").await, [0.22, -0.05], 0.006);
    // And the camera still sees the whole workspace.
    assert_eq!(lab.seen().await.len(), 4);
}

// Issue 17, failure 1: after a collision and clear_collision_detected, the next motion
// first retreats straight up, so the arm is never stuck in contact.
on_both_drivers!(
    after_a_collision_clearing_the_flag_lets_the_arm_retreat_and_work_again,
    Some(scene("hidden.toml"))
);
async fn after_a_collision_clearing_the_flag_lets_the_arm_retreat_and_work_again(lab: Lab) {
    let seen = lab.seen().await;
    assert_eq!(seen.len(), 1, "only the red cube is visible: {seen:?}");
    let cube = seen[0].1;
    lab.ok(
        "pick_object",
        json!({"object_name": "red cube", "pick_coordinate": cube}),
    )
    .await;
    // Onto the block the camera cannot see: the held cube hits it on the way down.
    let (text, _) = lab
        .call("place_object", json!({"place_coordinate": [0.25, -0.03]}))
        .await;
    assert!(
        text.contains("collision detected")
            && text
                .contains("; 'red cube' is still held: put it down with place_object, e.g. at ["),
        "{text}"
    );
    assert!(held(&lab, "red cube").await, "the collision keeps the cube");
    // Until the flag is cleared, nothing moves.
    let (text, _) = lab
        .call("move2observation_pose", json!({"workspace_id": "niryo_ws"}))
        .await;
    assert!(text.contains("collision detected"), "{text}");
    lab.ok("clear_collision_detected", json!({})).await;
    // The place looks first (a motion to the observation pose): it starts with the retreat.
    lab.ok("place_object", json!({"place_coordinate": [0.2, 0.04]}))
        .await;
    assert_near(&lab.truth_of("red cube").await, [0.2, 0.04], 0.006);
    let block = lab.truth_of("white block").await;
    assert_near(&block, [0.25, -0.03], 0.001);
    assert_eq!(lab.seen().await.len(), 1);
}

// Issue 17, failure 2: the fingers, open across the pencil, must not reach the cube.
on_both_drivers!(
    an_object_placed_right_next_to_another_can_be_picked_again,
    None
);
async fn an_object_placed_right_next_to_another_can_be_picked_again(lab: Lab) {
    let seen = lab.seen().await;
    let at = |label: &str| seen.iter().find(|s| s.0 == label).unwrap().1;
    lab.ok(
        "pick_place_object",
        json!({"object_name": "pencil", "pick_coordinate": at("pencil"),
                   "place_coordinate": at("red cube"), "location": "right next to"}),
    )
    .await;
    let pencil = lab.truth_of("pencil").await;
    lab.ok(
        "pick_place_object",
        json!({"object_name": "pencil", "pick_coordinate": [pencil.x_m, pencil.y_m],
                   "place_coordinate": [0.22, -0.05]}),
    )
    .await;
    assert_near(&lab.truth_of("pencil").await, [0.22, -0.05], 0.006);
    let cube = lab.truth_of("red cube").await;
    assert_near(&cube, [0.28, 0.04], 0.001);
}

// Issue 17, failure 3: the place is checked before the pick.
on_both_drivers!(a_move_whose_place_cannot_work_never_picks, None);
async fn a_move_whose_place_cannot_work_never_picks(lab: Lab) {
    let seen = lab.seen().await;
    let at = |label: &str| seen.iter().find(|s| s.0 == label).unwrap().1;
    // 30 mm up, the square would shove the cube along: refused, nothing moves.
    let (text, _) = lab
        .call(
            "push_object",
            json!({"object_name": "blue square", "push_coordinate": at("blue square"),
                       "direction": "up", "distance": 30.0}),
        )
        .await;
    assert!(text.contains("would shove 'red cube' along"), "{text}");
    lab.ok(
        "push_object",
        json!({"object_name": "blue square", "push_coordinate": at("blue square"),
                   "direction": "up", "distance": 20.0}),
    )
    .await;
    let before = lab.truth_of("red cube").await;
    assert_near(&before, [0.28, 0.04], 0.0005);
    let cube = lab
        .seen()
        .await
        .into_iter()
        .find(|s| s.0 == "red cube")
        .unwrap()
        .1;
    let (text, _) = lab
        .call(
            "move2by",
            json!({"object_name": "red cube", "pick_coordinate": cube,
                       "direction": "down", "distance": 0.04}),
        )
        .await;
    assert!(
        text.starts_with("❌")
            && text.contains("'blue square' is in the way")
            && !text.contains("still held"),
        "{text}"
    );
    let truth = lab.truth_of("red cube").await;
    assert!(!truth.held, "the cube was picked: {truth:?}");
    assert_near(&truth, [before.x_m, before.y_m], 0.0005);
    assert!(lab.seen().await.iter().any(|s| s.0 == "red cube"));
}

// Issue 17, failure 4: the green cylinder at [0.173, 0.074] would cover a corner marker.
on_both_drivers!(
    a_placement_that_would_cover_a_marker_is_refused_before_anything_moves,
    None
);
async fn a_placement_that_would_cover_a_marker_is_refused_before_anything_moves(lab: Lab) {
    let seen = lab.seen().await;
    let at = seen.iter().find(|s| s.0 == "green cylinder").unwrap().1;
    let (text, _) = lab
        .call(
            "pick_place_object",
            json!({"object_name": "green cylinder", "pick_coordinate": at,
                       "place_coordinate": [0.173, 0.074]}),
        )
        .await;
    assert!(
        text.starts_with("❌") && text.contains("would cover the marker at [0.163, 0.087]"),
        "{text}"
    );
    let truth = lab.truth_of("green cylinder").await;
    assert!(!truth.held);
    assert_near(&truth, [0.30, -0.06], 0.001);
    assert_eq!(lab.seen().await.len(), 4);
}

// The soak's finding: the gripper failed while the arm was down at the release pose, the
// next move to the observation pose swept the held pencil into its neighbours, and every
// later motion hit the same collision. A skill that fails down there now lifts the tool
// straight up first. (Simulator only: injected faults are the simulated driver's.)
#[test]
fn a_gripper_failure_at_the_release_pose_leaves_the_arm_clear_and_working() {
    runtime().block_on(async {
        let extra = ["robot.faults.gripper.fail_every_n=3".to_owned()];
        let lab = lab_with(0.05, &extra).await;
        let pencil = lab.truth_of("pencil").await;
        // Gripper commands: open (1) and close (2) of the pick, then the release's open (3)
        // fails with the pencil held just above the table.
        let (text, _) = lab
            .call(
                "pick_place_object",
                json!({"object_name": "pencil", "pick_coordinate": [pencil.x_m, pencil.y_m],
                       "place_coordinate": [0.22, -0.06]}),
            )
            .await;
        assert!(
            text.starts_with("❌")
                && text.contains("injected fault")
                && text.contains("'pencil' is still held"),
            "{text}"
        );
        assert!(held(&lab, "pencil").await);
        // The arm is clear of the table: looking works, and the pencil can be put down.
        let seen = lab.seen().await;
        assert_eq!(seen.len(), 3, "the held pencil is off the table: {seen:?}");
        lab.ok("place_object", json!({"place_coordinate": [0.22, -0.06]}))
            .await;
        assert_near(&lab.truth_of("pencil").await, [0.22, -0.06], 0.006);
        assert_eq!(lab.seen().await.len(), 4);
    });
}
