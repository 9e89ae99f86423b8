//! `get_largest_free_space_with_center`: the largest free square of the workspace, a good
//! place to put something down: anything that fits in a square of the answered area can be put
//! down at its centre (the workspace model's `free_space` module).

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
    /// Area of the free square, m²: anything whose longest side is at most its square root fits.
    area_m2: f64,
    /// Its centre, `[x, y]` metres.
    center: [f64; 2],
}

impl Tool for GetLargestFreeSpaceWithCenter {
    const NAME: &'static str = "get_largest_free_space_with_center";
    const DESCRIPTION: &'static str =
        "The largest free square of the workspace: its area in m² and its centre [x, y]. \
         Anything whose footprint fits in a square of that area (its longest side at most the \
         square root of the area) can be put down at the centre.";
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
