//! `get_largest_free_space_with_center`: the largest empty rectangle of the workspace, a good
//! place to put something down.

use super::{pt, xy, NoArguments, Reply, Tool};
use crate::view::{ask_fresh, unexpected};
use crate::{CallHooks, Registry};
use robotd_protocol::workspace::{WorkspaceReply, WorkspaceRequest};
use schemars::JsonSchema;
use serde::Serialize;

pub(crate) struct GetLargestFreeSpaceWithCenter;

/// The data of `get_largest_free_space_with_center`.
#[derive(Debug, Serialize, JsonSchema)]
pub(crate) struct Data {
    /// Area of the free rectangle, m².
    area_m2: f64,
    /// Its centre, `[x, y]` metres.
    center: [f64; 2],
}

impl Tool for GetLargestFreeSpaceWithCenter {
    const NAME: &'static str = "get_largest_free_space_with_center";
    const DESCRIPTION: &'static str =
        "The largest empty rectangle of the workspace: its area in m² and its centre [x, y], a \
         good place to put something down.";
    type Args = NoArguments;
    type Data = Data;

    async fn run(
        registry: &Registry,
        _: NoArguments,
        hooks: CallHooks,
    ) -> Result<Reply<Data>, String> {
        let fail = |reason: String| format!("❌ Error getting largest free space: {reason}");
        match ask_fresh(registry, WorkspaceRequest::GetLargestFreeSpace, &hooks)
            .await
            .map_err(fail)?
        {
            WorkspaceReply::FreeSpace { area_m2, center } => Ok(Reply::new(
                format!(
                    "✓ Largest free space: {area_m2:.4} m² at center coordinates {}",
                    pt(center)
                ),
                Data {
                    area_m2,
                    center: xy(center),
                },
            )),
            other => Err(fail(unexpected(&other))),
        }
    }
}
