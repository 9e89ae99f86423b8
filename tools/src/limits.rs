//! The length limit of every string argument: in its schema (`maxLength`), and checked before
//! a tool runs.
//!
//! Each tool's argument struct states the limit of its strings
//! (`#[schemars(length(max = …))]`, the word schemas of [`crate::schema`]), so the limit a
//! client reads in `tools/list` is the one robotd applies. The names of objects
//! (`object_name`, `label`: [`LABEL_FIELDS`]) are labels, whose limit is the workspace model's
//! (`workspace.max_label_chars`, [`crate::ToolSettings::max_label_chars`]); the registry writes
//! it into the schemas it serves ([`apply_label_limit`]).
//!
//! A string longer than its schema's `maxLength` (counted in characters, as JSON Schema
//! counts) is a problem of the call's arguments like any other: listed in the contract's
//! validation text with the call's other problems, in pydantic's words for
//! `string_too_long`: `String should have at most 2000 characters` ([`too_long`]).

use crate::args::FieldError;
use serde_json::{Map, Value};

/// Arguments that name an object by its label: their limit is the label limit.
pub const LABEL_FIELDS: &[&str] = &["object_name", "label"];

/// The start of the message of a string over its limit (pydantic's `string_too_long`).
pub(crate) const STRING_TOO_LONG: &str = "String should have at most";

/// The message of a string over a limit of `max` characters.
fn too_long_message(max: u64) -> String {
    let s = if max == 1 { "" } else { "s" };
    format!("{STRING_TOO_LONG} {max} character{s}")
}

/// The `maxLength` of a string `property` schema, or of its string branch (`anyOf`).
pub fn max_length(property: &Value) -> Option<u64> {
    if let Some(max) = property["maxLength"].as_u64() {
        return Some(max);
    }
    property["anyOf"]
        .as_array()?
        .iter()
        .find_map(|branch| branch["maxLength"].as_u64())
}

/// Writes `max` as the `maxLength` of the label arguments ([`LABEL_FIELDS`]) of an input
/// `schema`.
pub(crate) fn apply_label_limit(schema: &mut Map<String, Value>, max: usize) {
    let Some(properties) = schema.get_mut("properties").and_then(Value::as_object_mut) else {
        return;
    };
    for field in LABEL_FIELDS {
        if let Some(Value::Object(property)) = properties.get_mut(*field) {
            property.insert("maxLength".into(), max.into());
        }
    }
}

/// The problems of the string `arguments` longer than their `maxLength` in the input
/// `schema`, in the schema's order.
pub(crate) fn too_long(
    schema: &Map<String, Value>,
    arguments: &Map<String, Value>,
) -> Vec<FieldError> {
    let Some(properties) = schema.get("properties").and_then(Value::as_object) else {
        return Vec::new();
    };
    properties
        .iter()
        .filter_map(|(name, property)| {
            let max = max_length(property)?;
            let text = arguments.get(name)?.as_str()?;
            (text.chars().count() as u64 > max).then(|| FieldError {
                field: name.clone(),
                message: too_long_message(max),
            })
        })
        .collect()
}

/// `problems` (a tool's, its fields in declaration order `fields`, unknown arguments last)
/// with the `too_long` ones: a field too long is reported as such, and every problem keeps
/// its field's place.
pub(crate) fn merge(
    problems: Vec<FieldError>,
    too_long: Vec<FieldError>,
    fields: &[&str],
) -> Vec<FieldError> {
    let base =
        |e: &FieldError| -> String { e.field.split('.').next().unwrap_or_default().to_owned() };
    let long: Vec<String> = too_long.iter().map(|e| e.field.clone()).collect();
    let mut all: Vec<FieldError> = problems
        .into_iter()
        .filter(|e| !long.contains(&base(e)))
        .chain(too_long)
        .collect();
    let place = |e: &FieldError| {
        let field = base(e);
        fields
            .iter()
            .position(|f| *f == field)
            .unwrap_or(usize::MAX)
    };
    // Stable: the unknown arguments keep their sorted order at the end.
    all.sort_by_key(place);
    all
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    fn schema() -> Map<String, Value> {
        let schema = json!({"type": "object", "properties": {
            "object_name": {"type": "string", "maxLength": 100},
            "direction": {"type": "string", "enum": ["up"], "maxLength": 4},
            "location": {"anyOf": [{"type": "string", "maxLength": 5}, {"type": "null"}]},
            "distance": {"type": "number"}
        }});
        schema.as_object().cloned().unwrap()
    }

    #[test]
    fn strings_over_their_limit_are_problems_in_the_schemas_order() {
        let arguments = json!({"location": "sideways", "direction": "up", "object_name": "x".repeat(101),
                               "distance": 5});
        let problems = too_long(&schema(), arguments.as_object().unwrap());
        assert_eq!(
            problems,
            vec![
                FieldError {
                    field: "object_name".into(),
                    message: "String should have at most 100 characters".into()
                },
                FieldError {
                    field: "location".into(),
                    message: "String should have at most 5 characters".into()
                },
            ]
        );
        // Characters, not bytes.
        let arguments = json!({"object_name": "é".repeat(100)});
        assert!(too_long(&schema(), arguments.as_object().unwrap()).is_empty());
    }

    #[test]
    fn the_label_limit_is_written_into_label_arguments() {
        let mut schema = schema();
        apply_label_limit(&mut schema, 40);
        assert_eq!(schema["properties"]["object_name"]["maxLength"], 40);
        assert_eq!(schema["properties"]["direction"]["maxLength"], 4);
    }

    #[test]
    fn a_long_field_replaces_its_other_problems_and_keeps_its_place() {
        let e = |field: &str, message: &str| FieldError {
            field: field.into(),
            message: message.into(),
        };
        let problems = vec![
            e("a", "Field required"),
            e("c", "Value error, Direction must be one of: up"),
            e("zz", "Extra inputs are not permitted"),
        ];
        let merged = merge(
            problems,
            vec![
                e("c", "String should have at most 4 characters"),
                e("b", "String should have at most 1 character"),
            ],
            &["a", "b", "c"],
        );
        let fields: Vec<&str> = merged.iter().map(|e| e.field.as_str()).collect();
        assert_eq!(fields, ["a", "b", "c", "zz"]);
        assert!(merged[2].message.starts_with(STRING_TOO_LONG));
        assert_eq!(
            too_long_message(1),
            "String should have at most 1 character"
        );
    }
}
