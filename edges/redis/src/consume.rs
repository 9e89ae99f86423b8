//! Redis in to the bus: other programs' detections and label changes.
//!
//! A task reads `detected_objects` and `detectable_labels` with `XREAD BLOCK` on a connection
//! of its own, from the moment it starts (older entries are history, not news). Entries robotd
//! wrote itself are passed over. For the others:
//!
//! - **Detections** (when the trusted detector includes external ones): objects in world
//!   coordinates (written by another robotd) are published on `perception/detections` as they
//!   are; objects in the vision format (pixel boxes, masks) are mapped through the frame they
//!   were made from — named by `frame_id`, else the newest published frame taken at or before
//!   the entry's frame timestamp — with robotd's own pixel-to-world transform
//!   ([`robotd_vision::external`]). The workspace model then tracks them like its own
//!   (`source` = `redis:<model>`).
//! - **Labels**: each label not yet known is added to the workspace model's label registry.
//!
//! Every entry ends in one counted outcome: `consumed`, or `skipped_<why>` — broken JSON,
//! wrong types, huge values, stale detections, frames no longer kept. Nothing in an entry can
//! stop the task; it reconnects with backoff like the writer.

use crate::camera::SharedRing;
use crate::status::EdgeStatus;
use crate::wire::{self, Skip, DETECTABLE_LABELS, DETECTED_OBJECTS};
use crate::writer;
use robotd_protocol::camera::CameraIntrinsics;
use robotd_protocol::objects::{DetectedObject, Detections};
use robotd_protocol::workspace::{WorkspaceInfo, WorkspaceQuery, WorkspaceReply, WorkspaceRequest};
use robotd_runtime::backoff::Backoff;
use robotd_runtime::bus::{Bus, BusError, Client, Publisher};
use robotd_topics::{PERCEPTION_DETECTIONS, WORKSPACE_QUERY};
use robotd_vision::detector::{DetectError, Detector, FrameView, SheetView};
use robotd_vision::external::PixelObject;
use robotd_vision::labels::LabelTable;
use robotd_vision::Pipeline;
use serde_json::{Map, Value};
use std::sync::{Arc, Mutex};
use std::time::Duration;
use tokio_util::sync::CancellationToken;

/// How long one `XREAD` blocks, ms.
const BLOCK_MS: usize = 500;
/// Entries per stream per read.
const COUNT: usize = 20;

/// What the consumer needs besides the bus.
#[derive(Debug, Clone)]
pub struct ConsumerSettings {
    /// This robotd's instance id (its own entries are skipped).
    pub instance: String,
    /// Whether external detections go to the workspace model.
    pub consume_detections: bool,
    /// Largest entry accepted, bytes of field values.
    pub max_entry_bytes: usize,
    /// The camera (for the pixel-to-world transform).
    pub intrinsics: CameraIntrinsics,
    /// The configured workspaces.
    pub workspaces: Vec<WorkspaceInfo>,
    /// Heights of known labels.
    pub label_table: LabelTable,
}

/// A detector that finds nothing: the pipeline's markers and plane are all the consumer uses.
struct NoDetector;

impl Detector for NoDetector {
    fn name(&self) -> &str {
        "external"
    }
    fn labels(&self) -> Vec<String> {
        Vec::new()
    }
    fn detect(
        &mut self,
        _: &FrameView<'_>,
        _: &SheetView<'_>,
    ) -> Result<Vec<DetectedObject>, DetectError> {
        Ok(Vec::new())
    }
}

fn now_s() -> f64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_secs_f64())
        .unwrap_or(0.0)
}

struct Consumer {
    settings: ConsumerSettings,
    status: Arc<EdgeStatus>,
    ring: SharedRing,
    pipeline: Arc<Mutex<Pipeline>>,
    publisher: Publisher<Detections>,
    workspace: Client<WorkspaceQuery, WorkspaceReply>,
}

/// Starts the consumer task; returns once its bus ports are open.
pub fn start(
    bus: &Bus,
    client: redis::Client,
    settings: ConsumerSettings,
    ring: SharedRing,
    status: Arc<EdgeStatus>,
    stop: CancellationToken,
) -> Result<tokio::task::JoinHandle<()>, String> {
    let pipeline = Pipeline::new(
        &settings.intrinsics,
        settings.workspaces.clone(),
        Box::new(NoDetector),
    )
    .map_err(|e| e.to_string())?;
    let bus_error = |e: BusError| e.to_string();
    let consumer = Consumer {
        publisher: bus.publisher(&PERCEPTION_DETECTIONS).map_err(bus_error)?,
        workspace: bus.client(&WORKSPACE_QUERY).map_err(bus_error)?,
        settings,
        status,
        ring,
        pipeline: Arc::new(Mutex::new(pipeline)),
    };
    Ok(tokio::spawn(consumer.run(client, stop)))
}

/// An entry's fields as JSON strings; `Err` when a value is not UTF-8 text.
fn fields_of(
    map: &std::collections::HashMap<String, redis::Value>,
) -> Result<Map<String, Value>, Skip> {
    let mut out = Map::new();
    for (name, value) in map {
        let text = match value {
            redis::Value::BulkString(bytes) => {
                String::from_utf8(bytes.clone()).map_err(|_| Skip::Malformed {
                    field: "entry",
                    reason: format!("field '{name}' is not UTF-8 text"),
                })?
            }
            redis::Value::SimpleString(s) => s.clone(),
            redis::Value::Int(i) => i.to_string(),
            _ => {
                return Err(Skip::Malformed {
                    field: "entry",
                    reason: format!("field '{name}' is not a string"),
                })
            }
        };
        out.insert(name.clone(), Value::String(text));
    }
    Ok(out)
}

impl Consumer {
    async fn run(self, client: redis::Client, stop: CancellationToken) {
        let start_id = format!("{}-0", (now_s() * 1000.0) as u64);
        let mut ids = [start_id.clone(), start_id];
        let mut connection = None;
        let mut backoff = Backoff::up_to(writer::BACKOFF_MAX);
        loop {
            if stop.is_cancelled() {
                return;
            }
            let Some(conn) = connection.as_mut() else {
                let attempt = tokio::select! {
                    _ = stop.cancelled() => return,
                    attempt = writer::connect(&client) => attempt,
                };
                match attempt {
                    Ok(c) => {
                        connection = Some(c);
                        backoff.reset();
                    }
                    Err(_) => {
                        tokio::select! {
                            _ = stop.cancelled() => return,
                            _ = tokio::time::sleep(backoff.next_delay()) => {}
                        }
                    }
                }
                continue;
            };
            let options = redis::streams::StreamReadOptions::default()
                .block(BLOCK_MS)
                .count(COUNT);
            let read = tokio::select! {
                _ = stop.cancelled() => return,
                read = tokio::time::timeout(
                    writer::RESPONSE_TIMEOUT,
                    redis::AsyncCommands::xread_options::<_, _, redis::streams::StreamReadReply>(
                        conn,
                        &[DETECTED_OBJECTS, DETECTABLE_LABELS],
                        &ids,
                        &options,
                    ),
                ) => read,
            };
            let reply = match read {
                Ok(Ok(reply)) => reply,
                Ok(Err(error)) => {
                    tracing::debug!(%error, "redis edge: reading streams failed");
                    connection = None;
                    continue;
                }
                Err(_) => {
                    connection = None;
                    continue;
                }
            };
            for key in reply.keys {
                let (slot, stream) = if key.key == DETECTED_OBJECTS {
                    (0, DETECTED_OBJECTS)
                } else if key.key == DETECTABLE_LABELS {
                    (1, DETECTABLE_LABELS)
                } else {
                    continue;
                };
                for entry in key.ids {
                    ids[slot] = entry.id.clone();
                    let outcome = match fields_of(&entry.map) {
                        Ok(fields) => self.handle(stream, &fields).await,
                        Err(skip) => Err(skip),
                    };
                    match outcome {
                        Ok(Some(())) => self.status.count(stream, "consumed"),
                        Ok(None) => {}
                        Err(skip) => {
                            tracing::debug!(stream, id = %entry.id, %skip, "redis edge: skipped an entry");
                            self.status.count(stream, skip.outcome());
                        }
                    }
                }
            }
        }
    }

    /// Handles one entry: `Ok(None)` for robotd's own entries.
    async fn handle(
        &self,
        stream: &'static str,
        fields: &Map<String, Value>,
    ) -> Result<Option<()>, Skip> {
        if wire::writer(fields) == Some(self.settings.instance.as_str()) {
            return Ok(None);
        }
        wire::check_size(fields, self.settings.max_entry_bytes)?;
        if stream == DETECTABLE_LABELS {
            self.labels(fields).await?;
        } else {
            if !self.settings.consume_detections {
                return Ok(None);
            }
            self.detections(fields).await?;
        }
        Ok(Some(()))
    }

    async fn labels(&self, fields: &Map<String, Value>) -> Result<(), Skip> {
        let labels = wire::parse_labels(fields)?;
        let ask = |request| WorkspaceQuery {
            request,
            fresh_after_unix_ns: None,
            max_wait_ms: 0,
        };
        let known = match self
            .workspace
            .request(&ask(WorkspaceRequest::GetLabels), Duration::from_secs(2))
            .await
        {
            Ok(WorkspaceReply::Labels { labels, .. }) => labels,
            _ => Vec::new(),
        };
        for label in labels.into_iter().filter(|l| !known.contains(l)) {
            let added = self
                .workspace
                .request(
                    &ask(WorkspaceRequest::AddLabel {
                        label: label.clone(),
                    }),
                    Duration::from_secs(2),
                )
                .await;
            if let Err(error) = added {
                tracing::warn!(%error, %label, "redis edge: adding a label from Redis failed");
            }
        }
        Ok(())
    }

    async fn detections(&self, fields: &Map<String, Value>) -> Result<(), Skip> {
        let parsed = wire::parse_detections(fields, now_s())?;
        for bad in &parsed.bad_objects {
            self.status.count(DETECTED_OBJECTS, bad.outcome());
        }
        let who = wire::writer(fields)
            .map(str::to_owned)
            .unwrap_or(parsed.model.clone());
        let source = format!("redis:{who}");
        let timestamp_unix_ns = (parsed
            .frame_timestamp_unix_s
            .unwrap_or(parsed.timestamp_unix_s)
            * 1e9) as u64;
        if !parsed.world.is_empty() || parsed.vision.is_empty() {
            // World objects: one view per workspace they lie in.
            let mut by_workspace: Vec<(String, Vec<DetectedObject>)> = Vec::new();
            for object in &parsed.world {
                let ws = object.workspace_id.clone();
                match by_workspace.iter_mut().find(|(w, _)| *w == ws) {
                    Some((_, list)) => list.push(object.clone()),
                    None => by_workspace.push((ws, vec![object.clone()])),
                }
            }
            if by_workspace.is_empty() {
                if let Some(ws) = fields
                    .get("camera_pose")
                    .and_then(Value::as_str)
                    .and_then(|p| serde_json::from_str::<Value>(p).ok())
                    .and_then(|p| {
                        p.get("workspace_id")
                            .and_then(Value::as_str)
                            .map(str::to_owned)
                    })
                {
                    by_workspace.push((ws, Vec::new()));
                }
            }
            for (workspace_id, objects) in by_workspace {
                if !self
                    .settings
                    .workspaces
                    .iter()
                    .any(|w| w.id == workspace_id)
                {
                    return Err(Skip::Malformed {
                        field: "objects",
                        reason: format!("workspace '{workspace_id}' is not configured here"),
                    });
                }
                self.publish(Detections {
                    frame_id: parsed.frame_id.unwrap_or(0),
                    workspace_id,
                    timestamp_unix_ns,
                    source: source.clone(),
                    steady: parsed.steady,
                    objects,
                });
            }
        }
        if parsed.vision.is_empty() {
            return Ok(());
        }
        let frame = {
            let ring = self
                .ring
                .lock()
                .unwrap_or_else(std::sync::PoisonError::into_inner);
            match parsed.frame_id {
                Some(id) => ring.by_id(id).cloned(),
                None => ring
                    .at_or_before(
                        parsed
                            .frame_timestamp_unix_s
                            .unwrap_or(parsed.timestamp_unix_s),
                    )
                    .cloned(),
            }
        };
        let Some(frame) = frame else {
            return Err(Skip::Malformed {
                field: "camera_pose",
                reason: "the frame the detections were made from is no longer kept (or was \
                         never published by this robotd)"
                    .into(),
            });
        };
        let (w, h) = frame.size;
        let objects: Vec<PixelObject> = parsed
            .vision
            .iter()
            .map(|o| {
                let bbox = [
                    o.bbox[0].floor().clamp(0.0, w as f64) as u32,
                    o.bbox[1].floor().clamp(0.0, h as f64) as u32,
                    o.bbox[2].ceil().clamp(0.0, w as f64) as u32,
                    o.bbox[3].ceil().clamp(0.0, h as f64) as u32,
                ];
                PixelObject {
                    label: o.label.clone(),
                    confidence: o.confidence,
                    class_id: o.class_id,
                    bbox_px: bbox,
                    mask_pixels: o.mask.as_ref().map(|m| wire::mask_pixels(m, bbox, w, h)),
                }
            })
            .collect();
        let pipeline = self.pipeline.clone();
        let table = self.settings.label_table.clone();
        let source_for_task = source.clone();
        let located = tokio::task::spawn_blocking(move || {
            let mut pipeline = pipeline
                .lock()
                .unwrap_or_else(std::sync::PoisonError::into_inner);
            let rgb = frame.rgb()?;
            let view = FrameView {
                rgb: &rgb,
                width: w,
                height: h,
                frame_id: frame.frame_id,
                timestamp_unix_ns: frame.timestamp_unix_ns,
            };
            Ok::<_, String>(pipeline.locate_pixel_objects(
                &view,
                frame.tool_pose.as_ref(),
                frame.steady && parsed.steady,
                &source_for_task,
                &objects,
                &table,
            ))
        })
        .await
        .map_err(|e| e.to_string())
        .and_then(|located| located)
        .map_err(|reason| Skip::Malformed {
            field: "objects",
            reason: format!("mapping the pixels failed: {reason}"),
        })?;
        let (detections, sheet, skipped) = located;
        for _ in &skipped {
            self.status
                .count(DETECTED_OBJECTS, "skipped_object_not_placeable");
        }
        if sheet != robotd_vision::SheetStatus::Found {
            return Err(Skip::Malformed {
                field: "objects",
                reason: "the workspace markers are not visible in that frame".into(),
            });
        }
        self.publish(detections);
        Ok(())
    }

    fn publish(&self, detections: Detections) {
        if let Err(error) = self.publisher.publish(&detections) {
            tracing::warn!(%error, "redis edge: publishing external detections failed");
        }
    }
}
