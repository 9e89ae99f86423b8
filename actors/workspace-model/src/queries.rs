//! The object questions of the detection tools, as pure functions over a list of objects.
//!
//! Each function takes the objects on the table of the current workspace (in the order memory
//! keeps them: first seen first) and answers one tool of `docs/mcp-tools.md`:
//!
//! | function | tool | rule |
//! |---|---|---|
//! | [`matching`] | `get_detected_objects` | label substring filter (case-insensitive), then the [`Location`] filter around a reference coordinate; order kept |
//! | [`nearest`] | `get_detected_object` | within [`CLOSE_TO_RADIUS_M`] (0.02 m) of the coordinate, label filter, the nearest |
//! | [`largest`], [`smallest`] | `get_largest/smallest_detected_object` | by `size_m2`; on a tie the first |
//! | [`sorted_by_size`] | `get_detected_objects_sorted` | by `size_m2`, stable (ties keep their order, also descending) |
//!
//! Distances are measured between centres of mass on the table plane ([`DetectedObject::xy`]).
//!
//! ```
//! use robotd_protocol::geometry::{Point2, Point3};
//! use robotd_protocol::location::Location;
//! use robotd_protocol::objects::DetectedObject;
//! use robotd_workspace_model::queries;
//!
//! let mut cube = DetectedObject { label: "Red Cube".into(), ..Default::default() };
//! cube.position.center_of_mass = Point3::new(0.30, 0.05, 0.015);
//! let objects = [cube];
//! let left = queries::matching(&objects, Location::LeftNextTo, Some(Point2::new(0.25, 0.0)), Some("cube"))
//!     .unwrap();
//! assert_eq!(left.len(), 1);
//! assert!(queries::nearest(&objects, Point2::new(0.25, 0.0), None).is_none()); // 5.4 cm away
//! ```

use robotd_protocol::geometry::Point2;
use robotd_protocol::location::{Location, CLOSE_TO_RADIUS_M};
use robotd_protocol::objects::DetectedObject;
use robotd_protocol::workspace::WorkspaceError;
use std::cmp::Ordering;

fn label_passes(object: &DetectedObject, label: Option<&str>) -> bool {
    label.is_none_or(|l| object.label_contains(l))
}

fn by_size(a: &DetectedObject, b: &DetectedObject) -> Ordering {
    a.dimensions.size_m2.total_cmp(&b.dimensions.size_m2)
}

/// `get_detected_objects`: the objects whose label contains `label` (case-insensitive; `None`
/// or blank = any) and that pass `location` around `coordinate`. A location other than `none`
/// without a coordinate is [`WorkspaceError::CoordinateRequired`]; a coordinate with `none`
/// filters nothing.
pub fn matching<'a>(
    objects: impl IntoIterator<Item = &'a DetectedObject>,
    location: Location,
    coordinate: Option<Point2>,
    label: Option<&str>,
) -> Result<Vec<&'a DetectedObject>, WorkspaceError> {
    let reference = match coordinate {
        Some(c) => Some(c),
        None if location.needs_coordinate() => {
            return Err(WorkspaceError::CoordinateRequired { location })
        }
        None => None,
    };
    Ok(objects
        .into_iter()
        .filter(|o| label_passes(o, label))
        .filter(|o| reference.is_none_or(|c| location.filter_accepts(o.xy(), c)))
        .collect())
}

/// `get_detected_object`: of the objects within [`CLOSE_TO_RADIUS_M`] of `coordinate` whose
/// label contains `label`, the nearest (on equal distance, the first).
pub fn nearest<'a>(
    objects: impl IntoIterator<Item = &'a DetectedObject>,
    coordinate: Point2,
    label: Option<&str>,
) -> Option<&'a DetectedObject> {
    let mut best: Option<(f64, &DetectedObject)> = None;
    for object in objects {
        if !label_passes(object, label) {
            continue;
        }
        let distance = object.xy().distance_to(&coordinate);
        if distance > CLOSE_TO_RADIUS_M {
            continue;
        }
        if best.is_none_or(|(d, _)| distance < d) {
            best = Some((distance, object));
        }
    }
    best.map(|(_, o)| o)
}

/// `get_largest_detected_object`: the object with the largest `size_m2` (the first of equals).
pub fn largest<'a>(
    objects: impl IntoIterator<Item = &'a DetectedObject>,
) -> Option<&'a DetectedObject> {
    objects.into_iter().fold(None, |best, o| match best {
        Some(b) if by_size(o, b) != Ordering::Greater => Some(b),
        _ => Some(o),
    })
}

/// `get_smallest_detected_object`: the object with the smallest `size_m2` (the first of
/// equals).
pub fn smallest<'a>(
    objects: impl IntoIterator<Item = &'a DetectedObject>,
) -> Option<&'a DetectedObject> {
    objects.into_iter().fold(None, |best, o| match best {
        Some(b) if by_size(o, b) != Ordering::Less => Some(b),
        _ => Some(o),
    })
}

/// `get_detected_objects_sorted`: by `size_m2`, smallest first when `ascending`; equal sizes
/// keep their order in both directions.
pub fn sorted_by_size<'a>(
    objects: impl IntoIterator<Item = &'a DetectedObject>,
    ascending: bool,
) -> Vec<&'a DetectedObject> {
    let mut sorted: Vec<&DetectedObject> = objects.into_iter().collect();
    if ascending {
        sorted.sort_by(|a, b| by_size(a, b));
    } else {
        sorted.sort_by(|a, b| by_size(b, a));
    }
    sorted
}

#[cfg(test)]
mod tests {
    use super::*;
    use robotd_protocol::geometry::Point3;

    fn object(label: &str, x: f64, y: f64, size_m2: f64) -> DetectedObject {
        let mut o = DetectedObject {
            label: label.into(),
            ..Default::default()
        };
        o.position.center_of_mass = Point3::new(x, y, 0.01);
        o.dimensions.size_m2 = size_m2;
        o
    }

    /// Five objects around the reference point c = (0.25, 0.00):
    ///
    /// | # | label | x | y | size m² | from c |
    /// |---|---|---|---|---|---|
    /// | 0 | red cube | 0.26 | 0.01 | 0.0009 | √(0.01²+0.01²) = 14.1 mm |
    /// | 1 | Blue Cube | 0.25 | −0.015 | 0.0009 | 15.0 mm |
    /// | 2 | pencil | 0.20 | 0.05 | 0.0014 | 70.7 mm |
    /// | 3 | green cylinder | 0.30 | −0.05 | 0.0010 | 70.7 mm |
    /// | 4 | blue square | 0.25 | 0.00 | 0.0020 | 0 (exactly at c) |
    fn scene() -> Vec<DetectedObject> {
        vec![
            object("red cube", 0.26, 0.01, 0.0009),
            object("Blue Cube", 0.25, -0.015, 0.0009),
            object("pencil", 0.20, 0.05, 0.0014),
            object("green cylinder", 0.30, -0.05, 0.0010),
            object("blue square", 0.25, 0.00, 0.0020),
        ]
    }

    fn labels(objects: &[&DetectedObject]) -> Vec<String> {
        objects.iter().map(|o| o.label.clone()).collect()
    }

    const C: Option<Point2> = Some(Point2 {
        x_m: 0.25,
        y_m: 0.0,
    });

    #[test]
    fn matching_follows_the_location_table() {
        let s = scene();
        let m = |loc, c, label| labels(&matching(&s, loc, c, label).unwrap());
        // left = y > 0: red cube (0.01), pencil (0.05); blue square at y = 0 is not strictly left.
        assert_eq!(m(Location::LeftNextTo, C, None), ["red cube", "pencil"]);
        // right = y < 0: Blue Cube, green cylinder.
        assert_eq!(
            m(Location::RightNextTo, C, None),
            ["Blue Cube", "green cylinder"]
        );
        // above = x > 0.25: red cube (0.26), green cylinder (0.30).
        assert_eq!(m(Location::Above, C, None), ["red cube", "green cylinder"]);
        // below = x < 0.25: pencil only (Blue Cube and blue square are at exactly 0.25).
        assert_eq!(m(Location::Below, C, None), ["pencil"]);
        // close to = within 20 mm: red cube 14.1, Blue Cube 15.0, blue square 0.
        assert_eq!(
            m(Location::CloseTo, C, None),
            ["red cube", "Blue Cube", "blue square"]
        );
        assert!(m(Location::OnTopOf, C, None).is_empty());
        assert!(m(Location::Inside, C, None).is_empty());
        // none: no spatial filter, with or without a coordinate.
        assert_eq!(m(Location::None, None, None).len(), 5);
        assert_eq!(m(Location::None, C, None).len(), 5);
    }

    #[test]
    fn matching_filters_labels_by_case_insensitive_substring() {
        let s = scene();
        let m = |label| labels(&matching(&s, Location::None, None, label).unwrap());
        assert_eq!(m(Some("CUBE")), ["red cube", "Blue Cube"]);
        assert_eq!(m(Some("blue")), ["Blue Cube", "blue square"]);
        assert_eq!(m(Some(" pen ")), ["pencil"]);
        assert!(m(Some("banana")).is_empty());
        assert_eq!(m(Some("")).len(), 5, "a blank filter filters nothing");
        // Both filters: close to c and containing "blue".
        assert_eq!(
            labels(&matching(&s, Location::CloseTo, C, Some("blue")).unwrap()),
            ["Blue Cube", "blue square"]
        );
    }

    #[test]
    fn a_location_without_a_coordinate_is_refused_with_the_tool_text() {
        let err = matching(&scene(), Location::Below, None, None).unwrap_err();
        assert_eq!(
            err.to_string(),
            "Coordinate must be provided for location filter: below"
        );
    }

    #[test]
    fn nearest_is_within_two_centimetres_and_nearest_first() {
        let s = scene();
        let c = C.unwrap();
        assert_eq!(nearest(&s, c, None).unwrap().label, "blue square");
        // Among cubes: red 14.1 mm < Blue 15.0 mm.
        assert_eq!(nearest(&s, c, Some("cube")).unwrap().label, "red cube");
        // The pencil is 70.7 mm away: nothing within 2 cm.
        assert!(nearest(&s, c, Some("pencil")).is_none());
        // (0.21, 0.05) is 10 mm from the pencil, (0.175, 0.05) 25 mm.
        assert_eq!(
            nearest(&s, Point2::new(0.21, 0.05), None).unwrap().label,
            "pencil"
        );
        assert!(nearest(&s, Point2::new(0.175, 0.05), None).is_none());
        assert!(nearest(&[], c, None).is_none());
    }

    #[test]
    fn sizes_pick_the_first_of_equals_and_sort_stably() {
        let s = scene();
        // 0.0020 blue square is the largest; red cube and Blue Cube tie at 0.0009: the first.
        assert_eq!(largest(&s).unwrap().label, "blue square");
        assert_eq!(smallest(&s).unwrap().label, "red cube");
        assert_eq!(
            labels(&sorted_by_size(&s, true)),
            [
                "red cube",
                "Blue Cube",
                "green cylinder",
                "pencil",
                "blue square"
            ]
        );
        assert_eq!(
            labels(&sorted_by_size(&s, false)),
            [
                "blue square",
                "pencil",
                "green cylinder",
                "red cube",
                "Blue Cube"
            ]
        );
        let empty: [DetectedObject; 0] = [];
        assert!(largest(&empty).is_none() && smallest(&empty).is_none());
        assert!(sorted_by_size(&empty, false).is_empty());
    }
}
