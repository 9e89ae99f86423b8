//! What the page shows, kept up to date from the bus by one thread.
//!
//! The thread reads the bus the way every edge does (its ports live on the thread that opened
//! them) and keeps:
//!
//! - the **camera**: at most `camera_fps` times a second the newest frame, with the newest
//!   steady view's boxes drawn on it as the workspace model named them (its ids and names,
//!   [`named_view`](robotd_protocol::workspace::TrackedObjects::named_view); while the arm moves, the detector's boxes without ids),
//!   encoded as JPEG into a
//!   `watch` cell — each viewer takes the newest frame when it is ready for one, so a slow
//!   browser skips frames and the camera never waits (drop, don't queue). Frames are encoded
//!   only while someone watches: an open `/api/camera.mjpg` stream, or a `/api/camera.jpg`
//!   asked for in the last [`KEEP_ENCODING_AFTER_ASK`]. With no viewer the cell is emptied, so
//!   no stale frame is ever served, and a service nobody looks at spends no CPU on JPEGs;
//! - a **snapshot** (arm, objects, recent overlays and restarts, camera and detection rates),
//! - the **rates of the last five minutes**, one sample a second, so a page that opens or
//!   reloads plots the recent past at once,
//!   served as JSON by `/api/status` and `/api/objects`;
//! - a **broadcast** of events (agent events as they happen, overlays, restarts) for
//!   `/api/events` and `/api/chat`. A viewer that falls behind loses events, never blocks.
//!   The pictures the agent looked at are kept apart ([`crate::pictures`]): the events carry
//!   their URL, not their bytes.

use crate::pictures::{PictureEvent, Pictures};
use bytes::Bytes;
use robotd_protocol::agent::AgentEvent;
use robotd_protocol::objects::{DetectedObject, Detections};
use robotd_protocol::workspace::{WorkspaceQuery, WorkspaceReply, WorkspaceRequest};
use robotd_runtime::bus::{Bus, BusError};
use robotd_topics::{
    AGENT_EVENTS, ARM_STATE, CAMERA_FRAMES, HEALTH_RESTARTS, OVERLAY_TEXT, PERCEPTION_DETECTIONS,
    WORKSPACE_OBJECTS, WORKSPACE_QUERY,
};
use serde::Serialize;
use serde_json::{json, Value};
use std::collections::VecDeque;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};
use tokio::sync::{broadcast, watch};

/// Recent overlays and restarts kept for the page.
const RECENT: usize = 20;
/// Encode times kept for the median.
const ENCODE_SAMPLES: usize = 64;
/// How long frames keep being encoded after a `/api/camera.jpg` request, so a script polling
/// snapshots gets each one at once.
pub const KEEP_ENCODING_AFTER_ASK: Duration = Duration::from_secs(5);

/// One encoded camera frame.
#[derive(Debug, Clone)]
pub struct CameraJpeg {
    /// The JPEG file.
    pub jpeg: Bytes,
    /// The camera's frame id.
    pub frame_id: u64,
    /// Capture time, ns since the Unix epoch.
    pub timestamp_unix_ns: u64,
}

/// An event pushed to the page.
#[derive(Debug, Clone, Serialize)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum LiveEvent {
    /// An event of an agent request (plan, tool call, tool result, answer, error, cancelled).
    Agent(AgentEvent),
    /// A picture a tool returned to the agent, as a URL of [`crate::pictures`] (an `agent`
    /// event of kind `picture`).
    #[serde(rename = "agent")]
    Picture(PictureEvent),
    /// A text shown over the video (`speak`, `set_user_task`, system messages).
    Overlay(Value),
    /// An actor restarted.
    Restart(Value),
}

impl LiveEvent {
    /// The agent request this event is about, if it is an agent event.
    pub fn request_id(&self) -> Option<&str> {
        match self {
            LiveEvent::Agent(e) => Some(&e.request_id),
            LiveEvent::Picture(p) => Some(&p.request_id),
            LiveEvent::Overlay(_) | LiveEvent::Restart(_) => None,
        }
    }

    /// Whether it ends its agent request (answer, error, cancelled).
    pub fn is_terminal(&self) -> bool {
        matches!(self, LiveEvent::Agent(e) if e.event.is_terminal())
    }
}

/// The snapshot the page polls.
#[derive(Debug, Clone, Default, Serialize)]
pub struct Snapshot {
    /// The arm's last state (`tool_pose`, `moving`, `collision_detected`, …), if heard.
    pub arm: Option<Value>,
    /// The tracked objects of the workspace model.
    pub objects: Vec<DetectedObject>,
    /// Recent overlays, newest last.
    pub overlays: VecDeque<Value>,
    /// Recent restarts, newest last.
    pub restarts: VecDeque<Value>,
    /// The camera view's figures.
    pub camera: CameraFigures,
    /// The workspace model's largest free space (`area_m2`, `center`), asked every 2 s.
    pub free_space: Option<Value>,
}

/// Camera figures over the last second or so.
#[derive(Debug, Clone, Default, Serialize)]
pub struct CameraFigures {
    /// Frames per second arriving on the bus.
    pub bus_fps: f64,
    /// Frames per second encoded for the page.
    pub page_fps: f64,
    /// Detections per second from perception.
    pub detections_per_s: f64,
    /// Median JPEG encode time of the last frames, ms.
    pub encode_ms_p50: f64,
    /// The last encoded frame's id.
    pub frame_id: u64,
    /// Its capture time, ns since the Unix epoch.
    pub timestamp_unix_ns: u64,
}

/// One second of the rates the page plots.
#[derive(Debug, Clone, Copy, Default, Serialize)]
pub struct RateSample {
    /// End of the second, seconds since the Unix epoch.
    pub at_unix_s: f64,
    /// Frames per second encoded for the page.
    pub page_fps: f64,
    /// Detections per second from perception.
    pub detections_per_s: f64,
    /// Actor restarts heard in that second.
    pub restarts: u32,
}

/// Seconds of rate history kept for a page that opens (or reloads).
pub const RATE_HISTORY_S: usize = 300;

/// The live state shared by the thread and the HTTP handlers.
#[derive(Debug)]
pub struct Live {
    snapshot: Mutex<Snapshot>,
    rates: Mutex<VecDeque<RateSample>>,
    events: broadcast::Sender<LiveEvent>,
    pictures: Pictures,
    camera: watch::Sender<Option<CameraJpeg>>,
    /// When a single frame was last asked for (`/api/camera.jpg`).
    frame_asked_at: Mutex<Option<Instant>>,
    stop: AtomicBool,
}

impl Live {
    /// The current snapshot.
    pub fn snapshot(&self) -> Snapshot {
        self.snapshot
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .clone()
    }

    /// The rates of the last [`RATE_HISTORY_S`] seconds, one sample a second, oldest first.
    pub fn rates(&self) -> Vec<RateSample> {
        let rates = self.rates.lock().unwrap_or_else(|e| e.into_inner());
        rates.iter().copied().collect()
    }

    fn push_rate(&self, sample: RateSample) {
        let mut rates = self.rates.lock().unwrap_or_else(|e| e.into_inner());
        if rates.len() == RATE_HISTORY_S {
            rates.pop_front();
        }
        rates.push_back(sample);
    }

    /// Events from now on.
    pub fn events(&self) -> broadcast::Receiver<LiveEvent> {
        self.events.subscribe()
    }

    /// The pictures the agent looked at (the newest [`crate::pictures::KEPT`]).
    pub fn pictures(&self) -> &Pictures {
        &self.pictures
    }

    /// The newest camera frame, and changes from now on. Frames are encoded while a receiver
    /// is held.
    pub fn camera(&self) -> watch::Receiver<Option<CameraJpeg>> {
        self.camera.subscribe()
    }

    /// Someone wants single frames: keep encoding for [`KEEP_ENCODING_AFTER_ASK`].
    pub fn ask_for_frames(&self) {
        *self
            .frame_asked_at
            .lock()
            .unwrap_or_else(|e| e.into_inner()) = Some(Instant::now());
    }

    /// Whether anyone watches the camera: a receiver is held (an MJPEG stream, a request
    /// waiting for its frame), or a frame was asked for lately.
    fn camera_watched(&self) -> bool {
        self.camera.receiver_count() > 0
            || self
                .frame_asked_at
                .lock()
                .unwrap_or_else(|e| e.into_inner())
                .is_some_and(|at| at.elapsed() < KEEP_ENCODING_AFTER_ASK)
    }

    fn update(&self, change: impl FnOnce(&mut Snapshot)) {
        change(&mut self.snapshot.lock().unwrap_or_else(|e| e.into_inner()));
    }

    /// Stops the thread (at its next poll).
    pub fn stop(&self) {
        self.stop.store(true, Ordering::SeqCst);
    }
}

/// Starts the thread reading `bus`; it encodes at most `camera_fps` frames a second at
/// `jpeg_quality`.
pub fn start(bus: Bus, camera_fps: f64, jpeg_quality: u8) -> std::io::Result<Arc<Live>> {
    let (events, _) = broadcast::channel(256);
    let (camera, _) = watch::channel(None);
    let live = Arc::new(Live {
        snapshot: Mutex::default(),
        rates: Mutex::default(),
        events,
        pictures: Pictures::default(),
        camera,
        frame_asked_at: Mutex::new(None),
        stop: AtomicBool::new(false),
    });
    let shared = live.clone();
    robotd_runtime::bus::spawn_reader_thread("dashboard-live", move || async move {
        if let Err(error) = follow(&bus, &shared, camera_fps, jpeg_quality).await {
            tracing::error!(%error, "dashboard: the live view stopped: its bus ports failed");
        }
    })?;
    Ok(live)
}

/// Counts over a one-second window, as a rate.
#[derive(Debug)]
struct Rate {
    since: Instant,
    count: u32,
    value: f64,
}

impl Rate {
    fn new() -> Self {
        Self {
            since: Instant::now(),
            count: 0,
            value: 0.0,
        }
    }

    fn tick(&mut self) {
        self.count += 1;
    }

    /// The rate, refreshed once a second.
    fn value(&mut self) -> f64 {
        let elapsed = self.since.elapsed();
        if elapsed >= Duration::from_secs(1) {
            self.value = f64::from(self.count) / elapsed.as_secs_f64();
            (self.since, self.count) = (Instant::now(), 0);
        }
        self.value
    }
}

fn to_json(value: impl Serialize) -> Value {
    serde_json::to_value(value).unwrap_or(Value::Null)
}

fn push_recent(list: &mut VecDeque<Value>, value: Value) {
    if list.len() == RECENT {
        list.pop_front();
    }
    list.push_back(value);
}

fn now_unix_s() -> f64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0.0, |d| d.as_secs_f64())
}

async fn follow(bus: &Bus, live: &Live, camera_fps: f64, quality: u8) -> Result<(), BusError> {
    let mut frames = bus.frame_subscriber(&CAMERA_FRAMES)?;
    let mut arm = bus.subscriber(&ARM_STATE)?;
    let mut detections = bus.subscriber(&PERCEPTION_DETECTIONS)?;
    let mut objects = bus.subscriber(&WORKSPACE_OBJECTS)?;
    let mut overlays = bus.subscriber(&OVERLAY_TEXT)?;
    let mut restarts = bus.subscriber(&HEALTH_RESTARTS)?;
    let mut agent = bus.subscriber(&AGENT_EVENTS)?;
    let workspace = bus.client(&WORKSPACE_QUERY)?;
    let mut last_free_space: Option<Instant> = None;
    let every = Duration::from_secs_f64(1.0 / camera_fps);
    let mut last_encoded: Option<Instant> = None;
    // The boxes on the picture, and the newest steady view until the model has named it.
    let mut drawn: Vec<DetectedObject> = Vec::new();
    let mut pending: Option<Detections> = None;
    let (mut bus_rate, mut page_rate, mut detection_rate) = (Rate::new(), Rate::new(), Rate::new());
    let mut encode_ms: VecDeque<f64> = VecDeque::new();
    let mut last_rate_sample = Instant::now();
    let mut restarts_this_second = 0u32;
    while !live.stop.load(Ordering::SeqCst) {
        if let Some(state) = arm.try_recv()?.map(|m| m.body) {
            let mut latest = state;
            while let Some(newer) = arm.try_recv()? {
                latest = newer.body;
            }
            live.update(|s| s.arm = Some(to_json(&latest)));
        }
        while let Some(message) = detections.try_recv()? {
            detection_rate.tick();
            let view = message.body;
            if view.steady && !view.workspace_id.is_empty() {
                pending = Some(view);
            } else {
                // The arm moves: the model names no view, the boxes show what the detector
                // sees, without ids.
                pending = None;
                drawn = view.objects;
            }
        }
        while let Some(message) = objects.try_recv()? {
            let tracked = message.body;
            if let Some(named) = pending.as_ref().and_then(|v| tracked.named_view(v)) {
                pending = None;
                drawn = named;
            }
            live.update(|s| s.objects = tracked.objects);
        }
        while let Some(message) = overlays.try_recv()? {
            let mut value = to_json(&message.body);
            value["time_unix_s"] = json!(now_unix_s());
            live.update(|s| push_recent(&mut s.overlays, value.clone()));
            let _ = live.events.send(LiveEvent::Overlay(value));
        }
        while let Some(message) = restarts.try_recv()? {
            restarts_this_second += 1;
            let mut value = to_json(&message.body);
            value["time_unix_s"] = json!(now_unix_s());
            live.update(|s| push_recent(&mut s.restarts, value.clone()));
            let _ = live.events.send(LiveEvent::Restart(value));
        }
        while let Some(message) = agent.try_recv()? {
            // A picture is kept here and goes to the page as a URL.
            if let Some(event) = live.pictures.to_live(message.body) {
                let _ = live.events.send(event);
            }
        }
        if last_free_space.is_none_or(|t| t.elapsed() >= Duration::from_secs(2)) {
            last_free_space = Some(Instant::now());
            // From the workspace model's memory (never moves the arm); a short deadline so a
            // busy model costs the camera at most a frame.
            let query = WorkspaceQuery::now(WorkspaceRequest::GetLargestFreeSpace);
            let free = match workspace.request(&query, Duration::from_millis(150)).await {
                Ok(WorkspaceReply::FreeSpace { area_m2, center }) => {
                    Some(json!({"area_m2": area_m2, "center": [center.x_m, center.y_m]}))
                }
                _ => None,
            };
            live.update(|s| s.free_space = free);
        }
        let sample = match tokio::time::timeout(Duration::from_millis(25), frames.recv()).await {
            Err(_) => None,
            Ok(Err(error)) => {
                tracing::debug!(%error, "dashboard: receiving a frame failed");
                tokio::time::sleep(Duration::from_millis(25)).await;
                None
            }
            Ok(Ok(sample)) => Some(sample),
        };
        if let Some(sample) = sample {
            bus_rate.tick();
            let header = *sample.header();
            let (w, h) = (header.width as usize, header.height as usize);
            let bytes = w * h * 3;
            let due = last_encoded.is_none_or(|t| t.elapsed() >= every);
            let rgb8 = header.channels == 3 && header.encoding == 0;
            let watched = live.camera_watched();
            if !watched && live.camera.borrow().is_some() {
                // Nobody watches: no frame is kept to go stale.
                live.camera.send_replace(None);
            }
            if watched && due && rgb8 && sample.pixels().len() >= bytes {
                last_encoded = Some(Instant::now());
                let mut rgb = sample.pixels()[..bytes].to_vec();
                drop(sample);
                robotd_render::annotate::draw_objects(&mut rgb, w, h, &drawn);
                let started = Instant::now();
                match robotd_render::encode_jpeg(&rgb, w as u32, h as u32, quality) {
                    Ok(jpeg) => {
                        if encode_ms.len() == ENCODE_SAMPLES {
                            encode_ms.pop_front();
                        }
                        encode_ms.push_back(started.elapsed().as_secs_f64() * 1e3);
                        page_rate.tick();
                        live.camera.send_replace(Some(CameraJpeg {
                            jpeg: Bytes::from(jpeg),
                            frame_id: header.frame_id,
                            timestamp_unix_ns: header.timestamp_unix_ns,
                        }));
                        live.update(|s| {
                            s.camera.frame_id = header.frame_id;
                            s.camera.timestamp_unix_ns = header.timestamp_unix_ns;
                        });
                    }
                    Err(error) => tracing::warn!(%error, "dashboard: JPEG encoding failed"),
                }
            }
        }
        let median = median(&encode_ms);
        let (bus_fps, page_fps, per_s) =
            (bus_rate.value(), page_rate.value(), detection_rate.value());
        live.update(|s| {
            s.camera.bus_fps = bus_fps;
            s.camera.page_fps = page_fps;
            s.camera.detections_per_s = per_s;
            s.camera.encode_ms_p50 = median;
        });
        if last_rate_sample.elapsed() >= Duration::from_secs(1) {
            last_rate_sample = Instant::now();
            live.push_rate(RateSample {
                at_unix_s: now_unix_s(),
                page_fps,
                detections_per_s: per_s,
                restarts: std::mem::take(&mut restarts_this_second),
            });
        }
    }
    Ok(())
}

fn median(values: &VecDeque<f64>) -> f64 {
    let mut sorted: Vec<f64> = values.iter().copied().collect();
    sorted.sort_by(f64::total_cmp);
    sorted.get(sorted.len() / 2).copied().unwrap_or(0.0)
}
