//! Tool arguments: real serde deserialization that still lists every problem at once.
//!
//! MCP SDKs pass a tool's arguments through unchecked (the input schema is advice to the
//! client, not enforced), so robotd checks them itself. Each tool declares one argument
//! struct; `#[derive(JsonSchema)]` on it is what `tools/list` shows, and `#[derive(Deserialize)]`
//! on the *same* struct is how a call's arguments become the values its handler reads. So a
//! field cannot be listed without being read, or renamed in one place only.
//!
//! Plain serde stops at the first bad field; the contract wants every problem:
//!
//! ```text
//! ❌ Validation Error in <tool>:
//!   • <field>: <message>
//! ```
//!
//! [`from_args`] gets there with its own [`Deserializer`]. It hands the struct every field it
//! declares (absent ones too, so "is required" comes from the field's reader, not serde), in
//! declaration order. The field readers below (`#[serde(deserialize_with = "…")]`) word the
//! contract's messages. When a field is bad, the pass ends with that field's error; the field
//! is then *poisoned* — on the next pass its reader returns a placeholder without looking —
//! and deserialization runs again until it completes. The placeholders never leave this
//! module: any problem means the caller gets the list of problems, not the struct. Arguments
//! the struct does not declare are problems too (listed last, sorted).
//!
//! Enum-like words are matched case-insensitively with surrounding whitespace ignored, as the
//! contract asks; a coordinate written as the JSON text `"[0.2, 0.1]"` (some LLMs do that) is
//! accepted like the array itself.
//!
//! ```
//! use robotd_tools::args::{from_args, text, validation_text};
//!
//! #[derive(serde::Deserialize)]
//! struct Args {
//!     #[serde(deserialize_with = "text")]
//!     object_name: String,
//! }
//! let map = serde_json::json!({"object_name": " pencil "});
//! let args: Args = from_args(map.as_object().unwrap()).unwrap();
//! assert_eq!(args.object_name, "pencil");
//!
//! let map = serde_json::json!({"object_name": "", "colour": "red"});
//! let errors = from_args::<Args>(map.as_object().unwrap()).err().unwrap();
//! assert_eq!(
//!     validation_text("pick_object", &errors),
//!     "❌ Validation Error in pick_object:\n  \
//!      • object_name: must be a non-empty string\n  \
//!      • colour: unknown argument; expected object_name"
//! );
//! ```

use robotd_protocol::{ParseEnumError, Point2};
use serde::de::{self, DeserializeOwned, DeserializeSeed, Deserializer, MapAccess, Visitor};
use serde::Deserialize;
use serde_json::{Map, Value};
use std::cell::Cell;
use std::fmt;
use std::str::FromStr;

/// One problem with one argument.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct FieldError {
    /// The argument's name (`pick_coordinate[1]` for one item of a coordinate).
    pub field: String,
    /// What is wrong with it.
    pub message: String,
}

/// Formats problems as the contract's validation error text.
pub fn validation_text(tool: &str, errors: &[FieldError]) -> String {
    let mut text = format!("❌ Validation Error in {tool}:");
    for e in errors {
        text.push_str(&format!("\n  • {}: {}", e.field, e.message));
    }
    text
}

/// Deserializes a call's arguments into `T`, or lists every problem with them.
///
/// `T` is a struct whose fields all use the readers of this module (`deserialize_with`).
pub fn from_args<T: DeserializeOwned>(args: &Map<String, Value>) -> Result<T, Vec<FieldError>> {
    let fields = Cell::new(None);
    let mut poisoned: Vec<&'static str> = Vec::new();
    let mut errors = Vec::new();
    let mut value = None;
    // Each pass either completes or poisons one more field, so this ends; the bound is a
    // second guarantee against a field type that fails even when poisoned.
    for _ in 0..=args.len() + 64 {
        let de = ArgsDe {
            map: args,
            poisoned: &poisoned,
            fields: &fields,
        };
        match T::deserialize(de) {
            Ok(v) => {
                value = Some(v);
                break;
            }
            Err(ArgError {
                field: Some(field),
                index,
                message,
            }) if !poisoned.contains(&field) => {
                let name = match index {
                    Some(i) => format!("{field}[{i}]"),
                    None => field.to_owned(),
                };
                errors.push(FieldError {
                    field: name,
                    message,
                });
                poisoned.push(field);
            }
            // Not a field's problem, or a poisoned field failing again: stop here; the
            // problems found so far (or this one) are the answer.
            Err(other) => {
                if errors.is_empty() {
                    errors.push(FieldError {
                        field: "arguments".into(),
                        message: format!("could not be read: {}", other.message),
                    });
                }
                break;
            }
        }
    }
    let known = fields.get().unwrap_or(&[]);
    let mut unknown: Vec<&String> = args
        .keys()
        .filter(|k| !known.contains(&k.as_str()))
        .collect();
    unknown.sort();
    for key in unknown {
        let message = if known.is_empty() {
            "this tool takes no arguments".to_owned()
        } else {
            format!("unknown argument; expected {}", known.join(", "))
        };
        errors.push(FieldError {
            field: key.clone(),
            message,
        });
    }
    match value {
        Some(v) if errors.is_empty() => Ok(v),
        _ if !errors.is_empty() => Err(errors),
        _ => Err(vec![FieldError {
            field: "arguments".into(),
            message: "could not be read".into(),
        }]),
    }
}

/// The argument names `T` reads, in declaration order (what `from_args` accepts).
pub fn fields_of<T: DeserializeOwned>() -> &'static [&'static str] {
    let fields = Cell::new(None);
    let empty = Map::new();
    let _ = T::deserialize(ArgsDe {
        map: &empty,
        poisoned: &[],
        fields: &fields,
    });
    fields.get().unwrap_or(&[])
}

// ---------------------------------------------------------------------------------------
// The deserializer

/// Why one pass stopped: a problem with a field, or something else (`field` = `None`).
#[derive(Debug)]
struct ArgError {
    field: Option<&'static str>,
    index: Option<usize>,
    message: String,
}

impl fmt::Display for ArgError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.message)
    }
}

impl std::error::Error for ArgError {}

impl de::Error for ArgError {
    fn custom<T: fmt::Display>(msg: T) -> Self {
        let (index, message) = Problem::decode(&msg.to_string());
        ArgError {
            field: None,
            index,
            message,
        }
    }
}

/// The argument object, offering each declared field in turn.
struct ArgsDe<'a> {
    map: &'a Map<String, Value>,
    poisoned: &'a [&'static str],
    fields: &'a Cell<Option<&'static [&'static str]>>,
}

impl<'de> Deserializer<'de> for ArgsDe<'_> {
    type Error = ArgError;

    fn deserialize_struct<V: Visitor<'de>>(
        self,
        _name: &'static str,
        fields: &'static [&'static str],
        visitor: V,
    ) -> Result<V::Value, ArgError> {
        self.fields.set(Some(fields));
        visitor.visit_map(Fields {
            map: self.map,
            poisoned: self.poisoned,
            fields,
            next: 0,
        })
    }

    fn deserialize_any<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, ArgError> {
        self.deserialize_struct("", &[], visitor)
    }

    serde::forward_to_deserialize_any! {
        bool i8 i16 i32 i64 i128 u8 u16 u32 u64 u128 f32 f64 char str string bytes byte_buf
        option unit unit_struct newtype_struct seq tuple tuple_struct map enum identifier
        ignored_any
    }
}

struct Fields<'a> {
    map: &'a Map<String, Value>,
    poisoned: &'a [&'static str],
    fields: &'static [&'static str],
    next: usize,
}

impl<'de> MapAccess<'de> for Fields<'_> {
    type Error = ArgError;

    fn next_key_seed<K: DeserializeSeed<'de>>(
        &mut self,
        seed: K,
    ) -> Result<Option<K::Value>, ArgError> {
        match self.fields.get(self.next) {
            None => Ok(None),
            Some(field) => seed
                .deserialize(de::value::StrDeserializer::<ArgError>::new(field))
                .map(Some),
        }
    }

    fn next_value_seed<S: DeserializeSeed<'de>>(&mut self, seed: S) -> Result<S::Value, ArgError> {
        let Some(&field) = self.fields.get(self.next) else {
            return Err(de::Error::custom(
                "a value was asked for past the last field",
            ));
        };
        self.next += 1;
        let slot = if self.poisoned.contains(&field) {
            Slot::Poisoned
        } else {
            match self.map.get(field) {
                None => Slot::Absent,
                Some(v) => Slot::Present(v),
            }
        };
        seed.deserialize(slot).map_err(|mut e| {
            e.field = Some(field);
            e
        })
    }
}

/// One field's value as the field's reader sees it.
enum Slot<'a> {
    /// Not in the arguments.
    Absent,
    /// Given (possibly `null`).
    Present(&'a Value),
    /// Already reported bad: the reader returns a placeholder.
    Poisoned,
}

impl<'de> Deserializer<'de> for Slot<'_> {
    type Error = ArgError;

    /// The readers' protocol: absent → `visit_none`, given → `visit_some` (even `null`),
    /// poisoned → `visit_unit`.
    fn deserialize_option<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, ArgError> {
        match self {
            Slot::Absent => visitor.visit_none(),
            Slot::Present(v) => visitor.visit_some(v.clone()).map_err(de::Error::custom),
            Slot::Poisoned => visitor.visit_unit(),
        }
    }

    /// Fields without a reader of this module get the plain JSON value.
    fn deserialize_any<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, ArgError> {
        match self {
            Slot::Absent => Err(Problem::new("is required").into_error()),
            Slot::Present(v) => v
                .clone()
                .deserialize_any(visitor)
                .map_err(de::Error::custom),
            Slot::Poisoned => visitor.visit_unit(),
        }
    }

    serde::forward_to_deserialize_any! {
        bool i8 i16 i32 i64 i128 u8 u16 u32 u64 u128 f32 f64 char str string bytes byte_buf
        unit unit_struct newtype_struct seq tuple tuple_struct map struct enum identifier
        ignored_any
    }
}

// ---------------------------------------------------------------------------------------
// Field readers

/// A problem found by a reader: its message, and which item of a list it is about.
///
/// It crosses serde as an error's text, `"[i]: message"` for an item, so that any
/// deserializer can carry it; [`ArgError`] reads the index back.
struct Problem {
    index: Option<usize>,
    message: String,
}

impl Problem {
    fn new(message: impl Into<String>) -> Self {
        Self {
            index: None,
            message: message.into(),
        }
    }

    fn decode(text: &str) -> (Option<usize>, String) {
        let item = text
            .strip_prefix('[')
            .and_then(|rest| rest.split_once("]: "))
            .and_then(|(i, message)| Some((i.parse::<usize>().ok()?, message)));
        match item {
            Some((i, message)) => (Some(i), message.to_owned()),
            None => (None, text.to_owned()),
        }
    }

    fn into_error<E: de::Error>(self) -> E {
        E::custom(self)
    }
}

impl fmt::Display for Problem {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.index {
            Some(i) => write!(f, "[{i}]: {}", self.message),
            None => f.write_str(&self.message),
        }
    }
}

/// What a reader was given.
enum Raw {
    Absent,
    Present(Value),
    Poisoned,
}

struct RawVisitor;

impl<'de> Visitor<'de> for RawVisitor {
    type Value = Raw;

    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("any JSON value")
    }

    fn visit_none<E: de::Error>(self) -> Result<Raw, E> {
        Ok(Raw::Absent)
    }

    fn visit_unit<E: de::Error>(self) -> Result<Raw, E> {
        Ok(Raw::Poisoned)
    }

    fn visit_some<D: Deserializer<'de>>(self, d: D) -> Result<Raw, D::Error> {
        Value::deserialize(d).map(Raw::Present)
    }
}

/// Runs `check` on the field's value (`None` = absent or `null`), or gives `placeholder` for
/// a poisoned field.
fn read<'de, D: Deserializer<'de>, T>(
    d: D,
    placeholder: T,
    check: impl FnOnce(Option<&Value>, bool) -> Result<T, Problem>,
) -> Result<T, D::Error> {
    match d.deserialize_option(RawVisitor)? {
        Raw::Poisoned => Ok(placeholder),
        Raw::Absent => check(None, false),
        Raw::Present(Value::Null) => check(None, true),
        Raw::Present(v) => check(Some(&v), false),
    }
    .map_err(Problem::into_error)
}

fn kind_of(v: &Value) -> &'static str {
    match v {
        Value::Null => "null",
        Value::Bool(_) => "a boolean",
        Value::Number(_) => "a number",
        Value::String(_) => "a string",
        Value::Array(_) => "an array",
        Value::Object(_) => "an object",
    }
}

fn missing(got_null: bool) -> Problem {
    Problem::new(if got_null {
        "is required (got null)"
    } else {
        "is required"
    })
}

fn text_of(v: &Value) -> Result<String, Problem> {
    match v {
        Value::String(s) if s.trim().is_empty() => Err(Problem::new("must be a non-empty string")),
        Value::String(s) => Ok(s.trim().to_owned()),
        other => Err(Problem::new(format!(
            "must be a string, got {}",
            kind_of(other)
        ))),
    }
}

fn point_of(v: &Value) -> Result<Point2, Problem> {
    let parsed;
    let v = match v {
        Value::String(s) if s.trim_start().starts_with('[') => {
            parsed = serde_json::from_str::<Value>(s)
                .map_err(|_| Problem::new("must be a list of two numbers [x, y]"))?;
            &parsed
        }
        v => v,
    };
    let Value::Array(items) = v else {
        return Err(Problem::new(format!(
            "must be a list of two numbers [x, y], got {}",
            kind_of(v)
        )));
    };
    if items.len() != 2 {
        return Err(Problem::new(format!(
            "must have exactly 2 items [x, y], got {} item{}",
            items.len(),
            if items.len() == 1 { "" } else { "s" }
        )));
    }
    let mut xy = [0.0; 2];
    for (i, item) in items.iter().enumerate() {
        xy[i] = number_of(item).map_err(|mut p| {
            p.index = Some(i);
            p
        })?;
    }
    Ok(Point2::new(xy[0], xy[1]))
}

fn number_of(v: &Value) -> Result<f64, Problem> {
    match v.as_f64() {
        Some(n) if n.is_finite() => Ok(n),
        _ => Err(Problem::new(format!(
            "must be a finite number, got {}",
            kind_of(v)
        ))),
    }
}

/// Reader of a required string of at least one non-blank character, trimmed.
pub fn text<'de, D: Deserializer<'de>>(d: D) -> Result<String, D::Error> {
    read(d, String::new(), |v, null| match v {
        None => Err(missing(null)),
        Some(v) => text_of(v),
    })
}

/// Reader of an optional string (absent or `null` → `None`); a blank one counts as absent.
pub fn opt_text<'de, D: Deserializer<'de>>(d: D) -> Result<Option<String>, D::Error> {
    read(d, None, |v, _| match v {
        None => Ok(None),
        Some(Value::String(s)) if s.trim().is_empty() => Ok(None),
        Some(v) => text_of(v).map(Some),
    })
}

/// Reader of a required `[x, y]` coordinate in metres.
pub fn point<'de, D: Deserializer<'de>>(d: D) -> Result<Point2, D::Error> {
    read(d, Point2::new(0.0, 0.0), |v, null| match v {
        None => Err(missing(null)),
        Some(v) => point_of(v),
    })
}

/// Reader of an optional `[x, y]` coordinate.
pub fn opt_point<'de, D: Deserializer<'de>>(d: D) -> Result<Option<Point2>, D::Error> {
    read(d, None, |v, _| v.map(point_of).transpose())
}

/// Reader of a required word of an enum (case-insensitive, trimmed), e.g. a `Direction`.
pub fn word<'de, D, T>(d: D) -> Result<T, D::Error>
where
    D: Deserializer<'de>,
    T: FromStr<Err = ParseEnumError> + Placeholder,
{
    read(d, T::placeholder(), |v, null| match v {
        None => Err(missing(null)),
        Some(v) => word_of(v),
    })
}

/// Reader of an optional word of an enum (absent or `null` → `None`), e.g. a `Location`.
pub fn opt_word<'de, D, T>(d: D) -> Result<Option<T>, D::Error>
where
    D: Deserializer<'de>,
    T: FromStr<Err = ParseEnumError>,
{
    read(d, None, |v, _| v.map(word_of).transpose())
}

fn word_of<T: FromStr<Err = ParseEnumError>>(v: &Value) -> Result<T, Problem> {
    let Value::String(s) = v else {
        return Err(Problem::new(format!(
            "must be a string, got {}",
            kind_of(v)
        )));
    };
    s.parse::<T>().map_err(|e| Problem::new(e.to_string()))
}

/// A value a poisoned field of this type holds until the problems are reported.
pub trait Placeholder {
    /// Any value; it is never used.
    fn placeholder() -> Self;
}

impl Placeholder for robotd_protocol::Direction {
    fn placeholder() -> Self {
        robotd_protocol::Direction::Up
    }
}

/// A number in `[min, max]`, `default` when absent (for a reader of one field).
pub fn number_in<'de, D: Deserializer<'de>>(
    d: D,
    default: f64,
    min: f64,
    max: f64,
) -> Result<f64, D::Error> {
    read(d, default, |v, _| {
        let Some(v) = v else { return Ok(default) };
        let n = number_of(v)?;
        if !(min..=max).contains(&n) {
            return Err(Problem::new(format!(
                "must be between {min} and {max}, got {n}"
            )));
        }
        Ok(n)
    })
}

/// A required number greater than 0 and at most `max` (for a reader of one field).
pub fn positive<'de, D: Deserializer<'de>>(d: D, max: f64) -> Result<f64, D::Error> {
    read(d, max, |v, null| {
        let Some(v) = v else {
            return Err(missing(null));
        };
        let n = number_of(v)?;
        if n <= 0.0 {
            return Err(Problem::new(format!("must be greater than 0, got {n}")));
        }
        if n > max {
            return Err(Problem::new(format!("must be at most {max}, got {n}")));
        }
        Ok(n)
    })
}

/// A boolean, `default` when absent (for a reader of one field).
pub fn flag<'de, D: Deserializer<'de>>(d: D, default: bool) -> Result<bool, D::Error> {
    read(d, default, |v, _| match v {
        None => Ok(default),
        Some(Value::Bool(b)) => Ok(*b),
        Some(other) => Err(Problem::new(format!(
            "must be true or false, got {}",
            kind_of(other)
        ))),
    })
}

/// Reader of `z_offset`: height above the object's centre of mass at which to grip, metres,
/// in `[0, 0.1]`, [`DEFAULT_Z_OFFSET_M`](robotd_protocol::skills::DEFAULT_Z_OFFSET_M) when
/// absent.
pub fn z_offset<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
    number_in(d, robotd_protocol::skills::DEFAULT_Z_OFFSET_M, 0.0, 0.1)
}

#[cfg(test)]
mod tests {
    use super::*;
    use robotd_protocol::{Direction, Location};
    use serde_json::json;

    fn map(v: Value) -> Map<String, Value> {
        v.as_object().cloned().unwrap()
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
             • object_name: must be a non-empty string\n  \
             • pick_coordinate: must have exactly 2 items [x, y], got 3 items\n  \
             • place_coordinate: is required\n  \
             • z_offset: must be between 0 and 0.1, got 0.5\n  \
             • location: unknown location 'sideways'; valid values: 'left next to', 'right next to', \
             'above', 'below', 'on top of', 'inside', 'close to', 'none'\n  \
             • colour: unknown argument; expected object_name, pick_coordinate, \
             place_coordinate, z_offset, location"
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
        let got: Vec<(&str, &str)> = e
            .iter()
            .map(|e| (e.field.as_str(), e.message.as_str()))
            .collect();
        assert_eq!(
            got,
            [
                ("object_name", "is required (got null)"),
                (
                    "push_coordinate[1]",
                    "must be a finite number, got a string"
                ),
                ("direction", "must be a string, got a number"),
                ("distance", "must be greater than 0, got -5"),
                ("label", "must be a string, got a number"),
            ]
        );
        let m = map(
            json!({"object_name": "a", "push_coordinate": "[0.1,", "direction": "up",
                           "distance": 1001}),
        );
        let e = from_args::<Push>(&m).unwrap_err();
        assert_eq!(e[0].message, "must be a list of two numbers [x, y]");
        assert_eq!(e[1].message, "must be at most 1000, got 1001");
        assert_eq!(e.len(), 2);
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
        assert_eq!(e[0].message, "must be true or false, got a string");
        assert_eq!(
            (e[1].field.as_str(), e[1].message.as_str()),
            ("extra", "unknown argument; expected ascending")
        );
        let e = from_args::<Nothing>(&map(json!({"b": 1, "a": 2}))).unwrap_err();
        assert_eq!(e[0].field, "a");
        assert_eq!(e[1].message, "this tool takes no arguments");
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
        assert_eq!(
            (e[0].field.as_str(), e[0].message.as_str()),
            ("count", "is required")
        );
    }

    #[test]
    fn item_problems_survive_as_error_text() {
        assert_eq!(
            Problem::decode("[1]: must be x"),
            (Some(1), "must be x".into())
        );
        assert_eq!(Problem::decode("[x]: y"), (None, "[x]: y".into()));
        assert_eq!(Problem::decode("plain"), (None, "plain".into()));
    }
}
