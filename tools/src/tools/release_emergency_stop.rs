//! `release_emergency_stop`: release the emergency stop; a deliberate act, never a side
//! effect: the call must say `confirm = "release"`.

use super::emergency_stop::{send, EStopState};
use super::{Reply, Tool};
use crate::args::{self, validation_text, FieldError};
use crate::{CallHooks, Registry};
use robotd_protocol::health::EmergencyStop;
use robotd_protocol::safety::printable;
use schemars::JsonSchema;
use serde::Deserialize;

pub(crate) struct ReleaseEmergencyStop;

/// The arguments of `release_emergency_stop`.
#[derive(Debug, Deserialize, JsonSchema)]
pub(crate) struct Args {
    /// Must be exactly `release`: confirms that the cause of the stop was dealt with.
    #[serde(deserialize_with = "args::text")]
    confirm: String,
    /// Who releases it and why (recorded).
    #[serde(default, deserialize_with = "args::opt_text")]
    #[schemars(length(max = 200))]
    note: Option<String>,
}

impl Tool for ReleaseEmergencyStop {
    const NAME: &'static str = "release_emergency_stop";
    const DESCRIPTION: &'static str =
        "Release the emergency stop so that the arm may move again. Only after the cause was \
         dealt with; confirm must be 'release'.";
    type Args = Args;
    type Data = EStopState;

    async fn run(registry: &Registry, a: Args, _: CallHooks) -> Result<Reply<EStopState>, String> {
        if a.confirm != "release" {
            return Err(validation_text(
                Self::NAME,
                &[FieldError {
                    field: "confirm".into(),
                    // pydantic's `literal_error`, as for a `Literal["release"]`.
                    message: "Input should be 'release'".into(),
                }],
            ));
        }
        let reason = match a.note {
            Some(note) => format!("released by an MCP client: {}", printable(&note, 200)),
            None => "released by an MCP client".to_owned(),
        };
        let estop = EmergencyStop {
            engaged: false,
            reason: reason.clone(),
            source: "mcp".into(),
        };
        send(registry, &estop).map_err(|e| format!("❌ Emergency stop release not sent: {e}"))?;
        tracing::warn!(%reason, "emergency stop released by an MCP client");
        Ok(Reply::new(
            "✓ Emergency stop released; motions are accepted again",
            EStopState {
                engaged: false,
                reason,
            },
        ))
    }
}
