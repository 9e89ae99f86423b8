//! Talking to the LLM agent: a request in plain words, a stream of events back, and cancel.
//!
//! A front end (CLI, dashboard, another process) sends an [`AgentRequest`] (`"agent.request"`)
//! with an id it chose. The agent publishes [`AgentEvent`]s (`"agent.event"`) tagged with that
//! id as it works — its plan, each tool call and result as they happen, then exactly one
//! terminal event: the answer, an error, or "cancelled". An [`AgentCancel`] (`"agent.cancel"`)
//! stops a request between tool calls.
//!
//! A tool that returns a picture (`get_camera_image`) is followed by an
//! [`AgentEventKind::Picture`] with the file itself (base64, at most [`MAX_PICTURE_BYTES`]), so
//! a front end can show what the agent looked at.
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
    /// A picture a tool returned (`get_camera_image`: the camera's view with the objects' ids
    /// drawn), right after that call's `ToolResult`: what the agent looked at.
    Picture {
        /// Id of the call that returned it.
        call_id: String,
        /// Tool name.
        name: String,
        /// `image/jpeg` or `image/png` ([`PICTURE_TYPES`]).
        mime_type: String,
        /// The file, standard base64 with padding; at most [`MAX_PICTURE_BYTES`] decoded.
        data_base64: String,
        /// Whether the model was sent the picture (a text-only model gets the tool's text).
        shown_to_model: bool,
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

/// Largest picture an [`AgentEventKind::Picture`] carries, bytes before base64 (the pictures of
/// `get_camera_image` are at most 150 kB unless asked otherwise).
pub const MAX_PICTURE_BYTES: usize = 160 * 1024;

/// The picture formats an [`AgentEventKind::Picture`] may carry, with the base64 text each
/// file starts with (its magic bytes).
pub const PICTURE_TYPES: [(&str, &str); 2] = [("image/jpeg", "/9j/"), ("image/png", "iVBORw0KGgo")];

/// Checks a picture's type and text: a known type, standard base64 of at most
/// [`MAX_PICTURE_BYTES`] bytes, starting with that type's magic bytes.
pub fn validate_picture(mime_type: &str, data_base64: &str) -> Result<(), ValidationError> {
    let invalid = |field: &str, reason: String| ValidationError::Invalid {
        field: field.into(),
        reason,
    };
    let Some((_, magic)) = PICTURE_TYPES.iter().find(|(t, _)| *t == mime_type) else {
        return Err(invalid(
            "mime_type",
            format!("must be image/jpeg or image/png, got {mime_type:?}"),
        ));
    };
    let most = MAX_PICTURE_BYTES.div_ceil(3) * 4;
    if data_base64.len() > most {
        return Err(invalid(
            "data_base64",
            format!(
                "a picture is at most {MAX_PICTURE_BYTES} bytes ({most} base64 characters), got {} characters",
                data_base64.len()
            ),
        ));
    }
    let body = data_base64.trim_end_matches('=');
    let padding = data_base64.len() - body.len();
    let alphabet = |b: u8| b.is_ascii_alphanumeric() || b == b'+' || b == b'/';
    if !data_base64.len().is_multiple_of(4) || padding > 2 || !body.bytes().all(alphabet) {
        return Err(invalid(
            "data_base64",
            "must be standard base64 with padding".into(),
        ));
    }
    if !data_base64.starts_with(magic) {
        return Err(invalid(
            "data_base64",
            format!("is not a {mime_type} file (it must start with {magic:?})"),
        ));
    }
    Ok(())
}

impl Validate for AgentEvent {
    fn validate(&self) -> Result<(), ValidationError> {
        non_empty("request_id", &self.request_id)?;
        match &self.event {
            AgentEventKind::Picture {
                mime_type,
                data_base64,
                ..
            } => validate_picture(mime_type, data_base64).map_err(|e| e.within("event")),
            _ => Ok(()),
        }
    }
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

#[cfg(test)]
mod tests {
    use super::*;

    fn picture(mime_type: &str, data_base64: String) -> AgentEvent {
        AgentEvent {
            request_id: "r1".into(),
            seq: 4,
            event: AgentEventKind::Picture {
                call_id: "c1".into(),
                name: "get_camera_image".into(),
                mime_type: mime_type.into(),
                data_base64,
                shown_to_model: true,
            },
        }
    }

    #[test]
    fn a_picture_is_a_bounded_jpeg_or_png_in_base64() {
        // FF D8 FF E0 00 10 'J' 'F' 'I' in base64.
        assert_eq!(
            picture("image/jpeg", "/9j/4AAQSkZJ".into()).validate(),
            Ok(())
        );
        assert_eq!(
            picture("image/png", "iVBORw0KGgo=".into()).validate(),
            Ok(())
        );
        let largest = format!("/9j/{}", "A".repeat(MAX_PICTURE_BYTES.div_ceil(3) * 4 - 4));
        assert_eq!(picture("image/jpeg", largest.clone()).validate(), Ok(()));
        let refused = [
            picture("image/svg+xml", "/9j/4AAQSkZJ".into()),
            picture("image/png", "/9j/4AAQSkZJ".into()),
            picture("image/jpeg", "iVBORw0KGgo=".into()),
            picture("image/jpeg", format!("{largest}AAAA")),
            picture("image/jpeg", "/9j/4AAQSkZ".into()),
            picture("image/jpeg", "/9j/4AAQ\"<>".into()),
            picture("image/jpeg", "/9j/4A==AAAA".into()),
            picture("image/jpeg", String::new()),
        ];
        for event in refused {
            let error = event.validate().unwrap_err();
            assert!(error.field().starts_with("event."), "{error}");
        }
        let mut no_id = picture("image/jpeg", "/9j/4AAQSkZJ".into());
        no_id.request_id.clear();
        assert!(no_id.validate().is_err());
    }
}
