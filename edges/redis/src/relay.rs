//! Bus messages out to Redis: robotd's own detections, the label list, the overlay texts.
//!
//! - `perception/detections` from the built-in detector → `detected_objects` (at most
//!   `objects_fps` entries a second), each object with
//!   the id the workspace model tracks it under (taken from the newest `workspace/objects`:
//!   same label, within the tracker's 3 cm gate; a frame-local id `f<frame>-<n>` until the model
//!   has it), under the name `label_object` gave it if it has one. Detections that came in from
//!   Redis are not sent back out.
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

/// The tracked id of each of `detections`' objects, from `tracked` (same workspace and label,
/// nearest within 3 cm), else `f<frame>-<n>`; and the name `label_object` gave it, if any (a
/// named object is matched by what the detector calls it, `renamed`).
pub fn tracked_ids(
    detections: &Detections,
    tracked: Option<&TrackedObjects>,
) -> Vec<(String, Option<String>)> {
    let mut taken: Vec<&str> = Vec::new();
    detections
        .objects
        .iter()
        .enumerate()
        .map(|(n, object)| {
            let candidate = tracked
                .filter(|t| t.workspace_id == detections.workspace_id)
                .and_then(|t| {
                    let detected_as = |o: &robotd_protocol::objects::DetectedObject| {
                        t.renamed
                            .iter()
                            .find(|r| r.id == o.id)
                            .map(|r| r.detected_as.clone())
                    };
                    t.objects
                        .iter()
                        .filter(|o| !taken.contains(&o.id.as_str()))
                        .filter_map(|o| match detected_as(o) {
                            Some(label) => object.label_is(&label).then_some((o, true)),
                            None => o.label_is(&object.label).then_some((o, false)),
                        })
                        .map(|(o, named)| (o.xy().distance_to(&object.xy()), o, named))
                        .filter(|(d, _, _)| *d <= 0.03)
                        .min_by(|a, b| a.0.total_cmp(&b.0))
                        .map(|(_, o, named)| (o, named))
                });
            match candidate {
                Some((o, named)) => {
                    taken.push(&o.id);
                    (o.id.clone(), named.then(|| o.label.clone()))
                }
                None => (format!("f{}-{n}", detections.frame_id), None),
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
                    let matched = tracked_ids(&d, tracked.as_ref());
                    // A named object goes out under its name, as the tools list it.
                    let mut d = d;
                    for (object, (_, name)) in d.objects.iter_mut().zip(&matched) {
                        if let Some(name) = name {
                            object.label.clone_from(name);
                        }
                    }
                    let ids: Vec<String> = matched.into_iter().map(|(id, _)| id).collect();
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

#[cfg(test)]
mod tests {
    use super::*;
    use robotd_protocol::objects::DetectedObject;
    use robotd_protocol::workspace::RenamedObject;
    use robotd_protocol::Point3;

    fn object(id: &str, label: &str, x: f64, y: f64) -> DetectedObject {
        let mut o = DetectedObject {
            id: id.into(),
            label: label.into(),
            workspace_id: "niryo_ws".into(),
            ..Default::default()
        };
        o.position.center_of_mass = Point3::new(x, y, 0.01);
        o.position.center = o.position.center_of_mass;
        o
    }

    #[test]
    fn named_objects_keep_their_id_and_go_out_under_their_name() {
        let detections = Detections {
            frame_id: 7,
            workspace_id: "niryo_ws".into(),
            source: BUILTIN_SOURCE.into(),
            objects: vec![
                object("", "unknown object", 0.25, 0.0),
                object("", "red cube", 0.28, 0.04),
                object("", "red cube", 0.20, -0.06),
            ],
            ..Default::default()
        };
        let tracked = TrackedObjects {
            workspace_id: "niryo_ws".into(),
            objects: vec![
                object("obj-3", "screwdriver", 0.251, 0.001),
                object("obj-1", "red cube", 0.281, 0.04),
            ],
            renamed: vec![RenamedObject {
                id: "obj-3".into(),
                detected_as: "unknown object".into(),
            }],
            ..Default::default()
        };
        let matched = tracked_ids(&detections, Some(&tracked));
        assert_eq!(
            matched,
            vec![
                ("obj-3".to_owned(), Some("screwdriver".to_owned())),
                ("obj-1".to_owned(), None),
                ("f7-2".to_owned(), None),
            ]
        );
        // Without the model's list: frame-local ids, no names.
        assert_eq!(tracked_ids(&detections, None)[0], ("f7-0".to_owned(), None));
    }
}
