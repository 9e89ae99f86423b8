//! Object tracking across camera frames: stable ids, one name per object, agreement of views,
//! expiry, and the skills' picks and places.
//!
//! A detector reports each frame afresh, with no idea that the red cube of this frame is the
//! red cube of the last one. The tracker gives every object an id that stays the same while the
//! object is tracked, so a client can say "obj-7" across calls.
//!
//! **Association** ([`association`]). Each detection of a frame is matched to a remembered
//! object of the same workspace: one the detector called by the detection's label in a recent
//! view (case-insensitive) whose centre of mass is within [`ASSOCIATION_GATE_M`], or — whatever
//! the label — one at the detection's place: from the same detector, within
//! [`RELABEL_GATE_M`], of the same footprint (size and orientation). Pairs are taken greedily,
//! cheapest first (a differing label costs [`RELABEL_PENALTY_M`] more), each object and each
//! detection at most once, so two objects close together keep their own detections. A matched
//! object takes the new measurement (position, size, rotation, …) and keeps its id.
//!
//! **One name per object** ([`votes`]). An object's label is the one its detector gave most
//! often over its last [`LABEL_VOTES`] views (a tie keeps the label it has): a detector calling
//! the pencil "yellow bar" in one view neither renames it nor makes a second object of it. An
//! object a skill moved keeps the name it had: where it was put the camera may see it at
//! another angle (near the sheet's edge, a cylinder's side shows and it reads as a "green
//! box"), but it is the object the skill picked.
//!
//! **Agreement of views.** A detection of the built-in detector ([`BUILTIN_SOURCE`]) matching
//! nothing starts a *candidate*: not reported (not in [`Tracker::on_table`], no id), until it is
//! seen in [`CONFIRM_VIEWS`] views — its second sighting must come within the next two views
//! of that detector ([`CANDIDATE_MISSES`] misses drop it) — and then it becomes an object with
//! the next id of a per-process counter (`obj-1`, `obj-2`, …; an id is never reused). A one-view
//! phantom is never reported and uses no id. External detectors (the Redis edge, Python actors)
//! may answer a single frame and are trusted as they are (`redis.trust`): what they find is an
//! object at once. An object placed by a skill is reported where it was put (below).
//! [`Tracker::has_candidates`] tells a query waiting for a fresh view that one more view would
//! settle what is on the table.
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
//! the name (it wins over the detector's votes), while `detected_as` keeps what the detector
//! calls it (e.g. `unknown object`). The name survives new measurements, picks and places, and
//! goes when the object is forgotten or named again; naming it what the detector calls it
//! undoes the name.
//!
//! **Skills.** A picked object is *held*: it leaves the table (queries, free space), is not
//! matched and never expires — so whatever is put at its old place later is a new object. A
//! placed object is back on the table where the skill put it, reported at once but
//! *unconfirmed*: any steady view of its workspace may confirm it (match it near there) or miss
//! it, and missed `expire_after_frames` times it is forgotten like any other.
//!
//! **While holding.** The held object hangs in the wrist camera's view, close to the lens, and
//! hides the part of the table behind it; perception drops its image (and with it whatever
//! merges with it), but an object partly behind it is measured by what shows of it: its centre
//! shifted by millimetres, away from the hidden part. Places are planned from views taken
//! while holding, so such a view must not move what it half sees (a free spot planned beside
//! it would run the held object into it, or a spot suggested before the pick would be refused
//! after it). While any object is held, a view therefore only confirms the reported objects on
//! the table (their position, size and label stay those measured without the held object in
//! view) and ages none of them (one wholly behind it is hidden, not gone); nothing on the
//! table moves meanwhile, as the gripper cannot push while it holds. Candidates and new
//! objects are measured as always.

mod association;
mod stacks;
mod votes;

pub use association::{
    same_footprint, ASSOCIATION_GATE_M, FOOTPRINT_RATIO, ORIENTATION_TOLERANCE_RAD, RELABEL_GATE_M,
    RELABEL_PENALTY_M,
};
pub use stacks::{STACK_FRAGMENT_MARGIN_M, STACK_SUPPORT_TOLERANCE_M};
pub use votes::LABEL_VOTES;

use robotd_protocol::geometry::{Point2, Point3};
use robotd_protocol::objects::{DetectedObject, Detections};
use robotd_protocol::validate::{Validate, ValidationError};
use robotd_protocol::workspace::TrackedObjects;
use std::collections::HashMap;

/// The built-in detector's `source` in its [`Detections`]: its new objects need agreeing views.
pub const BUILTIN_SOURCE: &str = "robotd";

/// Views of the built-in detector a new object must be seen in before it is reported.
pub const CONFIRM_VIEWS: u32 = 2;

/// Views in a row of its detector a candidate may be missed in before it is dropped (at most
/// `expire_after_frames`): with [`CONFIRM_VIEWS`] = 2, seen in 2 of 3 views.
pub const CANDIDATE_MISSES: u32 = 2;

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
    /// What the detector calls it: the label of most votes.
    detected_as: String,
    /// The detector's labels of its recent views.
    votes: votes::LabelVotes,
    /// Named by `label_object`: `object.label` is the name, not the detector's label.
    named: bool,
    /// Reported, with an id; false for a candidate waiting for agreeing views.
    reported: bool,
    /// Views it was seen in while a candidate.
    sightings: u32,
    /// The id of the object it stands on, when a skill stacked it ([`stacks`]).
    support: Option<String>,
    /// Height of the surface it stands on, metres (0: the table).
    base_z_m: f64,
    /// A skill moved it: it is the object it was before, whatever the detector calls it where
    /// it was put (its name no longer follows the votes).
    moved: bool,
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

        // Greedy association, cheapest pairs first (see `association`).
        let stacked = stacks::in_stack(&self.tracks);
        // The held object hides part of the table (see "While holding" above).
        let holding = self.tracks.iter().any(|t| t.held);
        let pairs = association::pairs(&self.tracks, ws, source, &detections.objects);
        let mut track_seen = vec![false; self.tracks.len()];
        let mut det_taken = vec![false; detections.objects.len()];
        // Which track each detection was taken for (a piece of a stack: none).
        let mut det_track: Vec<Option<usize>> = vec![None; detections.objects.len()];
        for (_, t, d) in pairs {
            if track_seen[t] || det_taken[d] {
                continue;
            }
            track_seen[t] = true;
            det_taken[d] = true;
            det_track[d] = Some(t);
            let track = &mut self.tracks[t];
            track.missed = 0;
            track.confirmed = true;
            track.source = source.to_owned();
            if stacked[t] || (holding && track.reported) {
                // Part of a stack (see `stacks`), or maybe half behind the held object: seen,
                // but not measurable there.
                track.object.timestamp_unix_s = detections.objects[d].timestamp_unix_s;
                continue;
            }
            let id = std::mem::take(&mut track.object.id);
            let name = std::mem::take(&mut track.object.label);
            track.object = detections.objects[d].clone();
            track.object.id = id;
            track.votes.push(&track.object.label);
            if !track.moved {
                track.detected_as = track.votes.winner(&track.detected_as);
            }
            track.object.label = if track.named {
                name
            } else {
                track.detected_as.clone()
            };
            track.object.workspace_id = ws.to_owned();
            track.support = None;
            track.base_z_m = 0.0;
            if !track.reported {
                track.sightings += 1;
            }
        }

        // What shows of a stack around its top is a piece of it, not a new object.
        for (d, det) in detections.objects.iter().enumerate() {
            if det_taken[d] {
                continue;
            }
            if let Some(t) = stacks::stack_under(&self.tracks, &stacked, det.xy(), ws) {
                det_taken[d] = true;
                // The first piece shows the object beneath; more pieces show nothing new.
                if !track_seen[t] {
                    det_track[d] = Some(t);
                }
                track_seen[t] = true;
                self.tracks[t].missed = 0;
            }
        }
        // An object carrying one that is seen is hidden, not gone.
        for t in 0..self.tracks.len() {
            let carries_seen = stacked[t]
                && self.tracks.iter().enumerate().any(|(u, upper)| {
                    track_seen[u] && upper.support.as_deref() == Some(&self.tracks[t].object.id)
                });
            if carries_seen {
                track_seen[t] = true;
                self.tracks[t].missed = 0;
            }
        }

        // Objects this view could have seen and did not age; too old ones are forgotten, and
        // candidates missed too often dropped.
        let could_see: Vec<bool> = self
            .tracks
            .iter()
            .map(|track| {
                !track.confirmed || track.source == source || self.silent(&track.source, ws, now)
            })
            .collect();
        let limit = self.expire_after_frames;
        let candidate_limit = limit.min(CANDIDATE_MISSES);
        let mut index = 0;
        // Where each track is after the forgotten ones are gone.
        let mut kept_at: Vec<Option<usize>> = vec![None; self.tracks.len()];
        let mut kept = 0;
        self.tracks.retain_mut(|track| {
            let i = index;
            index += 1;
            let keep = track_seen[i]
                || track.held
                || (holding && track.reported)
                || track.object.workspace_id != ws
                || !could_see[i]
                || {
                    track.missed += 1;
                    track.missed
                        < if track.reported {
                            limit
                        } else {
                            candidate_limit
                        }
                };
            if keep {
                kept_at[i] = Some(kept);
                kept += 1;
            }
            keep
        });
        for t in det_track.iter_mut() {
            *t = t.and_then(|t| kept_at[t]);
        }
        // An object whose support was forgotten stands on the table as far as memory knows.
        for i in 0..self.tracks.len() {
            let Some(support) = &self.tracks[i].support else {
                continue;
            };
            if !self
                .tracks
                .iter()
                .any(|t| t.reported && t.object.id == *support)
            {
                self.tracks[i].support = None;
                self.tracks[i].set_base(0.0);
            }
        }

        // Candidates seen often enough are reported, first seen first.
        for track in self.tracks.iter_mut() {
            if !track.reported && track.sightings >= CONFIRM_VIEWS {
                track.reported = true;
                track.object.id = format!("obj-{}", self.next_id);
                self.next_id += 1;
            }
        }

        // What matched nothing is new: a candidate when the built-in detector saw it, else an
        // object at once.
        for (d, det) in detections.objects.iter().enumerate() {
            if det_taken[d] {
                continue;
            }
            let mut object = det.clone();
            let reported = source != BUILTIN_SOURCE || CONFIRM_VIEWS <= 1;
            if reported {
                object.id = format!("obj-{}", self.next_id);
                self.next_id += 1;
            } else {
                object.id.clear();
            }
            object.workspace_id = ws.to_owned();
            det_track[d] = Some(self.tracks.len());
            self.tracks.push(Track {
                detected_as: object.label.clone(),
                votes: votes::LabelVotes::new(&object.label),
                object,
                missed: 0,
                held: false,
                confirmed: true,
                source: source.to_owned(),
                named: false,
                reported,
                sightings: 1,
                support: None,
                base_z_m: 0.0,
                moved: false,
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
            source: source.to_owned(),
            detection_ids: det_track
                .iter()
                .map(|t| match t.map(|t| &self.tracks[t]) {
                    Some(track) if track.on_table_of(ws) => track.object.id.clone(),
                    _ => String::new(),
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
            .filter(move |t| t.reported && !t.held && t.object.workspace_id == ws)
            .map(|t| &t.object)
    }

    /// Whether workspace `ws` has candidates: detections seen in one view that the next views
    /// will report or drop.
    pub fn has_candidates(&self, ws: &str) -> bool {
        self.tracks
            .iter()
            .any(|t| !t.reported && t.object.workspace_id == ws)
    }

    /// The reported tracks (candidates have no id yet).
    fn reported(&self) -> impl Iterator<Item = &Track> + '_ {
        self.tracks.iter().filter(|t| t.reported)
    }

    /// The objects in the gripper.
    pub fn held(&self) -> impl Iterator<Item = &DetectedObject> + '_ {
        self.reported().filter(|t| t.held).map(|t| &t.object)
    }

    /// The remembered object with id `id` (on the table or held).
    pub fn get(&self, id: &str) -> Option<&DetectedObject> {
        self.reported()
            .find(|t| t.object.id == id.trim())
            .map(|t| &t.object)
    }

    /// The objects named by `label_object`: `(id, what the detector calls it)`.
    pub fn renamed(&self) -> impl Iterator<Item = (&str, &str)> + '_ {
        self.reported()
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
        self.reported()
            .find(|t| t.object.id == id.trim())
            .map(|t| t.confirmed)
    }

    fn track_mut(&mut self, id: &str) -> Result<&mut Track, UnknownObject> {
        let id = id.trim();
        match self
            .tracks
            .iter()
            .position(|t| t.reported && t.object.id == id)
        {
            Some(i) => Ok(&mut self.tracks[i]),
            None => Err(self.unknown(id)),
        }
    }

    /// The error for an id memory does not hold, naming the ids it does.
    pub fn unknown(&self, id: &str) -> UnknownObject {
        let mut ids: Vec<&str> = self.reported().map(|t| t.object.id.as_str()).collect();
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
    /// and size unchanged — or, when `at` lies on another object's footprint, on top of that
    /// one ([`stacks`]): its centre of mass at the lower one's top plus half its own height.
    pub fn place(
        &mut self,
        id: &str,
        at: Point2,
        workspace_id: &str,
    ) -> Result<&DetectedObject, UnknownObject> {
        self.track_mut(id)?;
        let support = stacks::support_at(&self.tracks, id.trim(), at, workspace_id)
            .map(|s| (self.tracks[s].object.id.clone(), self.tracks[s].top_z()));
        let track = self.track_mut(id)?;
        match support {
            Some((support, top)) => {
                track.support = Some(support);
                track.set_base(top);
            }
            None => {
                track.support = None;
                track.set_base(0.0);
            }
        }
        track.held = false;
        track.moved = true;
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
mod tests;
