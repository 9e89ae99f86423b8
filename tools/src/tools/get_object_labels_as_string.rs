//! `get_object_labels_as_string`: the labels of the objects robotd can recognise.

use super::{NoArguments, Reply, Tool};
use crate::view::{ask, unexpected};
use crate::{CallHooks, Registry};
use robotd_protocol::workspace::{WorkspaceReply, WorkspaceRequest};
use schemars::JsonSchema;
use serde::Serialize;

pub(crate) struct GetObjectLabelsAsString;

/// The data of `get_object_labels_as_string`.
#[derive(Debug, Serialize, JsonSchema)]
pub(crate) struct Data {
    /// The recognisable labels.
    labels: Vec<String>,
}

impl Tool for GetObjectLabelsAsString {
    const NAME: &'static str = "get_object_labels_as_string";
    const DESCRIPTION: &'static str = "The labels of the objects robotd can recognise.";
    type Args = NoArguments;
    type Data = Data;

    async fn run(registry: &Registry, _: NoArguments, _: CallHooks) -> Result<Reply<Data>, String> {
        let fail = |reason: String| format!("❌ Error getting object labels: {reason}");
        match ask(registry, WorkspaceRequest::GetLabels, None)
            .await
            .map_err(fail)?
        {
            WorkspaceReply::Labels { labels, .. } if labels.is_empty() => Ok(Reply::new(
                "✓ Detectable objects: No detectable objects configured.",
                Data { labels },
            )),
            WorkspaceReply::Labels { labels, .. } => Ok(Reply::new(
                format!(
                    "✓ Detectable objects: I can recognize these objects: {}",
                    labels.join(", ")
                ),
                Data { labels },
            )),
            other => Err(fail(unexpected(&other))),
        }
    }
}
