//! # robotd-redis: the Redis edge
//!
//! Labs keep GPU detectors, viewers and recorders in Python, talking Redis Streams
//! (`docs/redis-streams.md`). This edge speaks their format exactly, so each of them plugs into
//! robotd unchanged — and two robotd hosts sharing one Redis see each other's detections.
//!
//! ```text
//!  camera/frames ──► camera thread ──JPEG──┐                       ┌─► robot_camera, annotated_camera
//!  perception/detections ─┬─► relay ───────┼─► queue ─► writer ────┼─► detected_objects
//!  workspace/labels, overlay/text ─┘       │  (drops when full)    └─► detectable_labels, video_text_overlays
//!                                          │
//!  perception/detections ◄── consumer ◄── XREAD detected_objects, detectable_labels (others' entries)
//!  workspace/query (AddLabel) ◄──┘
//! ```
//!
//! Nothing in the robot waits on Redis: producers hand entries to a bounded queue and go on;
//! when Redis is slow or away the entries are dropped and counted, the edge reports itself
//! down, and it reconnects with backoff (at most 1 s between attempts). Its state and counters
//! are in [`EdgeStatus`] (`get_system_status`, `/health`) and in `/metrics`.
//!
//! ## Modules
//!
//! - [`settings`]: where to connect (`--redis`, `[redis] url`, `REDIS_*`), which detector to trust.
//! - [`wire`]: the entries, field by field; the readers' checks.
//! - [`camera`]: frames to JPEG entries, the ring of published frames.
//! - [`annotate`](robotd_render::annotate): boxes and labels drawn on a frame.
//! - [`relay`]: detections, labels and overlays out.
//! - [`consume`]: external detections and labels in.
//! - [`writer`]: the queue and the task that appends to Redis.
//! - [`status`]: state and counters.

pub mod config;
pub use config::RedisConfig;

pub mod camera;
pub mod consume;
pub mod relay;
pub mod settings;
pub mod status;
pub mod wire;
pub mod writer;

pub use settings::{resolve_target, RedisTarget, Trust};
pub use status::{EdgeStatus, LinkState};

use robotd_protocol::camera::CameraIntrinsics;
use robotd_protocol::workspace::WorkspaceInfo;
use robotd_runtime::bus::Bus;
use robotd_vision::labels::LabelTable;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use tokio_util::sync::CancellationToken;

/// Everything the edge needs.
#[derive(Debug, Clone)]
pub struct RedisEdgeSettings {
    /// Where Redis is.
    pub target: RedisTarget,
    /// Names this robotd in the entries it writes (so it skips its own when reading).
    pub instance: String,
    /// Frames per second to `robot_camera` (0 = none).
    pub camera_fps: f64,
    /// Frames per second to `annotated_camera` (0 = none).
    pub annotated_fps: f64,
    /// Entries per second of robotd's own detections to `detected_objects` (0 = none).
    pub objects_fps: f64,
    /// Which detector the workspace model believes.
    pub trust: Trust,
    /// Largest entry the consumer accepts, bytes of field values.
    pub max_entry_bytes: usize,
    /// The camera (for mapping external detections).
    pub intrinsics: CameraIntrinsics,
    /// The configured workspaces.
    pub workspaces: Vec<WorkspaceInfo>,
    /// Heights of known labels (for mapping external detections).
    pub label_table: LabelTable,
}

/// Why the edge could not start (Redis being away is not one: the edge starts and retries).
#[derive(Debug, thiserror::Error)]
pub enum RedisStartError {
    /// The connection settings are unusable.
    #[error("redis edge: {0}")]
    Settings(String),
    /// A bus port could not be opened.
    #[error("redis edge: cannot open its bus ports: {0}")]
    Bus(String),
    /// The camera thread could not start.
    #[error("redis edge: cannot start its camera thread: {0}")]
    Thread(std::io::Error),
}

/// The running edge.
#[derive(Debug)]
pub struct RedisEdge {
    status: Arc<EdgeStatus>,
    stop: CancellationToken,
    camera_stop: Arc<AtomicBool>,
    camera: Option<std::thread::JoinHandle<()>>,
    tasks: Vec<tokio::task::JoinHandle<()>>,
}

impl RedisEdge {
    /// Starts the edge on `bus` (inside a tokio runtime). Returns at once, connected or not.
    pub fn start(bus: &Bus, settings: RedisEdgeSettings) -> Result<RedisEdge, RedisStartError> {
        robotd_runtime::telemetry::install_tls_provider();
        let client = redis::Client::open(settings.target.info.clone())
            .map_err(|e| RedisStartError::Settings(e.to_string()))?;
        let status = Arc::new(EdgeStatus::new(
            &settings.target.display,
            settings.trust.as_str(),
        ));
        let stop = CancellationToken::new();
        let (sender, writer_task) = writer::start(client.clone(), status.clone(), stop.clone());
        let ring = Arc::new(Mutex::new(camera::FrameRing::default()));
        let relay_task = relay::start(
            bus,
            settings.instance.clone(),
            settings.objects_fps,
            sender.clone(),
            stop.clone(),
        )
        .map_err(|e| RedisStartError::Bus(e.to_string()))?;
        let consumer_task = consume::start(
            bus,
            client,
            consume::ConsumerSettings {
                instance: settings.instance.clone(),
                consume_detections: settings.trust.consumes_external(),
                max_entry_bytes: settings.max_entry_bytes,
                intrinsics: settings.intrinsics.clone(),
                workspaces: settings.workspaces.clone(),
                label_table: settings.label_table.clone(),
            },
            ring.clone(),
            status.clone(),
            stop.clone(),
        )
        .map_err(RedisStartError::Bus)?;
        let camera_stop = Arc::new(AtomicBool::new(false));
        let camera = camera::start(
            bus.clone(),
            camera::CameraSettings {
                camera_fps: settings.camera_fps,
                annotated_fps: settings.annotated_fps,
                workspaces: settings.workspaces.clone(),
                instance: settings.instance.clone(),
            },
            ring,
            sender,
            status.clone(),
            camera_stop.clone(),
        )
        .map_err(RedisStartError::Thread)?;
        tracing::info!(
            target = %settings.target.display,
            from = settings.target.source,
            trust = settings.trust.as_str(),
            camera_fps = settings.camera_fps,
            "redis edge started"
        );
        Ok(RedisEdge {
            status,
            stop,
            camera_stop,
            camera: Some(camera),
            tasks: vec![writer_task, relay_task, consumer_task],
        })
    }

    /// State and counters.
    pub fn status(&self) -> Arc<EdgeStatus> {
        self.status.clone()
    }

    /// Stops every task and the camera thread.
    pub async fn shutdown(mut self) {
        self.stop_all();
        for task in self.tasks.drain(..) {
            let _ = task.await;
        }
    }

    fn stop_all(&mut self) {
        self.stop.cancel();
        self.camera_stop.store(true, Ordering::SeqCst);
        if let Some(camera) = self.camera.take() {
            let _ = camera.join();
        }
    }
}

impl Drop for RedisEdge {
    fn drop(&mut self) {
        self.stop_all();
    }
}
