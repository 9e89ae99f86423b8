//! The stream entries, field by field, as `docs/redis-streams.md` and the Python tools have
//! them: building the ones robotd writes and checking the ones it reads.
//!
//! Everything here is pure (no I/O), so the formats are unit-tested and the readers fuzzed.
//! Every entry robotd writes carries one extra field, `robotd_instance`, naming the robotd
//! that wrote it: a reader skips its own entries (no echo of its own detections) and takes
//! those of other robotd instances sharing the Redis (the multi-machine set-up). Python readers
//! ignore the extra field.

use base64::Engine as _;
use robotd_protocol::geometry::Pose;
use robotd_protocol::objects::{DetectedObject, Detections};
use robotd_protocol::validate::Validate;
use serde_json::{json, Map, Value};

/// The camera stream.
pub const ROBOT_CAMERA: &str = "robot_camera";
/// Frames with boxes and labels drawn.
pub const ANNOTATED_CAMERA: &str = "annotated_camera";
/// Detections, robotd's and external detectors'.
pub const DETECTED_OBJECTS: &str = "detected_objects";
/// The detectable-label list.
pub const DETECTABLE_LABELS: &str = "detectable_labels";
/// Texts over the video.
pub const VIDEO_TEXT_OVERLAYS: &str = "video_text_overlays";

/// The approximate `MAXLEN` of each stream, as the spec gives it.
pub fn maxlen(stream: &str) -> usize {
    match stream {
        ROBOT_CAMERA => 5,
        ANNOTATED_CAMERA => 10,
        DETECTED_OBJECTS => 500,
        DETECTABLE_LABELS => 1,
        _ => 100,
    }
}

/// The field naming the robotd that wrote an entry.
pub const INSTANCE_FIELD: &str = "robotd_instance";

/// Detections older than this are stale (the Python side's rule), seconds.
pub const DETECTIONS_STALE_AFTER_S: f64 = 2.0;

/// One entry to append: stream and field/value pairs.
#[derive(Debug, Clone, PartialEq)]
pub struct Entry {
    /// The stream.
    pub stream: &'static str,
    /// Field/value pairs, in order.
    pub fields: Vec<(&'static str, String)>,
}

impl Entry {
    /// Bytes of all field values (for benchmarks and limits).
    pub fn value_bytes(&self) -> usize {
        self.fields.iter().map(|(_, v)| v.len()).sum()
    }
}

/// What a camera entry says about its frame.
#[derive(Debug, Clone, PartialEq)]
pub struct FrameMeta<'a> {
    /// The camera's frame id.
    pub frame_id: u64,
    /// Capture time, seconds since the Unix epoch.
    pub timestamp_unix_s: f64,
    /// Width and height, pixels.
    pub size: (u32, u32),
    /// The workspace the camera looks at.
    pub workspace_id: &'a str,
    /// The arm's pose when the frame was taken.
    pub robot_pose: Pose,
}

/// A `robot_camera` (or, with `annotation`, an `annotated_camera`) entry for a JPEG.
/// `annotation` is `(detection_count, model_id)`.
pub fn camera_entry(
    instance: &str,
    meta: &FrameMeta<'_>,
    jpeg: &[u8],
    annotation: Option<(usize, &str)>,
) -> Entry {
    let p = &meta.robot_pose;
    let mut metadata = json!({
        "workspace_id": meta.workspace_id,
        "frame_id": meta.frame_id,
        "robot_pose": {
            "x": p.x_m, "y": p.y_m, "z": p.z_m,
            "roll": p.roll_rad, "pitch": p.pitch_rad, "yaw": p.yaw_rad,
        },
        "image_source": "robot_mounted_camera",
    });
    let stream = match annotation {
        Some((count, model)) => {
            metadata["annotated"] = json!(true);
            metadata["detection_count"] = json!(count);
            metadata["model_id"] = json!(model);
            ANNOTATED_CAMERA
        }
        None => ROBOT_CAMERA,
    };
    let (w, h) = meta.size;
    Entry {
        stream,
        fields: vec![
            ("timestamp", meta.timestamp_unix_s.to_string()),
            (
                "image_data",
                base64::engine::general_purpose::STANDARD.encode(jpeg),
            ),
            ("format", "jpeg".into()),
            ("width", w.to_string()),
            ("height", h.to_string()),
            ("channels", "3".into()),
            ("dtype", "uint8".into()),
            ("compressed_size", jpeg.len().to_string()),
            ("original_size", (w as usize * h as usize * 3).to_string()),
            ("metadata", metadata.to_string()),
            (INSTANCE_FIELD, instance.to_owned()),
        ],
    }
}

/// A `detected_objects` entry for robotd's own detections of a frame; `ids` are the objects'
/// tracked ids (same order).
pub fn detections_entry(instance: &str, detections: &Detections, ids: &[String]) -> Entry {
    let objects: Vec<Value> = detections
        .objects
        .iter()
        .zip(ids)
        .map(|(object, id)| {
            let mut value = serde_json::to_value(object).unwrap_or(Value::Null);
            if let Value::Object(map) = &mut value {
                map.insert("id".into(), json!(id));
                map.insert("class_name".into(), json!(object.label));
                map.insert("workspace_id".into(), json!(detections.workspace_id));
            }
            value
        })
        .collect();
    let t = detections.timestamp_unix_ns as f64 / 1e9;
    let camera_pose = json!({
        "timestamp": t,
        "object_count": objects.len(),
        "detection_method": "robotd",
        "model_id": detections.source,
        "frame_id": detections.frame_id,
        "workspace_id": detections.workspace_id,
        "steady": detections.steady,
    });
    Entry {
        stream: DETECTED_OBJECTS,
        fields: vec![
            ("timestamp", t.to_string()),
            ("objects", Value::Array(objects).to_string()),
            ("camera_pose", camera_pose.to_string()),
            (INSTANCE_FIELD, instance.to_owned()),
        ],
    }
}

/// A `detectable_labels` entry; `added` names the label just added, if that is why.
pub fn labels_entry(instance: &str, now_s: f64, labels: &[String], added: Option<&str>) -> Entry {
    let metadata = match added {
        Some(label) => json!({"action": "add", "added_label": label}),
        None => json!({"action": "publish"}),
    };
    Entry {
        stream: DETECTABLE_LABELS,
        fields: vec![
            ("timestamp", now_s.to_string()),
            ("labels", json!(labels).to_string()),
            ("label_count", labels.len().to_string()),
            ("metadata", metadata.to_string()),
            (INSTANCE_FIELD, instance.to_owned()),
        ],
    }
}

/// A `video_text_overlays` entry.
pub fn overlay_entry(
    instance: &str,
    now_s: f64,
    text: &str,
    kind: &str,
    duration_s: f64,
    tool_name: Option<&str>,
) -> Entry {
    let mut metadata = json!({"duration_seconds": duration_s});
    if let Some(tool) = tool_name {
        metadata["tool_name"] = json!(tool);
    }
    Entry {
        stream: VIDEO_TEXT_OVERLAYS,
        fields: vec![
            ("timestamp", now_s.to_string()),
            ("text", text.to_owned()),
            ("type", kind.to_owned()),
            ("metadata", metadata.to_string()),
            (INSTANCE_FIELD, instance.to_owned()),
        ],
    }
}

// ------------------------------------------------------------------------------------------
// Reading

/// Why an entry (or one object of it) was skipped; the word is the metrics outcome.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum Skip {
    /// A field is missing.
    #[error("field '{0}' is missing")]
    Missing(&'static str),
    /// A field is not valid JSON / not a number.
    #[error("field '{field}' is malformed: {reason}")]
    Malformed {
        /// The field.
        field: &'static str,
        /// What is wrong.
        reason: String,
    },
    /// The entry is larger than the limit.
    #[error("entry of {bytes} bytes is larger than the limit of {limit}")]
    TooLarge {
        /// Its size.
        bytes: usize,
        /// The limit.
        limit: usize,
    },
    /// The detections are older than [`DETECTIONS_STALE_AFTER_S`].
    #[error("detections are {age_s:.1} s old (stale after {DETECTIONS_STALE_AFTER_S} s)")]
    Stale {
        /// Their age.
        age_s: f64,
    },
}

impl Skip {
    /// The metrics outcome word.
    pub fn outcome(&self) -> &'static str {
        match self {
            Skip::Missing(_) => "skipped_missing_field",
            Skip::Malformed { .. } => "skipped_malformed",
            Skip::TooLarge { .. } => "skipped_too_large",
            Skip::Stale { .. } => "skipped_stale",
        }
    }
}

fn field<'a>(fields: &'a Map<String, Value>, name: &'static str) -> Result<&'a str, Skip> {
    match fields.get(name) {
        Some(Value::String(s)) => Ok(s),
        Some(_) => Err(Skip::Malformed {
            field: name,
            reason: "not a string".into(),
        }),
        None => Err(Skip::Missing(name)),
    }
}

fn json_field(fields: &Map<String, Value>, name: &'static str) -> Result<Value, Skip> {
    serde_json::from_str(field(fields, name)?).map_err(|e| Skip::Malformed {
        field: name,
        reason: e.to_string(),
    })
}

fn timestamp(fields: &Map<String, Value>) -> Result<f64, Skip> {
    let t = field(fields, "timestamp")?;
    t.trim()
        .parse::<f64>()
        .ok()
        .filter(|t| t.is_finite() && *t >= 0.0)
        .ok_or_else(|| Skip::Malformed {
            field: "timestamp",
            reason: format!("'{}' is not a Unix time in seconds", truncate(t, 40)),
        })
}

fn truncate(s: &str, n: usize) -> &str {
    match s.char_indices().nth(n) {
        Some((i, _)) => &s[..i],
        None => s,
    }
}

/// Checks the size of an entry's values against `limit` bytes.
pub fn check_size(fields: &Map<String, Value>, limit: usize) -> Result<(), Skip> {
    let bytes: usize = fields
        .values()
        .map(|v| v.as_str().map_or(0, str::len))
        .sum();
    if bytes > limit {
        return Err(Skip::TooLarge { bytes, limit });
    }
    Ok(())
}

/// The entry's writer, if it is a robotd.
pub fn writer(fields: &Map<String, Value>) -> Option<&str> {
    fields.get(INSTANCE_FIELD).and_then(Value::as_str)
}

/// An object in the vision format of external detectors (pixel box, optional mask).
#[derive(Debug, Clone, PartialEq)]
pub struct VisionObject {
    /// Label.
    pub label: String,
    /// Confidence 0..=1.
    pub confidence: f64,
    /// Class index (−1 when absent).
    pub class_id: i64,
    /// `[x_min, y_min, x_max, y_max]`, pixels.
    pub bbox: [f64; 4],
    /// Mask: `(height, width, bytes)`; a non-zero byte is the object.
    pub mask: Option<(usize, usize, Vec<u8>)>,
}

/// The largest mask accepted, pixels (4K).
pub const MAX_MASK_PIXELS: usize = 4096 * 2160;

/// What a `detected_objects` entry from someone else holds.
#[derive(Debug, Clone, PartialEq)]
pub struct ExternalDetections {
    /// The entry's timestamp, Unix seconds.
    pub timestamp_unix_s: f64,
    /// The frame it was made from, when the detector names it.
    pub frame_id: Option<u64>,
    /// The capture time of that frame, when named (`camera_pose.timestamp` or
    /// `image_timestamp`), Unix seconds.
    pub frame_timestamp_unix_s: Option<f64>,
    /// Which model made it (`camera_pose.model_id` / `detection_method`).
    pub model: String,
    /// Whether the arm stood still (robotd writers say; others are taken as steady).
    pub steady: bool,
    /// Objects already in world coordinates (written by another robotd).
    pub world: Vec<DetectedObject>,
    /// Objects in pixels (vision format).
    pub vision: Vec<VisionObject>,
    /// Objects of the entry that were malformed and left out, with why.
    pub bad_objects: Vec<Skip>,
}

/// Parses a `detected_objects` entry written by an external detector (or another robotd).
/// `now_s` is the current Unix time for the freshness rule.
pub fn parse_detections(
    fields: &Map<String, Value>,
    now_s: f64,
) -> Result<ExternalDetections, Skip> {
    let timestamp_unix_s = timestamp(fields)?;
    let age_s = now_s - timestamp_unix_s;
    if age_s > DETECTIONS_STALE_AFTER_S {
        return Err(Skip::Stale { age_s });
    }
    let objects = json_field(fields, "objects")?;
    let Value::Array(objects) = objects else {
        return Err(Skip::Malformed {
            field: "objects",
            reason: "not a JSON list".into(),
        });
    };
    let pose = match fields.get("camera_pose") {
        Some(_) => json_field(fields, "camera_pose")?,
        None => Value::Null,
    };
    let number = |v: Option<&Value>| v.and_then(Value::as_f64).filter(|x| x.is_finite());
    let frame_id = pose
        .get("frame_id")
        .or_else(|| fields.get("frame_id"))
        .and_then(|v| match v {
            Value::Number(n) => n.as_u64(),
            Value::String(s) => s.trim().parse().ok(),
            _ => None,
        });
    let frame_timestamp_unix_s = number(pose.get("timestamp")).or_else(|| {
        fields
            .get("image_timestamp")
            .and_then(Value::as_str)
            .and_then(|s| s.trim().parse().ok())
    });
    let model = pose
        .get("model_id")
        .or_else(|| pose.get("detection_method"))
        .and_then(Value::as_str)
        .map(|s| truncate(s, 64).to_owned())
        .filter(|s| !s.is_empty())
        .unwrap_or_else(|| "external".into());
    let steady = pose.get("steady").and_then(Value::as_bool).unwrap_or(true);
    let mut out = ExternalDetections {
        timestamp_unix_s,
        frame_id,
        frame_timestamp_unix_s,
        model,
        steady,
        world: Vec::new(),
        vision: Vec::new(),
        bad_objects: Vec::new(),
    };
    for object in objects {
        if object.get("bbox").is_some() {
            match parse_vision_object(&object) {
                Ok(o) => out.vision.push(o),
                Err(e) => out.bad_objects.push(e),
            }
        } else {
            match serde_json::from_value::<DetectedObject>(object) {
                Ok(o) => match o.validate() {
                    Ok(()) => out.world.push(o),
                    Err(e) => out.bad_objects.push(Skip::Malformed {
                        field: "objects",
                        reason: e.to_string(),
                    }),
                },
                Err(e) => out.bad_objects.push(Skip::Malformed {
                    field: "objects",
                    reason: format!("neither a pixel box (bbox) nor a world object: {e}"),
                }),
            }
        }
    }
    Ok(out)
}

fn parse_vision_object(object: &Value) -> Result<VisionObject, Skip> {
    let bad = |reason: String| Skip::Malformed {
        field: "objects",
        reason,
    };
    let label = object
        .get("label")
        .or_else(|| object.get("class_name"))
        .and_then(Value::as_str)
        .map(str::trim)
        .filter(|l| !l.is_empty() && l.len() <= 100)
        .ok_or_else(|| bad("an object has no label (a string of 1-100 characters)".into()))?;
    let confidence = match object.get("confidence") {
        None | Some(Value::Null) => 1.0,
        Some(v) => v
            .as_f64()
            .filter(|c| (0.0..=1.0).contains(c))
            .ok_or_else(|| {
                bad(format!(
                    "'{label}': confidence must be a number from 0 to 1"
                ))
            })?,
    };
    let class_id = object.get("class_id").and_then(Value::as_i64).unwrap_or(-1);
    let b = object.get("bbox").unwrap_or(&Value::Null);
    let coord = |k: &str| {
        b.get(k)
            .and_then(Value::as_f64)
            .filter(|x| x.is_finite() && (0.0..=100_000.0).contains(x))
    };
    let (Some(x0), Some(y0), Some(x1), Some(y1)) = (
        coord("x_min"),
        coord("y_min"),
        coord("x_max"),
        coord("y_max"),
    ) else {
        return Err(bad(format!(
            "'{label}': bbox needs x_min, y_min, x_max, y_max as pixel numbers"
        )));
    };
    if x1 <= x0 || y1 <= y0 {
        return Err(bad(format!("'{label}': bbox is empty or inverted")));
    }
    let mask = if object.get("has_mask").and_then(Value::as_bool) == Some(true) {
        let shape = object
            .get("mask_shape")
            .and_then(Value::as_array)
            .filter(|a| a.len() == 2)
            .and_then(|a| Some((a[0].as_u64()? as usize, a[1].as_u64()? as usize)))
            .ok_or_else(|| bad(format!("'{label}': mask_shape must be [height, width]")))?;
        let (h, w) = shape;
        if h == 0 || w == 0 || h.saturating_mul(w) > MAX_MASK_PIXELS {
            return Err(bad(format!(
                "'{label}': mask of {h}x{w} pixels is empty or larger than {MAX_MASK_PIXELS}"
            )));
        }
        if let Some(dtype) = object.get("mask_dtype").and_then(Value::as_str) {
            if dtype != "uint8" && dtype != "bool" {
                return Err(bad(format!(
                    "'{label}': mask_dtype '{}' is not uint8",
                    truncate(dtype, 20)
                )));
            }
        }
        let data = object
            .get("mask_data")
            .and_then(Value::as_str)
            .ok_or_else(|| {
                bad(format!(
                    "'{label}': has_mask is true but mask_data is missing"
                ))
            })?;
        let bytes = base64::engine::general_purpose::STANDARD
            .decode(data.trim())
            .map_err(|e| bad(format!("'{label}': mask_data is not base64: {e}")))?;
        if bytes.len() != h * w {
            return Err(bad(format!(
                "'{label}': mask_data has {} bytes, mask_shape {h}x{w} needs {}",
                bytes.len(),
                h * w
            )));
        }
        Some((h, w, bytes))
    } else {
        None
    };
    Ok(VisionObject {
        label: label.to_lowercase(),
        confidence,
        class_id,
        bbox: [x0, y0, x1, y1],
        mask,
    })
}

/// Parses a `detectable_labels` entry: its lower-case labels (at most 1,000, each 1-100
/// characters).
pub fn parse_labels(fields: &Map<String, Value>) -> Result<Vec<String>, Skip> {
    let labels = json_field(fields, "labels")?;
    let Value::Array(items) = labels else {
        return Err(Skip::Malformed {
            field: "labels",
            reason: "not a JSON list".into(),
        });
    };
    if items.len() > 1000 {
        return Err(Skip::Malformed {
            field: "labels",
            reason: format!("{} labels; at most 1000 are taken", items.len()),
        });
    }
    let mut out = Vec::with_capacity(items.len());
    for item in items {
        let label = item
            .as_str()
            .map(|s| s.trim().to_lowercase())
            .filter(|s| !s.is_empty() && s.chars().count() <= 100)
            .ok_or_else(|| Skip::Malformed {
                field: "labels",
                reason: "every label must be a string of 1-100 characters".into(),
            })?;
        if !out.contains(&label) {
            out.push(label);
        }
    }
    Ok(out)
}

/// Scales a mask of `(h, w)` to the frame's `width × height` and lists the object's pixels
/// (indices `v × width + u`) inside the box.
pub fn mask_pixels(
    mask: &(usize, usize, Vec<u8>),
    bbox: [u32; 4],
    width: usize,
    height: usize,
) -> Vec<u32> {
    let (mh, mw, data) = mask;
    let [x0, y0, x1, y1] = bbox;
    let mut out = Vec::new();
    for v in y0 as usize..(y1 as usize).min(height) {
        let mv = v * mh / height;
        for u in x0 as usize..(x1 as usize).min(width) {
            let mu = u * mw / width;
            if data.get(mv * mw + mu).copied().unwrap_or(0) != 0 {
                out.push((v * width + u) as u32);
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fields(pairs: &[(&str, String)]) -> Map<String, Value> {
        pairs
            .iter()
            .map(|(k, v)| (k.to_string(), Value::String(v.clone())))
            .collect()
    }

    #[test]
    fn camera_entries_carry_the_fields_of_the_spec() {
        let meta = FrameMeta {
            frame_id: 42,
            timestamp_unix_s: 1700000000.5,
            size: (640, 480),
            workspace_id: "niryo_ws",
            robot_pose: Pose::new(0.17, 0.0, 0.28, 0.0, 1.57, 0.0),
        };
        let entry = camera_entry("me", &meta, &[0xff, 0xd8, 0xff], None);
        assert_eq!(entry.stream, ROBOT_CAMERA);
        let names: Vec<&str> = entry.fields.iter().map(|(k, _)| *k).collect();
        assert_eq!(
            names,
            [
                "timestamp",
                "image_data",
                "format",
                "width",
                "height",
                "channels",
                "dtype",
                "compressed_size",
                "original_size",
                "metadata",
                INSTANCE_FIELD
            ]
        );
        let get = |k: &str| {
            entry
                .fields
                .iter()
                .find(|(n, _)| *n == k)
                .unwrap()
                .1
                .clone()
        };
        assert_eq!(get("image_data"), "/9j/");
        assert_eq!(get("original_size"), "921600");
        assert_eq!(get("compressed_size"), "3");
        let metadata: Value = serde_json::from_str(&get("metadata")).unwrap();
        assert_eq!(metadata["frame_id"], 42);
        assert_eq!(metadata["image_source"], "robot_mounted_camera");
        assert_eq!(metadata["robot_pose"]["pitch"], 1.57);
        let annotated = camera_entry("me", &meta, &[1], Some((3, "robotd")));
        assert_eq!(annotated.stream, ANNOTATED_CAMERA);
        let metadata: Value = serde_json::from_str(
            &annotated
                .fields
                .iter()
                .find(|(n, _)| *n == "metadata")
                .unwrap()
                .1,
        )
        .unwrap();
        assert_eq!(metadata["annotated"], true);
        assert_eq!(metadata["detection_count"], 3);
    }

    #[test]
    fn vision_format_objects_are_read_with_their_masks() {
        let mask = base64::engine::general_purpose::STANDARD.encode([0u8, 1, 1, 0]);
        let objects = json!([{
            "label": "Red Cube", "confidence": 0.9, "class_id": 3,
            "bbox": {"x_min": 1, "y_min": 2, "x_max": 30, "y_max": 40},
            "has_mask": true, "mask_data": mask, "mask_shape": [2, 2], "mask_dtype": "uint8"
        }]);
        let f = fields(&[
            ("timestamp", "100.0".into()),
            ("objects", objects.to_string()),
            (
                "camera_pose",
                json!({"model_id": "owlv2", "frame_id": 7}).to_string(),
            ),
        ]);
        let d = parse_detections(&f, 100.5).unwrap();
        assert_eq!(d.frame_id, Some(7));
        assert_eq!(d.model, "owlv2");
        assert_eq!(d.vision[0].label, "red cube");
        assert_eq!(d.vision[0].mask.as_ref().unwrap().2, vec![0, 1, 1, 0]);
        let pixels = mask_pixels(d.vision[0].mask.as_ref().unwrap(), [0, 0, 4, 4], 4, 4);
        assert_eq!(pixels, vec![2, 3, 6, 7, 8, 9, 12, 13]);
    }

    #[test]
    fn stale_and_malformed_entries_say_why() {
        let f = fields(&[("timestamp", "1.0".into()), ("objects", "[]".into())]);
        assert!(matches!(
            parse_detections(&f, 10.0),
            Err(Skip::Stale { .. })
        ));
        let f = fields(&[("timestamp", "x".into()), ("objects", "[]".into())]);
        assert_eq!(
            parse_detections(&f, 1.0).unwrap_err().outcome(),
            "skipped_malformed"
        );
        let f = fields(&[("timestamp", "1.0".into())]);
        assert_eq!(
            parse_detections(&f, 1.0).unwrap_err(),
            Skip::Missing("objects")
        );
        let f = fields(&[("timestamp", "1.0".into()), ("objects", "{\"a\":".into())]);
        assert!(parse_detections(&f, 1.0).is_err());
        let objects = json!([{"label": "x", "bbox": {"x_min": 5, "y_min": 0, "x_max": 1, "y_max": 9}},
                             {"label": "y", "bbox": {"x_min": 0, "y_min": 0, "x_max": 1, "y_max": 9},
                              "has_mask": true, "mask_data": "AAAA", "mask_shape": [100000, 100000]},
                             {"nothing": true}]);
        let f = fields(&[
            ("timestamp", "1.0".into()),
            ("objects", objects.to_string()),
        ]);
        let d = parse_detections(&f, 1.0).unwrap();
        assert_eq!(d.bad_objects.len(), 3, "{:?}", d.bad_objects);
        assert!(d.vision.is_empty() && d.world.is_empty());
    }

    #[test]
    fn world_objects_from_another_robotd_round_trip() {
        let mut object = DetectedObject {
            label: "pencil".into(),
            confidence: 0.8,
            ..Default::default()
        };
        object.position.center_of_mass.x_m = 0.2;
        let detections = Detections {
            frame_id: 3,
            workspace_id: "niryo_ws".into(),
            timestamp_unix_ns: 5_000_000_000,
            source: "robotd".into(),
            steady: true,
            objects: vec![object],
        };
        let entry = detections_entry("a", &detections, &["obj-1".into()]);
        let f: Map<String, Value> = entry
            .fields
            .iter()
            .map(|(k, v)| (k.to_string(), Value::String(v.clone())))
            .collect();
        assert_eq!(writer(&f), Some("a"));
        let objects: Value = serde_json::from_str(f["objects"].as_str().unwrap()).unwrap();
        assert_eq!(objects[0]["id"], "obj-1");
        assert_eq!(objects[0]["class_name"], "pencil");
        let d = parse_detections(&f, 5.5).unwrap();
        assert_eq!(d.world.len(), 1);
        assert_eq!(d.world[0].workspace_id, "niryo_ws");
        assert_eq!(d.frame_id, Some(3));
    }

    #[test]
    fn labels_are_checked() {
        let f = fields(&[("labels", json!(["Screwdriver", "pen", "pen"]).to_string())]);
        assert_eq!(parse_labels(&f).unwrap(), ["screwdriver", "pen"]);
        let f = fields(&[("labels", json!(["ok", 3]).to_string())]);
        assert!(parse_labels(&f).is_err());
        let f = fields(&[("labels", "\"x\"".into())]);
        assert!(parse_labels(&f).is_err());
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(300))]
        /// Whatever is in the fields, the readers answer without panicking.
        #[test]
        fn readers_never_panic(
            timestamp in ".{0,20}",
            objects in ".{0,200}",
            pose in ".{0,80}",
            labels in ".{0,80}",
        ) {
            let f = fields(&[
                ("timestamp", timestamp),
                ("objects", objects),
                ("camera_pose", pose),
                ("labels", labels),
            ]);
            let _ = parse_detections(&f, 1e9);
            let _ = parse_labels(&f);
            let _ = check_size(&f, 10);
        }

        /// Well-formed JSON of the wrong shapes is refused, not trusted.
        #[test]
        fn json_of_wrong_shapes_never_panics(
            x0 in -1e6f64..1e6, y0 in -1e6f64..1e6, x1 in -1e6f64..1e6, y1 in -1e6f64..1e6,
            conf in -2.0f64..2.0, h in 0u64..5000, w in 0u64..5000, label in ".{0,120}",
        ) {
            let objects = json!([{
                "label": label, "confidence": conf,
                "bbox": {"x_min": x0, "y_min": y0, "x_max": x1, "y_max": y1},
                "has_mask": true, "mask_shape": [h, w], "mask_data": "AAAA"
            }, {"label": label, "position": {"center_of_mass": {"x": x0}}}]);
            let f = fields(&[("timestamp", "5".into()), ("objects", objects.to_string())]);
            let parsed = parse_detections(&f, 5.0).unwrap();
            for o in &parsed.vision {
                proptest::prop_assert!(o.bbox[0] < o.bbox[2] && o.bbox[1] < o.bbox[3]);
                proptest::prop_assert!((0.0..=1.0).contains(&o.confidence));
            }
        }
    }
}
