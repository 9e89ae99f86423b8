//! Detected objects: the world-frame description of what the camera sees.
//!
//! [`DetectedObject`] serialises to exactly the object JSON of `docs/mcp-tools.md` (the Python
//! server's format), so the MCP edge can print it, the Redis edge can publish it and Python
//! readers can parse it without a translation layer:
//!
//! ```text
//! {"id", "label", "workspace_id", "timestamp",
//!  "position": {"center_of_mass": {"x","y","z"}, "center": {"x","y","z"}},
//!  "image_coordinates": {"center_rel": {"u","v"}, "center_of_mass_rel": {"u","v"},
//!                        "bounding_box_rel": {"u_min","v_min","u_max","v_max"}},
//!  "dimensions": {"width_m", "height_m", "size_m2"},
//!  "gripper_rotation", "confidence", "class_id"}
//! ```
//!
//! Width is the extent along y, height the extent along x (metres). Ids are stable while an
//! object is tracked. The perception actor publishes [`Detections`] (`"perception.detections"`)
//! per processed frame.
//!
//! ```
//! use robotd_protocol::objects::DetectedObject;
//!
//! let mut obj = DetectedObject::default();
//! obj.label = "red cube".into();
//! assert!(obj.label_contains("CUBE"));
//! assert!(obj.label_is(" Red Cube "));
//! ```

use crate::envelope::Message;
use crate::geometry::{Point2, Point3};
use crate::validate::{finite, in_range, non_empty, Validate, ValidationError};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// A point in image coordinates, as fractions of the image width (`u`) and height (`v`),
/// origin top-left.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct RelPoint {
    /// Horizontal position, 0 = left edge, 1 = right edge.
    pub u: f64,
    /// Vertical position, 0 = top edge, 1 = bottom edge.
    pub v: f64,
}

/// An axis-aligned box in image coordinates, fractions of width and height.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct RelBox {
    /// Left edge.
    pub u_min: f64,
    /// Top edge.
    pub v_min: f64,
    /// Right edge.
    pub u_max: f64,
    /// Bottom edge.
    pub v_max: f64,
}

/// Where the object is in the base frame.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct ObjectPosition {
    /// Centre of mass of the object's mask, projected to the table (grip here), metres.
    pub center_of_mass: Point3,
    /// Centre of the bounding box, metres.
    pub center: Point3,
}

/// Where the object is in the image it was detected in.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct ImageCoordinates {
    /// Centre of the bounding box.
    pub center_rel: RelPoint,
    /// Centre of mass of the mask.
    pub center_of_mass_rel: RelPoint,
    /// Bounding box.
    pub bounding_box_rel: RelBox,
}

/// Size of the object on the table.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct Dimensions {
    /// Extent along y, metres.
    pub width_m: f64,
    /// Extent along x, metres.
    pub height_m: f64,
    /// Footprint area, square metres (used for largest/smallest/sorted).
    pub size_m2: f64,
}

/// One object the perception pipeline found, in the object JSON of the MCP tools.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct DetectedObject {
    /// Stable id while the object is tracked.
    pub id: String,
    /// Detector label, e.g. `"red cube"`.
    pub label: String,
    /// Workspace the object lies in.
    pub workspace_id: String,
    /// Detection time, seconds since the Unix epoch (fractional).
    #[serde(rename = "timestamp")]
    pub timestamp_unix_s: f64,
    /// Position in the base frame.
    pub position: ObjectPosition,
    /// Position in the image.
    pub image_coordinates: ImageCoordinates,
    /// Size on the table.
    pub dimensions: Dimensions,
    /// Yaw to rotate the gripper by to grasp across the object's narrow side, radians.
    #[serde(rename = "gripper_rotation")]
    pub gripper_rotation_rad: f64,
    /// Detector confidence, 0 … 1.
    pub confidence: f64,
    /// Detector class index.
    pub class_id: i64,
}

impl DetectedObject {
    /// Table-plane position of the centre of mass, the point tools compare coordinates to.
    pub fn xy(&self) -> Point2 {
        self.position.center_of_mass.xy()
    }

    /// Case-insensitive substring match, the label filter of the detection tools.
    pub fn label_contains(&self, filter: &str) -> bool {
        self.label
            .to_lowercase()
            .contains(&filter.trim().to_lowercase())
    }

    /// Case-insensitive exact match (surrounding whitespace ignored), how pick finds its object.
    pub fn label_is(&self, name: &str) -> bool {
        self.label.trim().to_lowercase() == name.trim().to_lowercase()
    }
}

impl Validate for DetectedObject {
    fn validate(&self) -> Result<(), ValidationError> {
        non_empty("label", &self.label)?;
        finite("timestamp", self.timestamp_unix_s)?;
        self.position
            .center_of_mass
            .validate()
            .map_err(|e| e.within("position.center_of_mass"))?;
        self.position
            .center
            .validate()
            .map_err(|e| e.within("position.center"))?;
        let ic = &self.image_coordinates;
        for (field, v) in [
            ("image_coordinates.center_rel.u", ic.center_rel.u),
            ("image_coordinates.center_rel.v", ic.center_rel.v),
            (
                "image_coordinates.center_of_mass_rel.u",
                ic.center_of_mass_rel.u,
            ),
            (
                "image_coordinates.center_of_mass_rel.v",
                ic.center_of_mass_rel.v,
            ),
            (
                "image_coordinates.bounding_box_rel.u_min",
                ic.bounding_box_rel.u_min,
            ),
            (
                "image_coordinates.bounding_box_rel.v_min",
                ic.bounding_box_rel.v_min,
            ),
            (
                "image_coordinates.bounding_box_rel.u_max",
                ic.bounding_box_rel.u_max,
            ),
            (
                "image_coordinates.bounding_box_rel.v_max",
                ic.bounding_box_rel.v_max,
            ),
        ] {
            finite(field, v)?;
        }
        for (field, v) in [
            ("dimensions.width_m", self.dimensions.width_m),
            ("dimensions.height_m", self.dimensions.height_m),
            ("dimensions.size_m2", self.dimensions.size_m2),
        ] {
            in_range(field, v, 0.0, f64::MAX)?;
        }
        finite("gripper_rotation", self.gripper_rotation_rad)?;
        in_range("confidence", self.confidence, 0.0, 1.0)
    }
}

/// The objects found in one camera frame.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct Detections {
    /// The frame they were detected in.
    pub frame_id: u64,
    /// Workspace in view; empty when no workspace sheet was found in the frame (then
    /// `objects` is empty too).
    pub workspace_id: String,
    /// Capture time of the frame, nanoseconds since the Unix epoch.
    pub timestamp_unix_ns: u64,
    /// Who detected them: `"robotd"` for the built-in detector, else the external detector's
    /// model id (so an edge does not feed its own detections back).
    pub source: String,
    /// True when the arm stood still while the frame was taken (a view the workspace model
    /// may trust); false for frames taken during a motion, which update nothing.
    #[serde(default)]
    pub steady: bool,
    /// The objects, in detector order.
    pub objects: Vec<DetectedObject>,
}

impl Validate for Detections {
    fn validate(&self) -> Result<(), ValidationError> {
        for (i, o) in self.objects.iter().enumerate() {
            o.validate()
                .map_err(|e| e.within(&format!("objects[{i}]")))?;
        }
        Ok(())
    }
}

impl Message for Detections {
    const TYPE: &'static str = "perception.detections";
}
