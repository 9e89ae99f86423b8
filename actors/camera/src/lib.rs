//! The camera actor: takes a frame at the configured rate and publishes it zero-copy.
//!
//! Each frame is loaned from the bus's shared memory, the driver writes (the simulator:
//! renders) the image straight into it, the header gets the frame id, the capture time and the
//! camera's pose, and the frame is sent: no byte of the image is copied. The topic is
//! latest-wins, so a slow consumer gets the newest frame and never slows the camera down.
//!
//! [`run_camera`] ticks at the frame rate and asks the supervised actor for each frame; a
//! driver that fails (or panics) costs that frame, the actor is restarted, and the frame ids
//! go on from where they were. It also publishes the camera's intrinsics on
//! `camera/intrinsics`, at once when the driver's change (a Ned2 sends its own when it
//! connects) and about once a second, so a consumer that joined late has them soon.

use kameo::prelude::*;
use robotd_driver::CameraDriver;
use robotd_kinematics::isometry_to_pose;
use robotd_protocol::camera::CameraIntrinsics;
use robotd_runtime::bus::{FramePublisher, Publisher, FRAME_BYTES, FRAME_CHANNELS};
use robotd_runtime::supervision::Supervised;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// Take one frame and publish it; replies with the frame id.
#[derive(Debug, Clone, Copy)]
pub struct CaptureFrame;

/// The supervised camera actor.
#[derive(Actor)]
pub struct CameraActor {
    driver: Arc<dyn CameraDriver>,
    publisher: Arc<FramePublisher>,
    next_frame_id: Arc<AtomicU64>,
}

impl CameraActor {
    /// An actor capturing with `driver` into frames of `publisher`; frame ids come from
    /// `next_frame_id`, shared across restarts.
    pub fn new(
        driver: Arc<dyn CameraDriver>,
        publisher: Arc<FramePublisher>,
        next_frame_id: Arc<AtomicU64>,
    ) -> Self {
        Self {
            driver,
            publisher,
            next_frame_id,
        }
    }

    fn capture(&mut self) -> Result<u64, String> {
        let (width, height) = self.driver.size();
        let bytes = width as usize * height as usize * FRAME_CHANNELS;
        if bytes > FRAME_BYTES {
            return Err(format!(
                "camera frames of {width}x{height} do not fit the bus frame of {FRAME_BYTES} bytes"
            ));
        }
        let mut frame = self.publisher.loan().map_err(|e| e.to_string())?;
        let info = self
            .driver
            .capture_into(&mut frame.pixels_mut()[..bytes])
            .map_err(|e| e.to_string())?;
        let frame_id = self.next_frame_id.fetch_add(1, Ordering::SeqCst);
        let pose = isometry_to_pose(&info.camera_pose);
        let header = frame.header_mut();
        header.frame_id = frame_id;
        header.timestamp_unix_ns = info.timestamp_unix_ns;
        header.width = width;
        header.height = height;
        header.channels = FRAME_CHANNELS as u32;
        header.encoding = 0;
        header.camera_pose = pose.to_array();
        frame.send().map_err(|e| e.to_string())?;
        Ok(frame_id)
    }
}

impl Message<CaptureFrame> for CameraActor {
    type Reply = Result<u64, String>;

    async fn handle(&mut self, _: CaptureFrame, _: &mut Context<Self, Self::Reply>) -> Self::Reply {
        self.capture()
    }
}

/// How often the intrinsics are published when they do not change.
const INTRINSICS_EVERY: Duration = Duration::from_secs(1);

/// Asks `camera` for a frame `fps` times a second (or as soon after as `driver` has one),
/// forever, and publishes the driver's intrinsics on `intrinsics` when they change and every
/// [`INTRINSICS_EVERY`]. Failures are logged and cost one frame; supervision restarts a
/// crashed camera actor meanwhile.
pub async fn run_camera(
    camera: Supervised<CameraActor>,
    driver: Arc<dyn CameraDriver>,
    fps: f64,
    intrinsics: Publisher<CameraIntrinsics>,
) {
    let period = Duration::from_secs_f64(1.0 / fps.clamp(0.1, 1000.0));
    let mut ticker = tokio::time::interval(period);
    ticker.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Skip);
    let mut failures: u64 = 0;
    let mut published: Option<(CameraIntrinsics, Instant)> = None;
    loop {
        let now = driver.intrinsics();
        let due = published
            .as_ref()
            .is_none_or(|(last, at)| *last != now || at.elapsed() >= INTRINSICS_EVERY);
        if due {
            match intrinsics.publish(&now) {
                Ok(_) => published = Some((now, Instant::now())),
                Err(error) => tracing::warn!(%error, "publishing the camera's intrinsics failed"),
            }
        }
        ticker.tick().await;
        let asked = match driver.frame_ready().await {
            Ok(()) => camera.ask(CaptureFrame).await.map_err(|e| e.to_string()),
            Err(error) => Err(error.to_string()),
        };
        match asked {
            Ok(_) => failures = 0,
            Err(error) => {
                failures += 1;
                // Log the first failure of a streak and then every 100th, not 15 a second.
                if failures == 1 || failures.is_multiple_of(100) {
                    tracing::warn!(%error, failures, "the camera did not deliver a frame");
                }
            }
        }
    }
}

/// Puts the camera on the bus: the actor under `supervisor`, publishing on `camera/frames`
/// at `fps`. Returns the actor and its ticking task.
pub async fn start(
    bus: &robotd_runtime::bus::Bus,
    supervisor: robotd_runtime::supervision::Supervisor,
    driver: Arc<dyn CameraDriver>,
    fps: f64,
) -> Result<
    (Supervised<CameraActor>, tokio::task::JoinHandle<()>),
    robotd_runtime::host::ActorStartError,
> {
    let frames = Arc::new(bus.frame_publisher(&robotd_topics::CAMERA_FRAMES)?);
    let intrinsics = bus.publisher(&robotd_topics::CAMERA_INTRINSICS)?;
    let frame_ids = Arc::new(AtomicU64::new(1));
    let actor_driver = driver.clone();
    let actor = supervisor
        .spawn_actor::<CameraActor>(move || {
            CameraActor::new(actor_driver.clone(), frames.clone(), frame_ids.clone())
        })
        .await?;
    let task = tokio::spawn(run_camera(actor.clone(), driver, fps, intrinsics));
    Ok((actor, task))
}
