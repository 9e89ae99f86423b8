//! What the robot says and shows: speech requests, speech events, text overlays.
//!
//! The `speak` tool returns at once; the text goes to the TTS actor as a [`SpeakRequest`]
//! (`"speech.speak"`), which queues it by priority and reports what happens to it as
//! [`SpeechEvent`]s (`"speech.event"`). Texts meant for people watching the video — the current
//! user task, what the robot says, system messages — are published as [`TextOverlay`]s
//! (`"overlay.text"`), which the Redis edge forwards to `video_text_overlays`.
//!
//! ```
//! use robotd_protocol::speech::{OverlayKind, SpeakRequest, TextOverlay};
//! use robotd_protocol::validate::Validate;
//!
//! let say = SpeakRequest::new("Picking up the pencil", "mcp");
//! assert!(say.validate().is_ok());
//! assert!(SpeakRequest::new("a".repeat(2001), "mcp").validate().is_err());
//! let overlay = TextOverlay::new("sort the cubes", OverlayKind::UserTask);
//! assert_eq!(serde_json::to_value(overlay.kind).unwrap(), "user_task");
//! ```

use crate::envelope::Message;
use crate::validate::{in_range, non_empty, Validate, ValidationError};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// Default priority of a [`SpeakRequest`]; higher is spoken first.
pub const DEFAULT_SPEECH_PRIORITY: u8 = 5;

/// Ask the TTS actor to say something.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct SpeakRequest {
    /// What to say.
    pub text: String,
    /// Queue priority, 0 (lowest) … 255; higher-priority texts are spoken first.
    pub priority: u8,
    /// Who asked (`"mcp"`, `"agent"`, `"skills"`, …), for logs and overlays.
    pub source: String,
}

impl SpeakRequest {
    /// A request with the default priority.
    pub fn new(text: impl Into<String>, source: impl Into<String>) -> Self {
        Self {
            text: text.into(),
            priority: DEFAULT_SPEECH_PRIORITY,
            source: source.into(),
        }
    }
}

/// Longest text one [`SpeakRequest`] may carry, in characters (about two minutes of speech).
pub const MAX_SPEECH_CHARS: usize = 2000;

impl Validate for SpeakRequest {
    fn validate(&self) -> Result<(), ValidationError> {
        non_empty("text", &self.text)?;
        let chars = self.text.chars().count();
        if chars > MAX_SPEECH_CHARS {
            return Err(ValidationError::Invalid {
                field: "text".into(),
                reason: format!(
                    "at most {MAX_SPEECH_CHARS} characters can be spoken at once, got {chars}; \
                     split the text"
                ),
            });
        }
        Ok(())
    }
}

impl Message for SpeakRequest {
    const TYPE: &'static str = "speech.speak";
}

/// What happened to a [`SpeakRequest`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum SpeechEvent {
    /// Speaking has begun.
    Started {
        /// The text.
        text: String,
    },
    /// Speaking has ended.
    Finished {
        /// The text.
        text: String,
        /// How long it took, milliseconds.
        duration_ms: u64,
    },
    /// The text was not spoken (queue full, superseded, TTS failed).
    Dropped {
        /// The text.
        text: String,
        /// Why.
        reason: String,
    },
}

impl Message for SpeechEvent {
    const TYPE: &'static str = "speech.event";
}

/// What an overlay text is, which decides how viewers show it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum OverlayKind {
    /// The task the user gave (`set_user_task`).
    UserTask,
    /// Something the robot says (`speak`).
    RobotSpeech,
    /// A message from robotd itself (restarts, e-stop, …).
    SystemMessage,
}

impl OverlayKind {
    /// Wire name: `"user_task"`, `"robot_speech"`, `"system_message"`.
    pub const fn as_str(&self) -> &'static str {
        match self {
            Self::UserTask => "user_task",
            Self::RobotSpeech => "robot_speech",
            Self::SystemMessage => "system_message",
        }
    }
}

/// A text to show over the video.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct TextOverlay {
    /// The text.
    pub text: String,
    /// What it is.
    pub kind: OverlayKind,
    /// How long to show it, seconds.
    pub duration_s: f64,
    /// The tool that caused it, if any.
    pub tool_name: Option<String>,
}

impl TextOverlay {
    /// Default time an overlay stays visible, seconds.
    pub const DEFAULT_DURATION_S: f64 = 4.0;

    /// An overlay shown for the default duration, not tied to a tool.
    pub fn new(text: impl Into<String>, kind: OverlayKind) -> Self {
        Self {
            text: text.into(),
            kind,
            duration_s: Self::DEFAULT_DURATION_S,
            tool_name: None,
        }
    }
}

impl Validate for TextOverlay {
    fn validate(&self) -> Result<(), ValidationError> {
        non_empty("text", &self.text)?;
        in_range("duration_s", self.duration_s, 0.0, 3600.0)
    }
}

impl Message for TextOverlay {
    const TYPE: &'static str = "overlay.text";
}
