//! `place_object`: put down the object the gripper holds — at a coordinate, or relative to
//! the object nearest it (`location`).

use super::{pt, Reply, Tool};
use crate::args;
use crate::schema::location_schema;
use crate::skill::{location_text, run_skill, Motion};
use crate::{CallHooks, Registry};
use robotd_protocol::skills::Skill;
use robotd_protocol::{Location, Point2};
use schemars::JsonSchema;
use serde::Deserialize;

pub(crate) struct PlaceObject;

/// The arguments of `place_object`.
#[derive(Debug, Deserialize, JsonSchema)]
pub(crate) struct Args {
    /// [x, y] where to place the held object, or of the reference object when `location` is given.
    #[schemars(with = "[f64; 2]")]
    #[serde(deserialize_with = "args::point")]
    place_coordinate: Point2,
    #[schemars(schema_with = "location_schema", default)]
    #[serde(deserialize_with = "args::opt_word")]
    location: Option<Location>,
}

impl Tool for PlaceObject {
    const NAME: &'static str = "place_object";
    const DESCRIPTION: &'static str =
        "Place the object the gripper holds at place_coordinate ([x, y] metres), or relative to \
         the object nearest it when location is given.";
    const MOVES_ARM: bool = true;
    type Args = Args;
    type Data = Motion;

    async fn run(registry: &Registry, a: Args, hooks: CallHooks) -> Result<Reply<Motion>, String> {
        let location = a.location.unwrap_or_default();
        let skill = Skill::Place {
            place_at: a.place_coordinate,
            location,
        };
        match run_skill(registry, skill, &hooks).await {
            Ok(done) => Ok(Reply::new(
                format!(
                    "✓ Successfully placed object{} {}",
                    location_text(location),
                    pt(a.place_coordinate)
                ),
                done,
            )),
            Err(failure) => Err(format!("❌ Failed to place object: {}", failure.reason())),
        }
    }
}
