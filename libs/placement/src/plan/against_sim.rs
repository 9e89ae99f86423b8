//! What the grasp check accepts, the simulator can do: random tables, each accepted grasp
//! played in the simulated world (`robotd-sim`, the gripper's true boxes), with the tool
//! coming down from the approach height to the grasp height with open fingers.
//!
//! The planner and the simulator share the gripper's sizes
//! (`robotd_protocol::gripper_geometry`); this test is what keeps the planner's footprint
//! rules (the fingers' sweep, the palm above them, the heights that count) honest against the
//! simulator's solid boxes. A descent that hits or shoves a neighbour after the check said
//! yes is a failure, and so is a check that refuses everything.

use super::*;
use robotd_protocol::objects::{Dimensions, ObjectPosition};
use robotd_protocol::{Point3, RobotModel};
use robotd_sim::{ObjectShape, ObjectSpec, Scene, ToolState, World};

struct Rng(u64);

impl Rng {
    fn unit(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
    fn range(&mut self, low: f64, high: f64) -> f64 {
        low + (high - low) * self.unit()
    }
}

/// What a perfect camera would report for a simulated object.
fn as_detected(o: &robotd_sim::SimObject) -> DetectedObject {
    let [along_x, along_y, tall] = o.spec.shape.extents_m();
    let yaw = o.yaw_rad();
    let p = o.pose.translation;
    DetectedObject {
        id: format!("obj-{}", o.id),
        label: o.spec.label.clone(),
        workspace_id: "niryo_ws".into(),
        position: ObjectPosition {
            center_of_mass: Point3::new(p.x, p.y, tall / 2.0),
            center: Point3::new(p.x, p.y, tall / 2.0),
        },
        dimensions: Dimensions {
            width_m: along_y,
            height_m: along_x,
            size_m2: along_x * along_y,
        },
        // The long side's direction.
        gripper_rotation_rad: if along_x >= along_y {
            yaw
        } else {
            yaw + FRAC_PI_2
        },
        ..Default::default()
    }
}

fn random_shape(rng: &mut Rng, narrow_m: f64) -> ObjectShape {
    if rng.unit() < 0.3 {
        ObjectShape::Cylinder {
            diameter_m: rng.range(0.010, narrow_m),
            height_m: rng.range(0.008, 0.09),
        }
    } else {
        ObjectShape::Box {
            length_x_m: rng.range(0.008, 0.12),
            width_y_m: rng.range(0.008, narrow_m),
            height_z_m: rng.range(0.004, 0.09),
        }
    }
}

#[test]
fn every_grasp_the_check_accepts_comes_down_without_touching_a_neighbour() {
    for (model, scene) in [
        (RobotModel::Ned2, Scene::default_ned2()),
        (RobotModel::WidowX250, Scene::default_widowx()),
    ] {
        grasps_on(model, scene);
    }
}

fn grasps_on(model: RobotModel, empty: Scene) {
    let settings = SkillsSettings::new(model, empty.workspace_infos());
    let ws = &settings.workspaces[0];
    let centre = (
        (ws.upper_left.x_m + ws.lower_right.x_m) / 2.0,
        (ws.upper_left.y_m + ws.lower_right.y_m) / 2.0,
    );
    let mut rng = Rng(0x6_7A5F_5EED);
    let (mut accepted, mut refused, mut failures) = (0, 0, Vec::new());
    for trial in 0..600 {
        let mut scene = empty.clone();
        scene.objects.clear();
        let mut world = World::new(&scene);
        let (x, y) = (
            centre.0 + rng.range(-0.05, 0.05),
            centre.1 + rng.range(-0.05, 0.05),
        );
        // The target: narrow enough for the open gripper across its short side.
        let target_shape = random_shape(&mut rng, settings.gripper_max_width_m - 0.006);
        let target = ObjectSpec::new("target", target_shape, [200, 30, 30], x, y)
            .with_yaw(rng.range(-3.1, 3.1));
        let Ok(target_id) = world.add_object(target) else {
            continue;
        };
        for n in 0..1 + (rng.unit() * 4.0) as usize {
            let (distance, bearing) = (rng.range(0.025, 0.075), rng.range(-3.2, 3.2));
            let spec = ObjectSpec::new(
                &format!("neighbour {n}"),
                random_shape(&mut rng, 0.05),
                [40, 80, 200],
                x + distance * bearing.cos(),
                y + distance * bearing.sin(),
            )
            .with_yaw(rng.range(-3.1, 3.1));
            // Overlapping specs are refused by the world: then the table has fewer.
            let _ = world.add_object(spec);
        }
        let objects: Vec<DetectedObject> = world.objects().iter().map(as_detected).collect();
        let object = objects
            .iter()
            .find(|o| o.id == format!("obj-{target_id}"))
            .expect("the target is on the table")
            .clone();
        let z_offset = if rng.unit() < 0.5 {
            0.0
        } else {
            rng.range(0.0, 0.03)
        };
        let grasp_z = grasp_height(&settings, &object, z_offset);
        let Ok(yaw) = grasp_yaw(&settings, &object, &objects, grasp_z) else {
            refused += 1;
            continue;
        };
        accepted += 1;
        let approach_z = top_z(&object) + settings.approach_height_m;
        let open = settings.gripper_max_width_m;
        world.set_tool(ToolState::pointing_down(x, y, approach_z, yaw, open));
        world.open_gripper(open);
        let (_, outcome) = world.move_tool(&ToolState::pointing_down(x, y, grasp_z, yaw, open));
        let shoved: Vec<u32> = outcome
            .pushed
            .iter()
            .copied()
            .filter(|id| *id != target_id)
            .collect();
        if outcome.collision.is_some() || !shoved.is_empty() {
            failures.push(format!(
                "trial {trial}: grasp of {:?} at yaw {yaw:.3}, z {grasp_z:.3}: collision {:?}, shoved {shoved:?}; table {:?}",
                object.dimensions,
                outcome.collision,
                world
                    .objects()
                    .iter()
                    .map(|o| (o.spec.label.clone(), o.spec.shape, o.spec.x_m, o.spec.y_m, o.spec.yaw_rad))
                    .collect::<Vec<_>>()
            ));
        }
    }
    assert!(
        failures.is_empty(),
        "{model:?}: {} of {accepted} accepted grasps hit the table or a neighbour:\n{}",
        failures.len(),
        failures.join("\n")
    );
    // Both answers must be common, or the test proves nothing.
    assert!(
        accepted > 150 && refused > 50,
        "{model:?}: accepted {accepted}, refused {refused}"
    );
}
