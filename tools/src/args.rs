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
//! declares (absent ones too, so "Field required" comes from the field's reader, not serde),
//! in declaration order. The field readers below (`#[serde(deserialize_with = "…")]`) word the
//! contract's messages. When a field is bad, the pass ends with that field's error; the field
//! is then *poisoned* — on the next pass its reader returns a placeholder without looking —
//! and deserialization runs again until it completes. The placeholders never leave this
//! module: any problem means the caller gets the list of problems, not the struct. Arguments
//! the struct does not declare are problems too (listed last, sorted).
//!
//! The messages are the Python server's, which are pydantic v2's: `Field required`,
//! `Input should be a valid string`, `String should have at least 1 character`,
//! `List should have at least 2 items after validation, not 1`,
//! `Input should be less than or equal to 0.1`, `Value error, Direction must be one of: …`, and
//! so on. A bad item of a coordinate is reported under pydantic's location of it,
//! `pick_coordinate.1`, one line per bad item. Numbers in the messages are printed as Python
//! prints the limits (`0`, `0.1`, `500`).
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
//!      • object_name: String should have at least 1 character\n  \
//!      • colour: Extra inputs are not permitted"
//! );
//! ```

use robotd_protocol::{Location, ParseEnumError, Point2};
use serde::de::{self, DeserializeOwned, DeserializeSeed, Deserializer, MapAccess, Visitor};
use serde::Deserialize;
use serde_json::{Map, Value};
use std::cell::Cell;
use std::fmt;
use std::str::FromStr;

/// One problem with one argument.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct FieldError {
    /// The argument's name (`pick_coordinate.1` for one item of a coordinate, as pydantic
    /// names it).
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
                issues,
            }) if !poisoned.contains(&field) => {
                for Issue { index, message } in issues {
                    let name = match index {
                        Some(i) => format!("{field}.{i}"),
                        None => field.to_owned(),
                    };
                    errors.push(FieldError {
                        field: name,
                        message,
                    });
                }
                poisoned.push(field);
            }
            // Not a field's problem, or a poisoned field failing again: stop here; the
            // problems found so far (or this one) are the answer.
            Err(other) => {
                if errors.is_empty() {
                    errors.push(FieldError {
                        field: "arguments".into(),
                        message: format!("could not be read: {other}"),
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
        errors.push(FieldError {
            field: key.clone(),
            message: EXTRA_FORBIDDEN.into(),
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

/// Why one pass stopped: problems with a field, or something else (`field` = `None`).
#[derive(Debug)]
struct ArgError {
    field: Option<&'static str>,
    /// At least one.
    issues: Vec<Issue>,
}

impl fmt::Display for ArgError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (i, issue) in self.issues.iter().enumerate() {
            if i > 0 {
                f.write_str("; ")?;
            }
            f.write_str(&issue.message)?;
        }
        Ok(())
    }
}

impl std::error::Error for ArgError {}

impl de::Error for ArgError {
    fn custom<T: fmt::Display>(msg: T) -> Self {
        ArgError {
            field: None,
            issues: Problem::decode(&msg.to_string()),
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
            Slot::Absent => Err(Problem::new(FIELD_REQUIRED).into_error()),
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

// pydantic v2's messages (pydantic-core's error types) for the problems the readers find.

/// `missing`.
const FIELD_REQUIRED: &str = "Field required";
/// `string_type`.
const STRING_TYPE: &str = "Input should be a valid string";
/// `string_too_short` with `min_length` 1 (a blank string counts as empty).
const STRING_TOO_SHORT: &str = "String should have at least 1 character";
/// `list_type`.
const LIST_TYPE: &str = "Input should be a valid list";
/// `float_type`.
const FLOAT_TYPE: &str = "Input should be a valid number";
/// `float_parsing`: robotd reads no numbers from strings.
const FLOAT_PARSING: &str = "Input should be a valid number, unable to parse string as a number";
/// `finite_number`.
const FINITE_NUMBER: &str = "Input should be a finite number";
/// `bool_type`.
const BOOL_TYPE: &str = "Input should be a valid boolean";
/// `bool_parsing`: robotd reads no booleans from strings or numbers.
const BOOL_PARSING: &str = "Input should be a valid boolean, unable to interpret input";
/// `int_type`.
const INT_TYPE: &str = "Input should be a valid integer";
/// `int_parsing`: robotd reads no numbers from strings.
const INT_PARSING: &str = "Input should be a valid integer, unable to parse string as an integer";
/// `int_from_float`.
const INT_FRACTION: &str = "Input should be a valid integer, got a number with a fractional part";
/// `extra_forbidden`.
const EXTRA_FORBIDDEN: &str = "Extra inputs are not permitted";

/// `too_short` of a list.
fn too_short(min: usize, actual: usize) -> String {
    format!(
        "List should have at least {min} item{} after validation, not {actual}",
        plural(min)
    )
}

/// `too_long` of a list.
fn too_long(max: usize, actual: usize) -> String {
    format!(
        "List should have at most {max} item{} after validation, not {actual}",
        plural(max)
    )
}

fn plural(n: usize) -> &'static str {
    if n == 1 {
        ""
    } else {
        "s"
    }
}

/// One problem, and which item of a list it is about.
#[derive(Debug, Clone, PartialEq, Eq)]
struct Issue {
    index: Option<usize>,
    message: String,
}

/// The problems a reader found with its field: one, or one per bad item of a list.
///
/// They cross serde as an error's text, `"[i]: message"` for an item and the items separated
/// by [`Problem::SEPARATOR`], so that any deserializer can carry them; [`ArgError`] reads them
/// back.
struct Problem(Vec<Issue>);

impl Problem {
    const SEPARATOR: char = '\u{1e}';

    fn new(message: impl Into<String>) -> Self {
        Self(vec![Issue {
            index: None,
            message: message.into(),
        }])
    }

    fn decode(text: &str) -> Vec<Issue> {
        let items: Option<Vec<Issue>> = text
            .split(Self::SEPARATOR)
            .map(|part| {
                let (i, message) = part.strip_prefix('[')?.split_once("]: ")?;
                Some(Issue {
                    index: Some(i.parse().ok()?),
                    message: message.to_owned(),
                })
            })
            .collect();
        items.unwrap_or_else(|| {
            vec![Issue {
                index: None,
                message: text.to_owned(),
            }]
        })
    }

    fn into_error<E: de::Error>(self) -> E {
        E::custom(self)
    }
}

impl fmt::Display for Problem {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (n, issue) in self.0.iter().enumerate() {
            if n > 0 {
                write!(f, "{}", Self::SEPARATOR)?;
            }
            match issue.index {
                Some(i) => write!(f, "[{i}]: {}", issue.message)?,
                None => f.write_str(&issue.message)?,
            }
        }
        Ok(())
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

/// The problem of a required field that is absent, or `null` (then the type's message, as
/// pydantic words `None` for a field that does not allow it).
fn required(got_null: bool, type_message: &str) -> Problem {
    Problem::new(if got_null {
        type_message
    } else {
        FIELD_REQUIRED
    })
}

fn text_of(v: &Value) -> Result<String, Problem> {
    match v {
        Value::String(s) if s.trim().is_empty() => Err(Problem::new(STRING_TOO_SHORT)),
        Value::String(s) => Ok(s.trim().to_owned()),
        _ => Err(Problem::new(STRING_TYPE)),
    }
}

fn point_of(v: &Value) -> Result<Point2, Problem> {
    let parsed;
    let v = match v {
        Value::String(s) if s.trim_start().starts_with('[') => {
            parsed = serde_json::from_str::<Value>(s).map_err(|_| Problem::new(LIST_TYPE))?;
            &parsed
        }
        v => v,
    };
    let Value::Array(items) = v else {
        return Err(Problem::new(LIST_TYPE));
    };
    // In pydantic's order: too many items first, then the items, then too few.
    if items.len() > 2 {
        return Err(Problem::new(too_long(2, items.len())));
    }
    let mut xy = [0.0; 2];
    let mut bad = Vec::new();
    for (i, item) in items.iter().enumerate() {
        match number_of(item) {
            Ok(n) => xy[i] = n,
            Err(message) => bad.push(Issue {
                index: Some(i),
                message: message.into(),
            }),
        }
    }
    if !bad.is_empty() {
        return Err(Problem(bad));
    }
    if items.len() < 2 {
        return Err(Problem::new(too_short(2, items.len())));
    }
    Ok(Point2::new(xy[0], xy[1]))
}

fn number_of(v: &Value) -> Result<f64, &'static str> {
    match v {
        Value::Number(n) => match n.as_f64() {
            Some(x) if x.is_finite() => Ok(x),
            _ => Err(FINITE_NUMBER),
        },
        Value::String(_) => Err(FLOAT_PARSING),
        _ => Err(FLOAT_TYPE),
    }
}

/// Reader of a required string of at least one non-blank character, trimmed.
pub fn text<'de, D: Deserializer<'de>>(d: D) -> Result<String, D::Error> {
    read(d, String::new(), |v, null| match v {
        None => Err(required(null, STRING_TYPE)),
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
        None => Err(required(null, LIST_TYPE)),
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
        None => Err(required(null, STRING_TYPE)),
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
        return Err(Problem::new(STRING_TYPE));
    };
    s.parse::<T>().map_err(|e| Problem::new(unknown_word(&e)))
}

/// The Python server's value error for a word it does not know: for a location
/// `Value error, Invalid location 'sideways'. Must be one of: left next to, …, close to`
/// (`none` is not listed: the Python server does not take it as a string), for the others
/// `Value error, Direction must be one of: up, down, left, right`.
fn unknown_word(e: &ParseEnumError) -> String {
    if e.kind == "location" {
        return format!(
            "Value error, Invalid location '{}'. Must be one of: {}",
            e.value,
            location_words(&[Location::None])
        );
    }
    let mut kind = e.kind.chars();
    let kind = match kind.next() {
        Some(first) => first.to_uppercase().chain(kind).collect::<String>(),
        None => String::new(),
    };
    format!("Value error, {kind} must be one of: {}", e.valid.join(", "))
}

/// The location words but `except`, comma-separated.
fn location_words(except: &[Location]) -> String {
    Location::ALL
        .iter()
        .filter(|l| !except.contains(l))
        .map(Location::as_str)
        .collect::<Vec<_>>()
        .join(", ")
}

/// Reader of `pick_place_object`'s `location`: an optional location word (absent or `null` →
/// `None`) other than `close to`, which the Python server refuses there with its own value
/// error (`… Note: 'close to' is not allowed for pick_place_object.`), as it does any unknown
/// word.
pub fn pick_place_location<'de, D: Deserializer<'de>>(d: D) -> Result<Option<Location>, D::Error> {
    read(d, None, |v, _| {
        let Some(v) = v else { return Ok(None) };
        let Value::String(s) = v else {
            return Err(Problem::new(STRING_TYPE));
        };
        match s.parse::<Location>() {
            Ok(location) if location != Location::CloseTo => Ok(Some(location)),
            _ => Err(Problem::new(format!(
                "Value error, Invalid location '{s}'. Must be one of: {}. Note: 'close to' is not \
                 allowed for pick_place_object.",
                location_words(&[Location::CloseTo, Location::None])
            ))),
        }
    })
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
///
/// The limits appear in the messages as Python prints them; Rust's `{}` does the same for the
/// limits used (`0`, `0.1`, `500`: no `.0` on whole numbers).
pub fn number_in<'de, D: Deserializer<'de>>(
    d: D,
    default: f64,
    min: f64,
    max: f64,
) -> Result<f64, D::Error> {
    read(d, default, |v, _| {
        let Some(v) = v else { return Ok(default) };
        let n = number_of(v).map_err(Problem::new)?;
        if n < min {
            return Err(Problem::new(format!(
                "Input should be greater than or equal to {min}"
            )));
        }
        if n > max {
            return Err(Problem::new(format!(
                "Input should be less than or equal to {max}"
            )));
        }
        Ok(n)
    })
}

/// A whole number in `[min, max]`, `default` when absent (for a reader of one field), with
/// pydantic's integer messages.
pub fn whole_in<'de, D: Deserializer<'de>>(
    d: D,
    default: u64,
    min: u64,
    max: u64,
) -> Result<u64, D::Error> {
    read(d, default, |v, _| {
        let Some(v) = v else { return Ok(default) };
        let n = match v {
            Value::Number(n) => n.as_f64().filter(|x| x.is_finite()).ok_or(INT_TYPE),
            Value::String(_) => Err(INT_PARSING),
            _ => Err(INT_TYPE),
        }
        .map_err(Problem::new)?;
        if n.fract() != 0.0 {
            return Err(Problem::new(INT_FRACTION));
        }
        if n < min as f64 {
            return Err(Problem::new(format!(
                "Input should be greater than or equal to {min}"
            )));
        }
        if n > max as f64 {
            return Err(Problem::new(format!(
                "Input should be less than or equal to {max}"
            )));
        }
        Ok(n as u64)
    })
}

/// A required number greater than 0 and at most `max` (for a reader of one field).
pub fn positive<'de, D: Deserializer<'de>>(d: D, max: f64) -> Result<f64, D::Error> {
    read(d, max, |v, null| {
        let Some(v) = v else {
            return Err(required(null, FLOAT_TYPE));
        };
        let n = number_of(v).map_err(Problem::new)?;
        if n <= 0.0 {
            return Err(Problem::new("Input should be greater than 0"));
        }
        if n > max {
            return Err(Problem::new(format!(
                "Input should be less than or equal to {max}"
            )));
        }
        Ok(n)
    })
}

/// A boolean, `default` when absent (for a reader of one field).
pub fn flag<'de, D: Deserializer<'de>>(d: D, default: bool) -> Result<bool, D::Error> {
    read(d, default, |v, _| match v {
        None => Ok(default),
        Some(Value::Bool(b)) => Ok(*b),
        // Only JSON booleans are taken. pydantic's words: a string or a whole number is a
        // value it could not interpret as a boolean, anything else is of the wrong type.
        Some(Value::String(_)) => Err(Problem::new(BOOL_PARSING)),
        Some(Value::Number(n)) if n.as_f64().is_some_and(|x| x.fract() == 0.0) => {
            Err(Problem::new(BOOL_PARSING))
        }
        Some(_) => Err(Problem::new(BOOL_TYPE)),
    })
}

/// Reader of `z_offset`: height above the object's centre of mass at which to grip, metres,
/// in `[0, 0.1]`, [`DEFAULT_Z_OFFSET_M`](robotd_protocol::skills::DEFAULT_Z_OFFSET_M) when
/// absent.
pub fn z_offset<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
    number_in(d, robotd_protocol::skills::DEFAULT_Z_OFFSET_M, 0.0, 0.1)
}

#[cfg(test)]
mod tests;
