//! Object tracking across camera frames: stable ids, expiry, and the skills' picks and places.
//!
//! A detector reports each frame afresh, with no idea that the red cube of this frame is the
//! red cube of the last one. The tracker gives every object an id that stays the same while the
//! object is tracked, so a client can say "obj-7" across calls.
//!
//! **Association.** Each detection of a frame is matched to a remembered object of the same
//! workspace and the same label (case-insensitive) whose centre of mass is within
//! [`ASSOCIATION_GATE_M`]; pairs are taken greedily, nearest first, each object and each
//! detection at most once. A matched object takes the new measurement (position, size,
//! rotation, …) and keeps its id. A detection matching nothing becomes a new object with the
//! next id of a per-process counter (`obj-1`, `obj-2`, …; an id is never reused).
//!
//! **Expiry.** A remembered object that a steady view of its workspace does not show is
//! *missed*; missed in `expire_after_frames` such views in a row, it is forgotten. Only views
//! that could have seen it count: views from the detector that last confirmed it (the built-in
//! detector cannot see what only an external model finds, and the other way round), or from
//! any detector once that one has sent no view of the workspace for [`SOURCE_SILENT_AFTER_NS`]
//! (a stopped detector leaves no ghosts). Frames taken while the arm moved, frames of no
//! workspace, and frames older than the newest view already applied from the same detector
//! change nothing.
//!
//! **Names.** `label_object` names a tracked object ([`Tracker::name`]): its `label` becomes
//! the name, while its views keep being matched by what the detector calls it (`detected_as`,
//! e.g. `unknown object`). The name survives new measurements, picks and places, and goes
//! when the object is forgotten or named again; naming it what the detector calls it undoes
//! the name.
//!
//! **Skills.** A picked object is *held*: it leaves the table (queries, free space), is not
//! matched and never expires. A placed object is back on the table where the skill put it,
//! *unconfirmed*: any steady view of its workspace may confirm it (match it near there) or miss
//! it, and missed `expire_after_frames` times it is forgotten like any other.

use robotd_protocol::geometry::{Point2, Point3};
use robotd_protocol::objects::{DetectedObject, Detections};
use robotd_protocol::validate::{Validate, ValidationError};
use robotd_protocol::workspace::{RenamedObject, TrackedObjects};
use std::collections::HashMap;

/// A detection this close (centre of mass, table plane) to a remembered object of the same
/// label is that object, metres.
pub const ASSOCIATION_GATE_M: f64 = 0.03;

/// A detector that has sent no view of a workspace for this long (capture time) is taken to be
/// gone: the objects only it saw are then aged by the other detectors' views, ns.
pub const SOURCE_SILENT_AFTER_NS: u64 = 5_000_000_000;

/// Why a frame's detections changed nothing.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum IgnoredView {
    /// The arm moved while the frame was taken.
    #[error("frame {frame_id} was taken while the arm moved")]
    Moving {
        /// The frame.
        frame_id: u64,
    },
    /// No workspace sheet was in view.
    #[error("frame {frame_id} shows no workspace")]
    NoWorkspace {
        /// The frame.
        frame_id: u64,
    },
    /// The frame names a workspace that is not configured.
    #[error(
        "frame {frame_id} shows workspace '{workspace_id}', which is not configured \
         (known: {}); check the scene file and the detector's workspace ids",
        known.join(", ")
    )]
    UnknownWorkspace {
        /// The frame.
        frame_id: u64,
        /// The id it names.
        workspace_id: String,
        /// The configured ids.
        known: Vec<String>,
    },
    /// A newer view of the workspace from the same detector was already applied.
    #[error(
        "frame {frame_id} from '{source_id}' was taken at {timestamp_unix_ns} ns, before the \
         newest view of '{workspace_id}' already applied from it ({latest_unix_ns} ns)"
    )]
    Stale {
        /// The frame.
        frame_id: u64,
        /// The detector.
        source_id: String,
        /// The workspace.
        workspace_id: String,
        /// Its capture time.
        timestamp_unix_ns: u64,
        /// Capture time of the newest view applied from the same detector.
        latest_unix_ns: u64,
    },
    /// The detections are malformed (non-finite numbers, …).
    #[error("frame {frame_id} from '{source_id}' has invalid detections: {error}")]
    Invalid {
        /// The frame.
        frame_id: u64,
        /// The detector.
        source_id: String,
        /// What is wrong.
        error: ValidationError,
    },
}

/// A skill hook named an object memory does not hold.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown object id '{id}'; remembered: {remembered}")]
pub struct UnknownObject {
    /// The id asked for.
    pub id: String,
    /// The ids memory holds (at most 20, then "…"), or "none".
    pub remembered: String,
}

#[derive(Debug, Clone)]
struct Track {
    object: DetectedObject,
    /// Steady views of its workspace in a row that could have seen it and did not.
    missed: u32,
    /// In the gripper.
    held: bool,
    /// Seen by a camera where memory has it (false after a place, until a view confirms).
    confirmed: bool,
    /// The detector that last confirmed it.
    source: String,
    /// What the detector calls it: views are matched by this label.
    detected_as: String,
    /// Named by `label_object`: `object.label` is the name, not the detector's label.
    named: bool,
}

/// The remembered objects of every workspace.
#[derive(Debug)]
pub struct Tracker {
    tracks: Vec<Track>,
    next_id: u64,
    expire_after_frames: u32,
    /// Newest capture time applied per (detector, workspace).
    latest: HashMap<(String, String), u64>,
    last_view_ns: u64,
}

impl Tracker {
    /// An empty tracker forgetting objects missed in `expire_after_frames` views in a row (at
    /// least 1).
    pub fn new(expire_after_frames: u32) -> Self {
        Self {
            tracks: Vec::new(),
            next_id: 1,
            expire_after_frames: expire_after_frames.max(1),
            latest: HashMap::new(),
            last_view_ns: 0,
        }
    }

    /// Capture time of the newest steady view applied, ns since the Unix epoch (0: none yet).
    pub fn last_view_ns(&self) -> u64 {
        self.last_view_ns
    }

    /// Applies one frame's detections of a configured workspace (the caller checks that
    /// `detections.workspace_id` is configured). Returns the objects now on that workspace's
    /// table.
    pub fn apply(&mut self, detections: &Detections) -> Result<TrackedObjects, IgnoredView> {
        let frame_id = detections.frame_id;
        if !detections.steady {
            return Err(IgnoredView::Moving { frame_id });
        }
        let ws = detections.workspace_id.as_str();
        if ws.is_empty() {
            return Err(IgnoredView::NoWorkspace { frame_id });
        }
        if let Err(error) = detections.validate() {
            return Err(IgnoredView::Invalid {
                frame_id,
                source_id: detections.source.clone(),
                error,
            });
        }
        let now = detections.timestamp_unix_ns;
        let source = detections.source.as_str();
        let key = (source.to_owned(), ws.to_owned());
        if let Some(&latest) = self.latest.get(&key) {
            if now < latest {
                return Err(IgnoredView::Stale {
                    frame_id,
                    source_id: source.to_owned(),
                    workspace_id: ws.to_owned(),
                    timestamp_unix_ns: now,
                    latest_unix_ns: latest,
                });
            }
        }

        // Greedy association, nearest pairs first; same workspace and label only.
        let mut pairs: Vec<(f64, usize, usize)> = Vec::new();
        for (t, track) in self.tracks.iter().enumerate() {
            if track.held || track.object.workspace_id != ws {
                continue;
            }
            for (d, det) in detections.objects.iter().enumerate() {
                if !det.label_is(&track.detected_as) {
                    continue;
                }
                let distance = track.object.xy().distance_to(&det.xy());
                if distance <= ASSOCIATION_GATE_M {
                    pairs.push((distance, t, d));
                }
            }
        }
        pairs.sort_by(|a, b| a.0.total_cmp(&b.0));
        let mut track_seen = vec![false; self.tracks.len()];
        let mut det_taken = vec![false; detections.objects.len()];
        for (_, t, d) in pairs {
            if track_seen[t] || det_taken[d] {
                continue;
            }
            track_seen[t] = true;
            det_taken[d] = true;
            let track = &mut self.tracks[t];
            let id = std::mem::take(&mut track.object.id);
            let name = std::mem::take(&mut track.object.label);
            track.object = detections.objects[d].clone();
            track.object.id = id;
            track.detected_as.clone_from(&track.object.label);
            if track.named {
                track.object.label = name;
            }
            track.object.workspace_id = ws.to_owned();
            track.missed = 0;
            track.confirmed = true;
            track.source = source.to_owned();
        }

        // Objects this view could have seen and did not age; too old ones are forgotten.
        let could_see: Vec<bool> = self
            .tracks
            .iter()
            .map(|track| {
                !track.confirmed || track.source == source || self.silent(&track.source, ws, now)
            })
            .collect();
        let limit = self.expire_after_frames;
        let mut index = 0;
        self.tracks.retain_mut(|track| {
            let i = index;
            index += 1;
            if track_seen[i] || track.held || track.object.workspace_id != ws || !could_see[i] {
                return true;
            }
            track.missed += 1;
            track.missed < limit
        });

        // What matched nothing is new.
        for (d, det) in detections.objects.iter().enumerate() {
            if det_taken[d] {
                continue;
            }
            let mut object = det.clone();
            object.id = format!("obj-{}", self.next_id);
            self.next_id += 1;
            object.workspace_id = ws.to_owned();
            self.tracks.push(Track {
                detected_as: object.label.clone(),
                object,
                missed: 0,
                held: false,
                confirmed: true,
                source: source.to_owned(),
                named: false,
            });
        }

        let latest = self.latest.entry(key).or_insert(now);
        *latest = (*latest).max(now);
        self.last_view_ns = self.last_view_ns.max(now);
        Ok(TrackedObjects {
            workspace_id: ws.to_owned(),
            frame_id,
            timestamp_unix_ns: now,
            objects: self.on_table(ws).cloned().collect(),
            renamed: self
                .tracks
                .iter()
                .filter(|t| t.named && !t.held && t.object.workspace_id == ws)
                .map(|t| RenamedObject {
                    id: t.object.id.clone(),
                    detected_as: t.detected_as.clone(),
                })
                .collect(),
        })
    }

    /// Whether `source` has sent no view of `ws` for [`SOURCE_SILENT_AFTER_NS`] before `now`.
    fn silent(&self, source: &str, ws: &str, now: u64) -> bool {
        match self.latest.get(&(source.to_owned(), ws.to_owned())) {
            Some(&last) => now.saturating_sub(last) > SOURCE_SILENT_AFTER_NS,
            None => true,
        }
    }

    /// The objects on the table of workspace `ws` (held ones excluded), first seen first.
    pub fn on_table<'a>(&'a self, ws: &'a str) -> impl Iterator<Item = &'a DetectedObject> + 'a {
        self.tracks
            .iter()
            .filter(move |t| !t.held && t.object.workspace_id == ws)
            .map(|t| &t.object)
    }

    /// The objects in the gripper.
    pub fn held(&self) -> impl Iterator<Item = &DetectedObject> + '_ {
        self.tracks.iter().filter(|t| t.held).map(|t| &t.object)
    }

    /// The remembered object with id `id` (on the table or held).
    pub fn get(&self, id: &str) -> Option<&DetectedObject> {
        self.tracks
            .iter()
            .find(|t| t.object.id == id.trim())
            .map(|t| &t.object)
    }

    /// The objects named by `label_object`: `(id, what the detector calls it)`.
    pub fn renamed(&self) -> impl Iterator<Item = (&str, &str)> + '_ {
        self.tracks
            .iter()
            .filter(|t| t.named)
            .map(|t| (t.object.id.as_str(), t.detected_as.as_str()))
    }

    /// Names the object `id` `label` (the caller normalises it): its label is `label` from now
    /// on, while its views are still matched by what the detector calls it. Naming it that
    /// undoes the name. Returns the object, its label before, and what the detector calls it.
    pub fn name(
        &mut self,
        id: &str,
        label: &str,
    ) -> Result<(&DetectedObject, String, String), UnknownObject> {
        let track = self.track_mut(id)?;
        let previous = std::mem::replace(&mut track.object.label, label.to_owned());
        track.named = !track.object.label_is(&track.detected_as);
        if !track.named {
            track.object.label.clone_from(&track.detected_as);
        }
        Ok((&track.object, previous, track.detected_as.clone()))
    }

    /// Whether the object `id` has been seen by a camera where memory has it.
    pub fn is_confirmed(&self, id: &str) -> Option<bool> {
        self.tracks
            .iter()
            .find(|t| t.object.id == id.trim())
            .map(|t| t.confirmed)
    }

    fn track_mut(&mut self, id: &str) -> Result<&mut Track, UnknownObject> {
        let id = id.trim();
        match self.tracks.iter().position(|t| t.object.id == id) {
            Some(i) => Ok(&mut self.tracks[i]),
            None => Err(self.unknown(id)),
        }
    }

    /// The error for an id memory does not hold, naming the ids it does.
    pub fn unknown(&self, id: &str) -> UnknownObject {
        let mut ids: Vec<&str> = self.tracks.iter().map(|t| t.object.id.as_str()).collect();
        let more = ids.len() > 20;
        ids.truncate(20);
        let remembered = if ids.is_empty() {
            "none".to_owned()
        } else if more {
            format!("{}, …", ids.join(", "))
        } else {
            ids.join(", ")
        };
        UnknownObject {
            id: id.trim().to_owned(),
            remembered,
        }
    }

    /// The skills picked `id` up: it is held (off the table, not matched, never expired) until
    /// placed. Picking a held object again changes nothing.
    pub fn pick(&mut self, id: &str) -> Result<&DetectedObject, UnknownObject> {
        let track = self.track_mut(id)?;
        track.held = true;
        track.missed = 0;
        Ok(&track.object)
    }

    /// The skills put `id` down at `at` in workspace `workspace_id` (held or not: a push moves
    /// an object without holding it). It is on the table there, unconfirmed, with its height
    /// and size unchanged.
    pub fn place(
        &mut self,
        id: &str,
        at: Point2,
        workspace_id: &str,
    ) -> Result<&DetectedObject, UnknownObject> {
        let track = self.track_mut(id)?;
        track.held = false;
        track.confirmed = false;
        track.missed = 0;
        track.object.workspace_id = workspace_id.to_owned();
        let position = &mut track.object.position;
        let (dx, dy) = (
            position.center.x_m - position.center_of_mass.x_m,
            position.center.y_m - position.center_of_mass.y_m,
        );
        position.center_of_mass = Point3::new(at.x_m, at.y_m, position.center_of_mass.z_m);
        position.center = Point3::new(at.x_m + dx, at.y_m + dy, position.center.z_m);
        Ok(&track.object)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn object(label: &str, x: f64, y: f64) -> DetectedObject {
        let mut o = DetectedObject {
            label: label.into(),
            ..Default::default()
        };
        o.position.center_of_mass = Point3::new(x, y, 0.01);
        o.position.center = o.position.center_of_mass;
        o.dimensions.width_m = 0.03;
        o.dimensions.height_m = 0.03;
        o.dimensions.size_m2 = 0.0009;
        o
    }

    fn view_from(source: &str, t: u64, objects: Vec<DetectedObject>) -> Detections {
        Detections {
            frame_id: t,
            workspace_id: "niryo_ws".into(),
            timestamp_unix_ns: t * 100_000_000, // 10 frames per second
            source: source.into(),
            steady: true,
            objects,
        }
    }

    fn view(t: u64, objects: Vec<DetectedObject>) -> Detections {
        view_from("robotd", t, objects)
    }

    fn ids(tracked: &TrackedObjects) -> Vec<(&str, &str)> {
        let mut v: Vec<(&str, &str)> = tracked
            .objects
            .iter()
            .map(|o| (o.id.as_str(), o.label.as_str()))
            .collect();
        v.sort();
        v
    }

    #[test]
    fn ids_stay_stable_over_100_noisy_frames() {
        let mut tracker = Tracker::new(3);
        let scene = || {
            vec![
                object("red cube", 0.30, 0.05),
                object("red cube", 0.30, 0.01), // a twin 4 cm away
                object("pencil", 0.20, -0.05),
            ]
        };
        let first = tracker.apply(&view(1, scene())).unwrap();
        assert_eq!(
            ids(&first),
            [
                ("obj-1", "red cube"),
                ("obj-2", "red cube"),
                ("obj-3", "pencil")
            ]
        );
        let where_is = |t: &TrackedObjects, id: &str| {
            t.objects
                .iter()
                .find(|o| o.id == id)
                .map(|o| o.xy())
                .unwrap()
        };
        for f in 2..=101u64 {
            // Deterministic ±2 mm noise, and the detector's order shuffled.
            let noise = |k: u64| ((f * 7 + k * 13) % 9) as f64 * 0.0005 - 0.002;
            let mut objects = scene();
            for (k, o) in objects.iter_mut().enumerate() {
                o.position.center_of_mass.x_m += noise(k as u64);
                o.position.center_of_mass.y_m -= noise(k as u64 + 5);
                if f % 2 == 0 {
                    o.label = o.label.to_uppercase();
                }
            }
            objects.rotate_left((f % 3) as usize);
            let t = tracker.apply(&view(f, objects)).unwrap();
            assert_eq!(t.objects.len(), 3, "frame {f}");
            assert!(where_is(&t, "obj-1").y_m > 0.04, "frame {f}: twins swapped");
            assert!(where_is(&t, "obj-2").y_m < 0.02, "frame {f}: twins swapped");
            assert!(where_is(&t, "obj-3").x_m < 0.21, "frame {f}");
        }
    }

    #[test]
    fn missed_objects_expire_after_n_steady_views_and_ids_are_never_reused() {
        let mut tracker = Tracker::new(3);
        tracker
            .apply(&view(
                1,
                vec![object("pencil", 0.2, 0.0), object("red cube", 0.3, 0.0)],
            ))
            .unwrap();
        let cube_only = || vec![object("red cube", 0.3, 0.0)];
        // A view during a motion and a view of no workspace change nothing.
        let mut moving = view(2, vec![]);
        moving.steady = false;
        assert_eq!(
            tracker.apply(&moving).unwrap_err(),
            IgnoredView::Moving { frame_id: 2 }
        );
        let mut elsewhere = view(3, vec![]);
        elsewhere.workspace_id.clear();
        assert!(matches!(
            tracker.apply(&elsewhere),
            Err(IgnoredView::NoWorkspace { .. })
        ));
        assert_eq!(
            tracker.apply(&view(4, cube_only())).unwrap().objects.len(),
            2
        );
        assert_eq!(
            tracker.apply(&view(5, cube_only())).unwrap().objects.len(),
            2
        );
        // Seen again before the third miss: the count starts over.
        tracker
            .apply(&view(
                6,
                vec![object("pencil", 0.2, 0.0), object("red cube", 0.3, 0.0)],
            ))
            .unwrap();
        assert_eq!(
            tracker.apply(&view(7, cube_only())).unwrap().objects.len(),
            2
        );
        assert_eq!(
            tracker.apply(&view(8, cube_only())).unwrap().objects.len(),
            2
        );
        let t = tracker.apply(&view(9, cube_only())).unwrap();
        assert_eq!(ids(&t), [("obj-2", "red cube")]);
        // The pencil comes back: a new id.
        let t = tracker
            .apply(&view(
                10,
                vec![object("pencil", 0.2, 0.0), object("red cube", 0.3, 0.0)],
            ))
            .unwrap();
        assert_eq!(ids(&t), [("obj-2", "red cube"), ("obj-3", "pencil")]);
    }

    #[test]
    fn a_moved_object_beyond_the_gate_or_relabelled_is_a_new_object() {
        let mut tracker = Tracker::new(1);
        tracker
            .apply(&view(1, vec![object("red cube", 0.3, 0.0)]))
            .unwrap();
        // 2.9 cm: same object.
        let t = tracker
            .apply(&view(2, vec![object("red cube", 0.3, 0.029)]))
            .unwrap();
        assert_eq!(ids(&t), [("obj-1", "red cube")]);
        // 3.1 cm further: another one (and obj-1, missed once, is forgotten).
        let t = tracker
            .apply(&view(3, vec![object("red cube", 0.3, 0.06)]))
            .unwrap();
        assert_eq!(ids(&t), [("obj-2", "red cube")]);
        // Same place, other label: another one.
        let t = tracker
            .apply(&view(4, vec![object("blue cube", 0.3, 0.06)]))
            .unwrap();
        assert_eq!(ids(&t), [("obj-3", "blue cube")]);
    }

    #[test]
    fn stale_and_invalid_views_change_nothing() {
        let mut tracker = Tracker::new(1);
        tracker
            .apply(&view(5, vec![object("pencil", 0.2, 0.0)]))
            .unwrap();
        let err = tracker.apply(&view(4, vec![])).unwrap_err();
        assert!(matches!(err, IgnoredView::Stale { .. }));
        assert!(
            err.to_string()
                .contains("before the newest view of 'niryo_ws'"),
            "{err}"
        );
        let mut bad = object("pencil", 0.2, 0.0);
        bad.position.center_of_mass.x_m = f64::NAN;
        let err = tracker.apply(&view(6, vec![bad])).unwrap_err();
        assert!(
            err.to_string()
                .contains("invalid detections: objects[0].position.center_of_mass.x"),
            "{err}"
        );
        assert_eq!(tracker.on_table("niryo_ws").count(), 1);
        assert_eq!(tracker.last_view_ns(), 500_000_000);
    }

    #[test]
    fn a_detector_ages_only_what_it_could_have_seen_until_the_other_falls_silent() {
        let mut tracker = Tracker::new(2);
        // The built-in detector sees the cube, an external model the screwdriver.
        tracker
            .apply(&view(1, vec![object("red cube", 0.3, 0.0)]))
            .unwrap();
        tracker
            .apply(&view_from("yolo", 1, vec![object("screwdriver", 0.2, 0.0)]))
            .unwrap();
        // Ten built-in views without the screwdriver do not forget it, nor yolo views the cube.
        for t in 2..12 {
            let a = tracker
                .apply(&view(t, vec![object("red cube", 0.3, 0.0)]))
                .unwrap();
            let b = tracker
                .apply(&view_from("yolo", t, vec![object("screwdriver", 0.2, 0.0)]))
                .unwrap();
            assert_eq!(a.objects.len(), 2);
            assert_eq!(b.objects.len(), 2);
        }
        // The external model stops. Within 5 s the screwdriver stays; after it, two built-in
        // views without it forget it.
        let cube = || vec![object("red cube", 0.3, 0.0)];
        assert_eq!(tracker.apply(&view(61, cube())).unwrap().objects.len(), 2);
        assert_eq!(tracker.apply(&view(62, cube())).unwrap().objects.len(), 2);
        let t = tracker.apply(&view(63, cube())).unwrap();
        assert_eq!(ids(&t), [("obj-1", "red cube")]);
    }

    #[test]
    fn held_objects_never_expire_and_placed_ones_wait_for_confirmation() {
        let mut tracker = Tracker::new(2);
        tracker
            .apply(&view(
                1,
                vec![object("red cube", 0.3, 0.05), object("pencil", 0.2, 0.0)],
            ))
            .unwrap();
        assert_eq!(tracker.pick("obj-1").unwrap().label, "red cube");
        for t in 2..10 {
            let tracked = tracker
                .apply(&view(t, vec![object("pencil", 0.2, 0.0)]))
                .unwrap();
            assert_eq!(ids(&tracked), [("obj-2", "pencil")]);
        }
        assert_eq!(tracker.held().count(), 1);
        let placed = tracker
            .place(" obj-1 ", Point2::new(0.25, -0.05), "niryo_ws")
            .unwrap();
        assert_eq!(placed.xy(), Point2::new(0.25, -0.05));
        assert_eq!(tracker.is_confirmed("obj-1"), Some(false));
        // Seen 1 cm from where it was put: confirmed, same id.
        let seen = vec![object("pencil", 0.2, 0.0), object("red cube", 0.26, -0.05)];
        let t = tracker.apply(&view(10, seen)).unwrap();
        assert_eq!(ids(&t), [("obj-1", "red cube"), ("obj-2", "pencil")]);
        assert_eq!(tracker.is_confirmed("obj-1"), Some(true));
        // Placed again, but the camera does not find it there: forgotten after 2 views.
        tracker
            .place("obj-1", Point2::new(0.18, 0.07), "niryo_ws")
            .unwrap();
        tracker
            .apply(&view(11, vec![object("pencil", 0.2, 0.0)]))
            .unwrap();
        assert!(tracker.get("obj-1").is_some());
        tracker
            .apply(&view(12, vec![object("pencil", 0.2, 0.0)]))
            .unwrap();
        assert!(tracker.get("obj-1").is_none());
        // Unknown ids are refused naming what memory holds.
        assert_eq!(
            tracker.pick("obj-1").unwrap_err().to_string(),
            "unknown object id 'obj-1'; remembered: obj-2"
        );
        assert_eq!(
            Tracker::new(3).pick("obj-9").unwrap_err().to_string(),
            "unknown object id 'obj-9'; remembered: none"
        );
    }

    #[test]
    fn a_name_stays_with_its_object_across_views_picks_and_places_until_it_leaves() {
        let mut tracker = Tracker::new(2);
        let unknown = |x, y| object("unknown object", x, y);
        tracker
            .apply(&view(1, vec![unknown(0.25, 0.0), unknown(0.30, 0.05)]))
            .unwrap();
        let (named, previous, detected_as) = tracker.name("obj-1", "screwdriver").unwrap();
        assert_eq!(named.label, "screwdriver");
        assert_eq!(
            (previous.as_str(), detected_as.as_str()),
            ("unknown object", "unknown object")
        );
        // New measurements are matched by the detector's label and keep the name.
        let t = tracker
            .apply(&view(2, vec![unknown(0.251, 0.0), unknown(0.30, 0.05)]))
            .unwrap();
        assert_eq!(
            ids(&t),
            [("obj-1", "screwdriver"), ("obj-2", "unknown object")]
        );
        assert_eq!(
            tracker.renamed().collect::<Vec<_>>(),
            [("obj-1", "unknown object")]
        );
        // Picked, placed elsewhere, seen there: still named.
        tracker.pick("obj-1").unwrap();
        tracker
            .place("obj-1", Point2::new(0.20, -0.05), "niryo_ws")
            .unwrap();
        assert_eq!(tracker.get("obj-1").unwrap().label, "screwdriver");
        let t = tracker
            .apply(&view(3, vec![unknown(0.201, -0.05), unknown(0.30, 0.05)]))
            .unwrap();
        assert_eq!(
            ids(&t),
            [("obj-1", "screwdriver"), ("obj-2", "unknown object")]
        );
        // Named again, then back to what the detector calls it.
        tracker.name("obj-1", "chisel").unwrap();
        assert_eq!(tracker.get("obj-1").unwrap().label, "chisel");
        tracker.name("obj-1", "Unknown Object").unwrap();
        assert_eq!(tracker.get("obj-1").unwrap().label, "unknown object");
        assert_eq!(tracker.renamed().count(), 0);
        tracker.name("obj-1", "chisel").unwrap();
        // Gone from two views: forgotten, and its name with it; a new object there is new.
        tracker.apply(&view(4, vec![unknown(0.30, 0.05)])).unwrap();
        tracker.apply(&view(5, vec![unknown(0.30, 0.05)])).unwrap();
        assert!(tracker.get("obj-1").is_none());
        let t = tracker
            .apply(&view(6, vec![unknown(0.201, -0.05), unknown(0.30, 0.05)]))
            .unwrap();
        assert_eq!(
            ids(&t),
            [("obj-2", "unknown object"), ("obj-3", "unknown object")]
        );
        assert!(tracker.name("obj-1", "x").is_err());
    }
}
