//! `get_camera_image`: what the wrist camera sees, as a picture for a model that looks.
//!
//! The picture is taken from the workspace's observation pose, the pose the detection tools
//! answer from: if the arm rests there already it is taken at once, otherwise the arm goes
//! there first (through the skills, under the same motion policy as every motion) and the
//! picture is the first frame after it came to rest. The objects of the workspace model's
//! view — the same ids and labels `get_detected_objects` gives — are drawn on it as boxes
//! with their ids ([`crate::picture`]) and listed in the text, so a model can say "obj-3"
//! about what it sees and name it with `label_object`. The JPEG is at most
//! `ToolSettings::image_max_bytes` (150 kB by default): re-encoded at a lower quality, then
//! made smaller, until it fits.

use super::{pt, Reply, Tool};
use crate::args;
use crate::picture::{self, Request};
use crate::view::{ask, fresh_view_of, unexpected};
use crate::{CallHooks, Registry, ToolImage};
use robotd_protocol::objects::DetectedObject;
use robotd_protocol::workspace::{WorkspaceReply, WorkspaceRequest};
use robotd_protocol::Location;
use schemars::JsonSchema;
use serde::{Deserialize, Deserializer, Serialize};

pub(crate) struct GetCameraImage;

/// Widest picture the tool makes, pixels (the camera's frames are 640 wide).
pub(crate) const MAX_WIDTH: u64 = 640;
/// Narrowest picture asked for, pixels: less shows nothing a model could name.
pub(crate) const MIN_WIDTH: u64 = 64;

fn annotated<'de, D: Deserializer<'de>>(d: D) -> Result<bool, D::Error> {
    args::flag(d, true)
}

fn max_width<'de, D: Deserializer<'de>>(d: D) -> Result<u64, D::Error> {
    args::whole_in(d, MAX_WIDTH, MIN_WIDTH, MAX_WIDTH)
}

/// The arguments of `get_camera_image`.
#[derive(Debug, Deserialize, JsonSchema)]
pub(crate) struct Args {
    /// Workspace to look at, e.g. "niryo_ws"; the robot's current workspace when absent.
    #[schemars(length(max = 100))]
    #[serde(deserialize_with = "args::opt_text")]
    workspace_id: Option<String>,
    /// Draw each detected object's box, id and label on the picture (default true).
    #[schemars(with = "Option<bool>", extend("default" = true))]
    #[serde(deserialize_with = "annotated")]
    annotated: bool,
    /// Widest picture in pixels, 64 … 640 (default 640, the camera's full width).
    #[schemars(with = "Option<u64>", range(min = 64, max = 640), extend("default" = 640))]
    #[serde(deserialize_with = "max_width")]
    max_width: u64,
}

/// One object marked on the picture.
#[derive(Debug, Serialize, JsonSchema)]
pub(crate) struct Marked {
    /// Its stable id, as drawn.
    id: String,
    /// Its label (a name given by `label_object`, or the detector's).
    label: String,
    /// Centre of mass `[x, y]` on the table, metres.
    position: [f64; 2],
    /// Extent along y and along x, metres.
    width_m: f64,
    height_m: f64,
}

/// The data of `get_camera_image` (the picture itself is the image content).
#[derive(Debug, Serialize, JsonSchema)]
pub(crate) struct Data {
    /// The workspace shown.
    workspace_id: String,
    /// The camera's frame id.
    frame_id: u64,
    /// Capture time, seconds since the Unix epoch.
    timestamp: f64,
    /// `image/jpeg`.
    mime_type: String,
    /// Picture size, pixels.
    width: usize,
    height: usize,
    /// JPEG size, bytes.
    bytes: usize,
    /// JPEG quality it was encoded at.
    quality: u8,
    /// Whether the objects are drawn on it.
    annotated: bool,
    /// The objects of the view, as drawn.
    objects: Vec<Marked>,
}

impl Tool for GetCameraImage {
    const NAME: &'static str = "get_camera_image";
    const DESCRIPTION: &'static str =
        "Take a picture with the wrist camera from the observation pose of a workspace \
         (moving there first if needed) and return it as a JPEG image, with each detected \
         object's box, id and label drawn on it (unless annotated is false), plus a text \
         listing the ids, labels and positions. Look before acting on an 'unknown object' or \
         a name you have not seen; then name what you see with label_object.";
    type Args = Args;
    type Data = Data;

    async fn run(registry: &Registry, a: Args, hooks: CallHooks) -> Result<Reply<Data>, String> {
        let fail = |reason: String| format!("❌ Error getting camera image: {reason}");
        let workspaces = &registry.settings().workspaces;
        let ws = match &a.workspace_id {
            None => &workspaces[0],
            Some(id) => workspaces.iter().find(|w| w.id == *id).ok_or_else(|| {
                let known: Vec<&str> = workspaces.iter().map(|w| w.id.as_str()).collect();
                fail(format!(
                    "unknown workspace '{id}'; known: {}",
                    known.join(", ")
                ))
            })?,
        };
        let camera = registry.camera().map_err(fail)?;
        let work = async {
            let fresh = fresh_view_of(registry, ws, &hooks).await?;
            let request = WorkspaceRequest::GetObjects {
                location: Location::None,
                coordinate: None,
                label: None,
            };
            let objects = match ask(registry, request, Some(fresh)).await? {
                WorkspaceReply::Objects { objects } => objects,
                other => return Err(unexpected(&other)),
            };
            let frame = camera
                .frame_after(fresh, registry.settings().query_timeout)
                .await?;
            Ok((objects, frame))
        };
        let (objects, frame) = tokio::select! {
            done = work => done.map_err(fail)?,
            () = hooks.cancel.cancelled() => return Err(fail("the call was cancelled".into())),
        };
        let request = Request {
            annotated: a.annotated,
            max_width: a.max_width as usize,
            max_bytes: registry.settings().image_max_bytes,
        };
        let drawn = objects.clone();
        let made = tokio::task::spawn_blocking(move || {
            picture::make(&frame.rgb, frame.width, frame.height, &drawn, &request)
                .map(|p| (p, frame.frame_id, frame.timestamp_unix_ns))
        })
        .await
        .map_err(|e| fail(format!("the picture could not be made: {e}")))?;
        let (picture, frame_id, taken_ns) = made.map_err(fail)?;
        let text = describe(&ws.id, &picture, a.annotated, &objects);
        let data = Data {
            workspace_id: ws.id.clone(),
            frame_id,
            timestamp: taken_ns as f64 / 1e9,
            mime_type: "image/jpeg".into(),
            width: picture.width,
            height: picture.height,
            bytes: picture.jpeg.len(),
            quality: picture.quality,
            annotated: a.annotated,
            objects: objects.iter().map(marked).collect(),
        };
        let image = ToolImage {
            mime_type: "image/jpeg",
            data: picture.jpeg,
        };
        Ok(Reply::new(text, data).with_image(image))
    }
}

fn marked(o: &DetectedObject) -> Marked {
    Marked {
        id: o.id.clone(),
        label: o.label.clone(),
        position: [o.xy().x_m, o.xy().y_m],
        width_m: o.dimensions.width_m,
        height_m: o.dimensions.height_m,
    }
}

/// The text item: what the picture is and the objects on it, one line each.
fn describe(
    ws: &str,
    picture: &picture::Picture,
    annotated: bool,
    objects: &[DetectedObject],
) -> String {
    let size = format!(
        "{}×{} JPEG, {:.1} kB",
        picture.width,
        picture.height,
        picture.jpeg.len() as f64 / 1000.0
    );
    if objects.is_empty() {
        return format!("✓ Camera image of workspace '{ws}' ({size}); no objects detected");
    }
    let how = if annotated {
        "marked on the image by id"
    } else {
        "(not drawn)"
    };
    let mut text = format!(
        "✓ Camera image of workspace '{ws}' ({size}); {} object(s) {how}:",
        objects.len()
    );
    for o in objects {
        text.push_str(&format!(
            "\n- {}: '{}' at {}, {:.0}×{:.0} mm",
            o.id,
            o.label,
            pt(o.xy()),
            o.dimensions.width_m * 1000.0,
            o.dimensions.height_m * 1000.0
        ));
    }
    text
}
