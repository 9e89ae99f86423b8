//! The camera side of the edge: frames from the bus to `robot_camera` and `annotated_camera`.
//!
//! A thread of its own (JPEG encoding is CPU work) reads `camera/frames` in shared memory,
//! and at most `camera_fps` times a second copies the newest frame, encodes it as JPEG
//! quality 85 and queues it for the writer. The camera actor never waits for it: frames it
//! skips are simply overwritten on the bus (latest wins), and frames the writer cannot take
//! are dropped and counted.
//!
//! The frames it published are kept in a [`FrameRing`] — as the JPEG that went to Redis, the
//! very image an external detector saw, about 50 KB where the raw frame is 900 KB — with the
//! arm's pose and whether the arm stood still: an external detector's answer names one of
//! them, and the consumer decodes that frame and maps the answer's pixels through it. When detections of a kept frame arrive (the built-in
//! detector's, or an external one's through the consumer), the frame is drawn with boxes and
//! labels and sent to `annotated_camera`, at most `annotated_fps` times a second.

use crate::status::EdgeStatus;
use crate::wire::{camera_entry, FrameMeta};
use crate::writer::EntrySender;
use robotd_protocol::geometry::Pose;
use robotd_protocol::objects::Detections;
use robotd_protocol::workspace::WorkspaceInfo;
use robotd_render::annotate::draw_objects;
use robotd_runtime::bus::Bus;
use robotd_topics::{ARM_STATE, CAMERA_FRAMES, PERCEPTION_DETECTIONS};
use std::collections::VecDeque;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// JPEG quality of the camera streams (the Python tools' value).
pub const JPEG_QUALITY: u8 = 85;
/// Published frames kept for external detections and annotation: 3.2 s at the default
/// 10 fps, time for a detector a second behind (a GPU model under load) to answer.
pub const RING_FRAMES: usize = 32;

/// A frame the edge published.
#[derive(Debug, Clone)]
pub struct FrameRecord {
    /// The camera's frame id.
    pub frame_id: u64,
    /// Capture time, ns since the Unix epoch.
    pub timestamp_unix_ns: u64,
    /// Width, height.
    pub size: (usize, usize),
    /// The frame as published: JPEG at [`JPEG_QUALITY`].
    pub jpeg: Arc<Vec<u8>>,
    /// The arm's tool pose at capture, if known.
    pub tool_pose: Option<Pose>,
    /// Whether the arm stood still.
    pub steady: bool,
}

impl FrameRecord {
    /// The frame's RGB8 pixels, decoded from its JPEG.
    pub fn rgb(&self) -> Result<Vec<u8>, String> {
        let (rgb, w, h) = robotd_render::decode_jpeg(&self.jpeg).map_err(|e| e.to_string())?;
        if (w as usize, h as usize) != self.size {
            return Err(format!(
                "kept frame {} decodes to {w}×{h}, not its {}×{}",
                self.frame_id, self.size.0, self.size.1
            ));
        }
        Ok(rgb)
    }
}

/// The last [`RING_FRAMES`] frames published.
#[derive(Debug, Default)]
pub struct FrameRing {
    frames: VecDeque<FrameRecord>,
}

impl FrameRing {
    /// Keeps `frame`, forgetting the oldest beyond [`RING_FRAMES`].
    pub fn push(&mut self, frame: FrameRecord) {
        if self.frames.len() == RING_FRAMES {
            self.frames.pop_front();
        }
        self.frames.push_back(frame);
    }

    /// The frame with this id.
    pub fn by_id(&self, frame_id: u64) -> Option<&FrameRecord> {
        self.frames.iter().find(|f| f.frame_id == frame_id)
    }

    /// The newest frame taken at or before `unix_s` (+ 50 ms for clock rounding), or the
    /// oldest kept frame when all are newer.
    pub fn at_or_before(&self, unix_s: f64) -> Option<&FrameRecord> {
        let limit = ((unix_s + 0.05) * 1e9) as u64;
        self.frames
            .iter()
            .rev()
            .find(|f| f.timestamp_unix_ns <= limit)
            .or_else(|| self.frames.front())
    }
}

/// The shared ring.
pub type SharedRing = Arc<Mutex<FrameRing>>;

/// Camera settings of the edge.
#[derive(Debug, Clone)]
pub struct CameraSettings {
    /// Frames per second to `robot_camera` (0 = none).
    pub camera_fps: f64,
    /// Frames per second to `annotated_camera` (0 = none).
    pub annotated_fps: f64,
    /// The configured workspaces (the nearest observation pose names the frame's workspace).
    pub workspaces: Vec<WorkspaceInfo>,
    /// This robotd's instance id.
    pub instance: String,
}

/// Encodes a `width × height` RGB8 frame as JPEG at [`JPEG_QUALITY`] (robotd's one encoder,
/// [`robotd_render::encode_jpeg`], which checks the buffer's size).
pub fn encode_jpeg(rgb: &[u8], width: usize, height: usize) -> Result<Vec<u8>, String> {
    let side = |v: usize| u32::try_from(v).map_err(|_| format!("a frame side of {v} pixels"));
    robotd_render::encode_jpeg(rgb, side(width)?, side(height)?, JPEG_QUALITY)
        .map_err(|e| e.to_string())
}

/// The workspace whose observation pose is nearest `tool`.
pub fn workspace_near<'a>(workspaces: &'a [WorkspaceInfo], tool: Option<&Pose>) -> &'a str {
    let first = workspaces.first().map_or("", |w| w.id.as_str());
    let Some(tool) = tool else {
        return first;
    };
    workspaces
        .iter()
        .min_by(|a, b| {
            a.observation_pose
                .distance_to(tool)
                .total_cmp(&b.observation_pose.distance_to(tool))
        })
        .map_or(first, |w| w.id.as_str())
}

/// Starts the camera thread. It stops when `stop` is set.
pub fn start(
    bus: Bus,
    settings: CameraSettings,
    ring: SharedRing,
    sender: EntrySender,
    status: Arc<EdgeStatus>,
    stop: Arc<AtomicBool>,
) -> std::io::Result<std::thread::JoinHandle<()>> {
    robotd_runtime::bus::spawn_reader_thread("redis-camera", move || {
        run(bus, settings, ring, sender, status, stop)
    })
}

fn interval(fps: f64) -> Option<Duration> {
    (fps > 0.0 && fps.is_finite()).then(|| Duration::from_secs_f64(1.0 / fps))
}

async fn run(
    bus: Bus,
    settings: CameraSettings,
    ring: SharedRing,
    sender: EntrySender,
    status: Arc<EdgeStatus>,
    stop: Arc<AtomicBool>,
) {
    {
        let ports = (|| {
            Ok::<_, robotd_runtime::bus::BusError>((
                bus.frame_subscriber(&CAMERA_FRAMES)?,
                bus.subscriber(&ARM_STATE)?,
                bus.subscriber(&PERCEPTION_DETECTIONS)?,
            ))
        })();
        let (mut frames, mut arm_states, mut detections) = match ports {
            Ok(p) => p,
            Err(error) => {
                tracing::error!(%error, "redis edge: the camera thread cannot open its bus ports");
                return;
            }
        };
        let camera_every = interval(settings.camera_fps);
        let annotated_every = interval(settings.annotated_fps);
        let mut last_camera: Option<Instant> = None;
        let mut last_annotated: Option<Instant> = None;
        let mut arm = robotd_protocol::arm::ArmMotion::default();
        while !stop.load(Ordering::SeqCst) {
            take_arm_states(&mut arm, &mut arm_states);
            // Annotate kept frames whose detections came in.
            while let Ok(Some(message)) = detections.try_recv() {
                let Some(every) = annotated_every else {
                    continue;
                };
                if last_annotated.is_some_and(|t| t.elapsed() < every) {
                    continue;
                }
                let frame = ring
                    .lock()
                    .ok()
                    .and_then(|r| r.by_id(message.body.frame_id).cloned());
                if let Some(frame) = frame {
                    last_annotated = Some(Instant::now());
                    publish_annotated(&settings, &frame, &message.body, &sender, &status);
                }
            }
            let Some(every) = camera_every else {
                tokio::time::sleep(Duration::from_millis(50)).await;
                continue;
            };
            let sample = match tokio::time::timeout(Duration::from_millis(50), frames.recv()).await
            {
                Err(_) => continue,
                Ok(Err(error)) => {
                    tracing::debug!(%error, "redis edge: receiving a frame failed");
                    tokio::time::sleep(Duration::from_millis(50)).await;
                    continue;
                }
                Ok(Ok(sample)) => sample,
            };
            if last_camera.is_some_and(|t| t.elapsed() < every) {
                continue;
            }
            // States that came in while this frame was awaited: without them a frame taken just
            // after the arm stopped would count as moving here and as steady in perception.
            take_arm_states(&mut arm, &mut arm_states);
            let header = *sample.header();
            let (w, h) = (header.width as usize, header.height as usize);
            let bytes = w * h * 3;
            if header.channels != 3 || header.encoding != 0 || sample.pixels().len() < bytes {
                status.count(crate::wire::ROBOT_CAMERA, "skipped_not_rgb8");
                continue;
            }
            last_camera = Some(Instant::now());
            let jpeg = match encode_jpeg(&sample.pixels()[..bytes], w, h) {
                Ok(jpeg) => jpeg,
                Err(error) => {
                    tracing::warn!(%error, "redis edge: JPEG encoding failed");
                    status.count(crate::wire::ROBOT_CAMERA, "skipped_encoding_failed");
                    continue;
                }
            };
            drop(sample);
            let record = FrameRecord {
                frame_id: header.frame_id,
                timestamp_unix_ns: header.timestamp_unix_ns,
                size: (w, h),
                jpeg: Arc::new(jpeg),
                tool_pose: arm.tool_pose,
                steady: arm.steady_at(header.timestamp_unix_ns),
            };
            let meta = frame_meta(&settings, &record);
            sender.offer(camera_entry(&settings.instance, &meta, &record.jpeg, None));
            if let Ok(mut ring) = ring.lock() {
                ring.push(record);
            }
        }
    }
}

fn frame_meta<'a>(settings: &'a CameraSettings, record: &FrameRecord) -> FrameMeta<'a> {
    let camera_pose = Pose::new(0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
    FrameMeta {
        frame_id: record.frame_id,
        timestamp_unix_s: record.timestamp_unix_ns as f64 / 1e9,
        size: (record.size.0 as u32, record.size.1 as u32),
        workspace_id: workspace_near(&settings.workspaces, record.tool_pose.as_ref()),
        robot_pose: record.tool_pose.unwrap_or(camera_pose),
    }
}

fn publish_annotated(
    settings: &CameraSettings,
    frame: &FrameRecord,
    detections: &Detections,
    sender: &EntrySender,
    status: &EdgeStatus,
) {
    let (w, h) = frame.size;
    let mut rgb = match frame.rgb() {
        Ok(rgb) => rgb,
        Err(error) => {
            tracing::warn!(%error, "redis edge: a kept frame does not decode");
            status.count(crate::wire::ANNOTATED_CAMERA, "skipped_encoding_failed");
            return;
        }
    };
    draw_objects(&mut rgb, w, h, &detections.objects);
    match encode_jpeg(&rgb, w, h) {
        Ok(jpeg) => {
            let meta = frame_meta(settings, frame);
            let annotation = Some((detections.objects.len(), detections.source.as_str()));
            sender.offer(camera_entry(&settings.instance, &meta, &jpeg, annotation));
        }
        Err(error) => {
            tracing::warn!(%error, "redis edge: JPEG encoding of an annotated frame failed");
            status.count(crate::wire::ANNOTATED_CAMERA, "skipped_encoding_failed");
        }
    }
}

/// Takes in every arm state waiting on `states`.
fn take_arm_states(
    motion: &mut robotd_protocol::arm::ArmMotion,
    states: &mut robotd_runtime::bus::Subscriber<robotd_protocol::arm::ArmState>,
) {
    while let Ok(Some(message)) = states.try_recv() {
        motion.update(&message.body, message.sent_at_unix_ns);
    }
}
