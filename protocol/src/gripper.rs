//! Commanding the gripper, and what it answers and reports.
//!
//! The gripper actor serves [`GripperCommand`] (`"gripper.command"`) with one [`GripperReply`]
//! (`"gripper.reply"`) and publishes [`GripperState`] (`"gripper.state"`). Every answer says
//! whether the gripper really holds something (the fingers stopped before closing fully) and
//! how far apart the fingers are, so a pick reports its real outcome.
//!
//! ```
//! use robotd_protocol::gripper::{GripperCommand, GripperReply};
//! use robotd_protocol::validate::Validate;
//!
//! assert!(GripperCommand::SetWidth { width_m: 0.03 }.validate().is_ok());
//! assert!(GripperCommand::SetWidth { width_m: -0.01 }.validate().is_err());
//!
//! let reply = GripperReply::State { holding: true, width_m: 0.029 };
//! assert!(reply.holding().unwrap());
//! ```

use crate::envelope::Message;
use crate::validate::{in_range, Validate, ValidationError};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// Widest opening any supported gripper can be asked for, metres (WidowX: 2 × 0.037).
pub const MAX_GRIPPER_WIDTH_M: f64 = 0.074;

/// A request to the gripper actor. Replied to with [`GripperReply`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum GripperCommand {
    /// Open fully.
    Open,
    /// Close until fully closed or blocked by an object.
    Close,
    /// Move the fingers to `width_m` apart (grippers that support it).
    SetWidth {
        /// Distance between the fingers, metres.
        width_m: f64,
    },
    /// Read the state without moving.
    GetState,
}

impl Validate for GripperCommand {
    fn validate(&self) -> Result<(), ValidationError> {
        match self {
            Self::SetWidth { width_m } => in_range("width_m", *width_m, 0.0, MAX_GRIPPER_WIDTH_M),
            Self::Open | Self::Close | Self::GetState => Ok(()),
        }
    }
}

impl Message for GripperCommand {
    const TYPE: &'static str = "gripper.command";
}

/// Why a gripper command failed.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, thiserror::Error)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum GripperError {
    /// The requested width is beyond what this gripper can do.
    #[error("gripper width {width_m:.3} m is outside 0 … {max_m:.3} m")]
    InvalidWidth {
        /// Requested width, metres.
        width_m: f64,
        /// Widest opening of this gripper, metres.
        max_m: f64,
    },
    /// The emergency stop is engaged.
    #[error("emergency stop engaged: {reason}")]
    EStopped {
        /// Why the e-stop was engaged.
        reason: String,
    },
    /// The safety policy refused the motion (e-stop, rate limit, approval, audit log).
    #[error("refused by the safety policy: {reason}")]
    Refused {
        /// The limit's short name.
        limit: String,
        /// Why.
        reason: String,
    },
    /// The gripper actor cannot serve commands right now.
    #[error("gripper unavailable: {reason}")]
    Unavailable {
        /// Why.
        reason: String,
    },
    /// The command itself is invalid.
    #[error("invalid command: {reason}")]
    InvalidCommand {
        /// What is wrong.
        reason: String,
    },
    /// The driver reported an error.
    #[error("gripper driver error: {message}")]
    Driver {
        /// The driver's message.
        message: String,
    },
}

impl From<ValidationError> for GripperError {
    fn from(e: ValidationError) -> Self {
        GripperError::InvalidCommand {
            reason: e.to_string(),
        }
    }
}

/// The gripper actor's answer to one [`GripperCommand`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum GripperReply {
    /// The command finished; the gripper's state afterwards.
    State {
        /// Whether an object is between the fingers (they stopped before closing fully).
        holding: bool,
        /// Distance between the fingers, metres.
        width_m: f64,
    },
    /// The command failed.
    Error {
        /// Why.
        error: GripperError,
    },
}

impl GripperReply {
    /// `Ok(holding)` for a state, `Err` for an error.
    pub fn holding(&self) -> Result<bool, &GripperError> {
        match self {
            Self::State { holding, .. } => Ok(*holding),
            Self::Error { error } => Err(error),
        }
    }
}

impl From<GripperError> for GripperReply {
    fn from(error: GripperError) -> Self {
        GripperReply::Error { error }
    }
}

impl From<GripperState> for GripperReply {
    fn from(s: GripperState) -> Self {
        GripperReply::State {
            holding: s.holding,
            width_m: s.width_m,
        }
    }
}

impl Message for GripperReply {
    const TYPE: &'static str = "gripper.reply";
}

/// The gripper's state, published on every change.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct GripperState {
    /// Whether an object is between the fingers.
    pub holding: bool,
    /// Distance between the fingers, metres.
    pub width_m: f64,
    /// Whether the fingers are moving.
    pub moving: bool,
}

impl Message for GripperState {
    const TYPE: &'static str = "gripper.state";
}
