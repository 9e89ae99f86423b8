//! `get_largest_detected_object`: the largest object the camera sees, by footprint area.
//! Also home of [`extreme_object`], which `get_smallest_detected_object` shares.

use super::{pretty, NoArguments, Reply, Tool};
use crate::view::{ask_fresh, unexpected, Object};
use crate::{CallHooks, Registry};
use robotd_protocol::workspace::{WorkspaceReply, WorkspaceRequest};

pub(crate) struct GetLargestDetectedObject;

impl Tool for GetLargestDetectedObject {
    const NAME: &'static str = "get_largest_detected_object";
    const DESCRIPTION: &'static str = "The largest object the camera sees (by footprint area).";
    type Args = NoArguments;
    type Data = Object;

    async fn run(
        registry: &Registry,
        _: NoArguments,
        hooks: CallHooks,
    ) -> Result<Reply<Object>, String> {
        extreme_object(registry, &hooks, true).await
    }
}

/// The largest (or smallest) object, worded as the contract does.
pub(super) async fn extreme_object(
    registry: &Registry,
    hooks: &CallHooks,
    largest: bool,
) -> Result<Reply<Object>, String> {
    let (word, title, request) = if largest {
        ("largest", "Largest", WorkspaceRequest::GetLargestObject)
    } else {
        ("smallest", "Smallest", WorkspaceRequest::GetSmallestObject)
    };
    let fail = |reason: String| format!("❌ Error getting {word} object: {reason}");
    match ask_fresh(registry, request, hooks).await.map_err(fail)? {
        WorkspaceReply::Object { object: None } => Ok(Reply::without_data("✓ No objects detected")),
        WorkspaceReply::Object {
            object: Some(object),
        } => Ok(Reply::new(
            format!(
                "✓ {title} object ({:.6} m²):\n{}",
                object.dimensions.size_m2,
                pretty(&object)
            ),
            Object(object),
        )),
        other => Err(fail(unexpected(&other))),
    }
}
