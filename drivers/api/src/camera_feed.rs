//! The newest frame of a camera that sends frames by itself (a stream, a capture device), or
//! the reason there is none: the part every such camera driver shares.
//!
//! A receiver (a task or thread of the driver) decodes each frame as it arrives and calls
//! [`CameraFeed::publish`], or [`CameraFeed::set_problem`] when the source fails. The camera
//! actor calls [`CameraFeed::frame_ready`] and [`CameraFeed::capture_into`] through the
//! driver's [`CameraDriver`](crate::CameraDriver) methods. Only the newest frame is kept: a
//! camera never queues old frames, and a frame is handed out once.

use crate::{CaptureInfo, DriverError, DriverFuture};
use nalgebra::Isometry3;
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::Duration;

/// Where the camera is when a frame arrives (e.g. from the arm's joints); `None` when unknown.
pub type PoseSource = Arc<dyn Fn() -> Option<Isometry3<f64>> + Send + Sync>;

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
    /// A feed for the camera at `source` that has no frame yet, for the reason `waiting`
    /// (e.g. "connecting to …").
    pub fn new(source: &str, waiting: String) -> Self {
        Self {
            source: source.to_owned(),
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

    /// A new frame: `rgb` (RGB8, the camera's size) taken as `info` says.
    pub fn publish(&self, rgb: Vec<u8>, info: CaptureInfo) {
        let mut latest = self.lock();
        latest.frame = Ok(Frame { rgb, info });
        latest.sequence += 1;
        drop(latest);
        self.arrived.notify_waiters();
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

    fn info() -> CaptureInfo {
        CaptureInfo {
            camera_pose: Isometry3::identity(),
            timestamp_unix_ns: 7,
        }
    }

    #[tokio::test(start_paused = true)]
    async fn a_frame_is_handed_out_once_and_a_lasting_problem_is_reported() {
        let feed = CameraFeed::new("test", "connecting".into());
        let mut out = vec![0u8; 3];
        assert!(feed.capture_into(&mut out).is_err());

        feed.publish(vec![1, 2, 3], info());
        feed.frame_ready().await.unwrap();
        assert_eq!(feed.capture_into(&mut out).unwrap().timestamp_unix_ns, 7);
        assert_eq!(out, [1, 2, 3]);
        // Already handed out: frame_ready waits for the next one.
        let waiting = tokio::time::timeout(Duration::from_secs(5), feed.frame_ready()).await;
        assert!(waiting.is_err(), "an old frame must not count as ready");

        feed.set_problem("unplugged".into());
        let error = feed.frame_ready().await.unwrap_err();
        assert!(error.to_string().contains("unplugged"), "{error}");
        assert_eq!(feed.problem().as_deref(), Some("unplugged"));

        let mut wrong = vec![0u8; 2];
        feed.publish(vec![4, 5, 6], info());
        assert!(feed.capture_into(&mut wrong).is_err());
    }
}
