//! `release_emergency_stop`: release the emergency stop; a deliberate act, never a side
//! effect: the call must say `confirm = "release"` (its schema says `const: "release"`).
//!
//! The release is a request to the safety policy's own service `safety/release` (not a
//! message on `safety/estop`, where `engaged: false` releases nothing): the policy checks the
//! confirmation, records the release with the call's origin (MCP session and request) and
//! answers with the new state.

use super::emergency_stop::EStopState;
use super::{Reply, Tool};
use crate::args::{self, validation_text, FieldError};
use crate::{CallHooks, Registry};
use robotd_protocol::health::EStopRelease;
use robotd_protocol::safety::printable;
use schemars::JsonSchema;
use serde::Deserialize;
use std::time::Duration;

/// How long the policy may take to answer a release.
const RELEASE_TIMEOUT: Duration = Duration::from_secs(5);

pub(crate) struct ReleaseEmergencyStop;

/// The arguments of `release_emergency_stop`.
#[derive(Debug, Deserialize, JsonSchema)]
pub(crate) struct Args {
    /// Must be exactly `release`: confirms that the cause of the stop was dealt with.
    #[serde(deserialize_with = "args::text")]
    #[schemars(extend("const" = "release"), length(max = 32))]
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
        let by = match a.note {
            Some(note) => format!("an MCP client: {}", printable(&note, 200)),
            None => "an MCP client".to_owned(),
        };
        let request = EStopRelease {
            confirm: a.confirm,
            by,
            only_if_reason: None,
        };
        let state = registry
            .inner
            .release
            .request(&request, RELEASE_TIMEOUT)
            .await
            .map_err(|e| format!("❌ Emergency stop not released: {e}"))?;
        tracing::warn!(reason = %state.reason, "emergency stop released by an MCP client");
        Ok(Reply::new(
            "✓ Emergency stop released; motions are accepted again",
            EStopState {
                engaged: state.engaged,
                reason: state.reason,
            },
        ))
    }
}
