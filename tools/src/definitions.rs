//! The 20 tools as clients see them: name, description, input schema (derived with schemars
//! from the typed parameter structs below) and output schema.
//!
//! The parameter structs are the single description of each tool's arguments: their schema
//! is what `tools/list` shows, and the handlers in [`crate::handlers`] read exactly these
//! fields through [`crate::args::Args`] (which also checks what a schema cannot make a client
//! obey). Every output schema is `{"result": <text>, "data": <typed payload or null>}`.

use robotd_protocol::{Direction, Location, WorkspacePoint};
use schemars::{JsonSchema, Schema, SchemaGenerator};
use serde_json::{json, Map, Value};

/// A tool as listed to clients.
#[derive(Debug, Clone)]
pub struct ToolInfo {
    /// The tool's name, e.g. `pick_place_object`.
    pub name: &'static str,
    /// What it does and how to call it, for people and LLMs.
    pub description: &'static str,
    /// JSON Schema of the arguments.
    pub input_schema: Map<String, Value>,
    /// JSON Schema of `structuredContent`.
    pub output_schema: Map<String, Value>,
    /// Whether the tool moves the arm (long-running, cancellable, reports progress).
    pub moves_arm: bool,
}

fn words_schema(words: &[&str], description: &str) -> Schema {
    let v = json!({"type": "string", "enum": words, "description": description});
    Schema::try_from(v).unwrap_or_default()
}

fn location_schema(_: &mut SchemaGenerator) -> Schema {
    let mut words = Location::STRINGS.to_vec();
    words.retain(|w| *w != "none");
    let v = json!({
        "anyOf": [
            {"type": "string", "enum": Location::STRINGS},
            {"type": "null"}
        ],
        "default": null,
        "description": "Spatial relation to the reference: 'left next to' (+y), 'right next to' (−y), \
                        'above' (+x, away from the robot), 'below' (−x), 'on top of', 'inside', \
                        'close to', or 'none'/null. Matched case-insensitively."
    });
    Schema::try_from(v).unwrap_or_default()
}

fn direction_schema(_: &mut SchemaGenerator) -> Schema {
    words_schema(
        Direction::STRINGS,
        "'up' (+x, away from the robot), 'down' (−x), 'left' (+y), 'right' (−y).",
    )
}

fn point_schema(_: &mut SchemaGenerator) -> Schema {
    words_schema(
        WorkspacePoint::STRINGS,
        "Which corner of the workspace, or its centre.",
    )
}

/// `pick_place_object`
#[derive(JsonSchema)]
#[allow(dead_code)]
pub struct PickPlaceObject {
    /// Label of the object to pick, exactly as detected (case-insensitive), e.g. "pencil".
    #[schemars(length(min = 1))]
    pub object_name: String,
    /// [x, y] of the object in metres (robot base frame: x forward, y left).
    pub pick_coordinate: [f64; 2],
    /// [x, y] where to place it, or of the reference object when `location` is given.
    pub place_coordinate: [f64; 2],
    #[schemars(schema_with = "location_schema", default)]
    pub location: Option<String>,
    /// Height above the object's centre of mass at which to close the gripper, metres.
    #[schemars(range(min = 0.0, max = 0.1), extend("default" = 0.001))]
    pub z_offset: Option<f64>,
}

/// `pick_object`
#[derive(JsonSchema)]
#[allow(dead_code)]
pub struct PickObject {
    /// Label of the object to pick (case-insensitive exact match).
    #[schemars(length(min = 1))]
    pub object_name: String,
    /// [x, y] of the object in metres.
    pub pick_coordinate: [f64; 2],
    /// Height above the object's centre of mass at which to close the gripper, metres.
    #[schemars(range(min = 0.0, max = 0.1), extend("default" = 0.001))]
    pub z_offset: Option<f64>,
}

/// `place_object`
#[derive(JsonSchema)]
#[allow(dead_code)]
pub struct PlaceObject {
    /// [x, y] where to place the held object, or of the reference object when `location` is given.
    pub place_coordinate: [f64; 2],
    #[schemars(schema_with = "location_schema", default)]
    pub location: Option<String>,
}

/// `push_object`
#[derive(JsonSchema)]
#[allow(dead_code)]
pub struct PushObject {
    /// Label of the object to push (case-insensitive exact match).
    #[schemars(length(min = 1))]
    pub object_name: String,
    /// [x, y] of the object in metres.
    pub push_coordinate: [f64; 2],
    #[schemars(schema_with = "direction_schema")]
    pub direction: String,
    /// How far to push, in MILLIMETRES.
    #[schemars(extend("exclusiveMinimum" = 0, "maximum" = 500))]
    pub distance: f64,
}

/// `move2by`
#[derive(JsonSchema)]
#[allow(dead_code)]
pub struct Move2By {
    /// Label of the object to move (case-insensitive exact match).
    #[schemars(length(min = 1))]
    pub object_name: String,
    /// [x, y] of the object in metres.
    pub pick_coordinate: [f64; 2],
    #[schemars(schema_with = "direction_schema")]
    pub direction: String,
    /// How far to move it, in METRES.
    #[schemars(extend("exclusiveMinimum" = 0, "maximum" = 0.5))]
    pub distance: f64,
    /// Height above the object's centre of mass at which to close the gripper, metres.
    #[schemars(range(min = 0.0, max = 0.1), extend("default" = 0.001))]
    pub z_offset: Option<f64>,
}

/// `move2observation_pose`, `get_workspace_coordinate_from_point`
#[derive(JsonSchema)]
#[allow(dead_code)]
pub struct WorkspaceId {
    /// Workspace id, e.g. "niryo_ws".
    #[schemars(length(min = 1))]
    pub workspace_id: String,
}

/// `get_workspace_coordinate_from_point`
#[derive(JsonSchema)]
#[allow(dead_code)]
pub struct WorkspaceCoordinate {
    /// Workspace id, e.g. "niryo_ws".
    #[schemars(length(min = 1))]
    pub workspace_id: String,
    #[schemars(schema_with = "point_schema")]
    pub point: String,
}

/// `get_detected_objects`
#[derive(JsonSchema)]
#[allow(dead_code)]
pub struct DetectedObjects {
    #[schemars(schema_with = "location_schema", default)]
    pub location: Option<String>,
    /// Reference [x, y] of the location filter, metres; required unless location is none.
    pub coordinate: Option<[f64; 2]>,
    /// Keep only objects whose label contains this text (case-insensitive).
    pub label: Option<String>,
}

/// `get_detected_object`
#[derive(JsonSchema)]
#[allow(dead_code)]
pub struct DetectedObject {
    /// [x, y] to look at, metres; objects within 2 cm count.
    pub coordinate: [f64; 2],
    /// Keep only objects whose label contains this text (case-insensitive).
    pub label: Option<String>,
}

/// `get_detected_objects_sorted`
#[derive(JsonSchema)]
#[allow(dead_code)]
pub struct Sorted {
    /// Smallest first when true (the default), largest first when false.
    #[schemars(extend("default" = true))]
    pub ascending: Option<bool>,
}

/// `add_object_name2object_labels`
#[derive(JsonSchema)]
#[allow(dead_code)]
pub struct ObjectName {
    /// The new label, e.g. "screwdriver" (stored lower-case).
    #[schemars(length(min = 1))]
    pub object_name: String,
}

/// `speak`
#[derive(JsonSchema)]
#[allow(dead_code)]
pub struct Speak {
    /// What to say (at most 2000 characters).
    #[schemars(length(min = 1, max = 2000))]
    pub text: String,
}

/// `set_user_task`
#[derive(JsonSchema)]
#[allow(dead_code)]
pub struct UserTask {
    /// The user's task, shown over the video.
    #[schemars(length(min = 1))]
    pub task: String,
}

/// A tool without arguments.
#[derive(JsonSchema)]
pub struct NoArguments {}

fn input_schema<T: JsonSchema>() -> Map<String, Value> {
    let settings = schemars::generate::SchemaSettings::draft2020_12().with(|s| {
        s.inline_subschemas = true;
        s.meta_schema = None;
    });
    let schema = settings.into_generator().into_root_schema_for::<T>();
    let mut map = match schema.to_value() {
        Value::Object(map) => map,
        _ => Map::new(),
    };
    map.remove("title");
    map.remove("description");
    map.insert("type".into(), "object".into());
    map.entry("properties").or_insert_with(|| json!({}));
    map.insert("additionalProperties".into(), false.into());
    map
}

/// The shape of an object in replies (the contract's object JSON).
fn object_schema() -> Value {
    let xyz = json!({"type": "object", "properties": {"x": {"type": "number"}, "y": {"type": "number"}, "z": {"type": "number"}}});
    let uv =
        json!({"type": "object", "properties": {"u": {"type": "number"}, "v": {"type": "number"}}});
    json!({
        "type": "object",
        "properties": {
            "id": {"type": "string"},
            "label": {"type": "string"},
            "workspace_id": {"type": "string"},
            "timestamp": {"type": "number"},
            "position": {"type": "object", "properties": {"center_of_mass": xyz, "center": xyz}},
            "image_coordinates": {"type": "object", "properties": {
                "center_rel": uv, "center_of_mass_rel": uv, "bounding_box_rel": {"type": "object"}}},
            "dimensions": {"type": "object", "properties": {
                "width_m": {"type": "number"}, "height_m": {"type": "number"}, "size_m2": {"type": "number"}}},
            "gripper_rotation": {"type": "number"},
            "confidence": {"type": "number"},
            "class_id": {"type": "integer"}
        },
        "required": ["id", "label", "position", "dimensions"]
    })
}

fn point_out() -> Value {
    json!({"type": "array", "items": {"type": "number"}, "minItems": 2, "maxItems": 2})
}

fn output_schema(data: Value) -> Map<String, Value> {
    let schema = json!({
        "type": "object",
        "properties": {
            "result": {"type": "string", "description": "The reply text (starts with ✓ or ❌)."},
            "data": {"anyOf": [data, {"type": "null"}], "description": "Machine-readable payload; null on failure."}
        },
        "required": ["result", "data"]
    });
    match schema {
        Value::Object(map) => map,
        _ => Map::new(),
    }
}

fn motion_data() -> Value {
    json!({
        "type": "object",
        "properties": {
            "object": {"anyOf": [object_schema(), {"type": "null"}]},
            "from": {"anyOf": [point_out(), {"type": "null"}]},
            "to": {"anyOf": [point_out(), {"type": "null"}]}
        }
    })
}

fn objects_data() -> Value {
    json!({"type": "array", "items": object_schema()})
}

fn object_data() -> Value {
    object_schema()
}

fn tool(
    name: &'static str,
    description: &'static str,
    input: Map<String, Value>,
    data: Value,
    moves_arm: bool,
) -> ToolInfo {
    ToolInfo {
        name,
        description,
        input_schema: input,
        output_schema: output_schema(data),
        moves_arm,
    }
}

/// Every tool, in the order of the contract.
pub fn all() -> Vec<ToolInfo> {
    let empty = json!({"type": "object"});
    vec![
        tool(
            "pick_place_object",
            "Pick up an object and place it somewhere else in one motion. The object is the one \
             labelled object_name nearest pick_coordinate (within 5 cm). Without a location it is \
             put exactly at place_coordinate; with a location it is put relative to the object \
             nearest place_coordinate (e.g. 'right next to' it, 'on top of' it). Coordinates are \
             [x, y] in metres in the robot base frame: x forward (away from the robot), y left. \
             Targets outside the workspace or out of reach are refused before anything moves.",
            input_schema::<PickPlaceObject>(),
            motion_data(),
            true,
        ),
        tool(
            "pick_object",
            "Pick up the object labelled object_name nearest pick_coordinate ([x, y] metres, within \
             5 cm) and hold it. Reports failure when the gripper does not really hold it.",
            input_schema::<PickObject>(),
            motion_data(),
            true,
        ),
        tool(
            "place_object",
            "Place the object the gripper holds at place_coordinate ([x, y] metres), or relative to \
             the object nearest it when location is given.",
            input_schema::<PlaceObject>(),
            motion_data(),
            true,
        ),
        tool(
            "push_object",
            "Push an object that is too wide to grip: the gripper starts just behind it and moves \
             distance MILLIMETRES in direction (up = +x away from the robot, down = −x, left = +y, \
             right = −y).",
            input_schema::<PushObject>(),
            motion_data(),
            true,
        ),
        tool(
            "move2by",
            "Pick up an object and put it down distance METRES away in direction (up = +x, down = \
             −x, left = +y, right = −y).",
            input_schema::<Move2By>(),
            motion_data(),
            true,
        ),
        tool(
            "move2observation_pose",
            "Move the arm to the observation pose of a workspace, from where the camera sees the \
             whole workspace.",
            input_schema::<WorkspaceId>(),
            json!({"type": "object", "properties": {"workspace_id": {"type": "string"}}}),
            true,
        ),
        tool(
            "clear_collision_detected",
            "Clear the arm's collision-detected flag so that it can move again.",
            input_schema::<NoArguments>(),
            empty.clone(),
            false,
        ),
        tool(
            "calibrate",
            "Calibrate the arm's joints (needed after power-up on a real Ned2).",
            input_schema::<NoArguments>(),
            empty.clone(),
            true,
        ),
        tool(
            "get_detected_objects",
            "List the objects the camera sees now, optionally filtered by a location relative to a \
             coordinate ('left next to' = larger y, 'right next to' = smaller y, 'above' = larger \
             x, 'below' = smaller x, 'close to' = within 2 cm) and by a label substring. Each \
             object has a stable id, its position in metres and its size.",
            input_schema::<DetectedObjects>(),
            objects_data(),
            false,
        ),
        tool(
            "get_detected_object",
            "The object nearest coordinate ([x, y] metres), within 2 cm, optionally filtered by a \
             label substring.",
            input_schema::<DetectedObject>(),
            object_data(),
            false,
        ),
        tool(
            "get_largest_detected_object",
            "The largest object the camera sees (by footprint area).",
            input_schema::<NoArguments>(),
            object_data(),
            false,
        ),
        tool(
            "get_smallest_detected_object",
            "The smallest object the camera sees (by footprint area).",
            input_schema::<NoArguments>(),
            object_data(),
            false,
        ),
        tool(
            "get_detected_objects_sorted",
            "Every object the camera sees, sorted by footprint area (smallest first unless \
             ascending is false).",
            input_schema::<Sorted>(),
            objects_data(),
            false,
        ),
        tool(
            "get_largest_free_space_with_center",
            "The largest empty rectangle of the workspace: its area in m² and its centre [x, y], a \
             good place to put something down.",
            input_schema::<NoArguments>(),
            json!({"type": "object", "properties": {"area_m2": {"type": "number"}, "center": point_out()}}),
            false,
        ),
        tool(
            "get_workspace_coordinate_from_point",
            "The [x, y] coordinate of a workspace corner ('upper left corner' = far left, 'lower \
             right corner' = near right, …) or of its 'center point'.",
            input_schema::<WorkspaceCoordinate>(),
            json!({"type": "object", "properties": {"workspace_id": {"type": "string"}, "point": {"type": "string"}, "coordinate": point_out()}}),
            false,
        ),
        tool(
            "get_object_labels_as_string",
            "The labels of the objects robotd can recognise.",
            input_schema::<NoArguments>(),
            json!({"type": "object", "properties": {"labels": {"type": "array", "items": {"type": "string"}}}}),
            false,
        ),
        tool(
            "add_object_name2object_labels",
            "Add a label to the list of recognisable objects (stored lower-case).",
            input_schema::<ObjectName>(),
            json!({"type": "object", "properties": {"label": {"type": "string"}, "already_known": {"type": "boolean"}}}),
            false,
        ),
        tool(
            "get_system_status",
            "The robot's id, current workspace and tool pose, the health and restart counts of \
             robotd's actors and the emergency-stop state.",
            input_schema::<NoArguments>(),
            json!({"type": "object"}),
            false,
        ),
        tool(
            "speak",
            "Say a text through the robot's speaker. Returns at once; speech is queued.",
            input_schema::<Speak>(),
            json!({"type": "object", "properties": {"text": {"type": "string"}}}),
            false,
        ),
        tool(
            "set_user_task",
            "Show the user's current task over the camera video.",
            input_schema::<UserTask>(),
            json!({"type": "object", "properties": {"task": {"type": "string"}}}),
            false,
        ),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn twenty_tools_with_strict_schemas() {
        let tools = all();
        assert_eq!(tools.len(), 20);
        let ppo = &tools[0];
        assert_eq!(ppo.name, "pick_place_object");
        let props = ppo.input_schema["properties"].as_object().unwrap();
        assert_eq!(props["pick_coordinate"]["minItems"], 2);
        assert_eq!(props["pick_coordinate"]["maxItems"], 2);
        assert_eq!(props["object_name"]["minLength"], 1);
        assert_eq!(props["z_offset"]["maximum"], 0.1);
        let required = ppo.input_schema["required"].as_array().unwrap();
        assert!(required.contains(&json!("object_name")));
        assert!(!required.contains(&json!("location")));
        let push = tools.iter().find(|t| t.name == "push_object").unwrap();
        let dir = &push.input_schema["properties"]["direction"];
        assert_eq!(dir["enum"], json!(["up", "down", "left", "right"]));
        let calibrate = tools.iter().find(|t| t.name == "calibrate").unwrap();
        assert_eq!(calibrate.input_schema["type"], "object");
        assert!(calibrate.output_schema["properties"]["result"].is_object());
        let mut names: Vec<_> = tools.iter().map(|t| t.name).collect();
        names.dedup();
        assert_eq!(names.len(), 20);
    }
}
