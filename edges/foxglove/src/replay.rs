//! `robotd replay`: a recording published back on the bus, so perception, the workspace model,
//! the dashboard and the tools run on recorded data (a lab's session debugged without the
//! robot).
//!
//! The file is read a message at a time ([`robotd_recording::reader`]), never whole into
//! memory. Messages go out in the file's order, at the recorded pace times `speed` (`0` = as
//! fast as possible). Camera frames are rebuilt from `/camera` (JPEG) and `/camera/meta` (the
//! header: frame id, size, camera pose) by [`robotd_recording::camera`] and published on
//! `camera/frames` stamped with the replay's clock, so readers that want fresh frames take
//! them. Bus topics come from `/bus/<topic>`; each message is decoded as its type before it is
//! sent, and one that does not decode is skipped and counted, never sent half-read.
//!
//! A bus where a robotd runs already has a robot publishing `camera/frames` and `arm/state`:
//! replayed and live data would mix there. `robotd replay` refuses that case; playing a
//! recording as a running robotd's robot is the replay driver's job (`robot.driver =
//! "replay"`).
//!
//! By default only what sensors produce is replayed — camera frames, `arm/state`,
//! `gripper/state` — and the running robotd computes the rest (detections, objects) again;
//! `--topics` chooses others. Replaying commands (`agent/request`, `speech/speak`) makes the
//! running robotd act on them: choose them on purpose.
//!
//! Safety topics (`safety/…`, such as `safety/estop`) are never replayed, even when asked for
//! ([`ReplayError::SafetyTopic`]): a recorded e-stop or release must not act on a live robot.
//! Engaging and releasing are done through robotd's own entry points (docs/safety.md).

use crate::topics::{self, JsonPublisher};
use robotd_recording::camera::{FramePairer, RecordedFrame};
use robotd_recording::reader::{Messages, ReadError};
use robotd_runtime::bus::{Bus, BusError, FRAME_CHANNELS, FRAME_HEIGHT, FRAME_WIDTH};
use robotd_topics::CAMERA_FRAMES;
use std::collections::BTreeMap;
use std::path::Path;
use std::time::{Duration, Instant};

/// The topics replayed when none are chosen.
pub const DEFAULT_TOPICS: &[&str] = &["camera/frames", "arm/state", "gripper/state"];

/// Why a replay failed.
#[derive(Debug, thiserror::Error)]
pub enum ReplayError {
    /// The file cannot be read or is not MCAP.
    #[error(transparent)]
    Read(#[from] ReadError),
    /// A topic asked for is not one of robotd's.
    #[error("unknown topic '{0}': choose from camera/frames and the bus topics ({1})")]
    UnknownTopic(String, String),
    /// A safety topic was asked for: never replayed.
    #[error(
        "'{0}' is never replayed: a recorded e-stop or release must not act on a live robot \
         (engage or release with robotd estop, POST /estop or the MCP tools); drop it from \
         --topics"
    )]
    SafetyTopic(String),
    /// The bus refused a port.
    #[error(transparent)]
    Bus(#[from] BusError),
}

/// Whether `topic` is a safety topic (`safety/…`), which a replay never publishes.
pub fn is_safety_topic(topic: &str) -> bool {
    topic.starts_with("safety/")
}

/// What a replay did.
#[derive(Debug, Clone, Default, serde::Serialize)]
pub struct ReplaySummary {
    /// Messages published per bus topic.
    pub published: BTreeMap<String, u64>,
    /// Messages skipped, by reason.
    pub skipped: BTreeMap<String, u64>,
    /// Wall time of the replay, seconds.
    pub seconds: f64,
    /// Recorded time span, seconds.
    pub recorded_seconds: f64,
}

/// How to replay.
#[derive(Debug, Clone)]
pub struct ReplayOptions {
    /// Pace relative to the recording (1 = as recorded, 0 = as fast as possible).
    pub speed: f64,
    /// Topics to publish (`camera/frames` and bus topics); `None` = [`DEFAULT_TOPICS`].
    pub topics: Option<Vec<String>>,
}

fn skip(summary: &mut ReplaySummary, reason: &str) {
    *summary.skipped.entry(reason.to_owned()).or_insert(0) += 1;
}

/// Replays the file at `path` onto `bus`.
pub async fn replay(
    bus: &Bus,
    path: &Path,
    options: &ReplayOptions,
) -> Result<ReplaySummary, ReplayError> {
    let wanted: Vec<String> = match &options.topics {
        Some(list) => list.clone(),
        None => DEFAULT_TOPICS.iter().map(|t| (*t).to_owned()).collect(),
    };
    let known: Vec<String> = topics::all().iter().map(|t| t.name().to_owned()).collect();
    if let Some(topic) = wanted.iter().find(|t| is_safety_topic(t)) {
        return Err(ReplayError::SafetyTopic(topic.clone()));
    }
    let mut publishers: BTreeMap<String, Box<dyn JsonPublisher>> = BTreeMap::new();
    let mut camera = None;
    for topic in &wanted {
        if topic == "camera/frames" {
            camera = Some(bus.frame_publisher(&CAMERA_FRAMES)?);
            continue;
        }
        let Some(json_topic) = topics::find(topic) else {
            return Err(ReplayError::UnknownTopic(topic.clone(), known.join(", ")));
        };
        publishers.insert(topics::channel_name(topic), json_topic.publisher(bus)?);
    }
    let stream = Messages::open(path)?;
    let mut summary = ReplaySummary::default();
    let started = Instant::now();
    let mut first_log_time: Option<u64> = None;
    let mut last_log_time = 0;
    let mut frames = FramePairer::default();
    for message in stream {
        let message = message?;
        let topic = &*message.topic;
        let is_camera = topic == robotd_recording::CAMERA || topic == robotd_recording::CAMERA_META;
        if !(publishers.contains_key(topic) || (is_camera && camera.is_some())) {
            continue;
        }
        let first = *first_log_time.get_or_insert(message.log_time);
        last_log_time = message.log_time;
        if options.speed > 0.0 {
            let due =
                Duration::from_nanos(message.log_time.saturating_sub(first)).div_f64(options.speed);
            if let Some(wait) = due.checked_sub(started.elapsed()) {
                tokio::time::sleep(wait).await;
            }
        }
        match topic {
            robotd_recording::CAMERA | robotd_recording::CAMERA_META => {
                let frame = match frames.take(&message) {
                    Ok(Some(frame)) => frame,
                    Ok(None) => continue,
                    Err(reason) => {
                        skip(&mut summary, &reason);
                        continue;
                    }
                };
                let Some(publisher) = camera.as_ref() else {
                    continue;
                };
                match publish_frame(publisher, &frame) {
                    Ok(()) => *summary.published.entry("camera/frames".into()).or_insert(0) += 1,
                    Err(reason) => skip(&mut summary, &reason),
                }
            }
            _ => {
                let Some(publisher) = publishers.get(topic) else {
                    continue;
                };
                match publisher.publish_json(&message.data) {
                    Ok(()) => {
                        let name = topic.trim_start_matches("/bus/").to_owned();
                        *summary.published.entry(name).or_insert(0) += 1;
                    }
                    Err(reason) => {
                        tracing::warn!(topic, %reason, "replay: message skipped");
                        skip(&mut summary, &format!("{topic}: undecodable"));
                    }
                }
            }
        }
    }
    summary.seconds = started.elapsed().as_secs_f64();
    summary.recorded_seconds =
        last_log_time.saturating_sub(first_log_time.unwrap_or(last_log_time)) as f64 / 1e9;
    Ok(summary)
}

fn publish_frame(
    publisher: &robotd_runtime::bus::FramePublisher,
    frame: &RecordedFrame,
) -> Result<(), String> {
    let meta = &frame.meta;
    if meta.width as usize > FRAME_WIDTH || meta.height as usize > FRAME_HEIGHT {
        return Err(format!(
            "camera: {}x{} is larger than a bus frame ({FRAME_WIDTH}x{FRAME_HEIGHT})",
            meta.width, meta.height
        ));
    }
    let rgb = frame.decode()?;
    let mut loan = publisher.loan().map_err(|e| e.to_string())?;
    let header = loan.header_mut();
    header.frame_id = meta.frame_id;
    header.width = meta.width;
    header.height = meta.height;
    header.channels = FRAME_CHANNELS as u32;
    header.encoding = 0;
    header.camera_pose = meta.camera_pose;
    // Stamped now: the replayed frame is what the camera "sees" at this moment.
    header.timestamp_unix_ns = 0;
    loan.pixels_mut()[..rgb.len()].copy_from_slice(&rgb);
    loan.send().map(drop).map_err(|e| e.to_string())
}
