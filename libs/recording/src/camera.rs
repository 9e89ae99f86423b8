//! Camera frames put back together from a recording.
//!
//! The recorder logs each frame twice at its capture time: the image on [`crate::CAMERA`]
//! (`foxglove.CompressedImage`, JPEG) and then its header on [`crate::CAMERA_META`] (a
//! [`FrameMeta`]). A [`FramePairer`] joins the two halves into a [`RecordedFrame`]; a half whose
//! partner is missing or of another time is dropped with the reason, never paired with the
//! wrong image. Decoding uses robotd's one JPEG decoder ([`robotd_render::decode_jpeg`]) and
//! checks the image against its header's size.

use crate::reader::Message;
use foxglove::messages::CompressedImage;
use foxglove::Decode;
use robotd_protocol::camera::CameraIntrinsics;
use serde::{Deserialize, Serialize};

/// The header of one recorded camera frame (`/camera/meta`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FrameMeta {
    /// The camera's frame counter.
    pub frame_id: u64,
    /// Capture time, ns since the Unix epoch.
    pub timestamp_unix_ns: u64,
    /// Image width, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
    /// Pose of the camera's optical frame at capture: x, y, z (m), roll, pitch, yaw (rad), in
    /// the robot's base frame.
    pub camera_pose: [f64; 6],
    /// The camera's intrinsics, when the recorder knew them (`robotd serve`'s recordings do;
    /// `robotd record`, another process, does not).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub intrinsics: Option<CameraIntrinsics>,
}

/// One camera frame of a recording, its JPEG not decoded yet.
#[derive(Debug, Clone, PartialEq)]
pub struct RecordedFrame {
    /// When it was logged (its capture time), ns since the Unix epoch.
    pub log_time: u64,
    /// Its header.
    pub meta: FrameMeta,
    /// The JPEG image.
    pub jpeg: Vec<u8>,
}

impl RecordedFrame {
    /// The image as RGB8 (row-major, `width × height × 3` bytes), checked against the size
    /// its header gives.
    pub fn decode(&self) -> Result<Vec<u8>, String> {
        let (rgb, width, height) = robotd_render::decode_jpeg(&self.jpeg)
            .map_err(|e| format!("camera frame {}: {e}", self.meta.frame_id))?;
        if (width, height) != (self.meta.width, self.meta.height) {
            return Err(format!(
                "camera frame {}: the image is {width}×{height}, its header says {}×{}",
                self.meta.frame_id, self.meta.width, self.meta.height
            ));
        }
        Ok(rgb)
    }
}

/// The JPEG bytes of a `/camera` message.
pub fn jpeg_of(data: &[u8]) -> Result<Vec<u8>, String> {
    let image =
        CompressedImage::decode(data).map_err(|e| format!("camera: not a CompressedImage: {e}"))?;
    if image.format != "jpeg" {
        return Err(format!(
            "camera: format '{}' (only jpeg is read)",
            image.format
        ));
    }
    Ok(image.data.to_vec())
}

/// Joins `/camera` images with their `/camera/meta` headers.
#[derive(Debug, Default)]
pub struct FramePairer {
    image: Option<(u64, Vec<u8>)>,
}

impl FramePairer {
    /// Takes one message of [`crate::CAMERA`] or [`crate::CAMERA_META`] (others are ignored):
    /// `Ok(Some(frame))` when it completes a frame, `Ok(None)` when it waits for its other
    /// half, `Err(reason)` when it (or an image waiting before it) is dropped.
    pub fn take(&mut self, message: &Message) -> Result<Option<RecordedFrame>, String> {
        match &*message.topic {
            crate::CAMERA => {
                let jpeg = jpeg_of(&message.data)?;
                let unpaired = self.image.replace((message.log_time, jpeg));
                match unpaired {
                    Some(_) => Err("camera image without its header".to_owned()),
                    None => Ok(None),
                }
            }
            crate::CAMERA_META => {
                let Some((time, jpeg)) = self.image.take() else {
                    return Err("camera header without its image".to_owned());
                };
                if time != message.log_time {
                    return Err("camera header of another image".to_owned());
                }
                let meta: FrameMeta = serde_json::from_slice(&message.data)
                    .map_err(|e| format!("camera header: {e}"))?;
                Ok(Some(RecordedFrame {
                    log_time: time,
                    meta,
                    jpeg,
                }))
            }
            _ => Ok(None),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fixture::{compressed_jpeg, jpeg_image, meta};
    use std::sync::Arc;

    fn message(topic: &str, log_time: u64, data: Vec<u8>) -> Message {
        Message {
            topic: Arc::from(topic),
            log_time,
            data,
        }
    }

    #[test]
    fn an_image_and_its_header_make_a_frame_that_decodes_to_its_size() {
        let mut pairer = FramePairer::default();
        let image = message(crate::CAMERA, 5, compressed_jpeg(&jpeg_image(16, 12, 200)));
        assert_eq!(pairer.take(&image), Ok(None));
        let header = serde_json::to_vec(&meta(7, 5, 16, 12)).unwrap();
        let frame = pairer
            .take(&message(crate::CAMERA_META, 5, header))
            .unwrap()
            .unwrap();
        assert_eq!(frame.meta.frame_id, 7);
        let rgb = frame.decode().unwrap();
        assert_eq!(rgb.len(), 16 * 12 * 3);
        assert!(rgb.iter().all(|&v| v.abs_diff(200) < 8), "a grey image");

        let mut lying = frame.clone();
        lying.meta.width = 640;
        assert!(lying.decode().unwrap_err().contains("16×12"));
    }

    #[test]
    fn halves_without_their_partner_are_dropped_never_mispaired() {
        let mut pairer = FramePairer::default();
        let header = |t| {
            message(
                crate::CAMERA_META,
                t,
                serde_json::to_vec(&meta(1, t, 16, 12)).unwrap(),
            )
        };
        let image = |t| message(crate::CAMERA, t, compressed_jpeg(&jpeg_image(16, 12, 9)));
        assert!(pairer
            .take(&header(1))
            .unwrap_err()
            .contains("without its image"));
        pairer.take(&image(2)).unwrap();
        assert!(pairer
            .take(&header(3))
            .unwrap_err()
            .contains("another image"));
        pairer.take(&image(4)).unwrap();
        assert!(pairer
            .take(&image(5))
            .unwrap_err()
            .contains("without its header"));
        assert!(
            pairer.take(&header(5)).unwrap().is_some(),
            "the newer image pairs"
        );
        let not_jpeg = CompressedImage {
            timestamp: None,
            frame_id: String::new(),
            data: vec![1, 2, 3].into(),
            format: "png".into(),
        };
        let mut bytes = Vec::new();
        foxglove::Encode::encode(&not_jpeg, &mut bytes).unwrap();
        assert!(pairer
            .take(&message(crate::CAMERA, 6, bytes))
            .unwrap_err()
            .contains("png"));
        assert_eq!(pairer.take(&message("/tf", 6, vec![])), Ok(None));
    }
}
