//! `get_workspace_coordinate_from_point`: the `[x, y]` of a workspace corner or centre.
//!
//! An unknown point word is a validation error worded as the Python server's
//! (`• point: Value error, Point must be one of: …`); `point` is read as text and parsed by the
//! handler, so case and spacing are forgiven like every other word-valued argument.

use super::{pt, xy, Reply, Tool};
use crate::args;
use crate::args::{validation_text, FieldError};
use crate::schema::point_schema;
use crate::view::{ask, unexpected};
use crate::{CallHooks, Registry};
use robotd_protocol::workspace::{WorkspaceReply, WorkspaceRequest};
use robotd_protocol::WorkspacePoint;
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

pub(crate) struct GetWorkspaceCoordinateFromPoint;

/// The arguments of `get_workspace_coordinate_from_point`.
#[derive(Debug, Deserialize, JsonSchema)]
pub(crate) struct Args {
    /// Workspace id, e.g. "niryo_ws".
    #[schemars(length(min = 1, max = 100))]
    #[serde(deserialize_with = "args::text")]
    workspace_id: String,
    #[schemars(schema_with = "point_schema")]
    #[serde(deserialize_with = "args::text")]
    point: String,
}

/// The data of `get_workspace_coordinate_from_point`.
#[derive(Debug, Serialize, JsonSchema)]
pub(crate) struct Data {
    /// The workspace asked about.
    workspace_id: String,
    /// The point, in the contract's words (e.g. "upper left corner").
    point: String,
    /// Its `[x, y]`, metres.
    coordinate: [f64; 2],
}

impl Tool for GetWorkspaceCoordinateFromPoint {
    const NAME: &'static str = "get_workspace_coordinate_from_point";
    const DESCRIPTION: &'static str =
        "The [x, y] coordinate of a workspace corner ('upper left corner' = far left, 'lower \
         right corner' = near right, …) or of its 'center point'.";
    type Args = Args;
    type Data = Data;

    async fn run(registry: &Registry, a: Args, _: CallHooks) -> Result<Reply<Data>, String> {
        let ws = a.workspace_id;
        let Ok(point) = a.point.parse::<WorkspacePoint>() else {
            return Err(validation_text(
                Self::NAME,
                &[FieldError {
                    field: "point".into(),
                    message: format!(
                        "Value error, Point must be one of: {}",
                        WorkspacePoint::STRINGS.join(", ")
                    ),
                }],
            ));
        };
        let request = WorkspaceRequest::GetWorkspacePoint {
            workspace_id: ws.clone(),
            point,
        };
        match ask(registry, request, None).await {
            Ok(WorkspaceReply::Coordinate { coordinate }) => Ok(Reply::new(
                format!(
                    "✓ Coordinate of '{point}' in workspace '{ws}': {}",
                    pt(coordinate)
                ),
                Data {
                    workspace_id: ws,
                    point: point.as_str().to_owned(),
                    coordinate: xy(coordinate),
                },
            )),
            Ok(other) => Err(format!(
                "❌ Could not get coordinate for '{point}' in workspace '{ws}': {}",
                unexpected(&other)
            )),
            Err(reason) => Err(format!("❌ Error getting workspace coordinate: {reason}")),
        }
    }
}
