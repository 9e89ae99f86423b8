//! Stable ids on the camera overlay.
//!
//! Perception reports what one frame shows, without ids; the workspace model tracks objects
//! across views and gives each a stable id (`obj-3`). The page's camera labels each box with
//! the id of the tracked object it shows: the nearest one with the same label in the same
//! workspace, no farther than [`MATCH_RADIUS_M`] on the table. A detection no tracked object
//! is close to (new, or the model has not seen it twice yet) keeps an empty id.
//!
//! An object named by `label_object` is tracked under its name while the detector still calls
//! it what it sees (`unknown object`): the workspace model lists it among the `renamed` with
//! that label, the detection is matched by it, and the box shows the name.

use robotd_protocol::objects::DetectedObject;
use robotd_protocol::workspace::RenamedObject;

/// Farthest a detection may lie from a tracked object and still be called that object, m.
pub const MATCH_RADIUS_M: f64 = 0.03;

/// `detections` with each empty `id` set from the matching object in `tracked` (and the label
/// of a `renamed` one set to its name); closest pairs first, and each tracked object names one
/// detection at most.
pub fn with_stable_ids(
    detections: &[DetectedObject],
    tracked: &[DetectedObject],
    renamed: &[RenamedObject],
) -> Vec<DetectedObject> {
    // The label each tracked object's detections carry.
    let detected_as = |object: &DetectedObject| -> String {
        renamed
            .iter()
            .find(|r| r.id == object.id)
            .map_or_else(|| object.label.clone(), |r| r.detected_as.clone())
    };
    let labels: Vec<String> = tracked.iter().map(detected_as).collect();
    let mut named = detections.to_vec();
    let mut pairs: Vec<(f64, usize, usize)> = Vec::new();
    for (d, detection) in detections.iter().enumerate() {
        if !detection.id.is_empty() {
            continue;
        }
        for (t, object) in tracked.iter().enumerate() {
            if labels[t] == detection.label && object.workspace_id == detection.workspace_id {
                let distance = table_distance(detection, object);
                if distance <= MATCH_RADIUS_M {
                    pairs.push((distance, d, t));
                }
            }
        }
    }
    pairs.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut object_used = vec![false; tracked.len()];
    let mut detection_named = vec![false; detections.len()];
    for (_, d, t) in pairs {
        if !object_used[t] && !detection_named[d] {
            object_used[t] = true;
            detection_named[d] = true;
            named[d].id = tracked[t].id.clone();
            named[d].label = tracked[t].label.clone();
        }
    }
    named
}

fn table_distance(a: &DetectedObject, b: &DetectedObject) -> f64 {
    let (p, q) = (&a.position.center_of_mass, &b.position.center_of_mass);
    (p.x_m - q.x_m).hypot(p.y_m - q.y_m)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn object(id: &str, label: &str, x: f64, y: f64) -> DetectedObject {
        let mut o = DetectedObject {
            id: id.into(),
            label: label.into(),
            workspace_id: "niryo_ws".into(),
            ..Default::default()
        };
        o.position.center_of_mass.x_m = x;
        o.position.center_of_mass.y_m = y;
        o
    }

    #[test]
    fn a_detection_takes_the_id_of_the_nearest_tracked_object_with_its_label() {
        let tracked = [
            object("obj-1", "pencil", 0.20, 0.00),
            object("obj-2", "pencil", 0.21, 0.02),
            object("obj-3", "red cube", 0.20, 0.001),
        ];
        let detections = [
            object("", "pencil", 0.209, 0.019),
            object("", "red cube", 0.30, 0.0),
            object("", "pencil", 0.201, 0.0),
        ];
        let named = with_stable_ids(&detections, &tracked, &[]);
        let ids: Vec<&str> = named.iter().map(|o| o.id.as_str()).collect();
        assert_eq!(ids, ["obj-2", "", "obj-1"]);
    }

    #[test]
    fn one_tracked_object_names_one_box() {
        let tracked = [object("obj-1", "pencil", 0.20, 0.00)];
        let detections = [
            object("", "pencil", 0.21, 0.0),
            object("", "pencil", 0.201, 0.0),
        ];
        let named = with_stable_ids(&detections, &tracked, &[]);
        let ids: Vec<&str> = named.iter().map(|o| o.id.as_str()).collect();
        assert_eq!(ids, ["", "obj-1"], "the closer box gets the id");
    }

    #[test]
    fn another_workspace_or_an_id_already_given_is_left_alone() {
        let mut elsewhere = object("obj-9", "pencil", 0.2, 0.0);
        elsewhere.workspace_id = "gazebo_1".into();
        let named = with_stable_ids(
            &[
                object("", "pencil", 0.2, 0.0),
                object("own", "pencil", 0.2, 0.0),
            ],
            &[elsewhere],
            &[],
        );
        assert_eq!(named[0].id, "");
        assert_eq!(named[1].id, "own");
    }

    #[test]
    fn a_renamed_object_is_matched_by_what_the_detector_sees_and_shows_its_name() {
        let tracked = [object("obj-4", "screwdriver", 0.25, 0.0)];
        let renamed = [RenamedObject {
            id: "obj-4".into(),
            detected_as: "unknown object".into(),
        }];
        let detections = [object("", "unknown object", 0.251, 0.0)];
        let named = with_stable_ids(&detections, &tracked, &renamed);
        assert_eq!(
            (named[0].id.as_str(), named[0].label.as_str()),
            ("obj-4", "screwdriver")
        );
        // Without the rename it is not that object.
        let plain = with_stable_ids(&detections, &tracked, &[]);
        assert_eq!(plain[0].id, "");
    }
}
