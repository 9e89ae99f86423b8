//! Which detection of a view is which remembered object: the candidate pairs and their costs.
//!
//! A detection pairs with a track of the same workspace that is on the table (not held) when
//!
//! - the detector called the object by the detection's label in one of its recent views
//!   (case-insensitive) and the centres of mass are within [`ASSOCIATION_GATE_M`], or
//! - the label differs but the detection lies at the track's place: the same detector that last
//!   confirmed the track, centres within [`RELABEL_GATE_M`], and the same footprint
//!   ([`same_footprint`]: long and short side within [`FOOTPRINT_RATIO`] of each other, and for
//!   elongated objects the same orientation within [`ORIENTATION_TOLERANCE_RAD`]) — or, for an
//!   object a skill moved, the detection's centre on its footprint (seen from another angle
//!   where it was put, it may look like another shape). Such a pair costs
//!   [`RELABEL_PENALTY_M`] more than its distance, so a detection with the right label nearby
//!   is preferred.
//!
//! The caller takes the pairs greedily, cheapest first, each track and each detection at most
//! once: of two objects close together each keeps its own detection.

use super::Track;
use robotd_protocol::objects::DetectedObject;
use std::f64::consts::PI;

/// A detection this close (centre of mass, table plane) to a remembered object the detector
/// called by the same label is that object, metres.
pub const ASSOCIATION_GATE_M: f64 = 0.03;

/// A detection with another label is the remembered object when it is this close (and of the
/// same footprint, from the same detector), metres.
pub const RELABEL_GATE_M: f64 = 0.015;

/// Added to the cost of a pair whose labels differ, metres.
pub const RELABEL_PENALTY_M: f64 = 0.01;

/// Longest and shortest sides of two footprints agree within this factor.
pub const FOOTPRINT_RATIO: f64 = 1.4;

/// Orientations of elongated footprints agree within this angle, radians (20°).
pub const ORIENTATION_TOLERANCE_RAD: f64 = 20.0 * PI / 180.0;

/// A footprint whose long side is at least this many times its short side has an orientation.
const ELONGATED: f64 = 1.3;

/// Sides shorter than this are measured as this, metres (noise on tiny objects).
const MIN_SIDE_M: f64 = 0.005;

/// Candidate pairs `(cost, track, detection)` of a view of workspace `ws` from `source`,
/// cheapest first.
pub(super) fn pairs(
    tracks: &[Track],
    ws: &str,
    source: &str,
    detections: &[DetectedObject],
) -> Vec<(f64, usize, usize)> {
    let mut pairs = Vec::new();
    for (t, track) in tracks.iter().enumerate() {
        if track.held || track.object.workspace_id != ws {
            continue;
        }
        for (d, det) in detections.iter().enumerate() {
            let distance = track.object.xy().distance_to(&det.xy());
            if track.votes.contains(&det.label) {
                if distance <= ASSOCIATION_GATE_M {
                    pairs.push((distance, t, d));
                }
            } else if track.source == source
                && distance <= RELABEL_GATE_M
                && (same_footprint(&track.object, det) || (track.moved && covers(track, det)))
            {
                pairs.push((distance + RELABEL_PENALTY_M, t, d));
            }
        }
    }
    pairs.sort_by(|a, b| a.0.total_cmp(&b.0));
    pairs
}

/// Whether the detection's centre lies on the track's footprint: two objects on a table never
/// overlap, so it is that object seen differently (a skill put it where the camera sees it at
/// another angle, as another shape).
fn covers(track: &Track, det: &DetectedObject) -> bool {
    robotd_placement::geometry::Rect::of_object(&track.object).contains(
        &robotd_placement::geometry::Rect::footprint(det.xy(), (0.0, 0.0)),
    )
}

/// Whether `a` and `b` cover the same footprint: long and short sides within
/// [`FOOTPRINT_RATIO`], and when both are elongated the same orientation (modulo half a turn)
/// within [`ORIENTATION_TOLERANCE_RAD`].
pub fn same_footprint(a: &DetectedObject, b: &DetectedObject) -> bool {
    let sides = |o: &DetectedObject| {
        let (w, h) = (
            o.dimensions.width_m.max(MIN_SIDE_M),
            o.dimensions.height_m.max(MIN_SIDE_M),
        );
        (w.max(h), w.min(h))
    };
    let ((a_long, a_short), (b_long, b_short)) = (sides(a), sides(b));
    let close = |x: f64, y: f64| x.max(y) <= FOOTPRINT_RATIO * x.min(y);
    if !close(a_long, b_long) || !close(a_short, b_short) {
        return false;
    }
    if a_long < ELONGATED * a_short || b_long < ELONGATED * b_short {
        return true;
    }
    let turn = (a.gripper_rotation_rad - b.gripper_rotation_rad).rem_euclid(PI);
    turn.min(PI - turn) <= ORIENTATION_TOLERANCE_RAD
}

#[cfg(test)]
mod tests {
    use super::*;

    fn footprint(w: f64, h: f64, rotation_deg: f64) -> DetectedObject {
        let mut o = DetectedObject::default();
        o.dimensions.width_m = w;
        o.dimensions.height_m = h;
        o.gripper_rotation_rad = rotation_deg.to_radians();
        o
    }

    #[test]
    fn footprints_agree_in_size_and_orientation() {
        let pencil = footprint(0.012, 0.12, 10.0);
        // The same bar measured with its sides swapped, and turned by half a turn.
        assert!(same_footprint(&pencil, &footprint(0.11, 0.013, 185.0)));
        // 25° off: another orientation.
        assert!(!same_footprint(&pencil, &footprint(0.012, 0.12, 35.0)));
        // Half as long: another object.
        assert!(!same_footprint(&pencil, &footprint(0.012, 0.06, 10.0)));
        // Squares have no orientation to compare.
        assert!(same_footprint(
            &footprint(0.03, 0.03, 0.0),
            &footprint(0.031, 0.029, 45.0)
        ));
        assert!(!same_footprint(
            &footprint(0.03, 0.03, 0.0),
            &footprint(0.045, 0.045, 0.0)
        ));
    }
}
