//! `label_object`: give a tracked object a name, for objects the detector cannot name.
//!
//! The built-in detector names objects by colour and shape; anything else is an
//! `unknown object`. A model that looked at the table (`get_camera_image`) can say what it is:
//! `label_object("obj-3", "screwdriver")`. The workspace model keeps the name for that object
//! while it is tracked — in every detection reply, on the dashboard, in Redis and recordings,
//! and when the skills pick or push by name — until it leaves the table or is named again.
//! The name follows the label table's rules (`workspace.max_label_chars`,
//! `workspace.max_labels`) and joins the detectable labels.

use super::{pretty, Reply, Tool};
use crate::args;
use crate::schema::ObjectJson;
use crate::view::{ask, unexpected};
use crate::{CallHooks, Registry};
use robotd_protocol::objects::DetectedObject;
use robotd_protocol::workspace::{WorkspaceReply, WorkspaceRequest};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

pub(crate) struct LabelObject;

/// The arguments of `label_object`.
#[derive(Debug, Deserialize, JsonSchema)]
pub(crate) struct Args {
    /// The object's id, as the detection tools and get_camera_image give it, e.g. "obj-3".
    #[schemars(length(min = 1, max = 100))]
    #[serde(deserialize_with = "args::text")]
    object_id: String,
    /// Its name, e.g. "screwdriver" (stored lower-case; pick it by this name afterwards).
    #[schemars(length(min = 1, max = 100))]
    #[serde(deserialize_with = "args::text")]
    label: String,
}

/// The data of `label_object`.
#[derive(Debug, Serialize, JsonSchema)]
pub(crate) struct Data {
    /// The object, with its new label.
    #[schemars(with = "ObjectJson")]
    object: DetectedObject,
    /// Its label before.
    previous: String,
    /// What the detector calls it.
    detected_as: String,
    /// Whether the name was new to the detectable labels.
    label_added: bool,
}

impl Tool for LabelObject {
    const NAME: &'static str = "label_object";
    const DESCRIPTION: &'static str =
        "Give a detected object a name, e.g. after looking at an 'unknown object' with \
         get_camera_image: label_object(object_id='obj-3', label='screwdriver'). The object \
         keeps the name while it is tracked (detection tools, picks and pushes by that name) \
         until it leaves the table or is named again; the name is added to the recognizable \
         objects.";
    type Args = Args;
    type Data = Data;

    async fn run(registry: &Registry, a: Args, _: CallHooks) -> Result<Reply<Data>, String> {
        let fail = |reason: String| format!("❌ Error labelling object: {reason}");
        let request = WorkspaceRequest::LabelObject {
            object_id: a.object_id,
            label: a.label,
        };
        match ask(registry, request, None).await.map_err(fail)? {
            WorkspaceReply::ObjectLabelled {
                object,
                previous,
                detected_as,
                label_added,
            } => {
                let mut text = format!(
                    "✓ {} is now '{}' (was '{previous}'):\n{}",
                    object.id,
                    object.label,
                    pretty(&object)
                );
                if label_added {
                    text.push_str(&format!(
                        "\nAdded {} to the list of recognizable objects.",
                        object.label
                    ));
                }
                Ok(Reply::new(
                    text,
                    Data {
                        object,
                        previous,
                        detected_as,
                        label_added,
                    },
                ))
            }
            other => Err(fail(unexpected(&other))),
        }
    }
}
