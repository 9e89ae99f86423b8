//! `emergency_stop`: halt the arm now and refuse every motion until a deliberate release.
//!
//! The stop goes out on `safety/estop` like every other entry point (HTTP `POST /estop`,
//! `robotd estop`, the bus); the arm halts within one control tick and the e-stop stays
//! engaged, across actor restarts, until `release_emergency_stop` (or `POST /estop/release`,
//! `robotd estop --release`) releases it. A new motion command never releases it.

use super::{Reply, Tool};
use crate::args;
use crate::{CallHooks, Registry};
use robotd_protocol::health::EmergencyStop;
use robotd_protocol::safety::printable;
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

pub(crate) struct EmergencyStopTool;

/// The arguments of `emergency_stop`.
#[derive(Debug, Deserialize, JsonSchema)]
pub(crate) struct Args {
    /// Why (shown in every refusal until release; at most 500 characters).
    #[serde(default, deserialize_with = "args::opt_text")]
    #[schemars(length(max = 500))]
    reason: Option<String>,
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

    async fn run(registry: &Registry, a: Args, _: CallHooks) -> Result<Reply<EStopState>, String> {
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
        tracing::warn!(%reason, "emergency stop engaged by an MCP client");
        Ok(Reply::new(
            format!(
                "✓ Emergency stop engaged: {reason}. Every motion is refused until it is released \
                 (release_emergency_stop with confirm='release')."
            ),
            EStopState {
                engaged: true,
                reason,
            },
        ))
    }
}
