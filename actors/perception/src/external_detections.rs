//! Detections from a detector outside robotd, in pixels, placed on the table.
//!
//! A detector on the bus (a Python actor, see `python/`) publishes [`PixelDetections`] for one
//! camera frame on `perception/pixel_detections`. Mapping pixels onto the table needs that
//! frame's workspace sheet. Perception remembers the sheet it found in the last frame it
//! processed ([`KnownSheet`]); it serves a message whose frame is that frame, or was taken from
//! the same camera pose (within 1 mm and 0.002 rad: the table then looks the same in both).
//! Otherwise the message is refused with a reason (the arm moved in between, or no sheet is in
//! view): a detector that answers late while the arm moves loses those answers, never maps them
//! through the wrong view.
//!
//! Each outcome is counted ([`ExternalStats`], shown in `/health`), and refusals are logged at
//! debug level with their reason.

use crate::external::{KnownSheet, PixelObject};
use crate::labels::LabelTable;
use crate::pipeline::Pipeline;
use robotd_protocol::objects::Detections;
use robotd_protocol::pixels::PixelDetections;
use robotd_protocol::validate::Validate;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Mutex;

/// How far apart two camera poses may be and still show the table the same way: metres.
const SAME_POSITION_M: f64 = 0.001;
/// The same, radians.
const SAME_ANGLE_RAD: f64 = 0.002;

/// What happened to external detections.
#[derive(Debug, Default)]
pub struct ExternalStats {
    /// Messages placed and published.
    pub placed: AtomicU64,
    /// Messages refused (invalid, no sheet, another view).
    pub refused: AtomicU64,
    /// Why the last refused message was refused.
    pub last_refusal: Mutex<Option<String>>,
}

impl ExternalStats {
    fn refuse(&self, reason: String) {
        self.refused.fetch_add(1, Ordering::Relaxed);
        tracing::debug!(%reason, "perception: external detections refused");
        if let Ok(mut last) = self.last_refusal.lock() {
            *last = Some(reason);
        }
    }
}

fn same_view(a: &[f64; 6], b: &[f64; 6]) -> bool {
    let position = (0..3).all(|i| (a[i] - b[i]).abs() <= SAME_POSITION_M);
    let angle = (3..6).all(|i| {
        let d = (a[i] - b[i]).rem_euclid(std::f64::consts::TAU);
        d.min(std::f64::consts::TAU - d) <= SAME_ANGLE_RAD
    });
    position && angle
}

/// Places `message` on `sheet` (the last sheet perception found), or says why not.
pub fn place(
    pipeline: &Pipeline,
    sheet: Option<&KnownSheet>,
    message: &PixelDetections,
    heights: &LabelTable,
    stats: &ExternalStats,
) -> Option<Detections> {
    if let Err(error) = message.validate() {
        stats.refuse(format!("invalid pixel detections: {error}"));
        return None;
    }
    let Some(sheet) = sheet else {
        stats.refuse(format!(
            "frame {}: no workspace sheet in view in the last processed frame",
            message.frame_id
        ));
        return None;
    };
    if sheet.frame_id != message.frame_id && !same_view(&sheet.camera_pose, &message.camera_pose) {
        stats.refuse(format!(
            "frame {}: the camera moved since (perception's last view is frame {} from another \
             pose); answer newer frames",
            message.frame_id, sheet.frame_id
        ));
        return None;
    }
    let size = pipeline.camera().size();
    let objects: Vec<PixelObject> = message
        .objects
        .iter()
        .map(|o| PixelObject {
            label: o.label.clone(),
            confidence: o.confidence,
            class_id: o.class_id,
            bbox_px: o.bbox_px,
            mask_pixels: o.mask_pixels.clone(),
        })
        .collect();
    let (mut detections, skipped) =
        pipeline.place_pixel_objects(sheet, size, message.source.trim(), &objects, heights);
    detections.frame_id = message.frame_id;
    stats.placed.fetch_add(1, Ordering::Relaxed);
    if !skipped.is_empty() {
        tracing::debug!(
            skipped = skipped.len(),
            source = %message.source,
            "perception: external objects that could not be placed (box outside the frame, \
             too small, or outside the workspace)"
        );
    }
    Some(detections)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn views_match_within_a_millimetre_and_wrap_angles() {
        let a = [0.2, 0.0, 0.3, 0.0, 1.5, std::f64::consts::PI];
        let mut b = a;
        b[0] += 0.0009;
        b[5] = -std::f64::consts::PI + 0.001;
        assert!(same_view(&a, &b));
        b[1] += 0.002;
        assert!(!same_view(&a, &b));
    }
}
