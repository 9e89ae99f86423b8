//! The newest frame of a camera that sends frames by itself (a stream, a capture device), or
//! the reason there is none: the part every such camera driver shares.
//!
//! A receiver (a task or thread of the driver) decodes each frame as it arrives and calls
//! [`CameraFeed::publish`], or [`CameraFeed::set_problem`] when the source fails. A stream does
//! not say when a frame was taken, so the feed dates each one `latency` before its arrival and
//! places the camera where the [`PoseSource`] says it is then. The camera
//! actor calls [`CameraFeed::frame_ready`] and [`CameraFeed::capture_into`] through the
//! driver's [`CameraDriver`] methods. Only the newest frame is kept: a
//! camera never queues old frames, and a frame is handed out once.

use crate::{CameraDriver, CaptureInfo, DriverError, DriverFuture};
use nalgebra::Isometry3;
use robotd_protocol::camera::CameraIntrinsics;
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::Duration;

/// Where the camera is when a frame arrives (e.g. from the arm's joints); `None` when unknown.
pub type PoseSource = Arc<dyn Fn() -> Option<Isometry3<f64>> + Send + Sync>;

/// A camera whose frames arrive through a [`CameraFeed`]: giving the feed gives it every
/// [`CameraDriver`] method.
pub trait FedCamera: Send + Sync + 'static {
    /// The feed its receiver publishes into.
    fn feed(&self) -> &CameraFeed;
}

impl<T: FedCamera> CameraDriver for T {
    fn size(&self) -> (u32, u32) {
        let intrinsics = &self.feed().intrinsics;
        (intrinsics.width, intrinsics.height)
    }

    fn intrinsics(&self) -> CameraIntrinsics {
        self.feed().intrinsics.clone()
    }

    fn frame_ready(&self) -> DriverFuture<'_, ()> {
        self.feed().frame_ready()
    }

    fn capture_into(&self, out: &mut [u8]) -> Result<CaptureInfo, DriverError> {
        self.feed().capture_into(out)
    }
}

/// How long [`CameraFeed::frame_ready`] waits for news before it reports a standing problem.
const PROBLEM_GRACE: Duration = Duration::from_secs(1);

struct Latest {
    frame: Result<Frame, String>,
    /// Counts published frames, so `frame_ready` can wait for a new one.
    sequence: u64,
    /// The sequence `capture_into` last handed out.
    taken: u64,
}

struct Frame {
    rgb: Vec<u8>,
    info: CaptureInfo,
}

/// The newest frame of one camera, or why there is none.
pub struct CameraFeed {
    /// Names the camera in logs (a URL, a device path).
    source: String,
    intrinsics: CameraIntrinsics,
    latency: Duration,
    pose: PoseSource,
    latest: Mutex<Latest>,
    arrived: tokio::sync::Notify,
}

impl std::fmt::Debug for CameraFeed {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("CameraFeed")
            .field("source", &self.source)
            .finish_non_exhaustive()
    }
}

impl CameraFeed {
    /// A feed for the camera at `source`, whose frames are `intrinsics.width × height`, are
    /// `latency` old when they arrive and are seen from where `pose` says. It has no frame
    /// yet, for the reason `waiting` (e.g. "connecting to …").
    pub fn new(
        source: &str,
        intrinsics: CameraIntrinsics,
        latency: Duration,
        pose: PoseSource,
        waiting: String,
    ) -> Self {
        Self {
            source: source.to_owned(),
            intrinsics,
            latency,
            pose,
            latest: Mutex::new(Latest {
                frame: Err(waiting),
                sequence: 0,
                taken: 0,
            }),
            arrived: tokio::sync::Notify::new(),
        }
    }

    fn lock(&self) -> MutexGuard<'_, Latest> {
        self.latest.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// The camera has no usable frame, because of `reason` (logged once per new reason).
    pub fn set_problem(&self, reason: String) {
        let mut latest = self.lock();
        if latest.frame.as_ref().err() != Some(&reason) {
            tracing::warn!(source = %self.source, %reason, "camera");
        }
        latest.frame = Err(reason);
        drop(latest);
        self.arrived.notify_waiters();
    }

    /// The intrinsics the frames must fit.
    pub fn intrinsics(&self) -> &CameraIntrinsics {
        &self.intrinsics
    }

    /// A new frame that has just arrived: `rgb` (RGB8, the camera's size).
    pub fn publish(&self, rgb: Vec<u8>) {
        let info = CaptureInfo {
            camera_pose: (self.pose)().unwrap_or_else(Isometry3::identity),
            timestamp_unix_ns: robotd_protocol::envelope::unix_now_ns()
                .saturating_sub(self.latency.as_nanos() as u64),
        };
        self.publish_taken(rgb, info);
    }

    /// A new frame whose source knows when and where it was taken (a recording): `rgb`
    /// (RGB8, the camera's size) with that `info`, instead of the feed's own dating.
    pub fn publish_taken(&self, rgb: Vec<u8>, info: CaptureInfo) {
        let mut latest = self.lock();
        latest.frame = Ok(Frame { rgb, info });
        latest.sequence += 1;
        drop(latest);
        self.arrived.notify_waiters();
    }

    /// Whether a frame is waiting that was not handed out yet.
    pub fn has_unread(&self) -> bool {
        let latest = self.lock();
        latest.frame.is_ok() && latest.sequence != latest.taken
    }

    /// The problem the camera has now, if any.
    pub fn problem(&self) -> Option<String> {
        self.lock().frame.as_ref().err().cloned()
    }

    /// Waits for a frame not handed out yet. A problem that lasts past a grace period is
    /// returned as the error, so a dead camera is reported instead of waited on forever.
    pub fn frame_ready(&self) -> DriverFuture<'_, ()> {
        Box::pin(async move {
            let mut waited_on_problem = false;
            loop {
                let arrived = self.arrived.notified();
                let problem = {
                    let latest = self.lock();
                    let fresh = latest.sequence != latest.taken;
                    match &latest.frame {
                        Ok(_) if fresh => return Ok(()),
                        Err(reason) => Some(reason.clone()),
                        Ok(_) => None,
                    }
                };
                match problem {
                    Some(reason) if waited_on_problem => return Err(DriverError::Hardware(reason)),
                    Some(_) => {
                        // Do not spin on a dead camera: wait a while for news first.
                        waited_on_problem = true;
                        let _ = tokio::time::timeout(PROBLEM_GRACE, arrived).await;
                    }
                    None => arrived.await,
                }
            }
        })
    }

    /// Copies the newest frame into `out` (which must be its size) and marks it handed out.
    pub fn capture_into(&self, out: &mut [u8]) -> Result<CaptureInfo, DriverError> {
        let mut latest = self.lock();
        let sequence = latest.sequence;
        let frame = match &latest.frame {
            Ok(frame) => frame,
            Err(reason) => return Err(DriverError::Hardware(reason.clone())),
        };
        if out.len() != frame.rgb.len() {
            return Err(DriverError::Hardware(format!(
                "frame buffer of {} bytes for a {}-byte frame",
                out.len(),
                frame.rgb.len()
            )));
        }
        out.copy_from_slice(&frame.rgb);
        let info = frame.info;
        latest.taken = sequence;
        Ok(info)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn intrinsics() -> CameraIntrinsics {
        CameraIntrinsics {
            width: 1,
            height: 1,
            fx: 1.0,
            fy: 1.0,
            cx: 0.5,
            cy: 0.5,
            distortion: [0.0; 5],
        }
    }

    #[tokio::test(start_paused = true)]
    async fn a_frame_is_handed_out_once_and_a_lasting_problem_is_reported() {
        let at = Isometry3::translation(0.1, 0.2, 0.3);
        let latency = Duration::from_millis(250);
        let feed = CameraFeed::new(
            "test",
            intrinsics(),
            latency,
            Arc::new(move || Some(at)),
            "connecting".into(),
        );
        let mut out = vec![0u8; 3];
        assert!(feed.capture_into(&mut out).is_err());

        let before = robotd_protocol::envelope::unix_now_ns();
        feed.publish(vec![1, 2, 3]);
        assert!(feed.has_unread());
        feed.frame_ready().await.unwrap();
        let info = feed.capture_into(&mut out).unwrap();
        assert!(!feed.has_unread());
        assert_eq!(out, [1, 2, 3]);
        assert_eq!(info.camera_pose, at);
        // Dated `latency` before it arrived.
        assert!(
            info.timestamp_unix_ns <= before.saturating_sub(latency.as_nanos() as u64) + 50_000_000
        );
        assert!(info.timestamp_unix_ns + latency.as_nanos() as u64 >= before);
        // Already handed out: frame_ready waits for the next one.
        let waiting = tokio::time::timeout(Duration::from_secs(5), feed.frame_ready()).await;
        assert!(waiting.is_err(), "an old frame must not count as ready");

        feed.set_problem("unplugged".into());
        let error = feed.frame_ready().await.unwrap_err();
        assert!(error.to_string().contains("unplugged"), "{error}");
        assert_eq!(feed.problem().as_deref(), Some("unplugged"));

        let mut wrong = vec![0u8; 2];
        feed.publish(vec![4, 5, 6]);
        assert!(feed.capture_into(&mut wrong).is_err());
    }
}
