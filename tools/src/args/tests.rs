//! Tests of the argument readers and their pydantic-worded messages.

use super::*;
use robotd_protocol::{Direction, Location};
use serde_json::json;

fn map(v: Value) -> Map<String, Value> {
    v.as_object().cloned().unwrap()
}

/// `(field, message)` of each problem.
fn pairs(e: &[FieldError]) -> Vec<(&str, &str)> {
    e.iter()
        .map(|e| (e.field.as_str(), e.message.as_str()))
        .collect()
}

#[derive(Debug, Deserialize)]
#[allow(dead_code)] // Read through Debug in the assertions only.
struct Place {
    #[serde(deserialize_with = "text")]
    object_name: String,
    #[serde(deserialize_with = "point")]
    pick_coordinate: Point2,
    #[serde(deserialize_with = "point")]
    place_coordinate: Point2,
    #[serde(deserialize_with = "z_offset")]
    z_offset: f64,
    #[serde(deserialize_with = "opt_word")]
    location: Option<Location>,
}

#[test]
fn every_problem_is_reported_once_per_field_in_field_order() {
    let m = map(json!({
        "colour": "red",
        "location": "sideways",
        "z_offset": 0.5,
        "pick_coordinate": [0.1, 0.2, 0.3],
        "object_name": "",
    }));
    let errors = from_args::<Place>(&m).unwrap_err();
    assert_eq!(
        validation_text("pick_place_object", &errors),
        "❌ Validation Error in pick_place_object:\n  \
         • object_name: String should have at least 1 character\n  \
         • pick_coordinate: List should have at most 2 items after validation, not 3\n  \
         • place_coordinate: Field required\n  \
         • z_offset: Input should be less than or equal to 0.1\n  \
         • location: Value error, Invalid location 'sideways'. Must be one of: left next to, \
         right next to, above, below, on top of, inside, close to\n  \
         • colour: Extra inputs are not permitted"
    );
}

#[derive(Debug, Deserialize)]
struct Push {
    #[serde(deserialize_with = "text")]
    object_name: String,
    #[serde(deserialize_with = "point")]
    push_coordinate: Point2,
    #[serde(deserialize_with = "word")]
    direction: Direction,
    #[serde(deserialize_with = "distance")]
    distance: f64,
    #[serde(deserialize_with = "z_offset")]
    z_offset: f64,
    #[serde(deserialize_with = "opt_text")]
    label: Option<String>,
}

fn distance<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
    positive(d, 1000.0)
}

#[test]
fn good_arguments_pass_with_defaults_and_lenient_words() {
    let m = map(json!({
        "object_name": " pencil ",
        "push_coordinate": "[0.2, -0.05]",
        "direction": " Left",
        "distance": 50,
        "label": "  "
    }));
    let a = from_args::<Push>(&m).unwrap();
    assert_eq!(a.object_name, "pencil");
    assert_eq!(a.push_coordinate, Point2::new(0.2, -0.05));
    assert_eq!(a.direction, Direction::Left);
    assert_eq!(a.distance, 50.0);
    assert_eq!(a.z_offset, robotd_protocol::skills::DEFAULT_Z_OFFSET_M);
    assert_eq!(a.label, None);
}

#[test]
fn types_signs_nulls_and_items_are_checked() {
    let m = map(json!({
        "object_name": null, "push_coordinate": [0.1, "x"], "direction": 3,
        "distance": -5, "label": 7
    }));
    let e = from_args::<Push>(&m).unwrap_err();
    assert_eq!(
        pairs(&e),
        [
            ("object_name", "Input should be a valid string"),
            (
                "push_coordinate.1",
                "Input should be a valid number, unable to parse string as a number"
            ),
            ("direction", "Input should be a valid string"),
            ("distance", "Input should be greater than 0"),
            ("label", "Input should be a valid string"),
        ]
    );
    let m = map(json!({
        "object_name": "a", "push_coordinate": "[0.1,", "direction": "sideways",
        "distance": 1001, "z_offset": -0.01
    }));
    let e = from_args::<Push>(&m).unwrap_err();
    assert_eq!(
        pairs(&e),
        [
            ("push_coordinate", "Input should be a valid list"),
            (
                "direction",
                "Value error, Direction must be one of: up, down, left, right"
            ),
            ("distance", "Input should be less than or equal to 1000"),
            ("z_offset", "Input should be greater than or equal to 0"),
        ]
    );
    let m = map(json!({
        "object_name": "a", "push_coordinate": [null, {}], "direction": null,
        "distance": null, "z_offset": "0.05"
    }));
    let e = from_args::<Push>(&m).unwrap_err();
    assert_eq!(
        pairs(&e),
        [
            ("push_coordinate.0", "Input should be a valid number"),
            ("push_coordinate.1", "Input should be a valid number"),
            ("direction", "Input should be a valid string"),
            ("distance", "Input should be a valid number"),
            (
                "z_offset",
                "Input should be a valid number, unable to parse string as a number"
            ),
        ]
    );
    let e = from_args::<Push>(&map(json!({"z_offset": true}))).unwrap_err();
    assert_eq!(
        pairs(&e),
        [
            ("object_name", "Field required"),
            ("push_coordinate", "Field required"),
            ("direction", "Field required"),
            ("distance", "Field required"),
            ("z_offset", "Input should be a valid number"),
        ]
    );
}

#[derive(Debug, Deserialize)]
#[allow(dead_code)] // Read through Debug in the assertions only.
struct At {
    #[serde(deserialize_with = "point")]
    at: Point2,
}

/// The problem with `at` (one line per bad item).
fn at_problems(at: Value) -> Vec<(String, String)> {
    from_args::<At>(&map(json!({ "at": at })))
        .unwrap_err()
        .into_iter()
        .map(|e| (e.field, e.message))
        .collect()
}

#[test]
fn coordinates_are_checked_in_pydantics_order() {
    let one = |field: &str, message: &str| vec![(field.to_owned(), message.to_owned())];
    assert_eq!(
        at_problems(json!([0.1])),
        one(
            "at",
            "List should have at least 2 items after validation, not 1"
        )
    );
    assert_eq!(
        at_problems(json!("[]")),
        one(
            "at",
            "List should have at least 2 items after validation, not 0"
        )
    );
    // Too many items is found before the items are looked at; too few only after.
    assert_eq!(
        at_problems(json!(["x", "y", "z"])),
        one(
            "at",
            "List should have at most 2 items after validation, not 3"
        )
    );
    assert_eq!(
        at_problems(json!(["x"])),
        one(
            "at.0",
            "Input should be a valid number, unable to parse string as a number"
        )
    );
    assert_eq!(
        at_problems(json!(0.1)),
        one("at", "Input should be a valid list")
    );
    assert_eq!(
        at_problems(json!(null)),
        one("at", "Input should be a valid list")
    );
    assert_eq!(
        at_problems(json!([true, [1]])),
        vec![
            (
                "at.0".to_owned(),
                "Input should be a valid number".to_owned()
            ),
            (
                "at.1".to_owned(),
                "Input should be a valid number".to_owned()
            ),
        ]
    );
}

#[derive(Debug, Deserialize)]
struct PickPlace {
    #[serde(deserialize_with = "pick_place_location")]
    location: Option<Location>,
}

#[test]
fn pick_place_location_refuses_close_to_with_the_python_note() {
    let read = |v: Value| from_args::<PickPlace>(&map(json!({ "location": v })));
    assert_eq!(
        read(json!(" On Top Of")).unwrap().location,
        Some(Location::OnTopOf)
    );
    assert_eq!(read(json!(null)).unwrap().location, None);
    assert_eq!(from_args::<PickPlace>(&Map::new()).unwrap().location, None);
    let note = |word: &str| {
        format!(
            "Value error, Invalid location '{word}'. Must be one of: left next to, right next \
             to, above, below, on top of, inside. Note: 'close to' is not allowed for \
             pick_place_object."
        )
    };
    for word in ["close to", "Close To ", "beside"] {
        let e = read(json!(word)).unwrap_err();
        assert_eq!(pairs(&e), [("location", note(word).as_str())]);
    }
    let e = read(json!(3)).unwrap_err();
    assert_eq!(pairs(&e), [("location", "Input should be a valid string")]);
}

#[derive(Debug, Deserialize)]
struct Sorted {
    #[serde(deserialize_with = "ascending")]
    ascending: bool,
}

fn ascending<'de, D: Deserializer<'de>>(d: D) -> Result<bool, D::Error> {
    flag(d, true)
}

#[derive(Debug, Deserialize)]
struct Nothing {}

#[test]
fn flags_default_and_unknown_arguments_are_named() {
    assert!(from_args::<Sorted>(&Map::new()).unwrap().ascending);
    let e = from_args::<Sorted>(&map(json!({"ascending": "yes", "extra": 1}))).unwrap_err();
    assert_eq!(
        pairs(&e),
        [
            (
                "ascending",
                "Input should be a valid boolean, unable to interpret input"
            ),
            ("extra", "Extra inputs are not permitted"),
        ]
    );
    let ascending = |v: Value| {
        from_args::<Sorted>(&map(json!({ "ascending": v })))
            .unwrap_err()
            .remove(0)
            .message
    };
    assert_eq!(
        ascending(json!(2)),
        "Input should be a valid boolean, unable to interpret input"
    );
    assert_eq!(ascending(json!(0.5)), "Input should be a valid boolean");
    assert_eq!(ascending(json!([true])), "Input should be a valid boolean");
    let e = from_args::<Nothing>(&map(json!({"b": 1, "a": 2}))).unwrap_err();
    assert_eq!(
        pairs(&e),
        [
            ("a", "Extra inputs are not permitted"),
            ("b", "Extra inputs are not permitted"),
        ]
    );
    assert!(from_args::<Nothing>(&Map::new()).is_ok());
    assert_eq!(fields_of::<Sorted>(), ["ascending"]);
    assert!(fields_of::<Nothing>().is_empty());
}

#[derive(Debug, Deserialize)]
#[allow(dead_code)] // Never built: every pass fails.
struct Plain {
    count: u32,
}

#[test]
fn a_field_without_a_reader_still_ends_with_its_problem() {
    let e = from_args::<Plain>(&map(json!({"count": "many"}))).unwrap_err();
    assert_eq!(e.len(), 1);
    assert_eq!(e[0].field, "count");
    assert!(e[0].message.contains("invalid type"), "{e:?}");
    let e = from_args::<Plain>(&Map::new()).unwrap_err();
    assert_eq!(pairs(&e), [("count", "Field required")]);
}

#[test]
fn item_problems_survive_as_error_text() {
    let issue = |index: Option<usize>, message: &str| Issue {
        index,
        message: message.into(),
    };
    let items = Problem(vec![issue(Some(0), "bad x"), issue(Some(1), "bad y")]);
    assert_eq!(
        Problem::decode(&items.to_string()),
        [issue(Some(0), "bad x"), issue(Some(1), "bad y")]
    );
    assert_eq!(
        Problem::decode("[1]: must be x"),
        [issue(Some(1), "must be x")]
    );
    assert_eq!(Problem::decode("[x]: y"), [issue(None, "[x]: y")]);
    assert_eq!(Problem::decode("plain"), [issue(None, "plain")]);
    assert_eq!(
        Problem::decode("[0]: a\u{1e}b"),
        [issue(None, "[0]: a\u{1e}b")]
    );
}
