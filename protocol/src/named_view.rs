//! A camera view named as the workspace model took it: one name and one id per object,
//! everywhere a view goes out (the dashboard's overlay, the Redis stream `detected_objects`).
//!
//! The detector names each box of a frame by what it sees; the workspace model decides which
//! object each box shows (a moved object keeps its name although the detector may read it as
//! something else at the sheet's edge; a box showing the rim of a stack's lower object is a
//! piece of the stack, not an object of its own; a box seen once is a candidate until a second
//! view agrees). It publishes that decision with the objects it then holds
//! ([`TrackedObjects::detection_ids`]). [`TrackedObjects::named_view`] puts the two together:
//! the view's boxes the model took for an object, each as the model reports that object, drawn
//! where the detector saw it.
//!
//! ```
//! use robotd_protocol::objects::{DetectedObject, Detections};
//! use robotd_protocol::workspace::TrackedObjects;
//!
//! let boxed = |label: &str| DetectedObject { label: label.into(), ..Default::default() };
//! let view = Detections {
//!     frame_id: 7,
//!     workspace_id: "niryo_ws".into(),
//!     source: "robotd".into(),
//!     steady: true,
//!     objects: vec![boxed("green box"), boxed("red cube")],
//!     ..Default::default()
//! };
//! let mut cylinder = boxed("green cylinder");
//! cylinder.id = "obj-2".into();
//! let tracked = TrackedObjects {
//!     workspace_id: "niryo_ws".into(),
//!     frame_id: 7,
//!     source: "robotd".into(),
//!     objects: vec![cylinder],
//!     detection_ids: vec!["obj-2".into(), "".into()],
//!     ..Default::default()
//! };
//! let named = tracked.named_view(&view).unwrap();
//! assert_eq!(named.len(), 1); // the unconfirmed red cube is left out
//! assert_eq!((named[0].id.as_str(), named[0].label.as_str()), ("obj-2", "green cylinder"));
//! ```

use crate::objects::{DetectedObject, Detections};
use crate::workspace::TrackedObjects;

impl TrackedObjects {
    /// Whether this is the model's answer to `view` (same frame, workspace and source).
    pub fn answers(&self, view: &Detections) -> bool {
        self.frame_id == view.frame_id
            && self.workspace_id == view.workspace_id
            && self.source == view.source
            && self.detection_ids.len() == view.objects.len()
    }

    /// `view`'s boxes the model took for an object it reports, in the view's order: each the
    /// model's object (id, name, position, size: a stacked object at its true height) with
    /// the box's image coordinates and time. `None` when this is not the model's answer to
    /// `view` ([`TrackedObjects::answers`]).
    pub fn named_view(&self, view: &Detections) -> Option<Vec<DetectedObject>> {
        if !self.answers(view) {
            return None;
        }
        let named = view
            .objects
            .iter()
            .zip(&self.detection_ids)
            .filter(|(_, id)| !id.is_empty())
            .filter_map(|(seen, id)| {
                let object = self.objects.iter().find(|o| &o.id == id)?;
                let mut named = object.clone();
                named.image_coordinates = seen.image_coordinates;
                named.timestamp_unix_s = seen.timestamp_unix_s;
                Some(named)
            })
            .collect();
        Some(named)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::objects::RelPoint;

    fn object(id: &str, label: &str, x: f64) -> DetectedObject {
        let mut o = DetectedObject {
            id: id.into(),
            label: label.into(),
            workspace_id: "niryo_ws".into(),
            ..Default::default()
        };
        o.position.center_of_mass.x_m = x;
        o.image_coordinates.center_rel = RelPoint { u: x, v: 0.5 };
        o
    }

    fn view(frame_id: u64, objects: Vec<DetectedObject>) -> Detections {
        Detections {
            frame_id,
            workspace_id: "niryo_ws".into(),
            source: "robotd".into(),
            steady: true,
            objects,
            ..Default::default()
        }
    }

    fn tracked(frame_id: u64, objects: Vec<DetectedObject>, ids: &[&str]) -> TrackedObjects {
        TrackedObjects {
            workspace_id: "niryo_ws".into(),
            frame_id,
            source: "robotd".into(),
            objects,
            detection_ids: ids.iter().map(|s| s.to_string()).collect(),
            ..Default::default()
        }
    }

    #[test]
    fn each_box_is_the_models_object_drawn_where_the_detector_saw_it() {
        let seen = view(
            3,
            vec![
                object("", "green box", 0.19),
                object("", "red cube", 0.25),
                object("", "blue cube", 0.30),
            ],
        );
        // The model: box 0 is the cylinder a skill put there, box 1 a piece of a stack, box
        // 2 the blue cube; the stacked cylinder sits at its true height.
        let mut cylinder = object("obj-2", "green cylinder", 0.186);
        cylinder.position.center_of_mass.z_m = 0.045;
        let blue = object("obj-4", "blue cube", 0.30);
        let model = tracked(3, vec![blue, cylinder], &["obj-2", "", "obj-4"]);
        let named = model
            .named_view(&seen)
            .expect("the model's answer to this view");
        let names: Vec<(&str, &str)> = named
            .iter()
            .map(|o| (o.id.as_str(), o.label.as_str()))
            .collect();
        assert_eq!(names, [("obj-2", "green cylinder"), ("obj-4", "blue cube")]);
        assert_eq!(named[0].position.center_of_mass.z_m, 0.045);
        assert_eq!(
            named[0].image_coordinates.center_rel,
            RelPoint { u: 0.19, v: 0.5 }
        );
    }

    #[test]
    fn another_frame_workspace_or_source_is_not_the_answer() {
        let seen = view(3, vec![object("", "red cube", 0.25)]);
        let cube = || vec![object("obj-1", "red cube", 0.25)];
        assert!(tracked(4, cube(), &["obj-1"]).named_view(&seen).is_none());
        let mut elsewhere = tracked(3, cube(), &["obj-1"]);
        elsewhere.workspace_id = "gazebo_1".into();
        assert!(elsewhere.named_view(&seen).is_none());
        let mut external = tracked(3, cube(), &["obj-1"]);
        external.source = "yolo".into();
        assert!(external.named_view(&seen).is_none());
        // An answer whose ids do not line up with the view's boxes is not trusted.
        assert!(tracked(3, cube(), &[]).named_view(&seen).is_none());
        assert_eq!(
            tracked(3, cube(), &["obj-1"])
                .named_view(&seen)
                .unwrap()
                .len(),
            1
        );
    }
}
