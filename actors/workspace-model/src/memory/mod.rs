//! The scene memory: the configured workspaces, the objects on them with stable ids, and the
//! detectable labels — and the answer to every detection and workspace question of the tools.
//!
//! [`SceneMemory`] is the workspace model actor's state without the bus: [`SceneMemory::apply`]
//! takes one frame's [`Detections`], [`SceneMemory::answer`] one [`WorkspaceRequest`]. It ties
//! together the [tracker](crate::tracker) (ids, expiry, picks and places), the
//! [queries](crate::queries) (filters and sorting), [free space](crate::free_space) and the
//! [label registry](crate::labels).
//!
//! The object questions are about the *current* workspace: the one of the newest steady view
//! applied (the first configured one until then), as the Python server answers about the
//! workspace its camera looks at. Workspace questions name their workspace; an id that is not
//! configured is answered with [`WorkspaceError::UnknownWorkspace`], which lists the known ones.
//!
//! This file holds the state and its updates (construction, accessors,
//! [`SceneMemory::apply`]). Answering a request — [`check_request`], [`SceneMemory::answer`]
//! and the placement rule [`PLACE_WORKSPACE_MARGIN_M`] — is in `memory/answer.rs` (re-exported
//! here); the unit tests are in `memory/tests.rs`.
//!
//! [`WorkspaceRequest`]: robotd_protocol::workspace::WorkspaceRequest
//! [`WorkspaceError::UnknownWorkspace`]: robotd_protocol::workspace::WorkspaceError::UnknownWorkspace
//!
//! ```
//! use robotd_protocol::geometry::{Point2, Point3, Pose, RobotModel};
//! use robotd_protocol::objects::{DetectedObject, Detections};
//! use robotd_protocol::workspace::{WorkspaceInfo, WorkspaceReply, WorkspaceRequest};
//! use robotd_workspace_model::{MemorySettings, SceneMemory};
//!
//! let ws = WorkspaceInfo {
//!     id: "niryo_ws".into(),
//!     robot: RobotModel::Ned2,
//!     upper_left: Point2::new(0.337, 0.087),
//!     lower_right: Point2::new(0.163, -0.087),
//!     observation_pose: Pose::new(0.173, -0.002, 0.277, -3.042, 1.327, -3.027),
//! };
//! let mut memory = SceneMemory::new(vec![ws], &[], &["pencil".into()], MemorySettings::default());
//! let mut pencil = DetectedObject { label: "pencil".into(), ..Default::default() };
//! pencil.position.center_of_mass = Point3::new(0.2, 0.0, 0.005);
//! let view = |t| Detections {
//!     frame_id: t,
//!     workspace_id: "niryo_ws".into(),
//!     timestamp_unix_ns: t,
//!     source: "robotd".into(),
//!     steady: true,
//!     objects: vec![pencil.clone()],
//! };
//! // A new object is reported once a second view agrees.
//! assert!(memory.apply(&view(1)).unwrap().objects.is_empty());
//! assert_eq!(memory.apply(&view(2)).unwrap().objects[0].id, "obj-1");
//! let reply = memory.answer(&WorkspaceRequest::GetObjectNear {
//!     coordinate: Point2::new(0.21, 0.0),
//!     label: Some("PEN".into()),
//! });
//! assert!(matches!(reply, WorkspaceReply::Object { object: Some(o) } if o.id == "obj-1"));
//! ```

mod answer;
#[cfg(test)]
mod tests;

pub use answer::{check_request, PLACE_WORKSPACE_MARGIN_M};

use crate::labels::LabelRegistry;
use crate::tracker::{IgnoredView, Tracker};
use robotd_protocol::objects::Detections;
use robotd_protocol::workspace::{DetectableLabels, TrackedObjects, WorkspaceInfo};

/// Settings of the memory.
#[derive(Debug, Clone, PartialEq)]
pub struct MemorySettings {
    /// Margin around objects for the free-space search, metres (config
    /// `workspace.free_space_margin_m`, default 0.01).
    pub free_space_margin_m: f64,
    /// Steady views of its workspace an object may be missed in, in a row, before it is
    /// forgotten (config `workspace.expire_after_frames`, default 3).
    pub expire_after_frames: u32,
    /// How many detectable labels are held and how long each may be (config
    /// `workspace.max_labels`, `workspace.max_label_chars`).
    pub label_limits: crate::labels::LabelLimits,
}

impl Default for MemorySettings {
    fn default() -> Self {
        Self {
            free_space_margin_m: 0.01,
            expire_after_frames: 3,
            label_limits: crate::labels::LabelLimits::default(),
        }
    }
}

/// Workspaces, remembered objects and detectable labels.
#[derive(Debug)]
pub struct SceneMemory {
    settings: MemorySettings,
    workspaces: Vec<WorkspaceInfo>,
    tracker: Tracker,
    labels: LabelRegistry,
    current: Option<usize>,
    /// The skills' sizes (gripper, markers' keep-out) for the free-space answer, defaults of
    /// the first workspace's robot.
    skills: robotd_placement::SkillsSettings,
}

impl SceneMemory {
    /// Memory of `workspaces`, with the detectable labels `labels` (then those of `builtin`
    /// not among them), of which the built-in detector sees `builtin`.
    pub fn new(
        workspaces: Vec<WorkspaceInfo>,
        labels: &[String],
        builtin: &[String],
        settings: MemorySettings,
    ) -> Self {
        let robot = workspaces
            .first()
            .map_or(robotd_protocol::RobotModel::Ned2, |w| w.robot);
        Self {
            skills: robotd_placement::SkillsSettings::new(robot, workspaces.clone()),
            tracker: Tracker::new(settings.expire_after_frames),
            labels: LabelRegistry::with_limits(labels, builtin, settings.label_limits),
            settings,
            workspaces,
            current: None,
        }
    }

    /// Capture time of the latest steady view applied, ns since the Unix epoch (0: none yet).
    pub fn last_view_ns(&self) -> u64 {
        self.tracker.last_view_ns()
    }

    /// Whether the current workspace has candidates (objects seen in one view, not yet
    /// reported): one more view settles what is on its table.
    pub fn has_candidates(&self) -> bool {
        self.current_workspace()
            .is_some_and(|ws| self.tracker.has_candidates(&ws.id))
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
        self.labels.labels()
    }

    /// The label registry as published on `workspace/labels`.
    pub fn labels_message(&self, added: Option<String>) -> DetectableLabels {
        self.labels.snapshot(added)
    }

    /// The objects tracked (on the table or held).
    pub fn tracker(&self) -> &Tracker {
        &self.tracker
    }

    /// Applies one frame's detections. A steady view of a configured workspace updates memory
    /// and makes that workspace the current one; the objects now on its table are returned.
    /// Any other frame changes nothing and says why.
    pub fn apply(&mut self, detections: &Detections) -> Result<TrackedObjects, IgnoredView> {
        let frame_id = detections.frame_id;
        if !detections.steady {
            return Err(IgnoredView::Moving { frame_id });
        }
        if detections.workspace_id.is_empty() {
            return Err(IgnoredView::NoWorkspace { frame_id });
        }
        let Some(index) = self
            .workspaces
            .iter()
            .position(|w| w.id == detections.workspace_id)
        else {
            return Err(IgnoredView::UnknownWorkspace {
                frame_id,
                workspace_id: detections.workspace_id.clone(),
                known: self.known_ids(),
            });
        };
        let tracked = self.tracker.apply(detections)?;
        self.current = Some(index);
        Ok(tracked)
    }

    fn known_ids(&self) -> Vec<String> {
        self.workspaces.iter().map(|w| w.id.clone()).collect()
    }
}
