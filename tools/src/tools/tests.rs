//! Tests of the tool table as a whole: unique names, schemas that match what the
//! deserializer reads, arguments that arrive, and `tools/list` unchanged for clients (against
//! `tests/fixtures/tools_list.json`, captured from the hand-written schemas before the tools
//! became typed units).

use super::*;
use serde_json::json;
use std::collections::HashSet;

fn props(entry: &Entry) -> Map<String, Value> {
    (entry.input_schema)()["properties"]
        .as_object()
        .cloned()
        .unwrap_or_default()
}

#[test]
fn the_python_servers_twenty_tools_then_robotds_four_with_unique_names() {
    assert_eq!(TOOLS.len(), 24);
    assert_eq!(TOOLS[19].name, "set_user_task");
    assert_eq!(TOOLS[20].name, "emergency_stop");
    assert_eq!(TOOLS[21].name, "release_emergency_stop");
    assert_eq!(TOOLS[22].name, "get_camera_image");
    assert_eq!(TOOLS[23].name, "label_object");
    let names: HashSet<&str> = TOOLS.iter().map(|t| t.name).collect();
    assert_eq!(names.len(), TOOLS.len(), "a tool name is used twice");
    for t in TOOLS {
        assert_eq!(find(t.name).map(|f| f.name), Some(t.name));
    }
    assert!(find("pick_place_objects").is_none());
}

#[test]
fn every_schema_property_is_an_argument_the_deserializer_reads_and_back() {
    for t in TOOLS {
        let schema: Vec<String> = props(t).keys().cloned().collect();
        let read: Vec<String> = (t.fields)().iter().map(|f| f.to_string()).collect();
        assert_eq!(
            schema, read,
            "{}: schema properties vs deserialized fields",
            t.name
        );
    }
}

/// A valid value for a property, chosen so that it differs from any default and shows in the
/// argument struct's `Debug`; and that text, when there is one to look for.
fn sample(name: &str, schema: &Value) -> (Value, Option<String>) {
    let words = schema["enum"]
        .as_array()
        .or_else(|| schema["anyOf"][0]["enum"].as_array());
    if let Some(words) = words {
        return (words[1].clone(), None);
    }
    let ty = match &schema["type"] {
        Value::Array(types) => types[0].as_str().unwrap_or_default().to_owned(),
        other => other.as_str().unwrap_or_default().to_owned(),
    };
    match ty.as_str() {
        "string" => (json!(format!("v_{name}")), Some(format!("v_{name}"))),
        "array" => (json!([0.0123, -0.0456]), Some("-0.0456".into())),
        "boolean" => (json!(false), Some("false".into())),
        "number" => {
            let max = schema["maximum"].as_f64().unwrap_or(1.0);
            let v = max * 0.37;
            (json!(v), Some(format!("{v}")))
        }
        "integer" => {
            let (min, max) = (schema["minimum"].as_u64(), schema["maximum"].as_u64());
            let v = (min.unwrap_or(0) + max.unwrap_or(10)) / 2 + 1;
            (json!(v), Some(format!("{v}")))
        }
        other => panic!("{name}: no sample for type {other:?}"),
    }
}

#[test]
fn an_argument_object_with_every_field_set_arrives_whole() {
    for t in TOOLS {
        let mut args = Map::new();
        let mut expect = Vec::new();
        for (name, schema) in props(t) {
            let (value, shows) = sample(&name, &schema);
            args.insert(name.clone(), value);
            expect.extend(shows.map(|s| (name, s)));
        }
        let parsed = (t.parse)(&args).unwrap_or_else(|e| panic!("{}: {e:?}", t.name));
        for (name, shows) in expect {
            assert!(
                parsed.contains(&format!("{name}: ")) && parsed.contains(&shows),
                "{}: {name} = {shows} did not arrive: {parsed}",
                t.name
            );
        }
    }
}

#[test]
fn unknown_and_renamed_arguments_are_refused_by_every_tool() {
    // Except a request to stop, which acts whatever it is sent (below).
    for t in TOOLS
        .iter()
        .filter(|t| !crate::ALWAYS_ACTS.contains(&t.name))
    {
        let mut args = Map::new();
        for (name, schema) in props(t) {
            args.insert(name.clone(), sample(&name, &schema).0);
        }
        let renamed = match args.keys().next().cloned() {
            Some(first) => {
                let v = args.remove(&first).unwrap_or_default();
                args.insert(format!("{first}s"), v);
                format!("{first}s")
            }
            None => {
                args.insert("extra".into(), json!(1));
                "extra".into()
            }
        };
        let errors = (t.parse)(&args).unwrap_err();
        let unknown = errors.iter().find(|e| e.field == renamed);
        let message = unknown.map(|e| e.message.as_str()).unwrap_or_default();
        assert_eq!(
            message, "Extra inputs are not permitted",
            "{}: {errors:?}",
            t.name
        );
    }
}

#[test]
fn emergency_stop_reads_any_arguments_and_keeps_what_was_wrong() {
    let stop = find("emergency_stop").unwrap();
    let read = |args: Value| (stop.parse)(args.as_object().unwrap()).unwrap();
    assert_eq!(
        read(json!({"reason": " smoke "})),
        "Args { reason: Some(\"smoke\"), problems: [] }"
    );
    assert_eq!(read(json!({})), "Args { reason: None, problems: [] }");
    let bad_reason = read(json!({"reason": 5}));
    assert!(
        bad_reason.contains("reason: None")
            && bad_reason.contains("argument 'reason': Input should be a valid string (got 5)"),
        "{bad_reason}"
    );
    let extra = read(json!({"reason": "smoke", "colour": "red"}));
    assert!(
        extra.contains("reason: Some(\"smoke\")")
            && extra.contains("argument 'colour': Extra inputs are not permitted"),
        "{extra}"
    );
    let mut wrapped = Map::new();
    wrapped.insert(crate::ARGUMENTS_NOT_AN_OBJECT.into(), json!([1, "x"]));
    let not_an_object = (stop.parse)(&wrapped).unwrap();
    assert!(
        not_an_object.contains("the arguments must be an object")
            && not_an_object.contains("[1,\\\"x\\\"]"),
        "{not_an_object}"
    );
    // Any other tool refuses the wrapper like any unknown argument.
    let speak = (find("speak").unwrap().parse)(&wrapped).unwrap_err();
    assert!(
        speak
            .iter()
            .any(|e| e.field == crate::ARGUMENTS_NOT_AN_OBJECT),
        "{speak:?}"
    );
}

#[test]
fn pick_place_object_reads_what_its_handler_uses() {
    let args = json!({
        "object_name": " pencil ", "pick_coordinate": "[0.2, -0.05]",
        "place_coordinate": [0.25, 0.1], "location": "Right Next To", "z_offset": 0.02
    });
    let parsed = (find("pick_place_object").unwrap().parse)(args.as_object().unwrap()).unwrap();
    assert_eq!(
        parsed,
        "Args { object_name: \"pencil\", pick_coordinate: Point2 { x_m: 0.2, y_m: -0.05 }, \
         place_coordinate: Point2 { x_m: 0.25, y_m: 0.1 }, location: Some(RightNextTo), z_offset: 0.02 }"
    );
}

fn fixture() -> Vec<Value> {
    let text = include_str!("../../tests/fixtures/tools_list.json");
    serde_json::from_str(text).expect("the fixture is JSON")
}

/// `schema` without `maxLength`s (robotd added one to every string, issue 43) and the
/// description that names the new one, to compare with what the fixture recorded before.
fn without_max_lengths(schema: &Value) -> Value {
    let mut schema = schema.clone();
    fn strip(v: &mut Value) {
        match v {
            Value::Object(map) => {
                map.remove("maxLength");
                map.values_mut().for_each(strip);
            }
            Value::Array(items) => items.iter_mut().for_each(strip),
            _ => {}
        }
    }
    strip(&mut schema);
    if let Some(task) = schema.pointer_mut("/properties/task/description") {
        *task = json!("The user's task, shown over the video.");
    }
    schema
}

#[test]
fn names_descriptions_and_input_schemas_are_unchanged() {
    // The fixture holds the Python server's 20 tools; robotd's own follow them. The
    // `maxLength`s of the strings are new (every string argument says its limit).
    let old = fixture();
    let new = crate::definitions::all();
    assert_eq!(old.len(), 20);
    assert_eq!(new.len(), 24);
    for (old, new) in old.iter().zip(&new) {
        assert_eq!(old["name"], new.name);
        assert_eq!(old["description"], new.description, "{}", new.name);
        assert_eq!(old["moves_arm"], new.moves_arm, "{}", new.name);
        assert_eq!(
            without_max_lengths(&old["inputSchema"]),
            without_max_lengths(&Value::Object(new.input_schema.clone())),
            "{}",
            new.name
        );
    }
}

/// The string schemas in a property's schema: itself, or its `anyOf` branches.
fn string_branches(schema: &Value) -> Vec<&Value> {
    let is_string = |s: &Value| {
        s["type"] == "string"
            || s["type"]
                .as_array()
                .is_some_and(|t| t.contains(&json!("string")))
    };
    match schema["anyOf"].as_array() {
        Some(any) => any.iter().filter(|s| is_string(s)).collect(),
        None => [schema].into_iter().filter(|s| is_string(s)).collect(),
    }
}

#[test]
fn every_string_argument_says_its_limit_and_a_longer_one_is_refused_for_it() {
    let mut strings = 0;
    for t in TOOLS {
        let schema = (t.input_schema)();
        for (name, property) in props(t) {
            for branch in string_branches(&property) {
                strings += 1;
                let max = branch["maxLength"]
                    .as_u64()
                    .unwrap_or_else(|| panic!("{}.{name} has no maxLength: {property}", t.name));
                let mut args = Map::new();
                args.insert(name.clone(), json!("x".repeat(max as usize + 1)));
                let problems = crate::limits::too_long(&schema, &args);
                assert_eq!(
                    problems
                        .iter()
                        .map(|e| e.field.as_str())
                        .collect::<Vec<_>>(),
                    [name.as_str()],
                    "{}",
                    t.name
                );
                args.insert(name.clone(), json!("x".repeat(max as usize)));
                assert!(
                    crate::limits::too_long(&schema, &args).is_empty(),
                    "{}.{name}",
                    t.name
                );
            }
        }
    }
    assert!(strings >= 20, "only {strings} string arguments found");
}

/// The JSON types a schema allows (`None` = any).
fn types(schema: &Value) -> Option<HashSet<String>> {
    if let Some(any) = schema["anyOf"].as_array() {
        let mut all = HashSet::new();
        for s in any {
            all.extend(types(s)?);
        }
        return Some(all);
    }
    match &schema["type"] {
        Value::String(t) => Some(HashSet::from([t.clone()])),
        Value::Array(ts) => Some(
            ts.iter()
                .filter_map(|t| t.as_str().map(String::from))
                .collect(),
        ),
        _ => None,
    }
}

/// Whether every value the old schema described by name and type is still described alike
/// (the new one may say more: formats, required fields, descriptions).
fn compatible(path: &str, old: &Value, new: &Value) -> Result<(), String> {
    let (old_types, new_types) = (types(old), types(new));
    if let (Some(o), Some(n)) = (&old_types, &new_types) {
        let lost: Vec<_> = o
            .iter()
            .filter(|t| !(n.contains(*t) || t.as_str() == "number" && n.contains("integer")))
            .collect();
        if !lost.is_empty() {
            return Err(format!("{path}: types {o:?} became {n:?}"));
        }
    } else if old_types.is_some() && new_types.is_none() && !new.is_object() {
        return Err(format!("{path}: type lost"));
    }
    // Compare like with like: the non-null branch of an `anyOf`.
    let branch = |s: &Value| -> Value {
        match s["anyOf"].as_array() {
            Some(any) => any
                .iter()
                .find(|b| b["type"] != "null")
                .cloned()
                .unwrap_or(Value::Null),
            None => s.clone(),
        }
    };
    let (old, new) = (branch(old), branch(new));
    if let Some(props) = old["properties"].as_object() {
        for (name, o) in props {
            let n = &new["properties"][name];
            if n.is_null() {
                return Err(format!("{path}.{name}: missing"));
            }
            compatible(&format!("{path}.{name}"), o, n)?;
        }
    }
    if old["items"].is_object() {
        compatible(&format!("{path}[]"), &old["items"], &new["items"])?;
    }
    for required in old["required"].as_array().into_iter().flatten() {
        let listed = new["required"].as_array().into_iter().flatten();
        if !listed.clone().any(|r| r == required) {
            return Err(format!("{path}: {required} no longer required"));
        }
    }
    Ok(())
}

#[test]
fn output_schemas_describe_the_same_data_as_before() {
    for (old, new) in fixture().iter().zip(crate::definitions::all()) {
        let new_schema = Value::Object(new.output_schema.clone());
        if let Err(e) = compatible(new.name, &old["outputSchema"], &new_schema) {
            panic!("{e}\nold: {}\nnew: {new_schema}", old["outputSchema"]);
        }
    }
}

#[test]
fn the_comparison_notices_a_changed_output() {
    let old = json!({"type": "object", "properties": {"labels": {"type": "array", "items": {"type": "string"}}}});
    let renamed = json!({"type": "object", "properties": {"label": {"type": "array"}}});
    let retyped = json!({"type": "object", "properties": {"labels": {"type": "array", "items": {"type": "number"}}}});
    assert!(compatible("t", &old, &old).is_ok());
    assert!(compatible("t", &old, &renamed).is_err());
    assert!(compatible("t", &old, &retyped).is_err());
}
