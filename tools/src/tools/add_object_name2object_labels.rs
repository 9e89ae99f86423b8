//! `add_object_name2object_labels`: add a label to the recognisable objects.
//!
//! A bad `object_name` alone gets the Python server's one-line
//! `❌ Validation Error: object_name must be a non-empty string`.

use super::{only_field_invalid, Reply, Tool};
use crate::args::{self, FieldError};
use crate::view::{ask, unexpected};
use crate::{CallHooks, Registry};
use robotd_protocol::workspace::{WorkspaceReply, WorkspaceRequest};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

pub(crate) struct AddObjectName2ObjectLabels;

/// The arguments of `add_object_name2object_labels`.
#[derive(Debug, Deserialize, JsonSchema)]
pub(crate) struct Args {
    /// The new label, e.g. "screwdriver" (stored lower-case).
    #[schemars(length(min = 1, max = 100))]
    #[serde(deserialize_with = "args::text")]
    object_name: String,
}

/// The data of `add_object_name2object_labels`.
#[derive(Debug, Serialize, JsonSchema)]
pub(crate) struct Data {
    /// The label as stored.
    label: String,
    /// Whether robotd knew it already.
    already_known: bool,
}

impl Tool for AddObjectName2ObjectLabels {
    const NAME: &'static str = "add_object_name2object_labels";
    const DESCRIPTION: &'static str =
        "Add a label to the list of recognisable objects (stored lower-case).";
    type Args = Args;
    type Data = Data;

    async fn run(registry: &Registry, a: Args, _: CallHooks) -> Result<Reply<Data>, String> {
        let fail = |reason: String| format!("❌ Error adding object label: {reason}");
        let name = a.object_name;
        let request = WorkspaceRequest::AddLabel {
            label: name.clone(),
        };
        match ask(registry, request, None).await.map_err(fail)? {
            WorkspaceReply::LabelAdded {
                label,
                already_known,
            } => {
                let text = if already_known {
                    format!("✓ {name} is already in the list of recognizable objects.")
                } else {
                    format!("✓ Added {name} to the list of recognizable objects.")
                };
                Ok(Reply::new(
                    text,
                    Data {
                        label,
                        already_known,
                    },
                ))
            }
            other => Err(fail(unexpected(&other))),
        }
    }

    fn invalid(errors: &[FieldError]) -> String {
        only_field_invalid(Self::NAME, "object_name", errors)
    }
}
