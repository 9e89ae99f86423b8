//! The Ned2's wrist camera over TCP: `GET_IMAGE_COMPRESSED` JPEGs, fetched at the robot's pace
//! (at most `robot.camera.fps`), decoded, and handed to the camera actor.
//!
//! Images are fetched through the same one connection as motions, first come first served,
//! so a motion waits at most one image transfer and an image is only ever taken *between*
//! motion segments, when the arm stands still at joints robotd has read back: the camera's
//! pose in each frame header is exact. A frame taken while the arm's position is being read
//! (right after a segment) is dropped rather than published with a stale pose.
//!
//! Frames are published as the lens made them, with the intrinsics and distortion read from
//! the robot (`GET_CAMERA_INTRINSICS`, the Ned2's nominal values until it answered):
//! perception undoes the distortion for the points it measures, exactly as for the
//! simulator's distorted camera. A robot whose software already undistorts its images
//! (pyniryo notes this for robot software from 5.8.0) is configured with
//! `robot.niryo.images_rectified = true`: its frames are then described without distortion,
//! so that nothing is undone twice.

use crate::link::Link;
use robotd_driver::{CameraDriver, CaptureInfo, DriverError, DriverFuture};
use robotd_kinematics::Kinematics;
use robotd_protocol::camera::CameraIntrinsics;
use robotd_protocol::envelope::unix_now_ns;
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::Duration;
use tokio::sync::Notify;

/// Image size of the Ned2's camera.
pub const WIDTH: u32 = 640;
/// Image height of the Ned2's camera.
pub const HEIGHT: u32 = 480;

/// One decoded image and where it was taken.
struct Picture {
    rgb: Vec<u8>,
    info: CaptureInfo,
    sequence: u64,
}

#[derive(Default)]
struct Latest {
    picture: Option<Picture>,
    delivered: u64,
    fetched: u64,
}

/// The Ned2's camera.
pub struct NiryoCamera {
    link: Arc<Link>,
    kinematics: Kinematics,
    latest: Mutex<Latest>,
    arrived: Notify,
    rectified: bool,
}

impl std::fmt::Debug for NiryoCamera {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("NiryoCamera").finish_non_exhaustive()
    }
}

impl NiryoCamera {
    /// The camera driver on `link`; [`NiryoCamera::run_fetcher`] brings its images.
    /// `rectified`: the robot already sends undistorted images (`robot.niryo.images_rectified`),
    /// so the frames are ideal pinhole images whatever distortion the robot reports.
    pub fn new(link: Arc<Link>, rectified: bool) -> Arc<Self> {
        let model = robotd_protocol::geometry::RobotModel::Ned2;
        Self::with_mount(
            link,
            rectified,
            robotd_kinematics::CameraMount::default_for(model),
        )
    }

    /// [`NiryoCamera::new`] for a camera at `mount` on the wrist (`[robot.camera.mount]`):
    /// each frame's camera pose is the wrist's, from the joints, times the mount.
    pub fn with_mount(
        link: Arc<Link>,
        rectified: bool,
        mount: robotd_kinematics::CameraMount,
    ) -> Arc<Self> {
        Arc::new(Self {
            link,
            kinematics: Kinematics::new(robotd_protocol::geometry::RobotModel::Ned2)
                .with_camera_mount(mount),
            latest: Mutex::new(Latest::default()),
            arrived: Notify::new(),
            rectified,
        })
    }

    fn latest(&self) -> MutexGuard<'_, Latest> {
        self.latest.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// Fetches images forever, at most `fps` a second; failures are logged once per streak.
    pub async fn run_fetcher(self: Arc<Self>, fps: f64) {
        let mut ticker = tokio::time::interval(Duration::from_secs_f64(1.0 / fps.clamp(0.1, 60.0)));
        ticker.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
        let mut failing = false;
        loop {
            ticker.tick().await;
            if self.link.status().is_err() {
                let _ = self.link.wait_connected(Duration::from_secs(1)).await;
                continue;
            }
            match self.fetch().await {
                Ok(true) => failing = false,
                Ok(false) => {}
                Err(error) => {
                    if !failing {
                        tracing::warn!(%error, "no image from the robot's camera");
                    }
                    failing = true;
                }
            }
        }
    }

    /// Fetches and decodes one image: `Ok(false)` when it was dropped (arm position unsettled).
    pub async fn fetch(&self) -> Result<bool, String> {
        let timeout = self.link.settings().query_timeout;
        let (_, jpeg) = self
            .link
            .call("GET_IMAGE_COMPRESSED", &[], timeout)
            .await
            .map_err(|e| e.to_string())?;
        let timestamp_unix_ns = unix_now_ns();
        let known = self.link.known();
        let (Some(joints), true) = (known.joints, known.settled) else {
            return Ok(false);
        };
        let camera_pose = self
            .kinematics
            .camera_pose(&joints)
            .ok_or("the Ned2 model has no camera pose")?;
        let rgb = decode(&jpeg)?;
        let mut latest = self.latest();
        latest.fetched += 1;
        let sequence = latest.fetched;
        latest.picture = Some(Picture {
            rgb,
            info: CaptureInfo {
                camera_pose,
                timestamp_unix_ns,
            },
            sequence,
        });
        drop(latest);
        self.arrived.notify_waiters();
        Ok(true)
    }
}

/// Decodes a `GET_IMAGE_COMPRESSED` JPEG into 640×480 RGB.
pub fn decode(jpeg: &[u8]) -> Result<Vec<u8>, String> {
    let (rgb, width, height) =
        robotd_jpeg::decode_jpeg(jpeg).map_err(|e| format!("the camera sent {e}"))?;
    if (width, height) != (WIDTH, HEIGHT) {
        return Err(format!(
            "the camera sent a {width}×{height} image; robotd expects the Ned2's {WIDTH}×{HEIGHT}"
        ));
    }
    Ok(rgb)
}

impl CameraDriver for NiryoCamera {
    fn size(&self) -> (u32, u32) {
        (WIDTH, HEIGHT)
    }

    fn intrinsics(&self) -> CameraIntrinsics {
        let mut intrinsics = robotd_driver::hardware::ned2_camera_intrinsics();
        if let Some(([fx, fy, cx, cy], distortion)) = self.link.known().intrinsics {
            intrinsics.fx = fx;
            intrinsics.fy = fy;
            intrinsics.cx = cx;
            intrinsics.cy = cy;
            intrinsics.distortion = distortion;
        }
        if self.rectified {
            intrinsics.distortion = [0.0; 5];
        }
        intrinsics
    }

    fn frame_ready(&self) -> DriverFuture<'_, ()> {
        Box::pin(async move {
            loop {
                let arrived = self.arrived.notified();
                {
                    let latest = self.latest();
                    if latest
                        .picture
                        .as_ref()
                        .is_some_and(|p| p.sequence > latest.delivered)
                    {
                        return Ok(());
                    }
                }
                if tokio::time::timeout(Duration::from_secs(2), arrived)
                    .await
                    .is_err()
                {
                    return Err(DriverError::Hardware(match self.link.status() {
                        Ok(()) => "no new image from the robot's camera for 2 s".into(),
                        Err(reason) => format!("robot not connected: {reason}"),
                    }));
                }
            }
        })
    }

    fn capture_into(&self, out: &mut [u8]) -> Result<CaptureInfo, DriverError> {
        let mut latest = self.latest();
        let Some(picture) = latest.picture.as_ref() else {
            return Err(DriverError::Hardware(match self.link.status() {
                Ok(()) => "no image from the robot's camera yet".into(),
                Err(reason) => format!("robot not connected: {reason}"),
            }));
        };
        if out.len() != picture.rgb.len() {
            return Err(DriverError::Hardware(format!(
                "frame buffer of {} bytes for a {}-byte image",
                out.len(),
                picture.rgb.len()
            )));
        }
        out.copy_from_slice(&picture.rgb);
        let (info, sequence) = (picture.info, picture.sequence);
        latest.delivered = sequence;
        Ok(info)
    }
}
