//! `get_detected_objects_sorted`: every object the camera sees, sorted by footprint area.

use super::{pretty, Reply, Tool};
use crate::args;
use crate::view::{ask_fresh, unexpected, Objects};
use crate::{CallHooks, Registry};
use robotd_protocol::workspace::{WorkspaceReply, WorkspaceRequest};
use schemars::JsonSchema;
use serde::{Deserialize, Deserializer};

pub(crate) struct GetDetectedObjectsSorted;

fn ascending<'de, D: Deserializer<'de>>(d: D) -> Result<bool, D::Error> {
    args::flag(d, true)
}

/// The arguments of `get_detected_objects_sorted`.
#[derive(Debug, Deserialize, JsonSchema)]
pub(crate) struct Args {
    /// Smallest first when true (the default), largest first when false.
    #[schemars(with = "Option<bool>", extend("default" = true))]
    #[serde(deserialize_with = "ascending")]
    ascending: bool,
}

impl Tool for GetDetectedObjectsSorted {
    const NAME: &'static str = "get_detected_objects_sorted";
    const DESCRIPTION: &'static str =
        "Every object the camera sees, sorted by footprint area (smallest first unless \
         ascending is false).";
    type Args = Args;
    type Data = Objects;

    async fn run(registry: &Registry, a: Args, hooks: CallHooks) -> Result<Reply<Objects>, String> {
        let fail = |reason: String| format!("❌ Error getting sorted objects: {reason}");
        let ascending = a.ascending;
        let request = WorkspaceRequest::GetObjectsSorted { ascending };
        match ask_fresh(registry, request, &hooks).await.map_err(fail)? {
            WorkspaceReply::Objects { objects } if objects.is_empty() => {
                Ok(Reply::new("✓ No objects detected", Objects(objects)))
            }
            WorkspaceReply::Objects { objects } => {
                let order = if ascending {
                    "smallest to largest"
                } else {
                    "largest to smallest"
                };
                Ok(Reply::new(
                    format!(
                        "✓ Found {} object(s) sorted {order}:\n{}",
                        objects.len(),
                        pretty(&objects)
                    ),
                    Objects(objects),
                ))
            }
            other => Err(fail(unexpected(&other))),
        }
    }
}
