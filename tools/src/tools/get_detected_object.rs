//! `get_detected_object`: the object nearest a coordinate (within 2 cm), optionally
//! filtered by a label substring.

use super::{pretty, pt, Reply, Tool};
use crate::args;
use crate::view::{ask_fresh, unexpected, Object};
use crate::{CallHooks, Registry};
use robotd_protocol::workspace::{WorkspaceReply, WorkspaceRequest};
use robotd_protocol::Point2;
use schemars::JsonSchema;
use serde::Deserialize;

pub(crate) struct GetDetectedObject;

/// The arguments of `get_detected_object`.
#[derive(Debug, Deserialize, JsonSchema)]
pub(crate) struct Args {
    /// [x, y] to look at, metres; objects within 2 cm count.
    #[schemars(with = "[f64; 2]")]
    #[serde(deserialize_with = "args::point")]
    coordinate: Point2,
    /// Keep only objects whose label contains this text (case-insensitive).
    #[schemars(length(max = 100))]
    #[serde(deserialize_with = "args::opt_text")]
    label: Option<String>,
}

impl Tool for GetDetectedObject {
    const NAME: &'static str = "get_detected_object";
    const DESCRIPTION: &'static str =
        "The object nearest coordinate ([x, y] metres), within 2 cm, optionally filtered by a \
         label substring.";
    type Args = Args;
    type Data = Object;

    async fn run(registry: &Registry, a: Args, hooks: CallHooks) -> Result<Reply<Object>, String> {
        let fail = |reason: String| format!("❌ Error getting detected object: {reason}");
        let coordinate = a.coordinate;
        let request = WorkspaceRequest::GetObjectNear {
            coordinate,
            label: a.label,
        };
        match ask_fresh(registry, request, &hooks).await.map_err(fail)? {
            WorkspaceReply::Object { object: None } => Ok(Reply::without_data(format!(
                "✓ No object found near {}",
                pt(coordinate)
            ))),
            WorkspaceReply::Object {
                object: Some(object),
            } => Ok(Reply::new(
                format!(
                    "✓ Found object near {}:\n{}",
                    pt(coordinate),
                    pretty(&object)
                ),
                Object(object),
            )),
            other => Err(fail(unexpected(&other))),
        }
    }
}
