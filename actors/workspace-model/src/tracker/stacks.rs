//! Stacks: an object a skill put on top of another, and the one beneath it.
//!
//! A camera looking down sees a stack as the top face of the upper object, measured as if it
//! stood on the table (the detector only knows each label's own height: higher up, closer to
//! the camera, it looks larger and shifted away from the image centre), and whatever shows of
//! the lower object around it (corners and side faces, which look like another object of its
//! colour, often under another label). So the tracker learns a stack from the skills, not from
//! the camera:
//!
//! - **Built by a place.** An object put down ([`super::Tracker::place`]) where its centre lies
//!   on the footprint of another object on the table (within
//!   [`STACK_SUPPORT_TOLERANCE_M`], the skills' own rule) stands on that one's top: its centre
//!   of mass is reported at the lower one's top plus half its own height, and the one beneath
//!   is remembered (`Track::support`).
//! - **Kept as it was built.** While an object is part of a stack (resting on another, or
//!   carrying one), the views only confirm it: its position, height, size and label stay those
//!   it had when the stack was built (the camera cannot measure them there), and a detection
//!   whose centre lies on the stack's footprint (grown by [`STACK_FRAGMENT_MARGIN_M`]) that
//!   matches nothing is a piece of the stack, never a new object. The lower object is not aged
//!   while the object on it is seen: it is hidden, not gone.
//! - **Taken apart by a pick.** Once the upper object is picked, the lower one is an ordinary
//!   object again, measured by the next view; the upper one is put down wherever the skill
//!   puts it (on the table, or on another stack).
//!
//! The skills read a stack from the reported heights alone
//! ([`robotd_placement::geometry::rests_on`]): an object whose centre lies on a lower object's
//! footprint stands on that one's top.

use super::Track;
use robotd_placement::geometry::Rect;
pub use robotd_placement::geometry::STACK_SUPPORT_TOLERANCE_M;
use robotd_protocol::geometry::Point2;

/// A detection matching nothing whose centre lies this far beyond a stack's footprint is still
/// a piece of that stack, metres.
pub const STACK_FRAGMENT_MARGIN_M: f64 = 0.01;

impl Track {
    /// On the table of workspace `ws` (reported, not held).
    pub(super) fn on_table_of(&self, ws: &str) -> bool {
        self.reported && !self.held && self.object.workspace_id == ws
    }

    /// Height of its top above the table, metres.
    pub(super) fn top_z(&self) -> f64 {
        (2.0 * self.object.position.center_of_mass.z_m - self.base_z_m).max(self.base_z_m)
    }

    /// Its own height, base to top, metres.
    pub(super) fn own_height(&self) -> f64 {
        self.top_z() - self.base_z_m
    }

    /// Stands on a surface at `base_z` (0: the table), keeping its own height.
    pub(super) fn set_base(&mut self, base_z: f64) {
        let half = self.own_height() / 2.0;
        self.base_z_m = base_z;
        self.object.position.center_of_mass.z_m = base_z + half;
        self.object.position.center.z_m = base_z + half;
    }
}

/// Which tracks are part of a stack: on the table and resting on another on the table, or
/// carrying one.
pub(super) fn in_stack(tracks: &[Track]) -> Vec<bool> {
    let mut stacked = vec![false; tracks.len()];
    for (i, upper) in tracks.iter().enumerate() {
        let Some(support) = &upper.support else {
            continue;
        };
        let ws = upper.object.workspace_id.as_str();
        if !upper.on_table_of(ws) {
            continue;
        }
        if let Some(lower) = tracks
            .iter()
            .position(|t| t.on_table_of(ws) && t.object.id == *support)
        {
            stacked[i] = true;
            stacked[lower] = true;
        }
    }
    stacked
}

/// The track an object put down at `at` in workspace `ws` stands on: of the objects on that
/// table other than `id`, the one with the highest top whose footprint holds `at`.
pub(super) fn support_at(tracks: &[Track], id: &str, at: Point2, ws: &str) -> Option<usize> {
    let spot = Rect::footprint(at, (0.0, 0.0));
    tracks
        .iter()
        .enumerate()
        .filter(|(_, t)| t.on_table_of(ws) && t.object.id != id)
        .filter(|(_, t)| {
            Rect::of_object(&t.object)
                .grown(STACK_SUPPORT_TOLERANCE_M)
                .contains(&spot)
        })
        .max_by(|(_, a), (_, b)| a.top_z().total_cmp(&b.top_z()))
        .map(|(i, _)| i)
}

/// The stacked track (of `stacked`) whose footprint, grown by [`STACK_FRAGMENT_MARGIN_M`],
/// holds `at` in workspace `ws`: the lowest, as what shows around a stack is its lower part.
pub(super) fn stack_under(
    tracks: &[Track],
    stacked: &[bool],
    at: Point2,
    ws: &str,
) -> Option<usize> {
    let spot = Rect::footprint(at, (0.0, 0.0));
    tracks
        .iter()
        .enumerate()
        .filter(|(i, t)| stacked[*i] && t.on_table_of(ws))
        .filter(|(_, t)| {
            Rect::of_object(&t.object)
                .grown(STACK_FRAGMENT_MARGIN_M)
                .contains(&spot)
        })
        .min_by(|(_, a), (_, b)| a.base_z_m.total_cmp(&b.base_z_m))
        .map(|(i, _)| i)
}

#[cfg(test)]
mod tests {
    use super::super::Tracker;
    use robotd_protocol::geometry::{Point2, Point3};
    use robotd_protocol::objects::{DetectedObject, Detections};

    fn object(label: &str, x: f64, y: f64, side: f64, z: f64) -> DetectedObject {
        let mut o = DetectedObject {
            label: label.into(),
            confidence: 0.99,
            ..Default::default()
        };
        o.position.center_of_mass = Point3::new(x, y, z);
        o.position.center = o.position.center_of_mass;
        o.dimensions.width_m = side;
        o.dimensions.height_m = side;
        o.dimensions.size_m2 = side * side;
        o
    }

    fn view(t: u64, objects: Vec<DetectedObject>) -> Detections {
        Detections {
            frame_id: t,
            workspace_id: "niryo_ws".into(),
            timestamp_unix_ns: t * 100_000_000,
            source: "robotd".into(),
            steady: true,
            objects,
        }
    }

    /// `(id, label, x, y, z)` of what is on the table, by id.
    fn table(tracker: &Tracker) -> Vec<(String, String, [f64; 3])> {
        let mut v: Vec<_> = tracker
            .on_table("niryo_ws")
            .map(|o| {
                let c = o.position.center_of_mass;
                (o.id.clone(), o.label.clone(), [c.x_m, c.y_m, c.z_m])
            })
            .collect();
        v.sort_by(|a, b| a.0.cmp(&b.0));
        v
    }

    fn near(a: [f64; 3], b: [f64; 3]) -> bool {
        a.iter().zip(b).all(|(p, q)| (p - q).abs() < 1e-9)
    }

    /// The default scene's red cube and green cylinder, seen in two views.
    fn cube_and_cylinder() -> Tracker {
        let mut tracker = Tracker::new(3);
        let scene = vec![
            object("red cube", 0.28, 0.04, 0.03, 0.015),
            object("green cylinder", 0.30, -0.06, 0.03, 0.02),
        ];
        tracker.apply(&view(1, scene.clone())).unwrap();
        tracker.apply(&view(2, scene)).unwrap();
        tracker
    }

    /// What the camera shows of the cylinder on the cube (the simulator's views): its top face,
    /// larger and shifted, and the cube's corners as a "red cylinder".
    fn stack_view(t: u64) -> Detections {
        let mut top = object("green cylinder", 0.2845, 0.0436, 0.0325, 0.02);
        top.confidence = 0.99;
        let mut corners = object("red cylinder", 0.2754, 0.0359, 0.0307, 0.01);
        corners.confidence = 0.6;
        view(t, vec![top, corners])
    }

    #[test]
    fn a_stack_keeps_its_two_objects_their_names_and_heights_over_many_views() {
        let mut tracker = cube_and_cylinder();
        tracker.pick("obj-2").unwrap();
        let placed = tracker
            .place("obj-2", Point2::new(0.28, 0.04), "niryo_ws")
            .unwrap();
        // On the cube's top (0.03) plus half its own 40 mm.
        assert!((placed.position.center_of_mass.z_m - 0.05).abs() < 1e-9);
        let want = [
            (
                "obj-1".to_owned(),
                "red cube".to_owned(),
                [0.28, 0.04, 0.015],
            ),
            (
                "obj-2".to_owned(),
                "green cylinder".to_owned(),
                [0.28, 0.04, 0.05],
            ),
        ];
        for t in 3..30 {
            // Some views show the cube's corners, some do not show it at all.
            let mut v = stack_view(t);
            if t % 3 == 0 {
                v.objects.pop();
            }
            let tracked = tracker.apply(&v).unwrap();
            // The top face is the cylinder, the corners around it the cube beneath.
            let boxes = ["obj-2", "obj-1"];
            assert_eq!(tracked.detection_ids, boxes[..v.objects.len()], "view {t}");
            let now = table(&tracker);
            assert_eq!(now.len(), 2, "view {t}: {now:?}");
            for (got, want) in now.iter().zip(&want) {
                assert_eq!((&got.0, &got.1), (&want.0, &want.1), "view {t}");
                assert!(near(got.2, want.2), "view {t}: {got:?}");
            }
            assert!(!tracker.has_candidates("niryo_ws"), "view {t}");
        }
    }

    #[test]
    fn pieces_of_a_stack_are_never_new_objects() {
        let mut tracker = cube_and_cylinder();
        tracker.pick("obj-2").unwrap();
        tracker
            .place("obj-2", Point2::new(0.28, 0.04), "niryo_ws")
            .unwrap();
        for t in 3..10 {
            let mut v = stack_view(t);
            // A side face of another colour just beside the footprint.
            v.objects
                .push(object("orange box", 0.28, 0.062, 0.012, 0.01));
            let tracked = tracker.apply(&v).unwrap();
            // One piece stands for the cube beneath; the other names nothing.
            assert_eq!(tracked.detection_ids, ["obj-2", "obj-1", ""], "view {t}");
        }
        assert_eq!(table(&tracker).len(), 2, "{:?}", table(&tracker));
        // An object 3 cm beside the stack is an object.
        for t in 10..12 {
            let mut v = stack_view(t);
            v.objects.push(object("blue cube", 0.28, 0.09, 0.02, 0.01));
            tracker.apply(&v).unwrap();
        }
        assert_eq!(table(&tracker).len(), 3, "{:?}", table(&tracker));
    }

    #[test]
    fn the_lower_object_is_itself_again_once_the_top_is_picked() {
        let mut tracker = cube_and_cylinder();
        tracker.pick("obj-2").unwrap();
        tracker
            .place("obj-2", Point2::new(0.28, 0.04), "niryo_ws")
            .unwrap();
        for t in 3..8 {
            tracker.apply(&stack_view(t)).unwrap();
        }
        tracker.pick("obj-2").unwrap();
        // The cylinder goes back on the table; the cube is measured again by the next
        // view (not while the cylinder is held: it hangs in the camera's view, see the
        // tracker's "While holding").
        let placed = tracker
            .place("obj-2", Point2::new(0.20, -0.02), "niryo_ws")
            .unwrap();
        assert!((placed.position.center_of_mass.z_m - 0.02).abs() < 1e-9);
        let cube = view(
            8,
            vec![
                object("red cube", 0.281, 0.041, 0.03, 0.015),
                object("green cylinder", 0.20, -0.02, 0.03, 0.02),
            ],
        );
        tracker.apply(&cube).unwrap();
        let now = table(&tracker);
        assert!(near(now[0].2, [0.281, 0.041, 0.015]), "{now:?}");
        assert_eq!(now[0].1, "red cube");
        // Three high: a cylinder on the cylinder on the cube.
        tracker
            .place("obj-2", Point2::new(0.281, 0.041), "niryo_ws")
            .unwrap();
        tracker
            .apply(&view(
                9,
                vec![object("green cylinder", 0.20, -0.02, 0.03, 0.02)],
            ))
            .unwrap();
        tracker
            .apply(&view(
                10,
                vec![object("green cylinder", 0.20, -0.02, 0.03, 0.02)],
            ))
            .unwrap();
        let third = table(&tracker)
            .into_iter()
            .find(|o| o.2[0] == 0.20)
            .expect("a new cylinder");
        tracker
            .place(&third.0, Point2::new(0.281, 0.041), "niryo_ws")
            .unwrap();
        let top = tracker.get(&third.0).unwrap();
        assert!((top.position.center_of_mass.z_m - 0.09).abs() < 1e-9);
    }
}
