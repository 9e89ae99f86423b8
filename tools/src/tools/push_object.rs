//! `push_object`: push an object too wide to grip, a distance in millimetres.

use super::{pt, Reply, Tool};
use crate::args;
use crate::schema::direction_schema;
use crate::skill::{run_skill, Motion};
use crate::{CallHooks, Registry};
use robotd_protocol::skills::Skill;
use robotd_protocol::{Direction, Point2};
use schemars::JsonSchema;
use serde::{Deserialize, Deserializer};

pub(crate) struct PushObject;

/// Longest push, millimetres (the workspaces are about 20 cm across).
const MAX_PUSH_MM: f64 = 500.0;

fn distance<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
    args::positive(d, MAX_PUSH_MM)
}

/// The arguments of `push_object`.
#[derive(Debug, Deserialize, JsonSchema)]
pub(crate) struct Args {
    /// Label of the object to push (case-insensitive exact match).
    #[schemars(length(min = 1, max = 100))]
    #[serde(deserialize_with = "args::text")]
    object_name: String,
    /// [x, y] of the object in metres.
    #[schemars(with = "[f64; 2]")]
    #[serde(deserialize_with = "args::point")]
    push_coordinate: Point2,
    #[schemars(schema_with = "direction_schema")]
    #[serde(deserialize_with = "args::word")]
    direction: Direction,
    /// How far to push, in MILLIMETRES.
    #[schemars(extend("exclusiveMinimum" = 0, "maximum" = 500))]
    #[serde(deserialize_with = "distance")]
    distance: f64,
}

impl Tool for PushObject {
    const NAME: &'static str = "push_object";
    const DESCRIPTION: &'static str =
        "Push an object that is too wide to grip: the gripper starts just behind it and moves \
         distance MILLIMETRES in direction (up = +x away from the robot, down = −x, left = +y, \
         right = −y).";
    const MOVES_ARM: bool = true;
    type Args = Args;
    type Data = Motion;

    async fn run(registry: &Registry, a: Args, hooks: CallHooks) -> Result<Reply<Motion>, String> {
        let (name, direction, distance_mm) = (&a.object_name, a.direction, a.distance);
        let skill = Skill::Push {
            object_name: name.clone(),
            push_at: a.push_coordinate,
            direction,
            distance_m: distance_mm / 1000.0,
        };
        match run_skill(registry, skill, &hooks).await {
            Ok(done) => Ok(Reply::new(
                format!(
                    "✓ Successfully pushed '{name}' from {} {direction} by {distance_mm:.1}mm",
                    pt(a.push_coordinate)
                ),
                done,
            )),
            Err(failure) => Err(format!("❌ Failed to push '{name}': {}", failure.reason())),
        }
    }
}
