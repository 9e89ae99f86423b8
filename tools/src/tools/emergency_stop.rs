//! `emergency_stop`: halt the arm now and refuse every motion until a deliberate release.
//!
//! The stop goes out on `safety/estop` like every other entry point (HTTP `POST /estop`,
//! `robotd estop`, the bus); the arm halts within one control tick and the e-stop stays
//! engaged, across actor restarts, until `release_emergency_stop` (or `POST /estop/release`,
//! `robotd estop --release`) releases it. A new motion command never releases it.
//!
//! Engaging never fails on the request: whatever the arguments (a `reason` that is not a
//! string, an unknown argument, no arguments, arguments that are not an object), the stop is
//! sent, and the reply says what was wrong with the request and that it was ignored.

use super::{Reply, Tool};
use crate::args::{self, from_args, FieldError};
use crate::{CallHooks, Registry, ARGUMENTS_NOT_AN_OBJECT};
use robotd_protocol::health::EmergencyStop;
use robotd_protocol::safety::printable;
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};
use serde_json::{Map, Value};

pub(crate) struct EmergencyStopTool;

/// The arguments of `emergency_stop`.
#[derive(Debug, Deserialize, JsonSchema)]
pub(crate) struct Args {
    /// Why (shown in every refusal until release; at most 500 characters).
    #[serde(default, deserialize_with = "args::opt_text")]
    #[schemars(length(max = 500))]
    reason: Option<String>,
    /// What was wrong with the request (ignored), for the reply.
    #[serde(skip)]
    #[schemars(skip)]
    problems: Vec<String>,
}

/// At most this many characters of a bad value are quoted back.
const QUOTE_MAX: usize = 60;

/// `value` as JSON, cut to [`QUOTE_MAX`] characters.
fn quote(value: &Value) -> String {
    let text = value.to_string();
    if text.chars().count() <= QUOTE_MAX {
        printable(&text, QUOTE_MAX)
    } else {
        format!("{}…", printable(&text, QUOTE_MAX))
    }
}

/// Reads what can be used of `arguments` and words the rest: a request to stop is never
/// refused for its form.
fn read_leniently(arguments: &Map<String, Value>) -> Args {
    if let Some(value) = arguments.get(ARGUMENTS_NOT_AN_OBJECT) {
        return Args {
            reason: None,
            problems: vec![format!(
                "the arguments must be an object such as {{\"reason\": \"…\"}}, got {}",
                quote(value)
            )],
        };
    }
    match from_args::<Args>(arguments) {
        Ok(args) => args,
        Err(errors) => {
            let reason = arguments
                .get("reason")
                .and_then(Value::as_str)
                .map(str::trim)
                .filter(|r| !r.is_empty())
                .map(str::to_owned);
            let problems = errors
                .iter()
                .map(|FieldError { field, message }| match arguments.get(field) {
                    Some(value) if field == "reason" => {
                        format!("argument 'reason': {message} (got {})", quote(value))
                    }
                    _ => format!("argument '{}': {message}", printable(field, QUOTE_MAX)),
                })
                .collect();
            Args { reason, problems }
        }
    }
}

/// The data of `emergency_stop` and `release_emergency_stop`.
#[derive(Debug, Serialize, JsonSchema)]
pub(crate) struct EStopState {
    /// Whether the emergency stop is engaged now.
    pub(crate) engaged: bool,
    /// The reason given.
    pub(crate) reason: String,
}

/// Sends `estop` on the bus; the error text when no arm took it.
pub(crate) fn send(registry: &Registry, estop: &EmergencyStop) -> Result<(), String> {
    let publisher = registry
        .inner
        .estop
        .lock()
        .unwrap_or_else(|e| e.into_inner());
    match publisher.publish(estop) {
        Ok(0) => Err("no arm is listening on safety/estop (is the arm actor running?)".into()),
        Ok(_) => Ok(()),
        Err(error) => Err(error.to_string()),
    }
}

impl Tool for EmergencyStopTool {
    const NAME: &'static str = "emergency_stop";
    const DESCRIPTION: &'static str =
        "Emergency stop: halt the arm at once and refuse every motion until a person releases \
         it (release_emergency_stop with confirm='release'). Use it whenever something looks \
         unsafe.";
    type Args = Args;
    type Data = EStopState;

    fn read(arguments: &Map<String, Value>) -> Result<Args, Vec<FieldError>> {
        Ok(read_leniently(arguments))
    }

    async fn run(registry: &Registry, a: Args, _: CallHooks) -> Result<Reply<EStopState>, String> {
        let note = match a.problems.as_slice() {
            [] => String::new(),
            problems => format!(
                " Note: the request was not well formed, and this was ignored: {}.",
                problems.join("; ")
            ),
        };
        let reason = match a.reason {
            Some(reason) => printable(&reason, 500),
            None => "engaged by an MCP client".to_owned(),
        };
        let estop = EmergencyStop {
            engaged: true,
            reason: reason.clone(),
            source: "mcp".into(),
        };
        send(registry, &estop).map_err(|e| format!("❌ Emergency stop not sent: {e}"))?;
        tracing::warn!(%reason, problems = ?a.problems, "emergency stop engaged by an MCP client");
        Ok(Reply::new(
            format!(
                "✓ Emergency stop engaged: {reason}. Every motion is refused until it is released \
                 (release_emergency_stop with confirm='release').{note}"
            ),
            EStopState {
                engaged: true,
                reason,
            },
        ))
    }
}
