//! Contact: grasps (centred, across the short side, within the opening), held objects,
//! releases onto boxes and into containers, collisions and pushes.

use super::*;

#[test]
fn grasp_succeeds_when_centred_at_mid_height_across_the_short_side() {
    let mut world = World::new(&Scene::default_ned2());
    let c = centre(&world, "red cube");
    world.set_tool(ToolState::pointing_down(c.x, c.y, c.z, 0.0, 0.040));
    let id = find(&world, "red cube").id;
    assert_eq!(
        world.close_gripper(),
        GraspOutcome::Grasped {
            id,
            label: "red cube".into()
        }
    );
    assert_eq!(world.held(), Some(id));
    assert!(find(&world, "red cube").held);
    assert!((world.gripper_width_m() - 0.030).abs() < 1e-12);
    // Closing again keeps it.
    assert!(matches!(
        world.close_gripper(),
        GraspOutcome::Grasped { .. }
    ));
}

#[test]
fn grasp_fails_off_centre_by_a_centimetre() {
    let mut world = World::new(&Scene::default_ned2());
    let c = centre(&world, "red cube");
    world.set_tool(ToolState::pointing_down(c.x + 0.01, c.y, c.z, 0.0, 0.040));
    let GraspOutcome::Empty { reason } = world.close_gripper() else {
        panic!("grasped off centre")
    };
    assert!(reason.contains("'red cube' is not centred"), "{reason}");
    assert!(reason.contains("10.0 mm"), "{reason}");
    assert_eq!(world.gripper_width_m(), 0.0);
    assert_eq!(world.held(), None);
}

#[test]
fn grasp_fails_above_the_object() {
    let mut world = World::new(&Scene::default_ned2());
    let c = centre(&world, "red cube");
    world.set_tool(ToolState::pointing_down(c.x, c.y, 0.040, 0.0, 0.040));
    let GraspOutcome::Empty { reason } = world.close_gripper() else {
        panic!("grasped from above")
    };
    assert!(reason.contains("10.0 mm short of 'red cube'"), "{reason}");
    // Far from everything.
    world.open_gripper(0.04);
    world.set_tool(ToolState::pointing_down(0.25, -0.01, 0.005, 0.0, 0.040));
    assert_eq!(
        world.close_gripper(),
        GraspOutcome::Empty {
            reason: "no object between the fingers".into()
        }
    );
}

#[test]
fn grasp_needs_the_jaw_across_the_short_side() {
    let mut world = World::new(&Scene::default_ned2());
    let c = centre(&world, "pencil");
    // yaw π/2: the fingers close along x, the pencil's length.
    world.set_tool(ToolState::pointing_down(c.x, c.y, c.z, FRAC_PI_2, 0.040));
    let GraspOutcome::Empty { reason } = world.close_gripper() else {
        panic!("grasped along the pencil")
    };
    assert!(
        reason.contains("jaw not across the short side of 'pencil' (off by 90°"),
        "{reason}"
    );

    // 20° off: refused; 10° off: grasped and squared up.
    world.set_tool(ToolState::pointing_down(
        c.x,
        c.y,
        c.z,
        20f64.to_radians(),
        0.040,
    ));
    let GraspOutcome::Empty { reason } = world.close_gripper() else {
        panic!("grasped 20° off")
    };
    assert!(reason.contains("off by 20°"), "{reason}");
    world.set_tool(ToolState::pointing_down(
        c.x,
        c.y,
        c.z,
        10f64.to_radians(),
        0.040,
    ));
    assert!(matches!(
        world.close_gripper(),
        GraspOutcome::Grasped { .. }
    ));
    assert!((world.gripper_width_m() - 0.012).abs() < 1e-12);
    assert!((find(&world, "pencil").yaw_rad() - 10f64.to_radians()).abs() < 1e-9);
}

#[test]
fn grasp_refuses_objects_wider_than_the_opening() {
    let mut world = World::new(&Scene::default_ned2());
    let c = centre(&world, "blue square");
    world.set_tool(ToolState::pointing_down(c.x, c.y, c.z, 0.0, 0.040));
    let GraspOutcome::Empty { reason } = world.close_gripper() else {
        panic!("grasped the wide square")
    };
    assert_eq!(
        reason,
        "'blue square' is 0.045 m wide, wider than the 0.040 m opening"
    );

    // A cube narrower than the gripper but wider than the current opening.
    let c = centre(&world, "red cube");
    world.set_tool(ToolState::pointing_down(c.x, c.y, c.z, 0.0, 0.025));
    let GraspOutcome::Empty { reason } = world.close_gripper() else {
        panic!("grasped through closed fingers")
    };
    assert!(
        reason.contains("wider than the 0.025 m opening"),
        "{reason}"
    );
}

#[test]
fn cylinders_grasp_at_any_yaw() {
    let mut world = World::new(&Scene::default_ned2());
    let c = centre(&world, "green cylinder");
    world.set_tool(ToolState::pointing_down(c.x, c.y, c.z, 1.0, 0.040));
    assert!(matches!(
        world.close_gripper(),
        GraspOutcome::Grasped { .. }
    ));
    assert!((world.gripper_width_m() - 0.030).abs() < 1e-12);
}

// ---- carrying and releasing ----

#[test]
fn held_object_follows_the_tool() {
    let mut world = World::new(&Scene::default_ned2());
    let id = pick(&mut world, "red cube", 0.0);
    let tcp = world.tool().tcp.translation.vector;
    let obj = world.object(id).unwrap().pose.translation.vector;
    assert!((obj - tcp).norm() < 1e-9, "cube centred on the TCP");
    assert!((obj.z - 0.09).abs() < 1e-9);
    go(&mut world, 0.25, -0.02, 0.10, 0.5);
    let obj = world.object(id).unwrap();
    assert!((obj.pose.translation.vector - Vector3::new(0.25, -0.02, 0.10)).norm() < 1e-9);
    assert!((obj.yaw_rad() - 0.5).abs() < 1e-9);
}

#[test]
fn release_stacks_on_a_box_and_drops_on_the_table_otherwise() {
    let mut world = World::new(&Scene::from_toml_str(PUSH_TOML, "push.toml").unwrap());
    let id = pick(&mut world, "red cube", 0.0);
    let b = centre(&world, "large box");
    go(&mut world, b.x, b.y, 0.12, 0.0);
    // Lowered so that the cube sinks 0.5 mm into the box: tolerated.
    go(&mut world, b.x, b.y, 0.05 + 0.015 - 0.0005, 0.0);
    // Further down is a collision with the box, stopped at 2 mm.
    let (reached, outcome) = world.move_tool(&down(b.x, b.y, 0.05, 0.0));
    assert_eq!(outcome.collision.as_deref(), Some("large box"));
    let z = reached.tcp.translation.z;
    assert!((z - (0.065 - HELD_TOLERANCE_M)).abs() < 1e-4, "{z}");
    go(&mut world, b.x, b.y, 0.08, 0.0);
    assert_eq!(world.open_gripper(0.04), Some(id));
    assert_eq!(world.held(), None);
    let placed = world.object(id).unwrap();
    assert!((placed.pose.translation.z - 0.065).abs() < 1e-9);
    assert!((placed.pose.translation.x - b.x).abs() < 1e-9);
    assert!(!placed.held);

    // Pick it up again and drop it beside the box.
    let id = pick(&mut world, "red cube", 0.0);
    go(&mut world, 0.32, -0.06, 0.08, 0.3);
    assert_eq!(world.open_gripper(0.04), Some(id));
    let placed = world.object(id).unwrap();
    assert!((placed.pose.translation.z - 0.015).abs() < 1e-9);
    assert!((placed.yaw_rad() - 0.3).abs() < 1e-9, "keeps its yaw");
}

#[test]
fn release_above_a_container_goes_inside() {
    let mut world = empty_world();
    let tray = world
        .add_object(
            ObjectSpec::new(
                "tray",
                ObjectShape::Box {
                    length_x_m: 0.07,
                    width_y_m: 0.07,
                    height_z_m: 0.03,
                },
                [130, 60, 170],
                0.22,
                -0.03,
            )
            .as_container(),
        )
        .unwrap();
    let small = world
        .add_object(
            ObjectSpec::new(
                "cup",
                ObjectShape::Box {
                    length_x_m: 0.025,
                    width_y_m: 0.025,
                    height_z_m: 0.02,
                },
                [1, 2, 3],
                0.30,
                -0.05,
            )
            .as_container(),
        )
        .unwrap();
    world
        .add_object(cube("red cube", 0.30, 0.05, 0.03))
        .unwrap();
    let id = pick(&mut world, "red cube", 0.0);
    // Lower it into the tray (its walls are hollow): no collision.
    go(&mut world, 0.22, -0.03, 0.08, 0.0);
    go(&mut world, 0.22, -0.03, 0.03, 0.0);
    assert_eq!(world.open_gripper(0.04), Some(id));
    let inside = world.object(id).unwrap().pose.translation.z;
    assert!(
        (inside - (CONTAINER_WALL_M + 0.015)).abs() < 1e-9,
        "{inside}"
    );
    assert_eq!(world.object(tray).unwrap().pose.translation.z, 0.015);

    // Too big for the cup: it rests on the rim.
    let id = pick(&mut world, "red cube", 0.0);
    go(&mut world, 0.30, -0.05, 0.08, 0.0);
    world.open_gripper(0.04);
    let z = world.object(id).unwrap().pose.translation.z;
    assert!((z - (0.02 + 0.015)).abs() < 1e-9, "{z}");
    assert_eq!(world.object(small).unwrap().pose.translation.z, 0.01);
}

// ---- collisions ----

#[test]
fn moving_down_into_an_object_or_the_table_stops_at_the_contact() {
    let mut world = World::new(&Scene::default_ned2());
    let c = centre(&world, "blue square");
    world.set_tool(ToolState::pointing_down(c.x, c.y, 0.10, 0.0, 0.040));
    let (reached, outcome) = world.move_tool(&ToolState::pointing_down(c.x, c.y, 0.0, 0.0, 0.040));
    assert_eq!(outcome.collision.as_deref(), Some("blue square"));
    assert_eq!(
        outcome.contact(),
        Some(Contact::Collision {
            what: "blue square".into()
        })
    );
    let z = reached.tcp.translation.z;
    assert!((z - 0.010).abs() < 2e-4, "stopped at {z}");
    assert_eq!(world.tool().tcp.translation.z, z);
    // The square did not move; the tool can go back up.
    assert_eq!(centre(&world, "blue square"), c);
    go(&mut world, c.x, c.y, 0.10, 0.0);

    world.set_tool(ToolState::pointing_down(0.25, -0.01, 0.05, 0.0, 0.040));
    let (reached, outcome) =
        world.move_tool(&ToolState::pointing_down(0.25, -0.01, -0.02, 0.0, 0.040));
    assert_eq!(outcome.collision.as_deref(), Some("table"));
    let z = reached.tcp.translation.z;
    assert!(z.abs() < 2e-4, "stopped at {z}");
}

#[test]
fn an_open_gripper_moving_sideways_into_a_small_object_collides() {
    let mut world = World::new(&Scene::default_ned2());
    let c = centre(&world, "red cube");
    // Fingers open (40 mm, wider than the 30 mm cube), beside the cube along x.
    world.set_tool(ToolState::pointing_down(
        c.x - 0.04,
        c.y + 0.02,
        0.015,
        0.0,
        0.040,
    ));
    let (_, outcome) = world.move_tool(&ToolState::pointing_down(
        c.x,
        c.y + 0.02,
        0.015,
        0.0,
        0.040,
    ));
    assert_eq!(outcome.collision.as_deref(), Some("red cube"));
    assert!(outcome.pushed.is_empty());
    assert_eq!(centre(&world, "red cube"), c);
}

#[test]
fn a_carried_object_collides_with_others() {
    let mut world = World::new(&Scene::default_ned2());
    pick(&mut world, "red cube", 0.0);
    let c = centre(&world, "green cylinder");
    go(&mut world, c.x, c.y + 0.005, 0.09, 0.0);
    let (_, outcome) = world.move_tool(&down(c.x, c.y + 0.005, 0.03, 0.0));
    assert_eq!(outcome.collision.as_deref(), Some("green cylinder"));
}

// ---- pushing ----

/// How far the gripper reaches beyond the TCP along +y at its current pose.
fn reach_along_y(world: &World) -> f64 {
    let tcp_y = world.tool().tcp.translation.y;
    world
        .gripper_boxes()
        .iter()
        .flat_map(|b| {
            let h = b.half_extents_m;
            [-1.0, 1.0].into_iter().flat_map(move |sx| {
                [-1.0, 1.0].into_iter().flat_map(move |sy| {
                    [-1.0, 1.0].into_iter().map(move |sz| {
                        (b.pose * nalgebra::Point3::new(sx * h.x, sy * h.y, sz * h.z)).y
                    })
                })
            })
        })
        .fold(f64::NEG_INFINITY, f64::max)
        - tcp_y
}

#[test]
fn a_closed_gripper_pushes_the_large_box() {
    let mut world = World::new(&Scene::from_toml_str(PUSH_TOML, "push.toml").unwrap());
    let b = centre(&world, "large box");
    let box_id = find(&world, "large box").id;
    let others: Vec<Vector3<f64>> = ["red cube", "green cylinder"]
        .iter()
        .map(|l| centre(&world, l))
        .collect();
    // Closed gripper, jaw along x (yaw π/2), 1 cm to the right of the box.
    world.set_tool(ToolState::pointing_down(b.x, -0.10, 0.10, FRAC_PI_2, 0.040));
    assert!(matches!(world.close_gripper(), GraspOutcome::Empty { .. }));
    let gap = 0.010;
    let start_y = b.y - 0.035 - reach_along_y(&world) - gap;
    go(&mut world, b.x, start_y, 0.10, FRAC_PI_2);
    go(&mut world, b.x, start_y, 0.005, FRAC_PI_2);
    let (reached, outcome) = world.move_tool(&down(b.x, start_y + 0.05, 0.005, FRAC_PI_2));
    assert_eq!(outcome.collision, None);
    assert_eq!(outcome.pushed, vec![box_id]);
    assert!((reached.tcp.translation.y - (start_y + 0.05)).abs() < 1e-9);
    let moved = find(&world, "large box");
    let dy = moved.pose.translation.y - b.y;
    assert!((dy - 0.040).abs() < 0.003, "box moved {dy}");
    assert!((moved.pose.translation.x - b.x).abs() < 1e-9);
    assert!((moved.pose.translation.z - b.z).abs() < 1e-9);
    assert!(moved.yaw_rad().abs() < 1e-9, "no rotation");
    let after: Vec<Vector3<f64>> = ["red cube", "green cylinder"]
        .iter()
        .map(|l| centre(&world, l))
        .collect();
    assert_eq!(after, others, "the others stayed put");
}

#[test]
fn a_pushed_object_shoves_the_next_one() {
    let mut world = empty_world();
    let box_id = world.add_object(large_box(0.25, -0.02)).unwrap();
    // 10 mm beyond the box's left side.
    let cube_id = world
        .add_object(cube("red cube", 0.25, 0.015 + 0.010 + 0.015, 0.03))
        .unwrap();
    world.set_tool(ToolState::pointing_down(0.25, -0.10, 0.10, FRAC_PI_2, 0.0));
    let start_y = -0.055 - reach_along_y(&world) - 0.010;
    go(&mut world, 0.25, start_y, 0.005, FRAC_PI_2);
    let (_, outcome) = world.move_tool(&down(0.25, start_y + 0.05, 0.005, FRAC_PI_2));
    assert_eq!(outcome.collision, None);
    assert_eq!(outcome.pushed, vec![box_id, cube_id]);
    let box_y = world.object(box_id).unwrap().pose.translation.y;
    let cube_y = world.object(cube_id).unwrap().pose.translation.y;
    assert!((box_y - 0.02).abs() < 0.003, "{box_y}");
    assert!((cube_y - 0.07).abs() < 0.003, "{cube_y}");
    let gap = (cube_y - 0.015) - (box_y + 0.035);
    assert!(gap > -CONTACT_TOLERANCE_M, "box and cube overlap by {gap}");
}

#[test]
fn a_pushed_box_carries_what_stands_on_it() {
    let mut world = empty_world();
    let box_id = world.add_object(large_box(0.25, -0.02)).unwrap();
    world
        .add_object(cube("red cube", 0.30, 0.05, 0.03))
        .unwrap();
    let cube_id = pick(&mut world, "red cube", 0.0);
    go(&mut world, 0.25, -0.02, 0.08, 0.0);
    world.open_gripper(0.04);
    world.close_gripper();
    go(&mut world, 0.25, -0.10, 0.10, FRAC_PI_2);
    let start_y = -0.055 - reach_along_y(&world) - 0.005;
    go(&mut world, 0.25, start_y, 0.005, FRAC_PI_2);
    let (_, outcome) = world.move_tool(&down(0.25, start_y + 0.025, 0.005, FRAC_PI_2));
    assert_eq!(outcome.collision, None);
    assert!(outcome.pushed.contains(&box_id) && outcome.pushed.contains(&cube_id));
    let on_top = world.object(cube_id).unwrap().pose.translation;
    assert!(
        (on_top.y - 0.0).abs() < 0.003 && (on_top.z - 0.065).abs() < 1e-9,
        "{on_top:?}"
    );
}

#[test]
fn pushing_downwards_is_a_collision() {
    let mut world = World::new(&Scene::from_toml_str(PUSH_TOML, "push.toml").unwrap());
    world.set_tool(ToolState::pointing_down(0.25, -0.02, 0.10, 0.0, 0.0));
    let (_, outcome) = world.move_tool(&down(0.25, -0.02, 0.03, 0.0));
    assert_eq!(outcome.collision.as_deref(), Some("large box"));
    assert!(outcome.pushed.is_empty());
}

// ---- world bookkeeping and robustness ----

#[test]
fn add_and_remove_objects() {
    let mut world = World::new(&Scene::default_ned2());
    let err = world
        .add_object(cube("second cube", 0.29, 0.05, 0.03))
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("'second cube'") && err.contains("'red cube'"),
        "{err}"
    );
    let err = world
        .add_object(cube("", 0.25, 0.0, 0.03))
        .unwrap_err()
        .to_string();
    assert!(err.contains("label must not be empty"), "{err}");
    let id = world
        .add_object(cube("second cube", 0.25, -0.01, 0.02))
        .unwrap();
    assert_eq!(world.object(id).unwrap().pose.translation.z, 0.01);
    let held = pick(&mut world, "red cube", 0.0);
    assert!(world.remove_object(held));
    assert_eq!(world.held(), None);
    assert!(!world.remove_object(held));
    assert!(world.object(held).is_none());
    assert_eq!(world.objects().len(), 4);
}

#[test]
fn bad_inputs_never_panic() {
    let mut world = World::new(&Scene::default_ned2());
    let before = *world.tool();
    let (reached, outcome) = world.move_tool(&down(f64::NAN, 0.0, 0.1, 0.0));
    assert_eq!(reached, before);
    assert_eq!(outcome, StepOutcome::default());
    world.set_tool(ToolState::pointing_down(
        f64::INFINITY,
        0.0,
        0.1,
        0.0,
        f64::NAN,
    ));
    assert_eq!(*world.tool(), before);
    world.set_tool(ToolState::pointing_down(0.2, 0.0, 0.1, 0.0, 5.0));
    assert_eq!(world.gripper_width_m(), 0.040);
    world.open_gripper(f64::NAN);
    assert_eq!(world.gripper_width_m(), 0.040);
    // A half turn of the tool in place, far above everything.
    let (_, outcome) = world.move_tool(&ToolState::from_xyz_rpy(
        [0.2, 0.0, 0.3],
        [0.0, 0.0, std::f64::consts::PI],
        0.04,
    ));
    assert_eq!(outcome.collision, None);
}

#[test]
fn gripper_geometry_per_robot() {
    assert_eq!(
        GripperGeometry::for_model(RobotModel::Ned2).max_opening_m,
        0.040
    );
    assert_eq!(
        GripperGeometry::for_model(RobotModel::WidowX250).max_opening_m,
        0.044
    );
    let world = World::new(&Scene::default_widowx());
    assert_eq!(world.gripper_width_m(), 0.044);
    // Fingertips at the TCP, inner faces at ± opening / 2.
    let world = World::new(&Scene::default_ned2());
    let [left, right, palm] = world.gripper_boxes();
    let tcp = world.tool().tcp;
    let local = |b: &GripperBox| tcp.inverse() * b.pose;
    assert!((local(&left).translation.y - (0.020 + 0.004)).abs() < 1e-12);
    assert!((local(&right).translation.y + (0.020 + 0.004)).abs() < 1e-12);
    assert!((local(&left).translation.x + 0.0175).abs() < 1e-12);
    assert!(local(&palm).translation.x < -0.035);
}

#[test]
fn fingers_opening_against_a_neighbour_stall_at_the_contact() {
    let mut world = empty_world();
    world
        .add_object(cube("pencil-ish", 0.25, 0.0, 0.012))
        .unwrap();
    world
        .add_object(cube("neighbour", 0.25, 0.036, 0.03))
        .unwrap();
    // Grasp the small cube across y: fully open, a finger would reach y = 0.028 > 0.021.
    world.set_tool(ToolState::pointing_down(0.25, 0.0, 0.006, 0.0, 0.012));
    assert!(matches!(
        world.close_gripper(),
        GraspOutcome::Grasped { .. }
    ));
    world.open_gripper(0.04);
    let opening = world.gripper_width_m();
    // Finger inner face at opening/2, 8 mm thick: stops where the neighbour's side begins.
    let outer = opening / 2.0 + 0.008;
    assert!(
        (outer - 0.021).abs() < 0.0002,
        "the finger stopped with its outer face at {outer:.4} m"
    );
    assert_eq!(world.held(), None, "opened past the held width: released");
    // And the arm is free to leave straight up.
    let (_, outcome) = world.move_tool(&down(0.25, 0.0, 0.06, 0.0));
    assert_eq!(outcome.collision, None);
}
