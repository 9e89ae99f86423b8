//! A camera driver for V4L2 capture devices: the USB cameras labs mount on a WidowX
//! (`/dev/video0`, or a udev name such as `/dev/wrist_cam`).
//!
//! [`V4l2Camera`] runs one capture thread. It opens the device, checks that it captures
//! video with streaming I/O, and asks for the size of the configured intrinsics in MJPG (or
//! JPEG, or else uncompressed YUYV). A camera that cannot give that size is a clear error
//! naming the size it gives: the intrinsics would not fit its frames. Each buffer is decoded
//! to RGB8 and offered to the camera actor as the newest frame (older ones are dropped).
//!
//! Frames are dated `latency` before they are dequeued, like the MJPEG driver's. A camera
//! that is unplugged, stalls for [`STALL_TIMEOUT`] or fails is reopened (100 ms, doubling to
//! 2 s between tries); meanwhile the camera says why it has no frame.
//!
//! Tested here: the conversions and the errors for a missing device and a file that is not a
//! camera. Not tested here: capture from a real device (this machine has no `/dev/video*`).

mod capture;
mod convert;

pub use capture::{probe, STALL_TIMEOUT};
pub use convert::{yuyv_to_rgb, Decoder};

use robotd_driver::camera_feed::{CameraFeed, FedCamera, PoseSource};
use robotd_protocol::camera::CameraIntrinsics;
use robotd_runtime::backoff::Backoff;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Weak};
use std::time::Duration;

/// A V4L2 capture device as a robotd camera.
pub struct V4l2Camera {
    device: PathBuf,
    feed: CameraFeed,
}

impl std::fmt::Debug for V4l2Camera {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("V4l2Camera")
            .field("device", &self.device)
            .finish_non_exhaustive()
    }
}

impl V4l2Camera {
    /// A camera on `device` giving `intrinsics.width × height` frames that are `latency` old
    /// when dequeued, seen from where `pose` says; starts its capture thread.
    pub fn start(
        device: &Path,
        intrinsics: CameraIntrinsics,
        latency: Duration,
        pose: PoseSource,
    ) -> std::io::Result<Arc<Self>> {
        let camera = Arc::new(Self {
            device: device.to_owned(),
            feed: CameraFeed::new(
                &device.display().to_string(),
                intrinsics,
                latency,
                pose,
                format!("opening camera {}", device.display()),
            ),
        });
        let weak = Arc::downgrade(&camera);
        std::thread::Builder::new()
            .name("robotd-v4l2".into())
            .spawn(move || capture_thread(weak))?;
        Ok(camera)
    }

    /// Why the camera has no frame now, if it has none.
    pub fn problem(&self) -> Option<String> {
        self.feed.problem()
    }
}

/// Capture sessions, reopened with backoff, until the camera is dropped.
fn capture_thread(camera: Weak<V4l2Camera>) {
    let mut backoff = Backoff::up_to(Duration::from_secs(2));
    loop {
        let Some(strong) = camera.upgrade() else {
            return;
        };
        let device = strong.device.clone();
        drop(strong);
        let sink = Sink {
            camera: camera.clone(),
            frames: std::sync::atomic::AtomicU64::new(0),
        };
        // A bug in the capture path (the V4L2 library, a decoder) must not end the thread
        // and leave the camera silent: it is one more reason to reopen the device.
        let session = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            capture::run_session(&device, &sink)
        }));
        let reason = session.unwrap_or_else(|panic| {
            let what = panic
                .downcast_ref::<&str>()
                .map(|s| (*s).to_owned())
                .or_else(|| panic.downcast_ref::<String>().cloned())
                .unwrap_or_default();
            format!("the capture of camera {} failed: {what}", device.display())
        });
        if sink.frames.load(std::sync::atomic::Ordering::Relaxed) > 0 {
            backoff.reset();
        }
        match camera.upgrade() {
            Some(strong) => strong.feed.set_problem(reason),
            None => return,
        }
        std::thread::sleep(backoff.next_delay());
    }
}

/// Where one session's frames go.
struct Sink {
    camera: Weak<V4l2Camera>,
    frames: std::sync::atomic::AtomicU64,
}

impl capture::FrameSink for Sink {
    fn size(&self) -> (u32, u32) {
        self.camera.upgrade().map_or((0, 0), |c| {
            let intrinsics = c.feed.intrinsics();
            (intrinsics.width, intrinsics.height)
        })
    }

    fn wanted(&self) -> bool {
        self.camera.strong_count() > 0
    }

    fn frame(&self, rgb: Vec<u8>) {
        let Some(camera) = self.camera.upgrade() else {
            return;
        };
        self.frames
            .fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        camera.feed.publish(rgb);
    }

    fn bad_frame(&self, reason: String) {
        if let Some(camera) = self.camera.upgrade() {
            camera.feed.set_problem(reason);
        }
    }
}

impl FedCamera for V4l2Camera {
    fn feed(&self) -> &CameraFeed {
        &self.feed
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use robotd_driver::CameraDriver;

    fn intrinsics() -> CameraIntrinsics {
        CameraIntrinsics {
            width: 640,
            height: 480,
            fx: 500.0,
            fy: 500.0,
            cx: 320.0,
            cy: 240.0,
            distortion: [0.0; 5],
        }
    }

    #[tokio::test]
    async fn an_absent_camera_reports_why_it_has_no_frame() {
        let camera = V4l2Camera::start(
            Path::new("/dev/video-robotd-absent"),
            intrinsics(),
            Duration::ZERO,
            Arc::new(|| None),
        )
        .unwrap();
        let error = camera.frame_ready().await.unwrap_err().to_string();
        assert!(
            error.contains("/dev/video-robotd-absent not found"),
            "{error}"
        );
        let mut out = vec![0u8; 640 * 480 * 3];
        assert!(camera.capture_into(&mut out).is_err());
    }
}
