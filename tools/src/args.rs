//! Tool-argument validation: robotd's own checks, one message per offending field.
//!
//! MCP SDKs pass a tool's arguments through unchecked (the input schema is advice to the
//! client, not enforced), so every tool reads its arguments through [`Args`], which checks
//! type, presence, length, range and enum value and collects every problem before the tool
//! does anything. The problems become the contract's
//!
//! ```text
//! ❌ Validation Error in <tool>:
//!   • <field>: <message>
//! ```
//!
//! Enum-like words are matched case-insensitively with surrounding whitespace ignored, as the
//! contract asks; a coordinate written as the JSON text `"[0.2, 0.1]"` (some LLMs do that) is
//! accepted like the array itself.

use robotd_protocol::{ParseEnumError, Point2};
use serde_json::{Map, Value};
use std::str::FromStr;

/// One problem with one argument.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct FieldError {
    /// The argument's name.
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

/// Reads the arguments of one call, collecting every problem.
#[derive(Debug)]
pub struct Args<'a> {
    map: &'a Map<String, Value>,
    known: Vec<&'static str>,
    errors: Vec<FieldError>,
}

impl<'a> Args<'a> {
    /// Arguments of a call (an absent argument object is an empty one).
    pub fn new(map: &'a Map<String, Value>) -> Self {
        Self {
            map,
            known: Vec::new(),
            errors: Vec::new(),
        }
    }

    fn fail(&mut self, field: &str, message: impl Into<String>) {
        self.errors.push(FieldError {
            field: field.to_owned(),
            message: message.into(),
        });
    }

    /// The value of `field`, `None` when absent or `null`.
    fn value(&mut self, field: &'static str) -> Option<&'a Value> {
        self.known.push(field);
        match self.map.get(field) {
            None | Some(Value::Null) => None,
            Some(v) => Some(v),
        }
    }

    fn missing(&mut self, field: &'static str) {
        let message = if self.map.contains_key(field) {
            "is required (got null)"
        } else {
            "is required"
        };
        self.fail(field, message);
    }

    /// A required string of at least one non-blank character, trimmed.
    pub fn text(&mut self, field: &'static str) -> Option<String> {
        match self.value(field) {
            None => {
                self.missing(field);
                None
            }
            Some(v) => self.text_of(field, v),
        }
    }

    /// An optional string (absent or `null` → `None`); an empty one counts as absent.
    pub fn opt_text(&mut self, field: &'static str) -> Option<String> {
        match self.value(field)? {
            Value::String(s) if s.trim().is_empty() => None,
            v => self.text_of(field, v),
        }
    }

    fn text_of(&mut self, field: &str, v: &Value) -> Option<String> {
        match v {
            Value::String(s) if s.trim().is_empty() => {
                self.fail(field, "must be a non-empty string");
                None
            }
            Value::String(s) => Some(s.trim().to_owned()),
            other => {
                self.fail(field, format!("must be a string, got {}", kind_of(other)));
                None
            }
        }
    }

    /// A required `[x, y]` coordinate in metres.
    pub fn point(&mut self, field: &'static str) -> Option<Point2> {
        match self.value(field) {
            None => {
                self.missing(field);
                None
            }
            Some(v) => self.point_of(field, v),
        }
    }

    /// An optional `[x, y]` coordinate.
    pub fn opt_point(&mut self, field: &'static str) -> Option<Point2> {
        let v = self.value(field)?;
        self.point_of(field, v)
    }

    fn point_of(&mut self, field: &str, v: &Value) -> Option<Point2> {
        let parsed;
        let v = match v {
            Value::String(s) if s.trim_start().starts_with('[') => {
                match serde_json::from_str::<Value>(s) {
                    Ok(inner) => {
                        parsed = inner;
                        &parsed
                    }
                    Err(_) => {
                        self.fail(field, "must be a list of two numbers [x, y]");
                        return None;
                    }
                }
            }
            v => v,
        };
        let Value::Array(items) = v else {
            self.fail(
                field,
                format!("must be a list of two numbers [x, y], got {}", kind_of(v)),
            );
            return None;
        };
        if items.len() != 2 {
            self.fail(
                field,
                format!(
                    "must have exactly 2 items [x, y], got {} item{}",
                    items.len(),
                    if items.len() == 1 { "" } else { "s" }
                ),
            );
            return None;
        }
        let mut xy = [0.0; 2];
        for (i, item) in items.iter().enumerate() {
            match item.as_f64() {
                Some(n) if n.is_finite() => xy[i] = n,
                _ => {
                    self.fail(
                        &format!("{field}[{i}]"),
                        format!("must be a finite number, got {}", kind_of(item)),
                    );
                    return None;
                }
            }
        }
        Some(Point2::new(xy[0], xy[1]))
    }

    fn number_of(&mut self, field: &str, v: &Value) -> Option<f64> {
        match v.as_f64() {
            Some(n) if n.is_finite() => Some(n),
            _ => {
                self.fail(
                    field,
                    format!("must be a finite number, got {}", kind_of(v)),
                );
                None
            }
        }
    }

    /// A number in `[min, max]`, `default` when absent.
    pub fn number_in(
        &mut self,
        field: &'static str,
        default: f64,
        min: f64,
        max: f64,
    ) -> Option<f64> {
        let Some(v) = self.value(field) else {
            return Some(default);
        };
        let n = self.number_of(field, v)?;
        if !(min..=max).contains(&n) {
            self.fail(field, format!("must be between {min} and {max}, got {n}"));
            return None;
        }
        Some(n)
    }

    /// A required number greater than 0 and at most `max`.
    pub fn positive(&mut self, field: &'static str, max: f64) -> Option<f64> {
        let Some(v) = self.value(field) else {
            self.missing(field);
            return None;
        };
        let n = self.number_of(field, v)?;
        if n <= 0.0 {
            self.fail(field, format!("must be greater than 0, got {n}"));
            return None;
        }
        if n > max {
            self.fail(field, format!("must be at most {max}, got {n}"));
            return None;
        }
        Some(n)
    }

    /// A boolean, `default` when absent.
    pub fn flag(&mut self, field: &'static str, default: bool) -> Option<bool> {
        match self.value(field) {
            None => Some(default),
            Some(Value::Bool(b)) => Some(*b),
            Some(other) => {
                self.fail(
                    field,
                    format!("must be true or false, got {}", kind_of(other)),
                );
                None
            }
        }
    }

    /// One of an enum's words (case-insensitive, trimmed), `default` when absent.
    pub fn word<T: FromStr<Err = ParseEnumError>>(
        &mut self,
        field: &'static str,
        default: Option<T>,
    ) -> Option<T> {
        let Some(v) = self.value(field) else {
            if default.is_none() {
                self.missing(field);
            }
            return default;
        };
        let Value::String(s) = v else {
            self.fail(field, format!("must be a string, got {}", kind_of(v)));
            return None;
        };
        match s.parse::<T>() {
            Ok(w) => Some(w),
            Err(e) => {
                self.fail(field, e.to_string());
                None
            }
        }
    }

    /// A required string, kept as given (trimmed) for the caller to interpret.
    pub fn raw_word(&mut self, field: &'static str) -> Option<String> {
        self.text(field)
    }

    /// Ends reading: unknown arguments are problems too. Returns every problem found.
    pub fn finish(mut self) -> Result<(), Vec<FieldError>> {
        let mut unknown: Vec<&String> = self
            .map
            .keys()
            .filter(|k| !self.known.contains(&k.as_str()))
            .collect();
        unknown.sort();
        for key in unknown {
            let expected = if self.known.is_empty() {
                "this tool takes no arguments".to_owned()
            } else {
                format!("unknown argument; expected {}", self.known.join(", "))
            };
            self.errors.push(FieldError {
                field: key.clone(),
                message: expected,
            });
        }
        if self.errors.is_empty() {
            Ok(())
        } else {
            Err(self.errors)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use robotd_protocol::{Direction, Location};
    use serde_json::json;

    fn map(v: Value) -> Map<String, Value> {
        v.as_object().cloned().unwrap()
    }

    #[test]
    fn every_problem_is_reported_once_per_field() {
        let m = map(json!({
            "object_name": "",
            "pick_coordinate": [0.1, 0.2, 0.3],
            "z_offset": 0.5,
            "location": "sideways",
            "colour": "red"
        }));
        let mut a = Args::new(&m);
        assert_eq!(a.text("object_name"), None);
        assert_eq!(a.point("pick_coordinate"), None);
        assert_eq!(a.point("place_coordinate"), None);
        assert_eq!(a.number_in("z_offset", 0.001, 0.0, 0.1), None);
        assert_eq!(a.word::<Location>("location", Some(Location::None)), None);
        let errors = a.finish().unwrap_err();
        let text = validation_text("pick_place_object", &errors);
        assert_eq!(
            text,
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

    #[test]
    fn good_arguments_pass_with_defaults_and_lenient_words() {
        let m = map(json!({
            "object_name": " pencil ",
            "push_coordinate": "[0.2, -0.05]",
            "direction": " Left",
            "distance": 50
        }));
        let mut a = Args::new(&m);
        assert_eq!(a.text("object_name").as_deref(), Some("pencil"));
        assert_eq!(a.point("push_coordinate"), Some(Point2::new(0.2, -0.05)));
        assert_eq!(
            a.word::<Direction>("direction", None),
            Some(Direction::Left)
        );
        assert_eq!(a.positive("distance", 1000.0), Some(50.0));
        assert_eq!(a.number_in("z_offset", 0.001, 0.0, 0.1), Some(0.001));
        assert!(a.finish().is_ok());
    }

    #[test]
    fn types_and_signs_are_checked() {
        let m = map(json!({"distance": -5, "ascending": "yes", "coordinate": [0.1, "x"]}));
        let mut a = Args::new(&m);
        assert_eq!(a.positive("distance", 1000.0), None);
        assert_eq!(a.flag("ascending", true), None);
        assert_eq!(a.opt_point("coordinate"), None);
        let e = a.finish().unwrap_err();
        assert_eq!(e[0].message, "must be greater than 0, got -5");
        assert_eq!(e[1].message, "must be true or false, got a string");
        assert_eq!(e[2].field, "coordinate[1]");
    }
}
