//! The simulated tabletop of a robot arm: the table, the workspace sheets with their corner
//! markers, the objects standing on them, and what the gripper physically does to them.
//!
//! robotd's `sim` driver needs a world that behaves like the real one closely enough that the
//! skills above it (pick, place, push) can fail the way they fail on a real robot. This crate is
//! that world — and only that: joints and inverse kinematics live in `robotd-kinematics` (this
//! crate is given the **tool centre point pose**), pixels in `robotd-render` (this crate
//! describes what is visible: [`World::sheet_quads`], [`World::markers`], [`World::objects`]).
//!
//! # Frame and conventions
//!
//! World frame = robot base frame: x forward, y left, z up, metres; the table top is z = 0.
//! The TCP pose is an [`nalgebra::Isometry3`]: the tool points along the TCP's +x (down when
//! pitch = +π/2, with R = Rz(yaw)·Ry(pitch)·Rx(roll)) and the two fingers close along the
//! TCP's y. The fingertips are at the TCP; fingers and palm are boxes
//! ([`GripperGeometry`]: Ned2 opens to 0.040 m, WidowX to 0.044 m).
//!
//! # What is modelled
//!
//! - **Motion** ([`World::move_tool`]): straight-line moves in ≤ 1 mm sub-steps. Fingers or
//!   palm entering the table or an object stop the motion at the contact and report a
//!   collision — except a mostly horizontal move of an empty gripper into an object that
//!   cannot slip between the fingers: that **pushes** the object (and whatever it runs into)
//!   along.
//! - **Grasping** ([`World::close_gripper`]): only an object really between the fingers is
//!   grasped — centred within 5 mm, fingers reaching into it, jaw across a side that fits in the
//!   opening. Otherwise the gripper closes on nothing and says why.
//! - **Carrying and releasing**: a held object follows the tool rigidly and collides like the
//!   gripper (with 2 mm of give, so it can be set down); released
//!   ([`World::open_gripper`]) it drops straight down onto the table, onto another object
//!   (stacking) or into an open container.
//!
//! Not modelled: friction, toppling, objects rotating when pushed off-centre, deformable or
//! tilted objects at rest.
//!
//! Scenes come from TOML files (`config/scenes/*.toml`) via [`Scene`]; the default Ned2 scene
//! is compiled in.
//!
//! # Example
//!
//! ```
//! use robotd_sim::{GraspOutcome, Scene, ToolState, World};
//!
//! let mut world = World::new(&Scene::default_ned2());
//! let cube = world.objects().iter().find(|o| o.spec.label == "red cube").unwrap();
//! let (id, x, y) = (cube.id, cube.pose.translation.x, cube.pose.translation.y);
//!
//! // Open gripper above the cube, jaw across it (yaw 0: fingers close along y), then down to
//! // the cube's mid-height.
//! world.set_tool(ToolState::pointing_down(x, y, 0.10, 0.0, 0.040));
//! let (_, outcome) = world.move_tool(&ToolState::pointing_down(x, y, 0.015, 0.0, 0.040));
//! assert_eq!(outcome.collision, None);
//!
//! assert!(matches!(world.close_gripper(), GraspOutcome::Grasped { .. }));
//! assert!((world.gripper_width_m() - 0.030).abs() < 1e-9); // the fingers rest on the cube
//!
//! // Lift: the cube comes along.
//! world.move_tool(&ToolState::pointing_down(x, y, 0.10, 0.0, 0.030));
//! assert!((world.object(id).unwrap().pose.translation.z - 0.10).abs() < 1e-6);
//!
//! // Released in the air, it drops straight down onto the table.
//! assert_eq!(world.open_gripper(0.040), Some(id));
//! assert!((world.object(id).unwrap().pose.translation.z - 0.015).abs() < 1e-9);
//! ```

mod geom;
mod gripper;
mod scene;
mod world;

pub use gripper::{GripperBox, GripperBoxes, GripperGeometry};
pub use scene::{
    colour_by_name, Marker, ObjectShape, ObjectSpec, Rgb, Scene, SceneError, WorkspaceSpec,
    COLOURS, CONTAINER_WALL_M, MARKER_RADIUS_M, MARKER_Z_M, MAX_COORD_M, MAX_SIZE_M, MIN_SIZE_M,
    SHEET_MARGIN_M, SHEET_Z_M,
};
pub use world::{
    Contact, GraspOutcome, SimObject, StepOutcome, ToolState, World, CONTACT_TOLERANCE_M,
    GRASP_ANGLE_TOLERANCE_DEG, GRASP_CENTRE_TOLERANCE_M, GRASP_MIN_ENGAGEMENT_M, HELD_TOLERANCE_M,
    SUB_STEP_M,
};

#[cfg(test)]
mod tests;
