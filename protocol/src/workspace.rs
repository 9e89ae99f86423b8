//! Questions about the workspace and the objects on it, and their answers.
//!
//! The workspace model actor keeps the objects of each workspace with stable ids, the
//! configured workspaces and the list of detectable labels. It answers a [`WorkspaceRequest`] —
//! one variant per detection or workspace tool of `docs/mcp-tools.md`, plus the skills' hooks
//! [`WorkspaceRequest::ObjectPicked`] and [`WorkspaceRequest::ObjectPlaced`] — with one
//! [`WorkspaceReply`] (`"workspace.reply"`). On the bus a request travels wrapped in a
//! [`WorkspaceQuery`] (`"workspace.query"`), which can ask for an answer from a view taken after
//! a given time. The actor publishes [`TrackedObjects`] (`"workspace.objects"`) after every
//! detection it applied, and [`DetectableLabels`] (`"workspace.labels"`) at start and whenever
//! the label list changes.
//!
//! A [`WorkspaceInfo`] describes one configured workspace: its rectangle on the table (upper =
//! far from the robot, left = +y) and the pose from which the camera sees it whole.
//!
//! ```
//! use robotd_protocol::geometry::{Point2, Pose};
//! use robotd_protocol::location::{Location, WorkspacePoint};
//! use robotd_protocol::workspace::{WorkspaceInfo, WorkspaceRequest};
//! use robotd_protocol::geometry::RobotModel;
//! use robotd_protocol::validate::Validate;
//!
//! let ws = WorkspaceInfo {
//!     id: "niryo_ws".into(),
//!     robot: RobotModel::Ned2,
//!     upper_left: Point2::new(0.337, 0.087),
//!     lower_right: Point2::new(0.163, -0.087),
//!     observation_pose: Pose::new(0.173, -0.002, 0.277, -3.042, 1.327, -3.027),
//! };
//! assert_eq!(ws.point(WorkspacePoint::UpperRightCorner), Point2::new(0.337, -0.087));
//! assert!(ws.contains(Point2::new(0.25, 0.0), 0.0));
//!
//! let bad = WorkspaceRequest::GetObjects { location: Location::Above, coordinate: None, label: None };
//! assert_eq!(bad.validate().unwrap_err().to_string(),
//!            "coordinate: Coordinate must be provided for location filter: above");
//! ```

use crate::envelope::Message;
use crate::geometry::{Point2, Pose, RobotModel};
use crate::location::{Location, WorkspacePoint};
use crate::objects::DetectedObject;
use crate::validate::{non_empty, Validate, ValidationError};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// Largest distance of a workspace corner from the robot base, metres.
pub const MAX_WORKSPACE_COORD_M: f64 = 2.0;

/// A workspace: a white sheet on the table with a circle marker at each corner.
///
/// "upper left" is the far-left corner (larger x, larger y), "lower right" the near-right one
/// (smaller x, smaller y). In the configuration (`[[robot.workspaces]]`):
///
/// ```toml
/// [[robot.workspaces]]
/// id = "niryo_ws"
/// upper_left = [0.337, 0.087]
/// lower_right = [0.163, -0.087]
/// observation_pose = [0.173, -0.002, 0.277, -3.042, 1.327, -3.027]  # x y z roll pitch yaw
/// ```
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WorkspaceSpec {
    /// Workspace id, as the MCP tools name it (`niryo_ws`).
    pub id: String,
    /// Far-left corner `[x, y]`, metres.
    pub upper_left: [f64; 2],
    /// Near-right corner `[x, y]`, metres.
    pub lower_right: [f64; 2],
    /// Tool pose from which the camera sees the whole sheet: x, y, z (m), roll, pitch, yaw (rad).
    pub observation_pose: [f64; 6],
}

impl WorkspaceSpec {
    /// The workspace as the rest of robotd describes it (the tools, the workspace model).
    pub fn to_info(&self, robot: RobotModel) -> WorkspaceInfo {
        WorkspaceInfo {
            id: self.id.clone(),
            robot,
            upper_left: Point2::new(self.upper_left[0], self.upper_left[1]),
            lower_right: Point2::new(self.lower_right[0], self.lower_right[1]),
            observation_pose: Pose::from_array(self.observation_pose),
        }
    }

    /// Centre of the sheet `[x, y]`.
    pub fn centre(&self) -> [f64; 2] {
        [
            (self.upper_left[0] + self.lower_right[0]) / 2.0,
            (self.upper_left[1] + self.lower_right[1]) / 2.0,
        ]
    }

    /// Every problem with the values; empty when all is well.
    pub fn problems(&self) -> Vec<String> {
        let mut out = Vec::new();
        if self.id.trim().is_empty() {
            out.push("id must not be empty".to_owned());
        }
        let corners = [
            ("upper_left", self.upper_left),
            ("lower_right", self.lower_right),
        ];
        let mut corners_ok = true;
        for (key, c) in corners {
            if c.iter()
                .any(|v| !v.is_finite() || v.abs() > MAX_WORKSPACE_COORD_M)
            {
                out.push(format!(
                    "{key} must be finite coordinates within ±{MAX_WORKSPACE_COORD_M} m, got {c:?}"
                ));
                corners_ok = false;
            }
        }
        if corners_ok
            && (self.upper_left[0] <= self.lower_right[0] + 0.01
                || self.upper_left[1] <= self.lower_right[1] + 0.01)
        {
            out.push(format!(
                "upper_left {:?} must be the far-left corner: larger x and larger y than \
                 lower_right {:?} (by at least 1 cm)",
                self.upper_left, self.lower_right
            ));
        }
        if let Some(v) = self.observation_pose.iter().find(|v| !v.is_finite()) {
            out.push(format!("observation_pose must be finite, got {v}"));
        }
        out
    }
}

/// The workspaces robotd knows for `model` when `[robot] workspaces` lists none: the sheets of
/// the robot's standard set-up (docs/robot-models.md, "Workspaces").
// gazebo_1's orientation is the one the Python stack configures, kept as written; its height
// is 3 cm lower (0.33 m, not 0.36 m): from 0.36 m the Ned2's wrist joint would have to reach
// -1.911 rad, beyond its limit less the safety margin (-1.910 rad), so the pose could not be
// reached at all. From 0.33 m it needs -1.785 rad and the camera still sees the whole sheet.
#[allow(clippy::approx_constant)]
pub fn builtin_workspaces(model: RobotModel) -> Vec<WorkspaceSpec> {
    let spec = |id: &str, upper_left, lower_right, observation_pose| WorkspaceSpec {
        id: id.to_owned(),
        upper_left,
        lower_right,
        observation_pose,
    };
    match model {
        RobotModel::Ned2 => vec![
            spec(
                "niryo_ws",
                [0.337, 0.087],
                [0.163, -0.087],
                [0.173, -0.002, 0.277, -3.042, 1.327, -3.027],
            ),
            spec(
                "gazebo_1",
                [0.337, 0.087],
                [0.163, -0.087],
                [0.18, 0.0, 0.33, 2.4, 1.5708, 2.4],
            ),
        ],
        RobotModel::WidowX250 => vec![spec(
            "widowx_ws",
            [0.35, 0.10],
            [0.15, -0.10],
            [0.30, 0.0, 0.25, 0.0, 0.0, 0.0],
        )],
    }
}

/// One configured workspace.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct WorkspaceInfo {
    /// Workspace id, e.g. `niryo_ws`.
    pub id: String,
    /// The robot it belongs to.
    pub robot: RobotModel,
    /// Far-left corner (largest x, largest y), metres.
    pub upper_left: Point2,
    /// Near-right corner (smallest x, smallest y), metres.
    pub lower_right: Point2,
    /// Tool pose from which the camera sees the whole workspace.
    pub observation_pose: Pose,
}

impl WorkspaceInfo {
    /// Centre of the rectangle.
    pub fn center(&self) -> Point2 {
        Point2::new(
            (self.upper_left.x_m + self.lower_right.x_m) / 2.0,
            (self.upper_left.y_m + self.lower_right.y_m) / 2.0,
        )
    }

    /// A named corner or the centre.
    pub fn point(&self, point: WorkspacePoint) -> Point2 {
        let (ul, lr) = (self.upper_left, self.lower_right);
        match point {
            WorkspacePoint::UpperLeftCorner => ul,
            WorkspacePoint::UpperRightCorner => Point2::new(ul.x_m, lr.y_m),
            WorkspacePoint::LowerLeftCorner => Point2::new(lr.x_m, ul.y_m),
            WorkspacePoint::LowerRightCorner => lr,
            WorkspacePoint::CenterPoint => self.center(),
        }
    }

    /// Extent along y, metres.
    pub fn width_m(&self) -> f64 {
        self.upper_left.y_m - self.lower_right.y_m
    }

    /// Extent along x, metres.
    pub fn height_m(&self) -> f64 {
        self.upper_left.x_m - self.lower_right.x_m
    }

    /// Area of the rectangle, square metres.
    pub fn area_m2(&self) -> f64 {
        self.width_m() * self.height_m()
    }

    /// Whether `p` lies within the rectangle grown by `margin_m` on every side.
    pub fn contains(&self, p: Point2, margin_m: f64) -> bool {
        p.x_m <= self.upper_left.x_m + margin_m
            && p.x_m >= self.lower_right.x_m - margin_m
            && p.y_m <= self.upper_left.y_m + margin_m
            && p.y_m >= self.lower_right.y_m - margin_m
    }
}

impl Validate for WorkspaceInfo {
    fn validate(&self) -> Result<(), ValidationError> {
        non_empty("id", &self.id)?;
        self.upper_left
            .validate()
            .map_err(|e| e.within("upper_left"))?;
        self.lower_right
            .validate()
            .map_err(|e| e.within("lower_right"))?;
        if self.upper_left.x_m <= self.lower_right.x_m
            || self.upper_left.y_m <= self.lower_right.y_m
        {
            return Err(ValidationError::Invalid {
                field: "upper_left".into(),
                reason: format!(
                    "upper left corner {} must be farther (larger x) and more to the left \
                     (larger y) than lower right corner {}",
                    self.upper_left, self.lower_right
                ),
            });
        }
        self.observation_pose
            .validate()
            .map_err(|e| e.within("observation_pose"))
    }
}

/// A question to the workspace model actor. Replied to with [`WorkspaceReply`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum WorkspaceRequest {
    /// `get_detected_objects`: objects passing the location filter around `coordinate` and the
    /// label substring filter. Replies `Objects`.
    GetObjects {
        /// Spatial filter; `none` for no filter.
        #[serde(default)]
        location: Location,
        /// Reference point of the filter; required unless `location` is `none`.
        #[serde(default)]
        coordinate: Option<Point2>,
        /// Case-insensitive substring of the label.
        #[serde(default)]
        label: Option<String>,
    },
    /// `get_detected_object`: the object nearest `coordinate` within 2 cm, optionally with a
    /// label filter. Replies `Object`.
    GetObjectNear {
        /// Where to look.
        coordinate: Point2,
        /// Case-insensitive substring of the label.
        #[serde(default)]
        label: Option<String>,
    },
    /// `get_largest_detected_object`. Replies `Object`.
    GetLargestObject,
    /// `get_smallest_detected_object`. Replies `Object`.
    GetSmallestObject,
    /// `get_detected_objects_sorted` by `size_m2`. Replies `Objects`.
    GetObjectsSorted {
        /// Smallest first when true.
        ascending: bool,
    },
    /// `get_largest_free_space_with_center`. Replies `FreeSpace`.
    GetLargestFreeSpace,
    /// `get_workspace_coordinate_from_point`. Replies `Coordinate`.
    GetWorkspacePoint {
        /// Workspace id.
        workspace_id: String,
        /// Which corner, or the centre.
        point: WorkspacePoint,
    },
    /// `get_object_labels_as_string`. Replies `Labels`.
    GetLabels,
    /// `add_object_name2object_labels`. Replies `LabelAdded`.
    AddLabel {
        /// The new label (stored lower-case).
        label: String,
    },
    /// The observation pose of a workspace. Replies `ObservationPose`.
    GetObservationPose {
        /// Workspace id.
        workspace_id: String,
    },
    /// Every configured workspace. Replies `Workspaces`.
    ListWorkspaces,
    /// The skills picked this object up: it is in the gripper, not on the table (it leaves
    /// the object queries and the free-space map). Replies `Object` with the object.
    ObjectPicked {
        /// The object's id.
        object_id: String,
    },
    /// The skills put this object down at `at`: memory moves it there until the camera
    /// confirms it (or, not seeing it, forgets it). Replies `Object` with the object.
    ObjectPlaced {
        /// The object's id.
        object_id: String,
        /// Where it was put, base frame, metres.
        at: Point2,
    },
    /// `label_object`: give the tracked object `object_id` the name `label`. The name stays
    /// with the object while it is tracked (across views, picks and places) until it leaves
    /// or is named again, and is added to the detectable labels. Replies `ObjectLabelled`.
    LabelObject {
        /// The object's id.
        object_id: String,
        /// The name (stored as labels are: trimmed, lower-case).
        label: String,
    },
}

impl Validate for WorkspaceRequest {
    fn validate(&self) -> Result<(), ValidationError> {
        match self {
            Self::GetObjects {
                location,
                coordinate,
                ..
            } => match coordinate {
                Some(c) => c.validate().map_err(|e| e.within("coordinate")),
                None if location.needs_coordinate() => Err(ValidationError::Invalid {
                    field: "coordinate".into(),
                    reason: WorkspaceError::CoordinateRequired {
                        location: *location,
                    }
                    .to_string(),
                }),
                None => Ok(()),
            },
            Self::GetObjectNear { coordinate, .. } => {
                coordinate.validate().map_err(|e| e.within("coordinate"))
            }
            Self::GetWorkspacePoint { workspace_id, .. }
            | Self::GetObservationPose { workspace_id } => non_empty("workspace_id", workspace_id),
            Self::AddLabel { label } => non_empty("label", label),
            Self::ObjectPicked { object_id } => non_empty("object_id", object_id),
            Self::LabelObject { object_id, label } => {
                non_empty("object_id", object_id)?;
                non_empty("label", label)
            }
            Self::ObjectPlaced { object_id, at } => {
                non_empty("object_id", object_id)?;
                at.validate().map_err(|e| e.within("at"))
            }
            Self::GetLargestObject
            | Self::GetSmallestObject
            | Self::GetObjectsSorted { .. }
            | Self::GetLargestFreeSpace
            | Self::GetLabels
            | Self::ListWorkspaces => Ok(()),
        }
    }
}

impl Message for WorkspaceRequest {
    const TYPE: &'static str = "workspace.request";
}

/// Why a workspace request failed.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, thiserror::Error)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum WorkspaceError {
    /// The workspace id is not configured.
    #[error("unknown workspace '{workspace_id}'; known: {}", known.join(", "))]
    UnknownWorkspace {
        /// The id asked for.
        workspace_id: String,
        /// Ids that are configured.
        known: Vec<String>,
    },
    /// A location filter was given without a reference coordinate.
    #[error("Coordinate must be provided for location filter: {location}")]
    CoordinateRequired {
        /// The filter that needs one.
        location: Location,
    },
    /// No sufficiently fresh detection could be obtained.
    #[error("no fresh detection: {reason}")]
    NoFreshDetection {
        /// Why (camera down, arm could not reach the observation pose, …).
        reason: String,
    },
    /// The request itself is invalid.
    #[error("invalid request: {reason}")]
    InvalidRequest {
        /// What is wrong.
        reason: String,
    },
    /// The workspace actor cannot serve requests right now.
    #[error("workspace model unavailable: {reason}")]
    Unavailable {
        /// Why.
        reason: String,
    },
}

impl From<ValidationError> for WorkspaceError {
    fn from(e: ValidationError) -> Self {
        WorkspaceError::InvalidRequest {
            reason: e.to_string(),
        }
    }
}

/// The workspace model actor's answer to one [`WorkspaceRequest`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum WorkspaceReply {
    /// A list of objects (possibly empty).
    Objects {
        /// The objects, in the order the request asks for.
        objects: Vec<DetectedObject>,
    },
    /// At most one object.
    Object {
        /// The object, or `None` when nothing matched.
        object: Option<DetectedObject>,
    },
    /// The largest free square of the workspace (its area and centre): anything that fits in a
    /// square of that area can be put down at its centre.
    FreeSpace {
        /// Its area, square metres.
        area_m2: f64,
        /// Its centre.
        center: Point2,
    },
    /// A workspace coordinate.
    Coordinate {
        /// The point asked for.
        coordinate: Point2,
    },
    /// The detectable labels, lower-case, in the order they were added.
    Labels {
        /// The labels.
        labels: Vec<String>,
        /// Those of them the built-in detector can see; the others need an external detector.
        #[serde(default)]
        builtin: Vec<String>,
    },
    /// Outcome of `AddLabel`.
    LabelAdded {
        /// The label as stored (lower-case).
        label: String,
        /// True when it was already in the list (nothing changed).
        already_known: bool,
    },
    /// Outcome of `LabelObject`.
    ObjectLabelled {
        /// The object, with its new label.
        object: DetectedObject,
        /// Its label before.
        previous: String,
        /// What the detector calls it (the label its views are matched by).
        detected_as: String,
        /// Whether the name was new to the detectable labels (and was added to them).
        label_added: bool,
    },
    /// A workspace's observation pose.
    ObservationPose {
        /// The pose.
        pose: Pose,
    },
    /// Every configured workspace.
    Workspaces {
        /// The workspaces.
        workspaces: Vec<WorkspaceInfo>,
    },
    /// The request failed.
    Error {
        /// Why.
        error: WorkspaceError,
    },
}

impl WorkspaceReply {
    /// `Err` for [`WorkspaceReply::Error`], `Ok(self)` otherwise.
    pub fn into_result(self) -> Result<WorkspaceReply, WorkspaceError> {
        match self {
            WorkspaceReply::Error { error } => Err(error),
            other => Ok(other),
        }
    }
}

impl From<WorkspaceError> for WorkspaceReply {
    fn from(error: WorkspaceError) -> Self {
        WorkspaceReply::Error { error }
    }
}

impl Message for WorkspaceReply {
    const TYPE: &'static str = "workspace.reply";
}

/// The detectable-label list, published at start and on every change.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct DetectableLabels {
    /// Lower-case labels.
    pub labels: Vec<String>,
    /// The label just added, when this publication is due to an addition.
    pub added: Option<String>,
    /// Those of `labels` the built-in detector can see; the others need an external detector
    /// (empty from senders that predate this field).
    #[serde(default)]
    pub builtin: Vec<String>,
}

impl Message for DetectableLabels {
    const TYPE: &'static str = "workspace.labels";
}

/// A [`WorkspaceRequest`] on the bus, with how fresh the view it is answered from must be.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct WorkspaceQuery {
    /// The question.
    pub request: WorkspaceRequest,
    /// Answer only from a detection of a frame taken after this time (ns since the Unix
    /// epoch) while the arm stood still; `None` answers from memory at once.
    #[serde(default)]
    pub fresh_after_unix_ns: Option<u64>,
    /// Longest to wait for such a detection, ms (at most [`MAX_FRESH_WAIT_MS`]; 0 = the
    /// workspace model's configured default); the answer is then
    /// [`WorkspaceError::NoFreshDetection`].
    #[serde(default)]
    pub max_wait_ms: u64,
}

/// Upper bound of [`WorkspaceQuery::max_wait_ms`].
pub const MAX_FRESH_WAIT_MS: u64 = 60_000;

impl WorkspaceQuery {
    /// A query answered from memory at once.
    pub fn now(request: WorkspaceRequest) -> Self {
        Self {
            request,
            fresh_after_unix_ns: None,
            max_wait_ms: 0,
        }
    }
}

impl Validate for WorkspaceQuery {
    fn validate(&self) -> Result<(), ValidationError> {
        self.request.validate().map_err(|e| e.within("request"))?;
        if self.max_wait_ms > MAX_FRESH_WAIT_MS {
            return Err(ValidationError::Invalid {
                field: "max_wait_ms".into(),
                reason: format!(
                    "must be at most {MAX_FRESH_WAIT_MS} ms, got {}",
                    self.max_wait_ms
                ),
            });
        }
        Ok(())
    }
}

impl Message for WorkspaceQuery {
    const TYPE: &'static str = "workspace.query";
}

/// The objects the workspace model remembers for a workspace, with stable ids, published
/// after every detection it applied.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct TrackedObjects {
    /// The workspace.
    pub workspace_id: String,
    /// The camera frame of the detection just applied.
    pub frame_id: u64,
    /// Its capture time, ns since the Unix epoch.
    pub timestamp_unix_ns: u64,
    /// The objects on the table (held ones excluded).
    pub objects: Vec<DetectedObject>,
    /// The `source` of the view just applied (the detector that sent it).
    #[serde(default)]
    pub source: String,
    /// One entry per object of the view just applied (`perception/detections` of `frame_id`,
    /// in order): the id of the object the model took it for, or `""` when it is none the model
    /// reports (a candidate no second view has confirmed yet, or a piece of a stack showing
    /// around its top). The edges name a view's boxes by it ([`TrackedObjects::named_view`]).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub detection_ids: Vec<String>,
}

impl Message for TrackedObjects {
    const TYPE: &'static str = "workspace.objects";
}

#[cfg(test)]
mod tests {
    use super::*;

    fn niryo() -> WorkspaceInfo {
        builtin_workspaces(RobotModel::Ned2)[0].to_info(RobotModel::Ned2)
    }

    #[test]
    fn named_points_match_the_spec_table() {
        let ws = niryo();
        assert!(ws.validate().is_ok());
        assert_eq!(
            ws.point(WorkspacePoint::UpperLeftCorner),
            Point2::new(0.337, 0.087)
        );
        assert_eq!(
            ws.point(WorkspacePoint::LowerRightCorner),
            Point2::new(0.163, -0.087)
        );
        assert_eq!(
            ws.point(WorkspacePoint::LowerLeftCorner),
            Point2::new(0.163, 0.087)
        );
        let c = ws.point(WorkspacePoint::CenterPoint);
        assert!((c.x_m - 0.25).abs() < 1e-12 && c.y_m.abs() < 1e-12);
        assert!((ws.area_m2() - 0.174 * 0.174).abs() < 1e-12);
        assert!(!ws.contains(Point2::new(0.40, 0.0), 0.01));
        assert!(ws.contains(Point2::new(0.34, 0.0), 0.01));
    }

    #[test]
    fn swapped_corners_are_refused() {
        let mut ws = niryo();
        std::mem::swap(&mut ws.upper_left, &mut ws.lower_right);
        assert_eq!(ws.validate().unwrap_err().field(), "upper_left");
    }

    #[test]
    fn error_texts_match_the_tools() {
        let e = WorkspaceError::CoordinateRequired {
            location: Location::CloseTo,
        };
        assert_eq!(
            e.to_string(),
            "Coordinate must be provided for location filter: close to"
        );
        let e = WorkspaceError::UnknownWorkspace {
            workspace_id: "x".into(),
            known: vec!["niryo_ws".into(), "widowx_ws".into()],
        };
        assert_eq!(
            e.to_string(),
            "unknown workspace 'x'; known: niryo_ws, widowx_ws"
        );
    }

    #[test]
    fn get_objects_defaults_from_other_languages() {
        let req: WorkspaceRequest =
            serde_json::from_value(serde_json::json!({"kind": "get_objects"})).unwrap();
        assert_eq!(
            req,
            WorkspaceRequest::GetObjects {
                location: Location::None,
                coordinate: None,
                label: None
            }
        );
        assert!(req.validate().is_ok());
        let req: WorkspaceRequest = serde_json::from_value(serde_json::json!(
            {"kind": "get_objects", "location": "Left Next To", "coordinate": [0.2, 0.0]}
        ))
        .unwrap();
        assert!(req.validate().is_ok());
    }

    #[test]
    fn labels_from_older_senders_read_without_the_builtin_list() {
        let labels: DetectableLabels =
            serde_json::from_value(serde_json::json!({"labels": ["pencil"], "added": null}))
                .unwrap();
        assert_eq!(labels.labels, ["pencil"]);
        assert!(labels.builtin.is_empty());
    }

    #[test]
    fn queries_wait_at_most_the_cap() {
        let mut q = WorkspaceQuery::now(WorkspaceRequest::GetLabels);
        assert!(q.validate().is_ok());
        q.max_wait_ms = MAX_FRESH_WAIT_MS + 1;
        assert_eq!(q.validate().unwrap_err().field(), "max_wait_ms");
        q.max_wait_ms = MAX_FRESH_WAIT_MS;
        q.request = WorkspaceRequest::ObjectPicked {
            object_id: " ".into(),
        };
        assert_eq!(q.validate().unwrap_err().field(), "request.object_id");
    }
}
