//! Bus messages out to Redis: robotd's own detections, the label list, the overlay texts.
//!
//! - `perception/detections` from the built-in detector → `detected_objects` (at most
//!   `objects_fps` entries a second), each object with
//!   the id the workspace model tracks it under (taken from the newest `workspace/objects`:
//!   same label, within the tracker's 3 cm gate; a frame-local id `f<frame>-<n>` until the model
//!   has it). Detections that came in from Redis are not sent back out.
//! - `workspace/labels` → `detectable_labels`, at start, on every change, and every 30 s
//!   (the Python side takes a list older than 60 s for stale).
//! - `overlay/text` → `video_text_overlays`.

use crate::wire::{detections_entry, labels_entry, overlay_entry};
use crate::writer::EntrySender;
use robotd_protocol::objects::Detections;
use robotd_protocol::workspace::{
    DetectableLabels, TrackedObjects, WorkspaceQuery, WorkspaceReply, WorkspaceRequest,
};
use robotd_runtime::bus::{Bus, BusError};
use robotd_runtime::catalog::{
    OVERLAY_TEXT, PERCEPTION_DETECTIONS, WORKSPACE_LABELS, WORKSPACE_OBJECTS, WORKSPACE_QUERY,
};
use std::time::Duration;
use tokio_util::sync::CancellationToken;

/// How often the label list is republished.
pub const LABELS_EVERY: Duration = Duration::from_secs(30);

/// The `source` of the built-in detector's detections.
pub const BUILTIN_SOURCE: &str = "robotd";

fn now_s() -> f64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_secs_f64())
        .unwrap_or(0.0)
}

/// The tracked ids of `detections`' objects, from `tracked` (same workspace and label, nearest
/// within 3 cm), else `f<frame>-<n>`.
pub fn tracked_ids(detections: &Detections, tracked: Option<&TrackedObjects>) -> Vec<String> {
    let mut taken: Vec<&str> = Vec::new();
    detections
        .objects
        .iter()
        .enumerate()
        .map(|(n, object)| {
            let candidate = tracked
                .filter(|t| t.workspace_id == detections.workspace_id)
                .and_then(|t| {
                    t.objects
                        .iter()
                        .filter(|o| o.label_is(&object.label) && !taken.contains(&o.id.as_str()))
                        .map(|o| (o.xy().distance_to(&object.xy()), o))
                        .filter(|(d, _)| *d <= 0.03)
                        .min_by(|a, b| a.0.total_cmp(&b.0))
                        .map(|(_, o)| o)
                });
            match candidate {
                Some(o) => {
                    taken.push(&o.id);
                    o.id.clone()
                }
                None => format!("f{}-{n}", detections.frame_id),
            }
        })
        .collect()
}

/// Starts the relay task. Returns once its bus ports are open.
pub fn start(
    bus: &Bus,
    instance: String,
    objects_fps: f64,
    sender: EntrySender,
    stop: CancellationToken,
) -> Result<tokio::task::JoinHandle<()>, BusError> {
    let mut detections = bus.subscriber(&PERCEPTION_DETECTIONS)?;
    let mut objects = bus.subscriber(&WORKSPACE_OBJECTS)?;
    let mut labels = bus.subscriber(&WORKSPACE_LABELS)?;
    let mut overlays = bus.subscriber(&OVERLAY_TEXT)?;
    let workspace = bus.client(&WORKSPACE_QUERY)?;
    let objects_every = (objects_fps > 0.0 && objects_fps.is_finite())
        .then(|| Duration::from_secs_f64(1.0 / objects_fps));
    Ok(tokio::spawn(async move {
        let mut last_objects: Option<tokio::time::Instant> = None;
        let mut tracked: Option<TrackedObjects> = None;
        let mut last_labels: Option<DetectableLabels> = None;
        // The list as it is now (its start-up publication may have gone before we listened).
        let ask = WorkspaceQuery {
            request: WorkspaceRequest::GetLabels,
            fresh_after_unix_ns: None,
            max_wait_ms: 0,
        };
        if let Ok(WorkspaceReply::Labels { labels, builtin }) =
            workspace.request(&ask, Duration::from_secs(2)).await
        {
            sender.offer(labels_entry(&instance, now_s(), &labels, None));
            last_labels = Some(DetectableLabels {
                labels,
                added: None,
                builtin,
            });
        }
        let mut republish = tokio::time::interval(LABELS_EVERY);
        republish.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
        loop {
            tokio::select! {
                _ = stop.cancelled() => break,
                received = detections.recv() => {
                    let Ok(message) = received else { continue };
                    // Keep the ids current first.
                    while let Ok(Some(t)) = objects.try_recv() {
                        tracked = Some(t.body);
                    }
                    let d = message.body;
                    if d.source != BUILTIN_SOURCE || d.workspace_id.is_empty() {
                        continue;
                    }
                    let Some(every) = objects_every else { continue };
                    if last_objects.is_some_and(|t| t.elapsed() < every) {
                        continue;
                    }
                    last_objects = Some(tokio::time::Instant::now());
                    let ids = tracked_ids(&d, tracked.as_ref());
                    sender.offer(detections_entry(&instance, &d, &ids));
                }
                received = objects.recv() => {
                    if let Ok(t) = received {
                        tracked = Some(t.body);
                    }
                }
                received = labels.recv() => {
                    let Ok(message) = received else { continue };
                    let l = message.body;
                    sender.offer(labels_entry(&instance, now_s(), &l.labels, l.added.as_deref()));
                    last_labels = Some(l);
                }
                _ = republish.tick() => {
                    if let Some(l) = &last_labels {
                        sender.offer(labels_entry(&instance, now_s(), &l.labels, None));
                    }
                }
                received = overlays.recv() => {
                    let Ok(message) = received else { continue };
                    let o = message.body;
                    sender.offer(overlay_entry(
                        &instance,
                        now_s(),
                        &o.text,
                        o.kind.as_str(),
                        o.duration_s,
                        o.tool_name.as_deref(),
                    ));
                }
            }
        }
    }))
}
