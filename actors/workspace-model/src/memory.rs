//! The scene memory: which objects lie where, with ids that stay the same while they are
//! tracked, and the answers to every detection and workspace question of the MCP tools.
//!
//! Detections come per camera frame. Only *steady* frames (the arm stood still) of a
//! workspace in view update memory. Each detection is associated with the remembered object of
//! the same label nearest to it (within [`ASSOCIATION_GATE_M`]), greedily by distance; the
//! object takes the new measurement and keeps its id. Detections matching nothing become new
//! objects with fresh ids (`obj-1`, `obj-2`, … never reused). A remembered object the camera
//! misses in `expire_after_frames` steady views of its workspace in a row is forgotten.
//!
//! The skills tell memory what they did: a picked object is *held* (off the table: out of the
//! queries and the free-space map); a placed one is back on the table where it was put,
//! unconfirmed until the camera sees it there.

use crate::free_space::largest_free_space;
use robotd_protocol::geometry::Point3;
use robotd_protocol::location::CLOSE_TO_RADIUS_M;
use robotd_protocol::objects::{DetectedObject, Detections};
use robotd_protocol::workspace::{
    TrackedObjects, WorkspaceError, WorkspaceInfo, WorkspaceReply, WorkspaceRequest,
};

/// A detection this close to a remembered object of the same label is that object, metres.
pub const ASSOCIATION_GATE_M: f64 = 0.03;

/// Settings of the memory.
#[derive(Debug, Clone, PartialEq)]
pub struct MemorySettings {
    /// Margin around objects for the free-space search, metres.
    pub free_space_margin_m: f64,
    /// Steady views of its workspace an object may be missed in before it is forgotten.
    pub expire_after_frames: u32,
}

impl Default for MemorySettings {
    fn default() -> Self {
        Self {
            free_space_margin_m: 0.01,
            expire_after_frames: 3,
        }
    }
}

#[derive(Debug, Clone)]
struct Tracked {
    object: DetectedObject,
    missed: u32,
    held: bool,
    confirmed: bool,
}

/// Workspaces, remembered objects and detectable labels.
#[derive(Debug)]
pub struct SceneMemory {
    settings: MemorySettings,
    workspaces: Vec<WorkspaceInfo>,
    objects: Vec<Tracked>,
    next_id: u64,
    current: Option<usize>,
    last_view_ns: u64,
    labels: Vec<String>,
    builtin: Vec<String>,
}

impl SceneMemory {
    /// Memory of `workspaces`, with the detectable labels `labels` of which the built-in
    /// detector sees `builtin`.
    pub fn new(
        workspaces: Vec<WorkspaceInfo>,
        labels: &[String],
        builtin: &[String],
        settings: MemorySettings,
    ) -> Self {
        let mut memory = Self {
            settings,
            workspaces,
            objects: Vec::new(),
            next_id: 1,
            current: None,
            last_view_ns: 0,
            labels: Vec::new(),
            builtin: builtin.iter().map(|l| l.trim().to_lowercase()).collect(),
        };
        for label in labels.iter().chain(builtin) {
            memory.add_label(label);
        }
        memory
    }

    /// Capture time of the latest steady view applied, ns since the Unix epoch (0: none yet).
    pub fn last_view_ns(&self) -> u64 {
        self.last_view_ns
    }

    /// The workspace the object questions are about: the one last seen, else the first.
    pub fn current_workspace(&self) -> Option<&WorkspaceInfo> {
        self.current
            .and_then(|i| self.workspaces.get(i))
            .or(self.workspaces.first())
    }

    /// The configured workspaces.
    pub fn workspaces(&self) -> &[WorkspaceInfo] {
        &self.workspaces
    }

    /// The detectable labels.
    pub fn labels(&self) -> &[String] {
        &self.labels
    }

    /// Adds a label (trimmed, lower-case); false when it was already known or is empty.
    pub fn add_label(&mut self, label: &str) -> bool {
        let label = label.trim().to_lowercase();
        if label.is_empty() || self.labels.contains(&label) {
            return false;
        }
        self.labels.push(label);
        true
    }

    /// Applies one frame's detections. Returns the objects now remembered for its workspace
    /// when the frame updated memory (a steady view of a configured workspace), else `None`.
    pub fn apply(&mut self, detections: &Detections) -> Option<TrackedObjects> {
        if !detections.steady || detections.workspace_id.is_empty() {
            return None;
        }
        let ws_index = self
            .workspaces
            .iter()
            .position(|w| w.id == detections.workspace_id)?;
        self.current = Some(ws_index);
        self.last_view_ns = self.last_view_ns.max(detections.timestamp_unix_ns);
        let ws_id = &detections.workspace_id;

        // Greedy association by distance, same label only.
        let mut pairs: Vec<(f64, usize, usize)> = Vec::new();
        for (t, tracked) in self.objects.iter().enumerate() {
            if tracked.held || tracked.object.workspace_id != *ws_id {
                continue;
            }
            for (d, det) in detections.objects.iter().enumerate() {
                if !tracked.object.label_is(&det.label) {
                    continue;
                }
                let dist = tracked.object.xy().distance_to(&det.xy());
                if dist <= ASSOCIATION_GATE_M {
                    pairs.push((dist, t, d));
                }
            }
        }
        pairs.sort_by(|a, b| a.0.total_cmp(&b.0));
        let mut track_taken = vec![false; self.objects.len()];
        let mut det_taken = vec![false; detections.objects.len()];
        for (_, t, d) in pairs {
            if track_taken[t] || det_taken[d] {
                continue;
            }
            track_taken[t] = true;
            det_taken[d] = true;
            let tracked = &mut self.objects[t];
            let id = std::mem::take(&mut tracked.object.id);
            tracked.object = detections.objects[d].clone();
            tracked.object.id = id;
            tracked.object.workspace_id = ws_id.clone();
            tracked.missed = 0;
            tracked.confirmed = true;
        }
        // Missed objects of this workspace age; too old ones are forgotten.
        let limit = self.settings.expire_after_frames;
        let mut index = 0;
        self.objects.retain_mut(|tracked| {
            let seen = track_taken.get(index).copied().unwrap_or(true);
            index += 1;
            if seen || tracked.held || tracked.object.workspace_id != *ws_id {
                return true;
            }
            tracked.missed += 1;
            tracked.missed < limit
        });
        // New objects.
        for (d, det) in detections.objects.iter().enumerate() {
            if det_taken[d] {
                continue;
            }
            let mut object = det.clone();
            object.id = format!("obj-{}", self.next_id);
            object.workspace_id = ws_id.clone();
            self.next_id += 1;
            self.objects.push(Tracked {
                object,
                missed: 0,
                held: false,
                confirmed: true,
            });
        }
        Some(TrackedObjects {
            workspace_id: ws_id.clone(),
            frame_id: detections.frame_id,
            timestamp_unix_ns: detections.timestamp_unix_ns,
            objects: self.on_table(ws_id).cloned().collect(),
        })
    }

    /// The objects on the table of workspace `ws_id`, in the order they were first seen.
    fn on_table<'a>(&'a self, ws_id: &'a str) -> impl Iterator<Item = &'a DetectedObject> + 'a {
        self.objects
            .iter()
            .filter(move |t| !t.held && t.object.workspace_id == ws_id)
            .map(|t| &t.object)
    }

    /// The objects of the current workspace on the table.
    fn current_objects(&self) -> Vec<&DetectedObject> {
        match self.current_workspace() {
            Some(ws) => self.on_table(&ws.id).collect(),
            None => Vec::new(),
        }
    }

    fn workspace(&self, id: &str) -> Result<&WorkspaceInfo, WorkspaceError> {
        self.workspaces
            .iter()
            .find(|w| w.id == id.trim())
            .ok_or_else(|| WorkspaceError::UnknownWorkspace {
                workspace_id: id.to_owned(),
                known: self.workspaces.iter().map(|w| w.id.clone()).collect(),
            })
    }

    /// Answers one request (the request is validated first).
    pub fn answer(&mut self, request: &WorkspaceRequest) -> WorkspaceReply {
        use robotd_protocol::validate::Validate;
        if let Err(e) = request.validate() {
            return WorkspaceError::from(e).into();
        }
        match self.answer_valid(request) {
            Ok(reply) => reply,
            Err(error) => error.into(),
        }
    }

    fn answer_valid(
        &mut self,
        request: &WorkspaceRequest,
    ) -> Result<WorkspaceReply, WorkspaceError> {
        let by_size = |a: &&DetectedObject, b: &&DetectedObject| {
            a.dimensions.size_m2.total_cmp(&b.dimensions.size_m2)
        };
        Ok(match request {
            WorkspaceRequest::GetObjects {
                location,
                coordinate,
                label,
            } => {
                let objects = self
                    .current_objects()
                    .into_iter()
                    .filter(|o| label.as_deref().is_none_or(|l| o.label_contains(l)))
                    .filter(|o| match coordinate {
                        Some(c) => location.filter_accepts(o.xy(), *c),
                        None => true,
                    })
                    .cloned()
                    .collect();
                WorkspaceReply::Objects { objects }
            }
            WorkspaceRequest::GetObjectNear { coordinate, label } => {
                let object = self
                    .current_objects()
                    .into_iter()
                    .filter(|o| label.as_deref().is_none_or(|l| o.label_contains(l)))
                    .map(|o| (o.xy().distance_to(coordinate), o))
                    .filter(|(d, _)| *d <= CLOSE_TO_RADIUS_M)
                    .min_by(|a, b| a.0.total_cmp(&b.0))
                    .map(|(_, o)| o.clone());
                WorkspaceReply::Object { object }
            }
            WorkspaceRequest::GetLargestObject => WorkspaceReply::Object {
                object: self.current_objects().into_iter().max_by(by_size).cloned(),
            },
            WorkspaceRequest::GetSmallestObject => WorkspaceReply::Object {
                object: self.current_objects().into_iter().min_by(by_size).cloned(),
            },
            WorkspaceRequest::GetObjectsSorted { ascending } => {
                let mut objects = self.current_objects();
                objects.sort_by(by_size);
                if !ascending {
                    objects.reverse();
                }
                WorkspaceReply::Objects {
                    objects: objects.into_iter().cloned().collect(),
                }
            }
            WorkspaceRequest::GetLargestFreeSpace => {
                let ws = self
                    .current_workspace()
                    .ok_or_else(|| WorkspaceError::Unavailable {
                        reason: "no workspace is configured".into(),
                    })?;
                let objects: Vec<DetectedObject> = self.on_table(&ws.id).cloned().collect();
                let (area_m2, center) =
                    largest_free_space(ws, &objects, self.settings.free_space_margin_m);
                WorkspaceReply::FreeSpace { area_m2, center }
            }
            WorkspaceRequest::GetWorkspacePoint {
                workspace_id,
                point,
            } => WorkspaceReply::Coordinate {
                coordinate: self.workspace(workspace_id)?.point(*point),
            },
            WorkspaceRequest::GetLabels => WorkspaceReply::Labels {
                labels: self.labels.clone(),
                builtin: self
                    .labels
                    .iter()
                    .filter(|l| self.builtin.contains(l))
                    .cloned()
                    .collect(),
            },
            WorkspaceRequest::AddLabel { label } => {
                let added = self.add_label(label);
                WorkspaceReply::LabelAdded {
                    label: label.trim().to_lowercase(),
                    already_known: !added,
                }
            }
            WorkspaceRequest::GetObservationPose { workspace_id } => {
                WorkspaceReply::ObservationPose {
                    pose: self.workspace(workspace_id)?.observation_pose,
                }
            }
            WorkspaceRequest::ListWorkspaces => WorkspaceReply::Workspaces {
                workspaces: self.workspaces.clone(),
            },
            WorkspaceRequest::ObjectPicked { object_id } => {
                let tracked = self.tracked_mut(object_id)?;
                tracked.held = true;
                WorkspaceReply::Object {
                    object: Some(tracked.object.clone()),
                }
            }
            WorkspaceRequest::ObjectPlaced { object_id, at } => {
                let tracked = self.tracked_mut(object_id)?;
                let z = tracked.object.position.center_of_mass.z_m;
                tracked.held = false;
                tracked.confirmed = false;
                tracked.missed = 0;
                tracked.object.position.center_of_mass = Point3::new(at.x_m, at.y_m, z);
                tracked.object.position.center = Point3::new(at.x_m, at.y_m, z);
                WorkspaceReply::Object {
                    object: Some(tracked.object.clone()),
                }
            }
        })
    }

    fn tracked_mut(&mut self, id: &str) -> Result<&mut Tracked, WorkspaceError> {
        let known: Vec<String> = self.objects.iter().map(|t| t.object.id.clone()).collect();
        self.objects
            .iter_mut()
            .find(|t| t.object.id == id.trim())
            .ok_or_else(|| WorkspaceError::InvalidRequest {
                reason: format!(
                    "unknown object id '{id}'; remembered: {}",
                    if known.is_empty() {
                        "none".to_owned()
                    } else {
                        known.join(", ")
                    }
                ),
            })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use robotd_protocol::geometry::{Point2, Pose, RobotModel};
    use robotd_protocol::location::{Location, WorkspacePoint};

    fn workspaces() -> Vec<WorkspaceInfo> {
        let niryo = WorkspaceInfo {
            id: "niryo_ws".into(),
            robot: RobotModel::Ned2,
            upper_left: Point2::new(0.337, 0.087),
            lower_right: Point2::new(0.163, -0.087),
            observation_pose: Pose::new(0.173, -0.002, 0.277, -3.042, 1.327, -3.027),
        };
        let gazebo = WorkspaceInfo {
            id: "gazebo_1".into(),
            observation_pose: Pose::new(0.18, 0.0, 0.36, 2.4, std::f64::consts::FRAC_PI_2, 2.4),
            ..niryo.clone()
        };
        vec![niryo, gazebo]
    }

    fn object(label: &str, x: f64, y: f64, w: f64, h: f64) -> DetectedObject {
        let mut o = DetectedObject {
            label: label.into(),
            ..Default::default()
        };
        o.position.center_of_mass = Point3::new(x, y, 0.01);
        o.position.center = o.position.center_of_mass;
        o.dimensions.width_m = w;
        o.dimensions.height_m = h;
        o.dimensions.size_m2 = w * h;
        o
    }

    fn view(frame_id: u64, objects: Vec<DetectedObject>) -> Detections {
        Detections {
            frame_id,
            workspace_id: "niryo_ws".into(),
            timestamp_unix_ns: frame_id * 1000,
            source: "robotd".into(),
            steady: true,
            objects,
        }
    }

    /// A red cube (far left), a pencil (near right), a blue square (near left) and a green
    /// cylinder (far right); sizes 0.0009, 0.00144, 0.002025, 0.001024 m².
    fn scene() -> Vec<DetectedObject> {
        vec![
            object("red cube", 0.30, 0.05, 0.03, 0.03),
            object("pencil", 0.20, -0.05, 0.012, 0.12),
            object("blue square", 0.22, 0.05, 0.045, 0.045),
            object("green cylinder", 0.28, -0.04, 0.032, 0.032),
        ]
    }

    fn memory() -> SceneMemory {
        let mut m = SceneMemory::new(
            workspaces(),
            &[],
            &["red cube".into(), "pencil".into()],
            MemorySettings::default(),
        );
        m.apply(&view(1, scene())).unwrap();
        m
    }

    fn labels_of(reply: WorkspaceReply) -> Vec<String> {
        match reply {
            WorkspaceReply::Objects { objects } => objects.into_iter().map(|o| o.label).collect(),
            WorkspaceReply::Object { object } => object.into_iter().map(|o| o.label).collect(),
            other => panic!("not objects: {other:?}"),
        }
    }

    fn get(location: Location, at: Option<(f64, f64)>, label: Option<&str>) -> WorkspaceRequest {
        WorkspaceRequest::GetObjects {
            location,
            coordinate: at.map(|(x, y)| Point2::new(x, y)),
            label: label.map(str::to_owned),
        }
    }

    #[test]
    fn detection_queries_match_the_hand_checked_table() {
        let mut m = memory();
        let all = ["red cube", "pencil", "blue square", "green cylinder"];
        assert_eq!(labels_of(m.answer(&get(Location::None, None, None))), all);
        assert_eq!(
            labels_of(m.answer(&get(Location::None, None, Some("CUBE")))),
            ["red cube"]
        );
        assert_eq!(
            labels_of(m.answer(&get(Location::None, None, Some(" cyl")))),
            ["green cylinder"]
        );
        assert_eq!(
            labels_of(m.answer(&get(Location::None, None, Some("e")))),
            all
        );
        assert!(labels_of(m.answer(&get(Location::None, None, Some("banana")))).is_empty());
        // Filters around (0.25, 0): left = y > 0, right = y < 0, above = x > 0.25, below = x < 0.25.
        let c = Some((0.25, 0.0));
        assert_eq!(
            labels_of(m.answer(&get(Location::LeftNextTo, c, None))),
            ["red cube", "blue square"]
        );
        assert_eq!(
            labels_of(m.answer(&get(Location::RightNextTo, c, None))),
            ["pencil", "green cylinder"]
        );
        assert_eq!(
            labels_of(m.answer(&get(Location::Above, c, None))),
            ["red cube", "green cylinder"]
        );
        assert_eq!(
            labels_of(m.answer(&get(Location::Below, c, None))),
            ["pencil", "blue square"]
        );
        assert_eq!(
            labels_of(m.answer(&get(Location::Below, c, Some("pen")))),
            ["pencil"]
        );
        // close to = within 2 cm: only the cube is 5 mm from (0.295, 0.05).
        assert_eq!(
            labels_of(m.answer(&get(Location::CloseTo, Some((0.295, 0.05)), None))),
            ["red cube"]
        );
        assert!(labels_of(m.answer(&get(Location::OnTopOf, c, None))).is_empty());
        assert!(labels_of(m.answer(&get(Location::Inside, c, None))).is_empty());
        match m.answer(&get(Location::Above, None, None)) {
            WorkspaceReply::Error { error } => assert_eq!(
                error.to_string(),
                "invalid request: coordinate: Coordinate must be provided for location filter: above"
            ),
            other => panic!("{other:?}"),
        }

        // Nearest within 2 cm.
        let near = |x, y, label: Option<&str>| WorkspaceRequest::GetObjectNear {
            coordinate: Point2::new(x, y),
            label: label.map(str::to_owned),
        };
        assert_eq!(
            labels_of(m.answer(&near(0.21, 0.05, None))),
            ["blue square"]
        );
        assert!(labels_of(m.answer(&near(0.25, 0.0, None))).is_empty());
        assert!(labels_of(m.answer(&near(0.21, 0.05, Some("red")))).is_empty());

        // By size: 0.0009 (cube) < 0.001024 (cylinder) < 0.00144 (pencil) < 0.002025 (square).
        assert_eq!(
            labels_of(m.answer(&WorkspaceRequest::GetLargestObject)),
            ["blue square"]
        );
        assert_eq!(
            labels_of(m.answer(&WorkspaceRequest::GetSmallestObject)),
            ["red cube"]
        );
        assert_eq!(
            labels_of(m.answer(&WorkspaceRequest::GetObjectsSorted { ascending: true })),
            ["red cube", "green cylinder", "pencil", "blue square"]
        );
        assert_eq!(
            labels_of(m.answer(&WorkspaceRequest::GetObjectsSorted { ascending: false })),
            ["blue square", "pencil", "green cylinder", "red cube"]
        );
    }

    #[test]
    fn workspace_queries_and_unknown_workspaces() {
        let mut m = memory();
        let point = |ws: &str, p| WorkspaceRequest::GetWorkspacePoint {
            workspace_id: ws.into(),
            point: p,
        };
        assert_eq!(
            m.answer(&point("niryo_ws", WorkspacePoint::UpperRightCorner)),
            WorkspaceReply::Coordinate {
                coordinate: Point2::new(0.337, -0.087)
            }
        );
        assert_eq!(
            m.answer(&point("gazebo_1", WorkspacePoint::LowerLeftCorner)),
            WorkspaceReply::Coordinate {
                coordinate: Point2::new(0.163, 0.087)
            }
        );
        match m.answer(&point("foo_ws", WorkspacePoint::CenterPoint)) {
            WorkspaceReply::Error { error } => assert_eq!(
                error.to_string(),
                "unknown workspace 'foo_ws'; known: niryo_ws, gazebo_1"
            ),
            other => panic!("{other:?}"),
        }
        match m.answer(&WorkspaceRequest::GetObservationPose {
            workspace_id: "gazebo_1".into(),
        }) {
            WorkspaceReply::ObservationPose { pose } => assert_eq!(pose.z_m, 0.36),
            other => panic!("{other:?}"),
        }
        assert!(matches!(
            m.answer(&WorkspaceRequest::GetObservationPose {
                workspace_id: "x".into()
            }),
            WorkspaceReply::Error {
                error: WorkspaceError::UnknownWorkspace { .. }
            }
        ));
        match m.answer(&WorkspaceRequest::ListWorkspaces) {
            WorkspaceReply::Workspaces { workspaces } => assert_eq!(workspaces.len(), 2),
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn labels_are_lower_case_and_unique() {
        let mut m = memory();
        let add = |l: &str| WorkspaceRequest::AddLabel { label: l.into() };
        assert_eq!(
            m.answer(&add(" Screwdriver ")),
            WorkspaceReply::LabelAdded {
                label: "screwdriver".into(),
                already_known: false
            }
        );
        assert_eq!(
            m.answer(&add("SCREWDRIVER")),
            WorkspaceReply::LabelAdded {
                label: "screwdriver".into(),
                already_known: true
            }
        );
        assert!(matches!(m.answer(&add("  ")), WorkspaceReply::Error { .. }));
        assert_eq!(
            m.answer(&WorkspaceRequest::GetLabels),
            WorkspaceReply::Labels {
                labels: vec!["red cube".into(), "pencil".into(), "screwdriver".into()],
                builtin: vec!["red cube".into(), "pencil".into()],
            }
        );
    }

    #[test]
    fn an_empty_scene_answers_empty() {
        let mut m = SceneMemory::new(workspaces(), &[], &[], MemorySettings::default());
        assert!(labels_of(m.answer(&get(Location::None, None, None))).is_empty());
        assert_eq!(
            m.answer(&WorkspaceRequest::GetLargestObject),
            WorkspaceReply::Object { object: None }
        );
        assert_eq!(
            m.answer(&WorkspaceRequest::GetSmallestObject),
            WorkspaceReply::Object { object: None }
        );
        match m.answer(&WorkspaceRequest::GetLargestFreeSpace) {
            WorkspaceReply::FreeSpace { area_m2, center } => {
                assert!((area_m2 - 0.174 * 0.174).abs() < 1e-12);
                assert!((center.x_m - 0.25).abs() < 1e-9);
            }
            other => panic!("{other:?}"),
        }
        assert_eq!(
            m.answer(&WorkspaceRequest::GetLabels),
            WorkspaceReply::Labels {
                labels: vec![],
                builtin: vec![]
            }
        );
    }

    #[test]
    fn ids_are_stable_and_missing_objects_expire() {
        let mut m = memory();
        let first = m.apply(&view(2, scene())).unwrap();
        let ids: Vec<String> = first.objects.iter().map(|o| o.id.clone()).collect();
        assert_eq!(ids, ["obj-1", "obj-2", "obj-3", "obj-4"]);
        // 100 frames with millimetre jitter and shuffled detector order: same ids.
        for f in 0..100u64 {
            let jitter = ((f % 7) as f64 - 3.0) * 0.001;
            let mut objects = scene();
            for o in &mut objects {
                o.position.center_of_mass.x_m += jitter;
                o.position.center_of_mass.y_m -= jitter;
            }
            objects.rotate_left((f % 4) as usize);
            let tracked = m.apply(&view(3 + f, objects)).unwrap();
            let mut got: Vec<(String, String)> = tracked
                .objects
                .iter()
                .map(|o| (o.id.clone(), o.label.clone()))
                .collect();
            got.sort();
            assert_eq!(
                got,
                [
                    ("obj-1", "red cube"),
                    ("obj-2", "pencil"),
                    ("obj-3", "blue square"),
                    ("obj-4", "green cylinder")
                ]
                .map(|(a, b)| (a.to_owned(), b.to_owned()))
            );
        }
        // Frames taken while the arm moved change nothing.
        let mut moving = view(200, vec![]);
        moving.steady = false;
        assert!(m.apply(&moving).is_none());
        // The pencil is gone: missed in 3 steady views, then forgotten; a new object gets a
        // new id, never an old one.
        let without_pencil: Vec<_> = scene()
            .into_iter()
            .filter(|o| o.label != "pencil")
            .collect();
        for f in 0..2 {
            let t = m.apply(&view(300 + f, without_pencil.clone())).unwrap();
            assert_eq!(t.objects.len(), 4, "kept while missed only {} times", f + 1);
        }
        let t = m.apply(&view(302, without_pencil.clone())).unwrap();
        assert_eq!(t.objects.len(), 3);
        let mut with_new = without_pencil;
        with_new.push(object("pencil", 0.20, -0.05, 0.012, 0.12));
        let t = m.apply(&view(303, with_new)).unwrap();
        assert!(t
            .objects
            .iter()
            .any(|o| o.id == "obj-5" && o.label == "pencil"));
    }

    #[test]
    fn memory_follows_picks_and_places() {
        let mut m = memory();
        let picked = m.answer(&WorkspaceRequest::ObjectPicked {
            object_id: "obj-1".into(),
        });
        assert!(
            matches!(picked, WorkspaceReply::Object { object: Some(ref o) } if o.label == "red cube")
        );
        assert_eq!(
            labels_of(m.answer(&get(Location::None, None, Some("cube")))),
            Vec::<String>::new()
        );
        // Held objects do not expire while the camera cannot see them on the table.
        for f in 0..5 {
            let rest: Vec<_> = scene()
                .into_iter()
                .filter(|o| o.label != "red cube")
                .collect();
            m.apply(&view(10 + f, rest)).unwrap();
        }
        let placed = m.answer(&WorkspaceRequest::ObjectPlaced {
            object_id: "obj-1".into(),
            at: Point2::new(0.18, 0.07),
        });
        assert!(
            matches!(placed, WorkspaceReply::Object { object: Some(ref o) } if o.xy() == Point2::new(0.18, 0.07))
        );
        let near = m.answer(&WorkspaceRequest::GetObjectNear {
            coordinate: Point2::new(0.18, 0.07),
            label: None,
        });
        assert_eq!(labels_of(near), ["red cube"]);
        // The camera confirms it there (same id) ...
        let mut moved = scene();
        moved[0].position.center_of_mass = Point3::new(0.181, 0.069, 0.015);
        let t = m.apply(&view(20, moved)).unwrap();
        assert!(t
            .objects
            .iter()
            .any(|o| o.id == "obj-1" && (o.xy().x_m - 0.181).abs() < 1e-12));
        // ... and an unknown id is refused with the ids it knows.
        match m.answer(&WorkspaceRequest::ObjectPicked {
            object_id: "obj-99".into(),
        }) {
            WorkspaceReply::Error { error } => assert!(error
                .to_string()
                .contains("unknown object id 'obj-99'; remembered: obj-1")),
            other => panic!("{other:?}"),
        }
    }
}
