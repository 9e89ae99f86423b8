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
