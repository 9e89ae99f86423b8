//! `pick_place_object`: pick an object up and put it down elsewhere, in one motion — at a
//! coordinate, or relative to the object nearest it (`location`).

use super::{pt, Reply, Tool};
use crate::args;
use crate::schema::location_schema;
use crate::skill::{location_text, run_skill, Motion, SkillFailure};
use crate::{CallHooks, Registry};
use robotd_protocol::skills::{Skill, DEFAULT_Z_OFFSET_M};
use robotd_protocol::{Location, Point2};
use schemars::JsonSchema;
use serde::Deserialize;

pub(crate) struct PickPlaceObject;

/// The arguments of `pick_place_object`.
#[derive(Debug, Deserialize, JsonSchema)]
pub(crate) struct Args {
    /// Label of the object to pick, exactly as detected (case-insensitive), e.g. "pencil".
    #[schemars(length(min = 1, max = 100))]
    #[serde(deserialize_with = "args::text")]
    object_name: String,
    /// [x, y] of the object in metres (robot base frame: x forward, y left).
    #[schemars(with = "[f64; 2]")]
    #[serde(deserialize_with = "args::point")]
    pick_coordinate: Point2,
    /// [x, y] where to place it, or of the reference object when `location` is given.
    #[schemars(with = "[f64; 2]")]
    #[serde(deserialize_with = "args::point")]
    place_coordinate: Point2,
    // `close to` is refused here, with the Python server's value error.
    #[schemars(schema_with = "location_schema", default)]
    #[serde(deserialize_with = "args::pick_place_location")]
    location: Option<Location>,
    /// Height above the object's centre of mass at which to close the gripper, metres.
    #[schemars(with = "Option<f64>", range(min = 0.0, max = 0.1), extend("default" = 0.001))]
    #[serde(deserialize_with = "args::z_offset")]
    z_offset: f64,
}

impl Tool for PickPlaceObject {
    const NAME: &'static str = "pick_place_object";
    const DESCRIPTION: &'static str =
        "Pick up an object and place it somewhere else in one motion. The object is the one \
         labelled object_name nearest pick_coordinate (within 5 cm). Without a location it is \
         put exactly at place_coordinate; with a location it is put relative to the object \
         nearest place_coordinate (e.g. 'right next to' it, 'on top of' it). Coordinates are \
         [x, y] in metres in the robot base frame: x forward (away from the robot), y left. \
         Targets outside the workspace or out of reach are refused before anything moves.";
    const MOVES_ARM: bool = true;
    type Args = Args;
    type Data = Motion;

    async fn run(registry: &Registry, a: Args, hooks: CallHooks) -> Result<Reply<Motion>, String> {
        // Never `close to`: the reader refuses it, in the Python server's words.
        let location = a.location.unwrap_or_default();
        let skill = Skill::PickPlace {
            object_name: a.object_name.clone(),
            pick_at: a.pick_coordinate,
            place_at: a.place_coordinate,
            location,
            z_offset_m: a.z_offset,
        };
        let name = &a.object_name;
        match run_skill(registry, skill, &hooks).await {
            Ok(done) => {
                let z = a.z_offset;
                let z_text = if (z - DEFAULT_Z_OFFSET_M).abs() > 1e-12 {
                    format!(" (z_offset: {z:.3}m)")
                } else {
                    String::new()
                };
                Ok(Reply::new(
                    format!(
                        "✓ Successfully picked '{name}' from {}{z_text} and placed it{} {}",
                        pt(a.pick_coordinate),
                        location_text(location),
                        pt(a.place_coordinate)
                    ),
                    done,
                ))
            }
            Err(SkillFailure::Unavailable(reason)) => {
                Err(format!("❌ Error during {}: {reason}", Self::NAME))
            }
            Err(failure) => Err(format!(
                "❌ Failed to pick and place '{name}': {}",
                failure.reason()
            )),
        }
    }
}
