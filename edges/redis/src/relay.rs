//! Bus messages out to Redis: robotd's own detections, the label list, the overlay texts.
//!
//! - `perception/detections` from the built-in detector → `detected_objects` (at most
//!   `objects_fps` entries a second), once the workspace model's answer to that view is in
//!   (`workspace/objects` of the same frame): each box the model took for an object goes out
//!   as the model reports that object — its tracked id, its one name (the one the tools use,
//!   `label_object`'s included), a stacked object at its true height. Boxes the model does not
//!   report (a candidate seen once, a piece of a stack) stay out, and so do views the model
//!   does not apply (taken while the arm moved). Detections that came in from Redis are not
//!   sent back out.
//! - `workspace/labels` → `detectable_labels`, at start, on every change, and every 30 s
//!   (the Python side takes a list older than 60 s for stale).
//! - `overlay/text` → `video_text_overlays`.

use crate::wire::{detections_entry, labels_entry, overlay_entry, Entry};
use crate::writer::EntrySender;
use robotd_protocol::objects::Detections;
use robotd_protocol::workspace::{
    DetectableLabels, TrackedObjects, WorkspaceQuery, WorkspaceReply, WorkspaceRequest,
};
use robotd_runtime::bus::{Bus, BusError};
use robotd_topics::{
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

/// The entry of `view` once `tracked` (the workspace model's answer to it) is in: the boxes the
/// model took for an object, under its id and name ([`TrackedObjects::named_view`]). `None`
/// when `tracked` is not the answer to `view`, or the view came in from Redis.
pub fn named_entry(instance: &str, view: &Detections, tracked: &TrackedObjects) -> Option<Entry> {
    if view.source != BUILTIN_SOURCE {
        return None;
    }
    let objects = tracked.named_view(view)?;
    let ids: Vec<String> = objects.iter().map(|o| o.id.clone()).collect();
    let named = Detections {
        objects,
        ..view.clone()
    };
    Some(detections_entry(instance, &named, &ids))
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
        // The newest view of the built-in detector, until the model's answer to it is in.
        let mut pending: Option<Detections> = None;
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
                    let view = message.body;
                    // The model names only the views it applies: steady ones of a workspace.
                    if view.source == BUILTIN_SOURCE && view.steady && !view.workspace_id.is_empty() {
                        pending = Some(view);
                    }
                }
                received = objects.recv() => {
                    let Ok(message) = received else { continue };
                    let tracked = message.body;
                    let Some(view) = pending.take_if(|v| tracked.answers(v)) else { continue };
                    let Some(every) = objects_every else { continue };
                    if last_objects.is_some_and(|t| t.elapsed() < every) {
                        continue;
                    }
                    if let Some(entry) = named_entry(&instance, &view, &tracked) {
                        last_objects = Some(tokio::time::Instant::now());
                        sender.offer(entry);
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

#[cfg(test)]
mod tests {
    use super::*;
    use robotd_protocol::objects::DetectedObject;
    use serde_json::Value;

    fn object(id: &str, label: &str) -> DetectedObject {
        DetectedObject {
            id: id.into(),
            label: label.into(),
            workspace_id: "niryo_ws".into(),
            ..Default::default()
        }
    }

    fn view(source: &str) -> Detections {
        Detections {
            frame_id: 7,
            workspace_id: "niryo_ws".into(),
            source: source.into(),
            steady: true,
            objects: vec![object("", "unknown object"), object("", "red cube")],
            ..Default::default()
        }
    }

    fn answer() -> TrackedObjects {
        TrackedObjects {
            workspace_id: "niryo_ws".into(),
            frame_id: 7,
            source: BUILTIN_SOURCE.into(),
            objects: vec![object("obj-3", "screwdriver"), object("obj-1", "red cube")],
            detection_ids: vec!["obj-3".into(), "".into()],
            ..Default::default()
        }
    }

    #[test]
    fn a_view_goes_out_as_the_model_names_it() {
        let entry = named_entry("me", &view(BUILTIN_SOURCE), &answer()).expect("an entry");
        let objects = &entry
            .fields
            .iter()
            .find(|(k, _)| *k == "objects")
            .unwrap()
            .1;
        let objects: Value = serde_json::from_str(objects).unwrap();
        let named: Vec<(&str, &str, &str)> = objects
            .as_array()
            .unwrap()
            .iter()
            .map(|o| {
                (
                    o["id"].as_str().unwrap(),
                    o["label"].as_str().unwrap(),
                    o["class_name"].as_str().unwrap(),
                )
            })
            .collect();
        // The named object under its name; the box the model has not confirmed is left out.
        assert_eq!(named, [("obj-3", "screwdriver", "screwdriver")]);
    }

    #[test]
    fn views_from_redis_or_of_another_frame_do_not_go_out() {
        assert!(named_entry("me", &view("external"), &answer()).is_none());
        let mut later = answer();
        later.frame_id = 8;
        assert!(named_entry("me", &view(BUILTIN_SOURCE), &later).is_none());
    }
}
