//! A camera driver for MJPEG-over-HTTP streams (IP cameras, mjpg-streamer, `robotd
//! fake-widowx`), and a small MJPEG server for fakes and tests.
//!
//! [`MjpegCamera`] keeps one HTTP connection to the stream's URL open
//! (`multipart/x-mixed-replace`: one JPEG per part, each with its Content-Length), decodes each
//! JPEG as it arrives, and offers the newest one to the camera actor: the camera never queues
//! old frames. The frame is described with the intrinsics from config and the camera's pose at
//! arrival, which a `pose` function gives (for a wrist camera: from the arm's joints). A lost
//! stream is retried (100 ms, doubling to 2 s); meanwhile the camera says why it has no frame.
//!
//! [`serve`] is the other end: a stream of frames from any [`CameraDriver`](robotd_driver::CameraDriver), the way a lab's
//! IP camera would send them.

mod client;
mod server;

pub use client::MjpegCamera;
pub use robotd_driver::camera_feed::PoseSource;
pub use server::{serve, MjpegServer};

/// Largest JPEG accepted in one part.
pub const MAX_FRAME_BYTES: usize = 8 << 20;
