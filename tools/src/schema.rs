//! JSON Schemas of the tools, derived with schemars from the Rust types the tools read and
//! return, plus the schema pieces several tools share.
//!
//! - [`input_schema`] turns a tool's argument struct into its `inputSchema`: inlined, no
//!   title, `additionalProperties: false` (robotd refuses unknown arguments anyway).
//! - [`output_schema`] wraps a tool's data type as `{"result": <text>, "data": <data or
//!   null>}`, the shape of every tool's `structuredContent`.
//! - The word schemas (`location`, `direction`, `point`) list the accepted words of the
//!   protocol's enums; the argument structs attach them with `#[schemars(schema_with = …)]`.
//! - Every string argument has a `maxLength` (the argument structs say it with
//!   `#[schemars(length(max = …))]`, the word schemas [`MAX_WORD_CHARS`]); `crate::limits`
//!   checks it.
//! - [`ObjectJson`] describes the object JSON of the contract: robotd's
//!   [`DetectedObject`](robotd_protocol::objects::DetectedObject) has no schema of its own, so
//!   fields holding one borrow this one (`#[schemars(with = "ObjectJson")]`); a test proves
//!   the two serialise alike.

use robotd_protocol::{Direction, Location, WorkspacePoint};
use schemars::{JsonSchema, Schema, SchemaGenerator};
use serde::{Deserialize, Serialize};
use serde_json::{json, Map, Value};

fn generator() -> SchemaGenerator {
    schemars::generate::SchemaSettings::draft2020_12()
        .with(|s| {
            s.inline_subschemas = true;
            s.meta_schema = None;
        })
        .into_generator()
}

fn object_of(schema: Schema) -> Map<String, Value> {
    match schema.to_value() {
        Value::Object(map) => map,
        _ => Map::new(),
    }
}

/// The `inputSchema` of a tool whose arguments are `T`.
pub fn input_schema<T: JsonSchema>() -> Map<String, Value> {
    let mut map = object_of(generator().into_root_schema_for::<T>());
    map.remove("title");
    map.remove("description");
    map.insert("type".into(), "object".into());
    map.entry("properties").or_insert_with(|| json!({}));
    map.insert("additionalProperties".into(), false.into());
    map
}

/// The `outputSchema` of a tool whose `structuredContent.data` is a `T` (or `null`).
pub fn output_schema<T: JsonSchema>() -> Map<String, Value> {
    let mut data = object_of(generator().into_root_schema_for::<T>());
    data.remove("title");
    let schema = json!({
        "type": "object",
        "properties": {
            "result": {"type": "string", "description": "The reply text (starts with ✓ or ❌)."},
            "data": {"anyOf": [data, {"type": "null"}], "description": "Machine-readable payload; null on failure."}
        },
        "required": ["result", "data"],
        // fastmcp clients read `result.data`; for the Python server it is the reply text. This
        // mark (fastmcp's own, for wrapped results) makes `result.data` the text here too,
        // while `structuredContent.data` keeps the objects.
        "x-fastmcp-wrap-result": true
    });
    match schema {
        Value::Object(map) => map,
        _ => Map::new(),
    }
}

/// Longest string a word argument takes: its longest word and some room for the surrounding
/// whitespace robotd ignores.
pub const MAX_WORD_CHARS: usize = 32;

fn words_schema(words: &[&str], description: &str) -> Schema {
    let v = json!({"type": "string", "enum": words, "maxLength": MAX_WORD_CHARS, "description": description});
    Schema::try_from(v).unwrap_or_default()
}

/// `location`: a word of [`Location`] or `null`, `none` by default.
pub fn location_schema(_: &mut SchemaGenerator) -> Schema {
    let v = json!({
        "anyOf": [
            {"type": "string", "enum": Location::STRINGS, "maxLength": MAX_WORD_CHARS},
            {"type": "null"}
        ],
        "default": null,
        "description": "Spatial relation to the reference: 'left next to' (+y), 'right next to' (−y), \
                        'above' (+x, away from the robot), 'below' (−x), 'on top of', 'inside', \
                        'close to', or 'none'/null. Matched case-insensitively."
    });
    Schema::try_from(v).unwrap_or_default()
}

/// `direction`: a word of [`Direction`].
pub fn direction_schema(_: &mut SchemaGenerator) -> Schema {
    words_schema(
        Direction::STRINGS,
        "'up' (+x, away from the robot), 'down' (−x), 'left' (+y), 'right' (−y).",
    )
}

/// `point`: a word of [`WorkspacePoint`].
pub fn point_schema(_: &mut SchemaGenerator) -> Schema {
    words_schema(
        WorkspacePoint::STRINGS,
        "Which corner of the workspace, or its centre.",
    )
}

/// A point in the base frame, metres.
#[derive(Debug, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Xyz {
    /// Forward.
    pub x: f64,
    /// Left.
    pub y: f64,
    /// Up.
    pub z: f64,
}

/// A point in the image, fractions of its width (`u`) and height (`v`).
#[derive(Debug, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Uv {
    /// From the left edge.
    pub u: f64,
    /// From the top edge.
    pub v: f64,
}

/// An axis-aligned box in the image, fractions of width and height.
#[derive(Debug, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct UvBox {
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
#[derive(Debug, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct PositionJson {
    /// Centre of mass of its mask on the table (grip here).
    pub center_of_mass: Xyz,
    /// Centre of its bounding box.
    pub center: Xyz,
}

/// Where the object is in the image it was seen in.
#[derive(Debug, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ImageJson {
    /// Centre of the bounding box.
    pub center_rel: Uv,
    /// Centre of mass of the mask.
    pub center_of_mass_rel: Uv,
    /// Bounding box.
    pub bounding_box_rel: UvBox,
}

/// Size of the object on the table.
#[derive(Debug, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct DimensionsJson {
    /// Extent along y, metres.
    pub width_m: f64,
    /// Extent along x, metres.
    pub height_m: f64,
    /// Footprint area, square metres.
    pub size_m2: f64,
}

/// One object the camera sees (the contract's object JSON).
#[derive(Debug, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ObjectJson {
    /// Stable id while the object is tracked.
    pub id: String,
    /// Detector label, e.g. "red cube".
    pub label: String,
    /// Workspace the object lies in.
    pub workspace_id: String,
    /// Detection time, seconds since the Unix epoch.
    pub timestamp: f64,
    /// Position in the base frame.
    pub position: PositionJson,
    /// Position in the image.
    pub image_coordinates: ImageJson,
    /// Size on the table.
    pub dimensions: DimensionsJson,
    /// Yaw to rotate the gripper by to grasp across the object's narrow side, radians.
    pub gripper_rotation: f64,
    /// Detector confidence, 0 … 1.
    pub confidence: f64,
    /// Detector class index.
    pub class_id: i64,
}

#[cfg(test)]
mod tests {
    use super::*;
    use robotd_protocol::objects::DetectedObject;

    #[test]
    fn object_json_is_the_shape_a_detected_object_serialises_to() {
        let object = DetectedObject {
            label: "pencil".into(),
            class_id: 3,
            ..DetectedObject::default()
        };
        let wire = serde_json::to_value(&object).unwrap();
        // deny_unknown_fields: every key of the wire form is in the schema's type …
        let mirror: ObjectJson = serde_json::from_value(wire.clone()).unwrap();
        // … and every key of the schema's type is in the wire form, with the same values.
        assert_eq!(serde_json::to_value(&mirror).unwrap(), wire);
    }

    #[test]
    fn output_schemas_wrap_the_data_type() {
        let out = output_schema::<Uv>();
        assert_eq!(out["required"], json!(["result", "data"]));
        let data = &out["properties"]["data"]["anyOf"];
        assert_eq!(data[0]["required"], json!(["u", "v"]));
        assert_eq!(data[1], json!({"type": "null"}));
    }
}
