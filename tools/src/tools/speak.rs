//! `speak`: say a text through the robot's speaker (queued; returns at once).
//!
//! A bad `text` alone gets the Python server's one-line
//! `❌ Validation Error: text must be a non-empty string`; a text over
//! [`MAX_SPEECH_CHARS`] is a validation error of the usual form
//! (`• text: String should have at most 2000 characters`).

use super::{only_field_invalid, Reply, Tool};
use crate::args::{self, validation_text, FieldError};
use crate::{CallHooks, Registry};
use robotd_protocol::speech::{SpeakRequest, MAX_SPEECH_CHARS};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

pub(crate) struct Speak;

/// The arguments of `speak`.
#[derive(Debug, Deserialize, JsonSchema)]
pub(crate) struct Args {
    /// What to say (at most 2000 characters).
    #[schemars(length(min = 1, max = 2000))]
    #[serde(deserialize_with = "args::text")]
    text: String,
}

/// The data of `speak`.
#[derive(Debug, Serialize, JsonSchema)]
pub(crate) struct Data {
    /// What is being said.
    text: String,
}

impl Tool for Speak {
    const NAME: &'static str = "speak";
    const DESCRIPTION: &'static str =
        "Say a text through the robot's speaker. Returns at once; speech is queued.";
    type Args = Args;
    type Data = Data;

    async fn run(registry: &Registry, a: Args, _: CallHooks) -> Result<Reply<Data>, String> {
        let text = a.text;
        let chars = text.chars().count();
        if chars > MAX_SPEECH_CHARS {
            return Err(validation_text(
                Self::NAME,
                &[FieldError {
                    field: "text".into(),
                    // pydantic's `string_too_long`.
                    message: format!("String should have at most {MAX_SPEECH_CHARS} characters"),
                }],
            ));
        }
        let publisher = registry
            .inner
            .speak
            .lock()
            .unwrap_or_else(|e| e.into_inner());
        match publisher.publish(&SpeakRequest::new(text.clone(), "mcp")) {
            Ok(0) => Err("❌ Error speaking: the text-to-speech actor is not running".into()),
            Ok(_) => Ok(Reply::new(format!("✓ Speaking: '{text}'"), Data { text })),
            Err(error) => Err(format!("❌ Error speaking: {error}")),
        }
    }

    fn invalid(errors: &[FieldError]) -> String {
        only_field_invalid(Self::NAME, "text", errors)
    }
}
