//! Talking to the LLM agent: a request in plain words, a stream of events back, and cancel.
//!
//! A front end (CLI, dashboard, another process) sends an [`AgentRequest`] (`"agent.request"`)
//! with an id it chose. The agent publishes [`AgentEvent`]s (`"agent.event"`) tagged with that
//! id as it works — its plan, each tool call and result as they happen, then exactly one
//! terminal event: the answer, an error, or "cancelled". An [`AgentCancel`] (`"agent.cancel"`)
//! stops a request between tool calls.
//!
//! ```
//! use robotd_protocol::agent::{AgentEvent, AgentEventKind};
//!
//! let ev = AgentEvent {
//!     request_id: "r1".into(),
//!     seq: 3,
//!     event: AgentEventKind::ToolCall {
//!         call_id: "c1".into(),
//!         name: "get_detected_objects".into(),
//!         arguments_json: r#"{"label":"cube"}"#.into(),
//!     },
//! };
//! assert!(!ev.event.is_terminal());
//! assert!(AgentEventKind::Cancelled.is_terminal());
//! ```

use crate::envelope::Message;
use crate::validate::{non_empty, Validate, ValidationError};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// Ask the agent to carry out a task.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct AgentRequest {
    /// Id chosen by the sender; every event about this request carries it.
    pub request_id: String,
    /// The task in the user's words.
    pub text: String,
}

impl Validate for AgentRequest {
    fn validate(&self) -> Result<(), ValidationError> {
        non_empty("request_id", &self.request_id)?;
        non_empty("text", &self.text)
    }
}

impl Message for AgentRequest {
    const TYPE: &'static str = "agent.request";
}

/// Stop working on a request (between tool calls; a motion under way finishes).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct AgentCancel {
    /// The request to cancel.
    pub request_id: String,
}

impl Message for AgentCancel {
    const TYPE: &'static str = "agent.cancel";
}

/// One step of the agent's work on a request.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct AgentEvent {
    /// The request this is about.
    pub request_id: String,
    /// 0, 1, 2, … per request, so a reader can spot gaps and order events.
    pub seq: u32,
    /// What happened.
    pub event: AgentEventKind,
}

impl Message for AgentEvent {
    const TYPE: &'static str = "agent.event";
}

/// What happened in an [`AgentEvent`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum AgentEventKind {
    /// The agent's understanding of the task and its plan.
    Plan {
        /// The plan, as the model wrote it.
        text: String,
    },
    /// The agent is calling a tool.
    ToolCall {
        /// Id of this call (matches the `ToolResult`).
        call_id: String,
        /// Tool name, e.g. `pick_place_object`.
        name: String,
        /// The arguments as a JSON object, verbatim.
        arguments_json: String,
    },
    /// A tool call finished.
    ToolResult {
        /// Id of the call.
        call_id: String,
        /// Tool name.
        name: String,
        /// The tool's reply text (`✓ …` or `❌ …`).
        text: String,
        /// Whether the tool succeeded.
        ok: bool,
    },
    /// Final answer; terminal.
    Answer {
        /// The answer text.
        text: String,
    },
    /// The request failed (provider unreachable, round limit reached, …); terminal.
    Error {
        /// What went wrong.
        message: String,
    },
    /// The request was cancelled; terminal.
    Cancelled,
}

impl AgentEventKind {
    /// Whether no more events follow for this request.
    pub const fn is_terminal(&self) -> bool {
        matches!(
            self,
            Self::Answer { .. } | Self::Error { .. } | Self::Cancelled
        )
    }
}
