//! `pick_object`: pick up the object nearest a coordinate and hold it.

use super::{pt, Reply, Tool};
use crate::args;
use crate::skill::{run_skill, Motion};
use crate::{CallHooks, Registry};
use robotd_protocol::skills::{Skill, DEFAULT_Z_OFFSET_M};
use robotd_protocol::Point2;
use schemars::JsonSchema;
use serde::Deserialize;

pub(crate) struct PickObject;

/// The arguments of `pick_object`.
#[derive(Debug, Deserialize, JsonSchema)]
pub(crate) struct Args {
    /// Label of the object to pick (case-insensitive exact match).
    #[schemars(length(min = 1, max = 100))]
    #[serde(deserialize_with = "args::text")]
    object_name: String,
    /// [x, y] of the object in metres.
    #[schemars(with = "[f64; 2]")]
    #[serde(deserialize_with = "args::point")]
    pick_coordinate: Point2,
    /// Height above the object's centre of mass at which to close the gripper, metres.
    #[schemars(with = "Option<f64>", range(min = 0.0, max = 0.1), extend("default" = 0.001))]
    #[serde(deserialize_with = "args::z_offset")]
    z_offset: f64,
}

impl Tool for PickObject {
    const NAME: &'static str = "pick_object";
    const DESCRIPTION: &'static str =
        "Pick up the object labelled object_name nearest pick_coordinate ([x, y] metres, within \
         5 cm) and hold it. Reports failure when the gripper does not really hold it.";
    const MOVES_ARM: bool = true;
    type Args = Args;
    type Data = Motion;

    async fn run(registry: &Registry, a: Args, hooks: CallHooks) -> Result<Reply<Motion>, String> {
        let skill = Skill::Pick {
            object_name: a.object_name.clone(),
            pick_at: a.pick_coordinate,
            z_offset_m: a.z_offset,
        };
        let (name, z) = (&a.object_name, a.z_offset);
        match run_skill(registry, skill, &hooks).await {
            Ok(done) => {
                let z_text = if (z - DEFAULT_Z_OFFSET_M).abs() > 1e-12 {
                    format!(" with z_offset {z:.3}m")
                } else {
                    String::new()
                };
                Ok(Reply::new(
                    format!(
                        "✓ Successfully picked '{name}' from {}{z_text}",
                        pt(a.pick_coordinate)
                    ),
                    done,
                ))
            }
            Err(failure) => Err(format!("❌ Failed to pick '{name}': {}", failure.reason())),
        }
    }
}
