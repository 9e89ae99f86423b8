//! `move2by`: pick an object up and put it down a distance in metres away.
//!
//! Unlike `push_object`, an unknown direction is not a validation error here but the
//! Python server's `❌ Error during move2by: Invalid direction '…'`, so `direction` is read
//! as text and parsed by the handler.

use super::{pt, Reply, Tool};
use crate::args;
use crate::schema::direction_schema;
use crate::skill::{run_skill, Motion};
use crate::{CallHooks, Registry};
use robotd_protocol::skills::Skill;
use robotd_protocol::{Direction, Point2};
use schemars::JsonSchema;
use serde::{Deserialize, Deserializer};

pub(crate) struct Move2By;

/// Longest move, metres.
const MAX_MOVE_M: f64 = 0.5;

fn distance<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
    args::positive(d, MAX_MOVE_M)
}

/// The arguments of `move2by`.
#[derive(Debug, Deserialize, JsonSchema)]
pub(crate) struct Args {
    /// Label of the object to move (case-insensitive exact match).
    #[schemars(length(min = 1, max = 100))]
    #[serde(deserialize_with = "args::text")]
    object_name: String,
    /// [x, y] of the object in metres.
    #[schemars(with = "[f64; 2]")]
    #[serde(deserialize_with = "args::point")]
    pick_coordinate: Point2,
    #[schemars(schema_with = "direction_schema")]
    #[serde(deserialize_with = "args::text")]
    direction: String,
    /// How far to move it, in METRES.
    #[schemars(extend("exclusiveMinimum" = 0, "maximum" = 0.5))]
    #[serde(deserialize_with = "distance")]
    distance: f64,
    /// Height above the object's centre of mass at which to close the gripper, metres.
    #[schemars(with = "Option<f64>", range(min = 0.0, max = 0.1), extend("default" = 0.001))]
    #[serde(deserialize_with = "args::z_offset")]
    z_offset: f64,
}

impl Tool for Move2By {
    const NAME: &'static str = "move2by";
    const DESCRIPTION: &'static str =
        "Pick up an object and put it down distance METRES away in direction (up = +x, down = \
         −x, left = +y, right = −y).";
    const MOVES_ARM: bool = true;
    type Args = Args;
    type Data = Motion;

    async fn run(registry: &Registry, a: Args, hooks: CallHooks) -> Result<Reply<Motion>, String> {
        let Ok(direction) = a.direction.parse::<Direction>() else {
            return Err(format!(
                "❌ Error during {}: Invalid direction '{}'",
                Self::NAME,
                a.direction
            ));
        };
        let (name, pick, distance) = (&a.object_name, a.pick_coordinate, a.distance);
        let target = direction.offset(pick, distance);
        let skill = Skill::MoveBy {
            object_name: name.clone(),
            pick_at: pick,
            direction,
            distance_m: distance,
            z_offset_m: a.z_offset,
        };
        match run_skill(registry, skill, &hooks).await {
            Ok(done) => Ok(Reply::new(
                format!(
                    "✓ Successfully picked '{name}' from {} and placed it {:.1} centimeters {direction}wards at {}",
                    pt(pick),
                    distance * 100.0,
                    pt(target)
                ),
                done,
            )),
            Err(failure) => Err(format!(
                "❌ Failed to pick and move '{name}': {}",
                failure.reason()
            )),
        }
    }
}
