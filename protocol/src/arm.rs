//! Commanding the arm, and what it answers and reports.
//!
//! The arm actor serves [`ArmCommand`] requests (`"arm.command"`) with one [`ArmReply`]
//! (`"arm.reply"`) each, and publishes [`ArmState`] (`"arm.state"`) as it moves. Motion
//! commands reply when the motion has ended, with the pose actually reached; a motion that
//! cannot start or does not finish replies [`ArmReply::Error`] with a typed [`ArmError`] whose
//! `Display` is the reason text of a tool failure (`❌ Failed to pick 'pen': <reason>`).
//!
//! Every enum is internally tagged with `"kind"` in snake case, so a Python msgpack reader sees
//! `{"kind": "move_to_pose", "target": {"x": …}, "path": "joint"}`.
//!
//! ```
//! use robotd_protocol::arm::{ArmCommand, ArmError, ArmReply};
//! use robotd_protocol::geometry::Pose;
//! use robotd_protocol::validate::Validate;
//!
//! let cmd = ArmCommand::move_to(Pose::new(0.25, 0.0, 0.12, 0.0, 1.57, 0.0));
//! assert!(cmd.validate().is_ok());
//!
//! let reply: ArmReply = ArmError::NotCalibrated.into();
//! assert_eq!(reply.into_result().unwrap_err().to_string(),
//!            "the arm is not calibrated; run calibrate first");
//! ```

use crate::envelope::Message;
use crate::geometry::{JointState, Pose, PoseDelta};
use crate::validate::{non_empty, Validate, ValidationError};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// How the tool travels to a target pose.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PathKind {
    /// Interpolated in joint space (fastest, curved tool path).
    #[default]
    Joint,
    /// Straight line of the tool centre point in Cartesian space.
    Linear,
}

/// A request to the arm actor. Replied to with [`ArmReply`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum ArmCommand {
    /// Move the tool to `target`. Replies `Ok` with the reached pose.
    MoveToPose {
        /// Goal tool pose, base frame.
        target: Pose,
        /// Joint-space or straight-line path.
        #[serde(default)]
        path: PathKind,
    },
    /// Move to the given joint positions (one per joint, radians). Replies `Ok`.
    MoveJoints {
        /// Goal joint positions, base to wrist, radians.
        positions_rad: Vec<f64>,
    },
    /// Move the tool relative to its current pose. Replies `Ok`.
    ShiftPose {
        /// Change of position (m) and orientation (rad).
        delta: PoseDelta,
    },
    /// Stop any motion now and hold. Replies `Ok`; an interrupted motion replies `Stopped`.
    Stop,
    /// Move to the observation pose of a workspace (from configuration). Replies `Ok`, or
    /// `UnknownWorkspace`.
    GoToObservationPose {
        /// Workspace id, e.g. `niryo_ws`.
        workspace_id: String,
    },
    /// Run the joint calibration (Ned2) or homing. Replies `Ok`.
    Calibrate,
    /// Clear the collision-detected flag so motion can continue. Replies `Ok`.
    ClearCollision,
    /// Read the current tool pose. Replies `Ok`.
    GetPose,
    /// Read the current joint state. Replies `Joints`.
    GetJoints,
    /// Read the collision flag. Replies `CollisionState`.
    GetCollisionState,
}

impl ArmCommand {
    /// A joint-space move to `target`.
    pub fn move_to(target: Pose) -> Self {
        Self::MoveToPose {
            target,
            path: PathKind::Joint,
        }
    }

    /// Whether the command makes the arm move (and so must be refused while e-stopped).
    pub fn moves_arm(&self) -> bool {
        matches!(
            self,
            Self::MoveToPose { .. }
                | Self::MoveJoints { .. }
                | Self::ShiftPose { .. }
                | Self::GoToObservationPose { .. }
                | Self::Calibrate
        )
    }
}

impl Validate for ArmCommand {
    fn validate(&self) -> Result<(), ValidationError> {
        match self {
            Self::MoveToPose { target, .. } => target.validate().map_err(|e| e.within("target")),
            Self::MoveJoints { positions_rad } => {
                if positions_rad.is_empty() {
                    return Err(ValidationError::Empty {
                        field: "positions_rad".into(),
                    });
                }
                JointState::from_positions(positions_rad.clone(), 0).validate()
            }
            Self::ShiftPose { delta } => delta.validate().map_err(|e| e.within("delta")),
            Self::GoToObservationPose { workspace_id } => non_empty("workspace_id", workspace_id),
            Self::Stop
            | Self::Calibrate
            | Self::ClearCollision
            | Self::GetPose
            | Self::GetJoints
            | Self::GetCollisionState => Ok(()),
        }
    }
}

impl Message for ArmCommand {
    const TYPE: &'static str = "arm.command";
}

/// Why an arm command failed. `Display` is a reason a user (or an LLM) can act on.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, thiserror::Error)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum ArmError {
    /// No joint solution reaches the target within the limits.
    #[error("target pose {target} is unreachable: {reason}")]
    Unreachable {
        /// The pose asked for.
        target: Pose,
        /// Why (outside the Cartesian box, IK did not converge, joint limit, …).
        reason: String,
    },
    /// A joint target lies outside the joint's limits.
    #[error("joint {joint} target {value_rad:.4} rad is outside its limits [{min_rad:.4}, {max_rad:.4}] rad")]
    JointLimit {
        /// Joint index, 0 = base.
        joint: u32,
        /// The requested position, radians.
        value_rad: f64,
        /// Lower limit, radians.
        min_rad: f64,
        /// Upper limit, radians.
        max_rad: f64,
    },
    /// The arm detected a collision and stopped; clear the flag before moving again.
    #[error("collision detected; the arm stopped (clear_collision_detected to continue)")]
    Collision,
    /// The arm needs calibration before it can move.
    #[error("the arm is not calibrated; run calibrate first")]
    NotCalibrated,
    /// A `Stop` command interrupted the motion.
    #[error("motion stopped by a stop command")]
    Stopped,
    /// The emergency stop is engaged; nothing moves until it is released.
    #[error("emergency stop engaged: {reason}")]
    EStopped {
        /// Why the e-stop was engaged.
        reason: String,
    },
    /// The safety policy refused the motion (a limit, the rate, approval, the audit log).
    #[error("refused by the safety policy: {reason}")]
    Refused {
        /// The limit's short name (`floor`, `fence`, `rate`, `approval`, `estop`, …).
        limit: String,
        /// Why, with the values.
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
    /// The command itself is invalid (see [`Validate`]).
    #[error("invalid command: {reason}")]
    InvalidCommand {
        /// What is wrong.
        reason: String,
    },
    /// The motion did not finish in time.
    #[error("motion did not finish within {after_ms} ms")]
    Timeout {
        /// How long the arm actor waited, milliseconds.
        after_ms: u64,
    },
    /// The arm actor is not able to serve commands right now (restarting, in safe state).
    #[error("arm unavailable: {reason}")]
    Unavailable {
        /// Why.
        reason: String,
    },
    /// The driver (robot connection, servo bus) reported an error.
    #[error("arm driver error: {message}")]
    Driver {
        /// The driver's message.
        message: String,
    },
}

impl From<ValidationError> for ArmError {
    fn from(e: ValidationError) -> Self {
        ArmError::InvalidCommand {
            reason: e.to_string(),
        }
    }
}

/// The arm actor's answer to one [`ArmCommand`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum ArmReply {
    /// The command succeeded; `pose` is the tool pose afterwards.
    Ok {
        /// Tool pose once the command finished.
        pose: Pose,
    },
    /// Answer to `GetJoints`.
    Joints {
        /// Current joint state.
        joints: JointState,
    },
    /// Answer to `GetCollisionState`.
    CollisionState {
        /// Whether a collision has been detected and not cleared.
        collision_detected: bool,
    },
    /// The command failed.
    Error {
        /// Why.
        error: ArmError,
    },
}

impl ArmReply {
    /// `Err` for [`ArmReply::Error`], `Ok(self)` otherwise.
    pub fn into_result(self) -> Result<ArmReply, ArmError> {
        match self {
            ArmReply::Error { error } => Err(error),
            other => Ok(other),
        }
    }
}

impl From<ArmError> for ArmReply {
    fn from(error: ArmError) -> Self {
        ArmReply::Error { error }
    }
}

impl Message for ArmReply {
    const TYPE: &'static str = "arm.reply";
}

/// What the arm is doing, published periodically and on every change.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct ArmState {
    /// Joint positions and velocities.
    pub joints: JointState,
    /// Tool centre point pose, base frame.
    pub tool_pose: Pose,
    /// Whether a motion is under way.
    pub moving: bool,
    /// Whether a collision has been detected and not cleared.
    pub collision_detected: bool,
    /// Whether the arm is calibrated.
    pub calibrated: bool,
    /// Whether the emergency stop is engaged (absent from older senders: not engaged).
    #[serde(default)]
    pub estop_engaged: bool,
    /// When the arm last came to rest, ns since the Unix epoch; 0 while it moves (absent from
    /// older senders: 0). A camera frame taken after this instant, while `moving` is false,
    /// shows the arm standing still, however short the motion before was.
    #[serde(default)]
    pub still_since_unix_ns: u64,
}

impl Message for ArmState {
    const TYPE: &'static str = "arm.state";
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn validate_names_nested_fields() {
        let cmd = ArmCommand::move_to(Pose::new(0.2, f64::NAN, 0.1, 0.0, 0.0, 0.0));
        assert_eq!(
            cmd.validate().unwrap_err().to_string(),
            "target.y: must be a finite number, got NaN"
        );
        let cmd = ArmCommand::GoToObservationPose {
            workspace_id: " ".into(),
        };
        assert_eq!(cmd.validate().unwrap_err().field(), "workspace_id");
        assert!(ArmCommand::MoveJoints {
            positions_rad: vec![]
        }
        .validate()
        .is_err());
    }

    #[test]
    fn error_texts() {
        let e = ArmError::UnknownWorkspace {
            workspace_id: "lab".into(),
            known: vec!["niryo_ws".into(), "gazebo_1".into()],
        };
        assert_eq!(
            e.to_string(),
            "unknown workspace 'lab'; known: niryo_ws, gazebo_1"
        );
        let e = ArmError::Unreachable {
            target: Pose::new(0.9, 0.0, 0.1, 0.0, 1.571, 0.0),
            reason: "outside the Cartesian box".into(),
        };
        assert_eq!(
            e.to_string(),
            "target pose (x=0.900, y=0.000, z=0.100, roll=0.000, pitch=1.571, yaw=0.000) \
             is unreachable: outside the Cartesian box"
        );
    }

    #[test]
    fn wire_form_is_tagged() {
        let v = serde_json::to_value(ArmCommand::Stop).unwrap();
        assert_eq!(v, serde_json::json!({"kind": "stop"}));
        let v = serde_json::to_value(ArmReply::from(ArmError::Collision)).unwrap();
        assert_eq!(
            v,
            serde_json::json!({"kind": "error", "error": {"kind": "collision"}})
        );
        // `path` may be left out by other-language senders.
        let cmd: ArmCommand = serde_json::from_value(serde_json::json!({
            "kind": "move_to_pose",
            "target": {"x": 0.2, "y": 0.0, "z": 0.1, "roll": 0.0, "pitch": 1.57, "yaw": 0.0}
        }))
        .unwrap();
        assert_eq!(
            cmd,
            ArmCommand::move_to(Pose::new(0.2, 0.0, 0.1, 0.0, 1.57, 0.0))
        );
        assert!(cmd.moves_arm());
        assert!(!ArmCommand::GetPose.moves_arm());
    }
}

/// What the arm's states say about motion, for telling which camera frames show the arm at
/// rest. Perception and the Redis edge both use it, so a frame one calls steady the other does
/// too.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ArmMotion {
    /// Whether any arm state was received (without an arm, frames count as steady).
    pub heard: bool,
    /// Whether the latest state said the arm moves.
    pub moving: bool,
    /// Since when the arm rests (`None` while it moves, or before any state): the state's
    /// `still_since_unix_ns`, or for senders without it the send time of the first state that
    /// said the arm rests.
    pub rest_since_ns: Option<u64>,
    /// The latest tool pose.
    pub tool_pose: Option<Pose>,
}

impl ArmMotion {
    /// Takes in one arm state, sent at `sent_at_unix_ns`.
    pub fn update(&mut self, state: &ArmState, sent_at_unix_ns: u64) {
        self.heard = true;
        self.tool_pose = Some(state.tool_pose);
        if state.moving {
            self.rest_since_ns = None;
        } else if state.still_since_unix_ns > 0 {
            self.rest_since_ns = Some(state.still_since_unix_ns);
        } else if self.moving || self.rest_since_ns.is_none() {
            self.rest_since_ns = Some(sent_at_unix_ns);
        }
        self.moving = state.moving;
    }

    /// Whether a frame captured at `capture_ns` shows the arm at rest: taken after the arm
    /// came to rest, with no state since saying it moves. A frame taken during a motion, even
    /// one too short for any state to say "moving", is older than the rest that followed.
    pub fn steady_at(&self, capture_ns: u64) -> bool {
        !self.heard || (!self.moving && self.rest_since_ns.is_some_and(|r| capture_ns > r))
    }
}
