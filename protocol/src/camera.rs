//! Camera frames as messages: the header that describes a frame, the camera's intrinsics, and
//! an encoded image body for consumers outside shared memory.
//!
//! On the bus, raw frames travel zero-copy in fixed shared-memory slots (see the runtime's
//! frame topic); what travels as an ordinary message is the [`CameraFrameHeader`] describing a
//! frame — when it was taken, its size and pixel encoding, where the camera was — and, for
//! consumers that want bytes (the Redis edge, the dashboard, a process in another language), a
//! [`CameraImage`]: header plus the image bytes. Those bytes are encoded as a MessagePack
//! `bin` (one length prefix, then the bytes), not as an array of small integers, so a 640×480
//! JPEG costs its own size on the wire.
//!
//! ```
//! use robotd_protocol::camera::{CameraFrameHeader, CameraImage, ImageEncoding};
//! use robotd_protocol::geometry::Pose;
//! use robotd_protocol::validate::Validate;
//!
//! let header = CameraFrameHeader {
//!     frame_id: 1,
//!     timestamp_unix_ns: 1_700_000_000_000_000_000,
//!     width: 2,
//!     height: 1,
//!     channels: 3,
//!     encoding: ImageEncoding::Rgb8,
//!     camera_pose: Pose::default(),
//!     workspace_id: Some("niryo_ws".into()),
//! };
//! let image = CameraImage { header, data: vec![255, 0, 0, 0, 255, 0] };
//! assert!(image.validate().is_ok());
//! ```

use crate::envelope::Message;
use crate::geometry::Pose;
use crate::validate::{finite, Validate, ValidationError};
use serde::{Deserialize, Serialize};

/// How the bytes of an image are laid out.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ImageEncoding {
    /// Row-major, 3 bytes per pixel, red first.
    Rgb8,
    /// Row-major, 3 bytes per pixel, blue first (OpenCV's order).
    Bgr8,
    /// A JPEG file.
    Jpeg,
}

impl ImageEncoding {
    /// Bytes per pixel of raw encodings; `None` for compressed ones.
    pub const fn bytes_per_pixel(&self) -> Option<u32> {
        match self {
            Self::Rgb8 | Self::Bgr8 => Some(3),
            Self::Jpeg => None,
        }
    }

    /// Wire name: `"rgb8"`, `"bgr8"`, `"jpeg"`.
    pub const fn as_str(&self) -> &'static str {
        match self {
            Self::Rgb8 => "rgb8",
            Self::Bgr8 => "bgr8",
            Self::Jpeg => "jpeg",
        }
    }
}

/// Describes one camera frame.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CameraFrameHeader {
    /// The camera's frame counter, increasing by one per frame.
    pub frame_id: u64,
    /// Capture time, nanoseconds since the Unix epoch.
    pub timestamp_unix_ns: u64,
    /// Image width, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
    /// Channels per pixel of the decoded image (3 for colour).
    pub channels: u32,
    /// Encoding of the image bytes.
    pub encoding: ImageEncoding,
    /// Pose of the camera at capture time, base frame.
    pub camera_pose: Pose,
    /// Workspace in view, when the arm was at a workspace's observation pose.
    pub workspace_id: Option<String>,
}

impl CameraFrameHeader {
    /// Bytes a raw image of this header occupies (`width × height × channels`); `None` for
    /// compressed encodings.
    pub fn raw_len(&self) -> Option<usize> {
        self.encoding
            .bytes_per_pixel()
            .map(|_| self.width as usize * self.height as usize * self.channels as usize)
    }
}

impl Validate for CameraFrameHeader {
    fn validate(&self) -> Result<(), ValidationError> {
        if self.width == 0 || self.height == 0 {
            return Err(ValidationError::Invalid {
                field: "width".into(),
                reason: format!(
                    "image size must be non-zero, got {}x{}",
                    self.width, self.height
                ),
            });
        }
        if let Some(bpp) = self.encoding.bytes_per_pixel() {
            if self.channels != bpp {
                return Err(ValidationError::Invalid {
                    field: "channels".into(),
                    reason: format!(
                        "{} images have {bpp} channels, got {}",
                        self.encoding.as_str(),
                        self.channels
                    ),
                });
            }
        }
        self.camera_pose
            .validate()
            .map_err(|e| e.within("camera_pose"))
    }
}

impl Message for CameraFrameHeader {
    const TYPE: &'static str = "camera.frame_header";
}

/// A frame with its bytes: raw pixels or a JPEG file, as `header.encoding` says.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CameraImage {
    /// What the bytes are.
    pub header: CameraFrameHeader,
    /// The image bytes (MessagePack `bin` on the wire).
    #[serde(with = "serde_bytes")]
    pub data: Vec<u8>,
}

/// The first bytes of every JPEG file (SOI marker and the start of the next marker).
const JPEG_MAGIC: [u8; 3] = [0xFF, 0xD8, 0xFF];

impl Validate for CameraImage {
    fn validate(&self) -> Result<(), ValidationError> {
        self.header.validate().map_err(|e| e.within("header"))?;
        match self.header.raw_len() {
            Some(expected) if self.data.len() != expected => Err(ValidationError::WrongLength {
                field: "data".into(),
                expected,
                got: self.data.len(),
            }),
            Some(_) => Ok(()),
            None if !self.data.starts_with(&JPEG_MAGIC) => Err(ValidationError::Invalid {
                field: "data".into(),
                reason: "not a JPEG file (missing the FF D8 FF start marker)".into(),
            }),
            None => Ok(()),
        }
    }
}

impl Message for CameraImage {
    const TYPE: &'static str = "camera.image";
}

/// Pinhole intrinsics and Brown–Conrady distortion of a camera, for the image size they were
/// calibrated at.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CameraIntrinsics {
    /// Image width the intrinsics apply to, pixels.
    pub width: u32,
    /// Image height the intrinsics apply to, pixels.
    pub height: u32,
    /// Focal length along u, pixels.
    pub fx: f64,
    /// Focal length along v, pixels.
    pub fy: f64,
    /// Principal point u, pixels.
    pub cx: f64,
    /// Principal point v, pixels.
    pub cy: f64,
    /// `[k1, k2, p1, p2, k3]` (OpenCV order).
    pub distortion: [f64; 5],
}

impl Validate for CameraIntrinsics {
    fn validate(&self) -> Result<(), ValidationError> {
        for (field, v) in [("fx", self.fx), ("fy", self.fy)] {
            finite(field, v)?;
            if v <= 0.0 {
                return Err(ValidationError::Invalid {
                    field: field.into(),
                    reason: format!("focal length must be positive, got {v}"),
                });
            }
        }
        finite("cx", self.cx)?;
        finite("cy", self.cy)?;
        for (i, k) in self.distortion.iter().enumerate() {
            finite(&format!("distortion[{i}]"), *k)?;
        }
        Ok(())
    }
}

impl Message for CameraIntrinsics {
    const TYPE: &'static str = "camera.intrinsics";
}

#[cfg(test)]
mod tests {
    use super::*;

    fn header(encoding: ImageEncoding) -> CameraFrameHeader {
        CameraFrameHeader {
            frame_id: 7,
            timestamp_unix_ns: 1,
            width: 4,
            height: 2,
            channels: 3,
            encoding,
            camera_pose: Pose::default(),
            workspace_id: None,
        }
    }

    #[test]
    fn raw_length_must_match() {
        let img = CameraImage {
            header: header(ImageEncoding::Bgr8),
            data: vec![0; 23],
        };
        assert_eq!(
            img.validate().unwrap_err().to_string(),
            "data: must have 24 entries, got 23"
        );
    }

    #[test]
    fn jpeg_needs_its_marker() {
        let mut img = CameraImage {
            header: header(ImageEncoding::Jpeg),
            data: vec![0xFF, 0xD8, 0xFF, 0xE0, 1, 2],
        };
        assert!(img.validate().is_ok());
        img.data = vec![1, 2, 3];
        assert!(img.validate().is_err());
    }

    #[test]
    fn channels_must_match_raw_encoding() {
        let mut h = header(ImageEncoding::Rgb8);
        h.channels = 1;
        assert_eq!(h.validate().unwrap_err().field(), "channels");
    }
}
