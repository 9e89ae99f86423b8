//! Detections in pixels, from a detector outside robotd (a Python actor on the bus).
//!
//! A detector that reads `camera/frames` finds objects as boxes (and, often, masks) in the
//! pixels of one frame. It publishes them as [`PixelDetections`] on
//! `perception/pixel_detections`, naming the frame (`frame_id`) and echoing the frame header's
//! `camera_pose`; robotd's perception maps them onto the table through the workspace sheet it
//! found in that frame — or in a frame taken from the same camera pose, which shows the table
//! the same way — and publishes world [`Detections`](crate::objects::Detections) with
//! `source` = the detector's name, which the workspace model tracks like the built-in ones.

use crate::envelope::Message;
use crate::validate::{in_range, non_empty, Validate, ValidationError};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// Most objects one message may carry.
pub const MAX_PIXEL_OBJECTS: usize = 256;
/// Longest label or source name, bytes.
pub const MAX_NAME_BYTES: usize = 128;
/// Largest frame side a box may reach, pixels.
pub const MAX_FRAME_SIDE: u32 = 8192;

/// One object in pixels.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct PixelDetection {
    /// Its label (stored lower-case).
    pub label: String,
    /// The detector's confidence, 0 … 1.
    pub confidence: f64,
    /// The detector's class index (−1: none).
    #[serde(default = "no_class")]
    pub class_id: i64,
    /// Bounding box `[x_min, y_min, x_max, y_max]`, pixels, max exclusive.
    pub bbox_px: [u32; 4],
    /// The object's pixels from its mask, as indices `v × width + u`; absent: the whole box.
    #[serde(default)]
    pub mask_pixels: Option<Vec<u32>>,
}

fn no_class() -> i64 {
    -1
}

/// The objects a detector found in one camera frame.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct PixelDetections {
    /// The frame they were found in (its header's `frame_id`).
    pub frame_id: u64,
    /// That frame's header `camera_pose`: x, y, z (m), roll, pitch, yaw (rad).
    pub camera_pose: [f64; 6],
    /// The detector's name, e.g. `"python-colour"`; becomes the detections' `source`.
    pub source: String,
    /// The objects.
    pub objects: Vec<PixelDetection>,
}

impl Message for PixelDetections {
    const TYPE: &'static str = "perception.pixel_detections";
}

fn short(field: &str, value: &str) -> Result<(), ValidationError> {
    non_empty(field, value)?;
    if value.len() > MAX_NAME_BYTES || value.chars().any(char::is_control) {
        return Err(ValidationError::Invalid {
            field: field.into(),
            reason: format!("at most {MAX_NAME_BYTES} bytes, no control characters"),
        });
    }
    Ok(())
}

impl Validate for PixelDetections {
    fn validate(&self) -> Result<(), ValidationError> {
        short("source", &self.source)?;
        if self.source.trim().eq_ignore_ascii_case("robotd") {
            return Err(ValidationError::Invalid {
                field: "source".into(),
                reason: "\"robotd\" is the built-in detector's name; name your detector".into(),
            });
        }
        for (i, v) in self.camera_pose.iter().enumerate() {
            crate::validate::finite(&format!("camera_pose[{i}]"), *v)?;
        }
        if self.objects.len() > MAX_PIXEL_OBJECTS {
            return Err(ValidationError::Invalid {
                field: "objects".into(),
                reason: format!(
                    "{} objects; at most {MAX_PIXEL_OBJECTS} per frame",
                    self.objects.len()
                ),
            });
        }
        for (i, o) in self.objects.iter().enumerate() {
            let at = |e: ValidationError| e.within(&format!("objects[{i}]"));
            short("label", &o.label).map_err(at)?;
            in_range("confidence", o.confidence, 0.0, 1.0).map_err(at)?;
            let [x0, y0, x1, y1] = o.bbox_px;
            if x0 >= x1 || y0 >= y1 || x1 > MAX_FRAME_SIDE || y1 > MAX_FRAME_SIDE {
                return Err(at(ValidationError::Invalid {
                    field: "bbox_px".into(),
                    reason: format!(
                        "[{x0}, {y0}, {x1}, {y1}] is not a box [x_min, y_min, x_max, y_max] with \
                         min < max (max exclusive)"
                    ),
                }));
            }
            if let Some(mask) = &o.mask_pixels {
                let area = u64::from(x1 - x0) * u64::from(y1 - y0);
                if mask.is_empty() || mask.len() as u64 > area {
                    return Err(at(ValidationError::Invalid {
                        field: "mask_pixels".into(),
                        reason: format!(
                            "{} pixels for a box of {area}; give 1 … {area} or leave it out",
                            mask.len()
                        ),
                    }));
                }
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn one(bbox_px: [u32; 4], mask_pixels: Option<Vec<u32>>) -> PixelDetections {
        PixelDetections {
            frame_id: 3,
            camera_pose: [0.2, 0.0, 0.3, 0.0, 1.5, 0.0],
            source: "python-colour".into(),
            objects: vec![PixelDetection {
                label: "red object".into(),
                confidence: 0.9,
                class_id: -1,
                bbox_px,
                mask_pixels,
            }],
        }
    }

    #[test]
    fn sensible_detections_pass_and_each_bad_field_is_named() {
        assert_eq!(one([10, 10, 20, 30], None).validate(), Ok(()));
        assert_eq!(one([10, 10, 20, 30], Some(vec![5, 6])).validate(), Ok(()));
        let field = |d: PixelDetections| d.validate().unwrap_err().field().to_owned();
        assert_eq!(field(one([20, 10, 20, 30], None)), "objects[0].bbox_px");
        assert_eq!(
            field(one([0, 0, 2, 2], Some(vec![0; 5]))),
            "objects[0].mask_pixels"
        );
        let mut d = one([0, 0, 2, 2], None);
        d.source = "robotd".into();
        assert_eq!(field(d), "source");
        let mut d = one([0, 0, 2, 2], None);
        d.objects[0].label = "a\nforged line".into();
        assert_eq!(field(d), "objects[0].label");
        let mut d = one([0, 0, 2, 2], None);
        d.objects[0].confidence = f64::NAN;
        assert_eq!(field(d), "objects[0].confidence");
        let mut d = one([0, 0, 2, 2], None);
        d.camera_pose[2] = f64::INFINITY;
        assert_eq!(field(d), "camera_pose[2]");
    }
}
