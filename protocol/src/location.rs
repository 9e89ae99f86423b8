//! The word-valued parameters of the MCP tools: [`Location`], [`Direction`], [`WorkspacePoint`].
//!
//! LLMs and existing clients send these as strings (`"right next to"`, `"up"`,
//! `"upper left corner"`). Each enum here is spelled on the wire — in JSON and in
//! MessagePack — as exactly the string of `docs/mcp-tools.md`, parses it case-insensitively with
//! surrounding whitespace trimmed, and refuses anything else with an error that names the bad
//! value and lists the valid ones, so an LLM can correct itself from the message alone.
//!
//! ```
//! use robotd_protocol::location::{Direction, Location, WorkspacePoint};
//!
//! let loc: Location = "  Right Next To ".parse().unwrap();
//! assert_eq!(loc, Location::RightNextTo);
//! assert_eq!(loc.to_string(), "right next to");
//!
//! let err = "besides".parse::<Location>().unwrap_err();
//! assert!(err.to_string().starts_with("unknown location 'besides'; valid values: 'left next to'"));
//!
//! assert_eq!("UP".parse::<Direction>().unwrap(), Direction::Up);
//! assert_eq!(WorkspacePoint::CenterPoint.as_str(), "center point");
//! ```

use crate::geometry::Point2;
use std::fmt;

/// A string did not name any value of a word-valued enum.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown {kind} '{value}'; valid values: {}", quoted_list(valid))]
pub struct ParseEnumError {
    /// What was being parsed (`"location"`, `"direction"`, …).
    pub kind: &'static str,
    /// The string as given (untrimmed).
    pub value: String,
    /// Every accepted spelling.
    pub valid: &'static [&'static str],
}

fn quoted_list(valid: &[&str]) -> String {
    valid
        .iter()
        .map(|v| format!("'{v}'"))
        .collect::<Vec<_>>()
        .join(", ")
}

/// Defines a unit-only enum whose wire form, `Display` and `FromStr` are fixed strings.
macro_rules! word_enum {
    (
        $(#[$meta:meta])*
        $name:ident, $kind:literal {
            $( $(#[$vmeta:meta])* $variant:ident = $text:literal, )+
        }
    ) => {
        $(#[$meta])*
        #[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
        pub enum $name {
            $( $(#[$vmeta])* $variant, )+
        }

        impl $name {
            /// Every value, in the order of the spec.
            pub const ALL: &'static [$name] = &[$($name::$variant),+];
            /// Every accepted string, in the order of the spec.
            pub const STRINGS: &'static [&'static str] = &[$($text),+];

            /// The exact string of the spec.
            pub const fn as_str(&self) -> &'static str {
                match self {
                    $( $name::$variant => $text, )+
                }
            }
        }

        impl fmt::Display for $name {
            fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                f.write_str(self.as_str())
            }
        }

        impl std::str::FromStr for $name {
            type Err = ParseEnumError;

            /// Case-insensitive, surrounding whitespace ignored.
            fn from_str(s: &str) -> Result<Self, Self::Err> {
                let trimmed = s.trim();
                $(
                    if trimmed.eq_ignore_ascii_case($text) {
                        return Ok($name::$variant);
                    }
                )+
                Err(ParseEnumError {
                    kind: $kind,
                    value: s.to_owned(),
                    valid: Self::STRINGS,
                })
            }
        }

        impl serde::Serialize for $name {
            fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
                serializer.serialize_str(self.as_str())
            }
        }

        impl<'de> serde::Deserialize<'de> for $name {
            fn deserialize<D: serde::Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
                struct V;
                impl serde::de::Visitor<'_> for V {
                    type Value = $name;
                    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                        write!(f, "a {} string, one of {}", $kind, quoted_list($name::STRINGS))
                    }
                    fn visit_str<E: serde::de::Error>(self, v: &str) -> Result<$name, E> {
                        v.parse().map_err(E::custom)
                    }
                }
                deserializer.deserialize_str(V)
            }
        }
    };
}

word_enum! {
    /// Where an object is relative to a reference, as the tools' `location` parameter.
    ///
    /// For filters (`get_detected_objects`) the reference is a coordinate `c`; for placement
    /// (`place_object`, `pick_place_object`) it is the object nearest the place coordinate.
    /// "Left" is +y, "above" is +x (see [`Location::filter_accepts`]). The default is `none`.
    #[derive(Default)]
    Location, "location" {
        /// Filter: y > c.y. Place: to the +y side of the reference.
        LeftNextTo = "left next to",
        /// Filter: y < c.y. Place: to the −y side of the reference.
        RightNextTo = "right next to",
        /// Filter: x > c.x. Place: to the +x (far) side of the reference.
        Above = "above",
        /// Filter: x < c.x. Place: to the −x (near) side of the reference.
        Below = "below",
        /// Filter: nothing matches. Place: stacked on the reference.
        OnTopOf = "on top of",
        /// Filter: nothing matches. Place: into the reference (a container).
        Inside = "inside",
        /// Filter: within [`CLOSE_TO_RADIUS_M`] of c. Place: beside the reference, never on it.
        CloseTo = "close to",
        /// No spatial relation: no filter, or exactly at the coordinate.
        #[default]
        None = "none",
    }
}

/// Radius of the `close to` filter, metres.
pub const CLOSE_TO_RADIUS_M: f64 = 0.02;

/// Gap left between a placed object and its reference for the `next to`/`above`/`below`
/// placements, metres.
pub const PLACE_GAP_M: f64 = 0.02;

impl Location {
    /// Whether the location needs a reference coordinate when used as a filter (all but `none`).
    pub const fn needs_coordinate(&self) -> bool {
        !matches!(self, Location::None)
    }

    /// The filter meaning of the Location table: does an object at `object` pass the filter
    /// with reference coordinate `reference`?
    pub fn filter_accepts(&self, object: Point2, reference: Point2) -> bool {
        match self {
            Location::LeftNextTo => object.y_m > reference.y_m,
            Location::RightNextTo => object.y_m < reference.y_m,
            Location::Above => object.x_m > reference.x_m,
            Location::Below => object.x_m < reference.x_m,
            Location::OnTopOf | Location::Inside => false,
            Location::CloseTo => object.distance_to(&reference) <= CLOSE_TO_RADIUS_M,
            Location::None => true,
        }
    }
}

word_enum! {
    /// A direction on the table, as the `direction` parameter of `push_object` and `move2by`.
    /// Up is +x (away from the robot), left is +y.
    Direction, "direction" {
        /// +x, away from the robot.
        Up = "up",
        /// −x, towards the robot.
        Down = "down",
        /// +y.
        Left = "left",
        /// −y.
        Right = "right",
    }
}

impl Direction {
    /// Unit vector `(dx, dy)` of the direction in the base frame.
    pub const fn unit_xy(&self) -> (f64, f64) {
        match self {
            Direction::Up => (1.0, 0.0),
            Direction::Down => (-1.0, 0.0),
            Direction::Left => (0.0, 1.0),
            Direction::Right => (0.0, -1.0),
        }
    }

    /// `from` moved `distance_m` metres in this direction.
    pub fn offset(&self, from: Point2, distance_m: f64) -> Point2 {
        let (dx, dy) = self.unit_xy();
        Point2::new(from.x_m + dx * distance_m, from.y_m + dy * distance_m)
    }
}

word_enum! {
    /// A named point of a workspace rectangle, as `get_workspace_coordinate_from_point`'s
    /// `point`. Upper = far from the robot (+x), left = +y.
    WorkspacePoint, "workspace point" {
        /// Far-left corner.
        UpperLeftCorner = "upper left corner",
        /// Far-right corner.
        UpperRightCorner = "upper right corner",
        /// Near-left corner.
        LowerLeftCorner = "lower left corner",
        /// Near-right corner.
        LowerRightCorner = "lower right corner",
        /// Centre of the rectangle.
        CenterPoint = "center point",
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_exact_string_round_trips() {
        let expected = [
            "left next to",
            "right next to",
            "above",
            "below",
            "on top of",
            "inside",
            "close to",
            "none",
        ];
        assert_eq!(Location::STRINGS, expected);
        for (loc, text) in Location::ALL.iter().zip(expected) {
            assert_eq!(loc.as_str(), text);
            assert_eq!(loc.to_string(), text);
            assert_eq!(text.parse::<Location>().unwrap(), *loc);
            assert_eq!(serde_json::to_value(loc).unwrap(), text);
            assert_eq!(
                serde_json::from_value::<Location>(text.into()).unwrap(),
                *loc
            );
        }
    }

    #[test]
    fn parsing_ignores_case_and_surrounding_whitespace() {
        assert_eq!(
            "LEFT NEXT TO".parse::<Location>().unwrap(),
            Location::LeftNextTo
        );
        assert_eq!(
            "\t On Top Of \n".parse::<Location>().unwrap(),
            Location::OnTopOf
        );
        assert_eq!(" None".parse::<Location>().unwrap(), Location::None);
        assert_eq!(
            serde_json::from_str::<Location>("\" Close To \"").unwrap(),
            Location::CloseTo
        );
        // Inner whitespace is part of the value.
        assert!("left  next to".parse::<Location>().is_err());
        assert!("leftnextto".parse::<Location>().is_err());
    }

    #[test]
    fn bad_value_error_names_it_and_lists_valid_ones() {
        let err = "next to".parse::<Location>().unwrap_err();
        assert_eq!(err.value, "next to");
        assert_eq!(
            err.to_string(),
            "unknown location 'next to'; valid values: 'left next to', 'right next to', \
             'above', 'below', 'on top of', 'inside', 'close to', 'none'"
        );
        let err = serde_json::from_str::<Location>("\"beside\"").unwrap_err();
        assert!(
            err.to_string().contains("unknown location 'beside'"),
            "{err}"
        );
        let err = serde_json::from_str::<Location>("3").unwrap_err();
        assert!(err.to_string().contains("a location string"), "{err}");
    }

    #[test]
    fn direction_and_workspace_point_strings() {
        assert_eq!(Direction::STRINGS, ["up", "down", "left", "right"]);
        for d in Direction::ALL {
            assert_eq!(d.as_str().to_uppercase().parse::<Direction>().unwrap(), *d);
        }
        assert_eq!(
            "sideways".parse::<Direction>().unwrap_err().to_string(),
            "unknown direction 'sideways'; valid values: 'up', 'down', 'left', 'right'"
        );
        assert_eq!(
            WorkspacePoint::STRINGS,
            [
                "upper left corner",
                "upper right corner",
                "lower left corner",
                "lower right corner",
                "center point"
            ]
        );
        assert_eq!(
            " Center Point ".parse::<WorkspacePoint>().unwrap(),
            WorkspacePoint::CenterPoint
        );
        assert!("centre"
            .parse::<WorkspacePoint>()
            .unwrap_err()
            .to_string()
            .starts_with("unknown workspace point 'centre'; valid values: 'upper left corner'"));
    }

    #[test]
    fn filter_semantics_follow_the_table() {
        let c = Point2::new(0.25, 0.0);
        let left = Point2::new(0.25, 0.05);
        let far = Point2::new(0.30, 0.0);
        let near = Point2::new(0.255, 0.01);
        assert!(Location::LeftNextTo.filter_accepts(left, c));
        assert!(!Location::RightNextTo.filter_accepts(left, c));
        assert!(Location::Above.filter_accepts(far, c));
        assert!(!Location::Below.filter_accepts(far, c));
        assert!(Location::CloseTo.filter_accepts(near, c));
        assert!(!Location::CloseTo.filter_accepts(far, c));
        assert!(!Location::OnTopOf.filter_accepts(c, c));
        assert!(!Location::Inside.filter_accepts(c, c));
        assert!(Location::None.filter_accepts(far, c));
        assert!(!Location::None.needs_coordinate());
        assert!(Location::Above.needs_coordinate());
    }

    #[test]
    fn directions_move_in_the_tool_frame() {
        let p = Point2::new(0.2, 0.0);
        assert_eq!(
            Direction::Up.offset(p, 0.1),
            Point2::new(0.30000000000000004, 0.0)
        );
        assert_eq!(Direction::Left.offset(p, 0.1), Point2::new(0.2, 0.1));
        assert_eq!(Direction::Right.offset(p, 0.1), Point2::new(0.2, -0.1));
        assert_eq!(Direction::Down.offset(p, 0.1), Point2::new(0.1, 0.0));
    }
}
