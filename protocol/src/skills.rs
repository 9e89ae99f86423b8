//! The skills actor's messages: pick, place, push and the other robot-control tools as one
//! request each.
//!
//! A skill is a short plan of arm and gripper commands built around the workspace model's
//! objects (see `docs/mcp-tools.md`, "Robot control"). Every target is checked — inside the
//! workspace plus a margin, reachable by the arm — before anything moves, and the reply is the
//! real outcome: `Done` only when the gripper really held (or released) the object.
//!
//! Each request carries a `run_id` chosen by the caller. While it runs, the actor publishes
//! [`SkillProgress`] with that id (step `n` of `total`, what it is doing), and a
//! [`SkillCancel`] with the id stops the arm and ends the skill with
//! [`SkillError::Cancelled`].

use crate::envelope::Message;
use crate::geometry::Point2;
use crate::location::{Direction, Location};
use crate::objects::DetectedObject;
use crate::validate::{finite, in_range, non_empty, Validate, ValidationError};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// Largest `z_offset` a pick accepts, metres.
pub const MAX_Z_OFFSET_M: f64 = 0.1;

/// The default `z_offset` of the pick tools, metres.
pub const DEFAULT_Z_OFFSET_M: f64 = 0.001;

/// One skill to run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Skill {
    /// Pick the object labelled `object_name` nearest `pick_at` (within 5 cm).
    Pick {
        /// Label, matched exactly (case-insensitive).
        object_name: String,
        /// Where the caller believes the object is.
        pick_at: Point2,
        /// How far above the object's centre of mass to close the fingers, metres.
        z_offset_m: f64,
    },
    /// Place the held object at `place_at`, or relative to the object nearest it.
    Place {
        /// The coordinate (or the reference object's neighbourhood).
        place_at: Point2,
        /// Spatial relation to the reference object; `none` places exactly at `place_at`.
        location: Location,
    },
    /// Pick, then place.
    PickPlace {
        /// Label of the object to pick.
        object_name: String,
        /// Where it is.
        pick_at: Point2,
        /// Where it goes.
        place_at: Point2,
        /// Spatial relation to the object nearest `place_at`.
        location: Location,
        /// See [`Skill::Pick`].
        z_offset_m: f64,
    },
    /// Push the object from behind, `distance_m` in `direction`.
    Push {
        /// Label of the object to push.
        object_name: String,
        /// Where it is.
        push_at: Point2,
        /// Which way.
        direction: Direction,
        /// How far, metres.
        distance_m: f64,
    },
    /// Pick the object and place it `distance_m` in `direction` of where it was.
    MoveBy {
        /// Label of the object.
        object_name: String,
        /// Where it is.
        pick_at: Point2,
        /// Which way.
        direction: Direction,
        /// How far, metres.
        distance_m: f64,
        /// See [`Skill::Pick`].
        z_offset_m: f64,
    },
    /// Move to a workspace's observation pose.
    GoToObservationPose {
        /// Workspace id.
        workspace_id: String,
    },
    /// Calibrate the arm.
    Calibrate,
    /// Clear the collision flag.
    ClearCollision,
}

impl Skill {
    /// The skill's name in log lines and metrics.
    pub fn name(&self) -> &'static str {
        match self {
            Skill::Pick { .. } => "pick",
            Skill::Place { .. } => "place",
            Skill::PickPlace { .. } => "pick_place",
            Skill::Push { .. } => "push",
            Skill::MoveBy { .. } => "move_by",
            Skill::GoToObservationPose { .. } => "go_to_observation_pose",
            Skill::Calibrate => "calibrate",
            Skill::ClearCollision => "clear_collision",
        }
    }

    /// The MCP tool that runs this skill (how `[safety] approval_tools` names it).
    pub fn tool_name(&self) -> &'static str {
        match self {
            Skill::Pick { .. } => "pick_object",
            Skill::Place { .. } => "place_object",
            Skill::PickPlace { .. } => "pick_place_object",
            Skill::Push { .. } => "push_object",
            Skill::MoveBy { .. } => "move2by",
            Skill::GoToObservationPose { .. } => "move2observation_pose",
            Skill::Calibrate => "calibrate",
            Skill::ClearCollision => "clear_collision_detected",
        }
    }
}

fn point(field: &str, p: &Point2) -> Result<(), ValidationError> {
    finite(&format!("{field}.x_m"), p.x_m)?;
    finite(&format!("{field}.y_m"), p.y_m)
}

fn distance(field: &str, d: f64) -> Result<(), ValidationError> {
    finite(field, d)?;
    if d <= 0.0 {
        return Err(ValidationError::Invalid {
            field: field.into(),
            reason: format!("must be greater than 0, got {d}"),
        });
    }
    Ok(())
}

impl Validate for Skill {
    fn validate(&self) -> Result<(), ValidationError> {
        match self {
            Skill::Pick {
                object_name,
                pick_at,
                z_offset_m,
            } => {
                non_empty("object_name", object_name)?;
                point("pick_at", pick_at)?;
                in_range("z_offset_m", *z_offset_m, 0.0, MAX_Z_OFFSET_M)
            }
            Skill::Place { place_at, .. } => point("place_at", place_at),
            Skill::PickPlace {
                object_name,
                pick_at,
                place_at,
                z_offset_m,
                ..
            } => {
                non_empty("object_name", object_name)?;
                point("pick_at", pick_at)?;
                point("place_at", place_at)?;
                in_range("z_offset_m", *z_offset_m, 0.0, MAX_Z_OFFSET_M)
            }
            Skill::Push {
                object_name,
                push_at,
                distance_m,
                ..
            } => {
                non_empty("object_name", object_name)?;
                point("push_at", push_at)?;
                distance("distance_m", *distance_m)
            }
            Skill::MoveBy {
                object_name,
                pick_at,
                distance_m,
                z_offset_m,
                ..
            } => {
                non_empty("object_name", object_name)?;
                point("pick_at", pick_at)?;
                distance("distance_m", *distance_m)?;
                in_range("z_offset_m", *z_offset_m, 0.0, MAX_Z_OFFSET_M)
            }
            Skill::GoToObservationPose { workspace_id } => non_empty("workspace_id", workspace_id),
            Skill::Calibrate | Skill::ClearCollision => Ok(()),
        }
    }
}

/// A request to the skills actor.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SkillRequest {
    /// Caller-chosen id that progress and cancel messages refer to.
    pub run_id: u64,
    /// What to do.
    pub skill: Skill,
}

impl Validate for SkillRequest {
    fn validate(&self) -> Result<(), ValidationError> {
        self.skill.validate()
    }
}

impl Message for SkillRequest {
    const TYPE: &'static str = "skills.request";
}

/// Why a skill failed. `Display` is the reason after `❌ Failed to …: ` in the tool texts.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, thiserror::Error)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum SkillError {
    /// No object with the label near the coordinate.
    #[error("no '{object_name}' within 5 cm of [{:.3}, {:.3}]{}", at.x_m, at.y_m, nearby_text(nearby))]
    ObjectNotFound {
        /// The label asked for.
        object_name: String,
        /// The coordinate given.
        at: Point2,
        /// Labels seen within 5 cm of it.
        nearby: Vec<String>,
    },
    /// A target lies outside every workspace (plus the margin).
    #[error("{what} coordinate [{:.3}, {:.3}] is outside workspace '{workspace_id}'", at.x_m, at.y_m)]
    OutsideWorkspace {
        /// `pick`, `place` or `push`.
        what: String,
        /// The coordinate.
        at: Point2,
        /// The workspace it was checked against.
        workspace_id: String,
    },
    /// The arm cannot reach a pose of the plan.
    #[error("{what} is out of the arm's reach: {reason}")]
    Unreachable {
        /// Which pose of the plan.
        what: String,
        /// Why (from the kinematics).
        reason: String,
    },
    /// `place` with nothing in the gripper.
    #[error("the gripper holds nothing to place")]
    NothingHeld,
    /// The fingers closed on nothing.
    #[error("the gripper closed on nothing at [{:.3}, {:.3}]; the object was not grasped", at.x_m, at.y_m)]
    GraspMissed {
        /// Where the grasp was tried.
        at: Point2,
    },
    /// The object is wider than the gripper opens.
    #[error("'{object_name}' is {width_mm:.1} mm wide across the grasp but the gripper opens only {max_mm:.1} mm; push it instead")]
    TooWide {
        /// Label.
        object_name: String,
        /// Its extent across the fingers, millimetres.
        width_mm: f64,
        /// The gripper's largest opening, millimetres.
        max_mm: f64,
    },
    /// A location the placement cannot use (e.g. `inside` a non-container).
    #[error("{reason}")]
    BadPlacement {
        /// Why.
        reason: String,
    },
    /// The motion ran but the camera shows it did not do what was asked (a push that was
    /// blocked, an object that slipped).
    #[error("{reason}")]
    NotAsExpected {
        /// What the camera shows.
        reason: String,
    },
    /// The workspace id is not configured.
    #[error("unknown workspace '{workspace_id}'; known: {}", known.join(", "))]
    UnknownWorkspace {
        /// The id asked for.
        workspace_id: String,
        /// Ids that are configured.
        known: Vec<String>,
    },
    /// The arm reported an error (collision, e-stop, driver).
    #[error("{message}")]
    Arm {
        /// What went wrong.
        message: String,
    },
    /// The gripper reported an error.
    #[error("{message}")]
    Gripper {
        /// What went wrong.
        message: String,
    },
    /// The workspace model could not answer.
    #[error("{message}")]
    Perception {
        /// What went wrong.
        message: String,
    },
    /// The safety policy refused the skill before it started (no approval).
    #[error("{reason}")]
    Refused {
        /// Why, and that nothing moved.
        reason: String,
    },
    /// A cancel request (or a client that went away) stopped the skill; the arm is held where
    /// it stopped.
    #[error("cancelled; the arm was stopped")]
    Cancelled,
    /// The request itself is invalid.
    #[error("invalid request: {reason}")]
    Invalid {
        /// What is wrong.
        reason: String,
    },
}

impl SkillReply {
    /// A failure that leaves the gripper empty (or holding what it held before, untouched).
    pub fn failed(error: SkillError) -> Self {
        Self::Failed {
            error,
            still_held: None,
            put_down_at: None,
        }
    }
}

impl SkillError {
    /// An arm failure with `message`.
    pub fn arm(message: impl Into<String>) -> Self {
        Self::Arm {
            message: message.into(),
        }
    }

    /// A gripper failure with `message`.
    pub fn gripper(message: impl Into<String>) -> Self {
        Self::Gripper {
            message: message.into(),
        }
    }

    /// A workspace-model failure with `message`.
    pub fn perception(message: impl Into<String>) -> Self {
        Self::Perception {
            message: message.into(),
        }
    }
}

fn nearby_text(nearby: &[String]) -> String {
    if nearby.is_empty() {
        "; no objects seen there".to_owned()
    } else {
        format!("; seen there: {}", nearby.join(", "))
    }
}

impl From<ValidationError> for SkillError {
    fn from(e: ValidationError) -> Self {
        SkillError::Invalid {
            reason: e.to_string(),
        }
    }
}

/// The skills actor's answer.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum SkillReply {
    /// The skill finished with the real outcome it reports.
    Done {
        /// The object picked or pushed, as the workspace model knew it before the skill.
        #[serde(default)]
        object: Option<Box<DetectedObject>>,
        /// Where it was picked or pushed from.
        #[serde(default)]
        from: Option<Point2>,
        /// Where it was placed, or where the push ended.
        #[serde(default)]
        to: Option<Point2>,
    },
    /// The skill failed; what was done before the failure stays done.
    Failed {
        /// Why.
        error: SkillError,
        /// The label of the object the gripper still holds after the failure (absent: none).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        still_held: Option<String>,
        /// A free spot where the held object fits, to put it down (absent: none known).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        put_down_at: Option<Point2>,
    },
}

impl Message for SkillReply {
    const TYPE: &'static str = "skills.reply";
}

/// Progress of a running skill.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct SkillProgress {
    /// The request's `run_id`.
    pub run_id: u64,
    /// Steps done so far.
    pub step: u32,
    /// Steps in the plan.
    pub total: u32,
    /// What the step does, e.g. "closing the gripper".
    pub message: String,
}

impl Message for SkillProgress {
    const TYPE: &'static str = "skills.progress";
}

/// Stop the skill with this `run_id` (the arm stops at once and holds).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct SkillCancel {
    /// The request's `run_id`.
    pub run_id: u64,
}

impl Message for SkillCancel {
    const TYPE: &'static str = "skills.cancel";
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn error_texts_follow_the_contract() {
        let e = SkillError::ObjectNotFound {
            object_name: "pencil".into(),
            at: Point2::new(0.2, -0.05),
            nearby: vec!["red cube".into()],
        };
        assert_eq!(
            e.to_string(),
            "no 'pencil' within 5 cm of [0.200, -0.050]; seen there: red cube"
        );
        let e = SkillError::OutsideWorkspace {
            what: "place".into(),
            at: Point2::new(99.9, 99.9),
            workspace_id: "niryo_ws".into(),
        };
        assert_eq!(
            e.to_string(),
            "place coordinate [99.900, 99.900] is outside workspace 'niryo_ws'"
        );
        // Every error travels on the bus (MessagePack, internally tagged).
        let reply = SkillReply::Failed {
            error: SkillError::arm("collision detected"),
            still_held: Some("pencil".into()),
            put_down_at: Some(Point2::new(0.25, 0.05)),
        };
        let mut bytes = Vec::new();
        crate::envelope::encode(&crate::envelope::Envelope::new(reply.clone()), &mut bytes)
            .unwrap();
        let back: crate::envelope::Envelope<SkillReply> = crate::envelope::decode(&bytes).unwrap();
        assert_eq!(back.body, reply);
    }

    #[test]
    fn validation_refuses_bad_numbers() {
        let s = Skill::Push {
            object_name: "box".into(),
            push_at: Point2::new(0.25, 0.0),
            direction: Direction::Right,
            distance_m: 0.0,
        };
        assert_eq!(s.validate().unwrap_err().field(), "distance_m");
        let s = Skill::Pick {
            object_name: " ".into(),
            pick_at: Point2::new(0.25, 0.0),
            z_offset_m: 0.001,
        };
        assert_eq!(s.validate().unwrap_err().field(), "object_name");
        let wire = serde_json::to_value(Skill::Calibrate).unwrap();
        assert_eq!(wire, serde_json::json!({"kind": "calibrate"}));
    }
}
