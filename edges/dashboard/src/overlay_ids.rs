//! Stable ids on the camera overlay.
//!
//! Perception reports what one frame shows, without ids; the workspace model tracks objects
//! across views and gives each a stable id (`obj-3`). The page's camera labels each box with
//! the id of the tracked object it shows: the nearest one with the same label in the same
//! workspace, no farther than [`MATCH_RADIUS_M`] on the table. A detection no tracked object
//! is close to (new, or the model has not seen it twice yet) keeps an empty id.

use robotd_protocol::objects::DetectedObject;

/// Farthest a detection may lie from a tracked object and still be called that object, m.
pub const MATCH_RADIUS_M: f64 = 0.03;

/// `detections` with each empty `id` set from the matching object in `tracked`.
pub fn with_stable_ids(
    detections: &[DetectedObject],
    tracked: &[DetectedObject],
) -> Vec<DetectedObject> {
    detections
        .iter()
        .map(|detection| {
            let mut detection = detection.clone();
            if detection.id.is_empty() {
                if let Some(object) = nearest_same_object(&detection, tracked) {
                    detection.id = object.id.clone();
                }
            }
            detection
        })
        .collect()
}

fn nearest_same_object<'a>(
    detection: &DetectedObject,
    tracked: &'a [DetectedObject],
) -> Option<&'a DetectedObject> {
    let at = &detection.position.center_of_mass;
    tracked
        .iter()
        .filter(|o| o.label == detection.label && o.workspace_id == detection.workspace_id)
        .map(|o| {
            let p = &o.position.center_of_mass;
            (o, (p.x_m - at.x_m).hypot(p.y_m - at.y_m))
        })
        .filter(|(_, distance)| *distance <= MATCH_RADIUS_M)
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .map(|(o, _)| o)
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
        let named = with_stable_ids(&detections, &tracked);
        let ids: Vec<&str> = named.iter().map(|o| o.id.as_str()).collect();
        assert_eq!(ids, ["obj-2", "", "obj-1"]);
    }

    #[test]
    fn another_workspace_or_an_id_already_given_is_left_alone() {
        let mut elsewhere = object("obj-9", "pencil", 0.2, 0.0);
        elsewhere.workspace_id = "gazebo_1".into();
        let named = with_stable_ids(
            &[object("", "pencil", 0.2, 0.0), object("own", "pencil", 0.2, 0.0)],
            &[elsewhere],
        );
        assert_eq!(named[0].id, "");
        assert_eq!(named[1].id, "own");
    }
}
