//! `get_detected_objects`: the objects the camera sees now, optionally filtered by a
//! location relative to a coordinate and by a label substring.

use super::{pretty, Reply, Tool};
use crate::args;
use crate::schema::location_schema;
use crate::view::{ask_fresh, unexpected, Objects};
use crate::{CallHooks, Registry};
use robotd_protocol::workspace::{WorkspaceReply, WorkspaceRequest};
use robotd_protocol::{Location, Point2};
use schemars::JsonSchema;
use serde::Deserialize;

pub(crate) struct GetDetectedObjects;

/// The arguments of `get_detected_objects`.
#[derive(Debug, Deserialize, JsonSchema)]
pub(crate) struct Args {
    #[schemars(schema_with = "location_schema", default)]
    #[serde(deserialize_with = "args::opt_word")]
    location: Option<Location>,
    /// Reference [x, y] of the location filter, metres; required unless location is none.
    #[schemars(with = "Option<[f64; 2]>")]
    #[serde(deserialize_with = "args::opt_point")]
    coordinate: Option<Point2>,
    /// Keep only objects whose label contains this text (case-insensitive).
    #[schemars(length(max = 100))]
    #[serde(deserialize_with = "args::opt_text")]
    label: Option<String>,
}

impl Tool for GetDetectedObjects {
    const NAME: &'static str = "get_detected_objects";
    const DESCRIPTION: &'static str =
        "List the objects the camera sees now, optionally filtered by a location relative to a \
         coordinate ('left next to' = larger y, 'right next to' = smaller y, 'above' = larger \
         x, 'below' = smaller x, 'close to' = within 2 cm) and by a label substring. Each \
         object has a stable id, its position in metres and its size.";
    type Args = Args;
    type Data = Objects;

    async fn run(registry: &Registry, a: Args, hooks: CallHooks) -> Result<Reply<Objects>, String> {
        let location = a.location.unwrap_or_default();
        let fail = |reason: String| format!("❌ Error getting detected objects: {reason}");
        if location.needs_coordinate() && a.coordinate.is_none() {
            return Err(fail(format!(
                "Coordinate must be provided for location filter: {}",
                location
            )));
        }
        let request = WorkspaceRequest::GetObjects {
            location,
            coordinate: a.coordinate,
            label: a.label,
        };
        match ask_fresh(registry, request, &hooks).await.map_err(fail)? {
            WorkspaceReply::Objects { objects } if objects.is_empty() => Ok(Reply::new(
                "✓ No objects detected matching the criteria",
                Objects(objects),
            )),
            WorkspaceReply::Objects { objects } => Ok(Reply::new(
                format!("✓ Found {} object(s):\n{}", objects.len(), pretty(&objects)),
                Objects(objects),
            )),
            other => Err(fail(unexpected(&other))),
        }
    }
}
