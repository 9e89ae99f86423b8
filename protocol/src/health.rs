//! Health, supervision and safety: how actors are doing, restarts, the emergency stop.
//!
//! Supervisors publish an [`ActorHealth`] (`"health.actor"`) whenever an actor changes state
//! and a [`RestartEvent`] (`"health.restart"`) for every restart attempt — after the failed
//! actor was driven to its safe state (motion stopped, holding). An [`EmergencyStop`]
//! (`"safety.estop"`) with `engaged: true` engages the e-stop from anyone; while engaged,
//! hardware actors refuse motion. Only an [`EStopRelease`] (`"safety.estop_release"`), a
//! request to the safety policy's own service `safety/release`, releases it; the policy
//! answers with the [`EStopState`] (`"safety.estop_state"`). [`SystemStatus`] (`"health.status"`) is the whole picture, the data of
//! `get_system_status` and of the dashboard.
//!
//! ```
//! use robotd_protocol::health::{ActorHealth, ActorState};
//!
//! let arm = ActorHealth::new("arm", ActorState::Running);
//! assert!(arm.state.is_serving());
//! assert_eq!(serde_json::to_value(ActorState::SafeState).unwrap(), "safe_state");
//! ```

use crate::envelope::Message;
use crate::geometry::{Pose, RobotModel};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};
use std::fmt;

/// Life-cycle state of a supervised actor.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ActorState {
    /// Being set up (connecting to hardware, opening the bus).
    Starting,
    /// Serving messages.
    Running,
    /// Failed; waiting for its backoff before the next start.
    Restarting,
    /// Failed and held in its safe state (no motion) until restarted or released.
    SafeState,
    /// Failed and not restarted again (restart budget spent).
    Failed,
    /// Stopped on purpose.
    Stopped,
}

impl ActorState {
    /// Wire name, e.g. `"safe_state"`.
    pub const fn as_str(&self) -> &'static str {
        match self {
            Self::Starting => "starting",
            Self::Running => "running",
            Self::Restarting => "restarting",
            Self::SafeState => "safe_state",
            Self::Failed => "failed",
            Self::Stopped => "stopped",
        }
    }

    /// Whether the actor serves requests in this state.
    pub const fn is_serving(&self) -> bool {
        matches!(self, Self::Running)
    }
}

impl fmt::Display for ActorState {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// How one actor is doing.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ActorHealth {
    /// Actor name, e.g. `"arm"`, `"camera"`.
    pub actor: String,
    /// Current state.
    pub state: ActorState,
    /// Restarts since robotd started.
    pub restarts: u32,
    /// The last failure, if any.
    pub last_error: Option<String>,
}

impl ActorHealth {
    /// A healthy record: no restarts, no error.
    pub fn new(actor: impl Into<String>, state: ActorState) -> Self {
        Self {
            actor: actor.into(),
            state,
            restarts: 0,
            last_error: None,
        }
    }
}

impl Message for ActorHealth {
    const TYPE: &'static str = "health.actor";
}

/// A supervisor is restarting (or giving up on) an actor.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct RestartEvent {
    /// Actor name.
    pub actor: String,
    /// Attempt number within the current restart window, from 1.
    pub attempt: u32,
    /// Why the actor failed.
    pub reason: String,
    /// Wait before the restart, milliseconds.
    pub backoff_ms: u64,
    /// Whether driving the actor to its safe state succeeded before the restart.
    pub safe_state_ok: bool,
    /// True when the restart budget is spent: no restart follows, the actor stays failed.
    pub budget_exhausted: bool,
}

impl Message for RestartEvent {
    const TYPE: &'static str = "health.restart";
}

/// Engage the emergency stop (`safety/estop`). A message with `engaged: false` releases
/// nothing: it is ignored and written to the audit log; releasing is an [`EStopRelease`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct EmergencyStop {
    /// True: stop all motion and refuse new motion. False: ignored (and audited).
    pub engaged: bool,
    /// Why.
    pub reason: String,
    /// Who (`"dashboard"`, `"cli"`, `"supervisor"`, a process name).
    pub source: String,
}

impl Message for EmergencyStop {
    const TYPE: &'static str = "safety.estop";
}

/// A deliberate release of the emergency stop, asked of the safety policy (`safety/release`).
/// The request's origin says who asks; the policy records it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EStopRelease {
    /// Must be exactly `release`: the cause of the stop was dealt with.
    pub confirm: String,
    /// Who releases it and why (recorded).
    pub by: String,
    /// Release only if the e-stop's reason is exactly this (absent: whatever it is): a tool
    /// that engaged the e-stop itself releases its own stop and never one somebody else
    /// engaged meanwhile (their reason joins the reason, so it no longer matches).
    #[serde(default)]
    pub only_if_reason: Option<String>,
}

impl Message for EStopRelease {
    const TYPE: &'static str = "safety.estop_release";
}

/// The emergency stop's state, as the safety policy answers a release.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EStopState {
    /// Whether it is engaged now.
    pub engaged: bool,
    /// Why it is engaged, or how it was released.
    pub reason: String,
}

impl Message for EStopState {
    const TYPE: &'static str = "safety.estop_state";
}

/// The state of the whole robot.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SystemStatus {
    /// Configured robot id.
    pub robot_id: String,
    /// Arm model.
    pub robot_model: RobotModel,
    /// Current workspace id.
    pub workspace_id: String,
    /// Current tool pose; `None` when the arm cannot be read.
    pub pose: Option<Pose>,
    /// Every supervised actor.
    pub actors: Vec<ActorHealth>,
    /// Whether the e-stop is engaged.
    pub estop_engaged: bool,
    /// Time since robotd started, milliseconds.
    pub uptime_ms: u64,
}

impl SystemStatus {
    /// Total restarts over all actors.
    pub fn total_restarts(&self) -> u64 {
        self.actors.iter().map(|a| u64::from(a.restarts)).sum()
    }
}

impl Message for SystemStatus {
    const TYPE: &'static str = "health.status";
}
