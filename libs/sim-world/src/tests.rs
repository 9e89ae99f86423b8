//! Tests of scenes and of the world's physics.

use crate::*;
use nalgebra::Vector3;
use robotd_protocol::geometry::RobotModel;
use std::f64::consts::FRAC_PI_2;

const PUSH_TOML: &str = include_str!("../../../config/scenes/push.toml");
const WIDOWX_TOML: &str = include_str!("../../../config/scenes/widowx.toml");

/// Reach of a Ned2-sized arm, roughly: within 0.45 m of the base and below 0.3 m.
fn roughly_reachable(x: f64, y: f64, z: f64) -> bool {
    x.hypot(y) < 0.45 && x > 0.05 && z < 0.3
}

const WS: &str = r#"
name = "test"
robot = "ned2"

[[workspaces]]
id = "niryo_ws"
upper_left = [0.337, 0.087]
lower_right = [0.163, -0.087]
observation_pose = [0.173, -0.002, 0.277, -3.042, 1.327, -3.027]
"#;

fn cube_toml(label: &str, x: f64, y: f64, size: f64) -> String {
    format!(
        "[[objects]]\nlabel = \"{label}\"\nshape = \"box\"\nlength_x_m = {size}\n\
         width_y_m = {size}\nheight_z_m = {size}\ncolor = \"red\"\nx_m = {x}\ny_m = {y}\n"
    )
}

fn parse(objects: &str) -> Result<Scene, SceneError> {
    Scene::from_toml_str(&format!("{WS}\n{objects}"), "test.toml")
}

fn empty_world() -> World {
    World::new(&parse("").unwrap())
}

fn cube(label: &str, x: f64, y: f64, size: f64) -> ObjectSpec {
    ObjectSpec::new(
        label,
        ObjectShape::Box {
            length_x_m: size,
            width_y_m: size,
            height_z_m: size,
        },
        [200, 30, 30],
        x,
        y,
    )
}

fn large_box(x: f64, y: f64) -> ObjectSpec {
    ObjectSpec::new(
        "large box",
        ObjectShape::Box {
            length_x_m: 0.090,
            width_y_m: 0.070,
            height_z_m: 0.050,
        },
        [240, 130, 30],
        x,
        y,
    )
}

fn find<'a>(world: &'a World, label: &str) -> &'a SimObject {
    world
        .objects()
        .iter()
        .find(|o| o.spec.label == label)
        .unwrap()
}

fn centre(world: &World, label: &str) -> Vector3<f64> {
    find(world, label).pose.translation.vector
}

fn down(x: f64, y: f64, z: f64, yaw: f64) -> ToolState {
    ToolState::pointing_down(x, y, z, yaw, 0.0)
}

/// Moves there (asserting no collision).
fn go(world: &mut World, x: f64, y: f64, z: f64, yaw: f64) {
    let (_, outcome) = world.move_tool(&down(x, y, z, yaw));
    assert_eq!(outcome.collision, None, "moving to ({x}, {y}, {z})");
}

/// Picks the object `label` at its centre from above: open, down to mid-height, close, lift.
fn pick(world: &mut World, label: &str, yaw: f64) -> u32 {
    let c = centre(world, label);
    let top = find(world, label).top_z();
    world.open_gripper(1.0);
    go(world, c.x, c.y, top + 0.06, yaw);
    go(world, c.x, c.y, c.z, yaw);
    match world.close_gripper() {
        GraspOutcome::Grasped { id, .. } => {
            go(world, c.x, c.y, top + 0.06, yaw);
            id
        }
        GraspOutcome::Empty { reason } => panic!("could not pick {label}: {reason}"),
    }
}

// ---- scenes ----

mod contact;
mod scenes;
