//! `get_system_status`: the robot's id, workspace and tool pose, plus whatever the runtime
//! adds through [`ToolSettings::status`](crate::ToolSettings::status) (actor health,
//! restarts, e-stop).

use super::{pretty, NoArguments, Reply, Tool};
use crate::{CallHooks, Registry};
use robotd_protocol::arm::{ArmCommand, ArmReply};
use schemars::JsonSchema;
use serde::Serialize;
use serde_json::{Map, Value};
use std::time::Duration;

pub(crate) struct GetSystemStatus;

/// The data of `get_system_status`.
#[derive(Debug, Serialize, JsonSchema)]
pub(crate) struct Status {
    /// The robot's id.
    robot_id: String,
    /// The robot's current workspace.
    workspace_id: String,
    /// The tool pose, metres and radians (rounded to 3 decimals).
    pose: PoseJson,
    /// What the runtime adds: actor health, restart counts, emergency-stop state, ….
    #[serde(flatten)]
    extra: Map<String, Value>,
}

/// A pose, metres and radians.
#[derive(Debug, Serialize, JsonSchema)]
pub(crate) struct PoseJson {
    x: f64,
    y: f64,
    z: f64,
    roll: f64,
    pitch: f64,
    yaw: f64,
}

fn round3(v: f64) -> f64 {
    // + 0.0 turns -0.0 into 0.0.
    (v * 1000.0).round() / 1000.0 + 0.0
}

impl Tool for GetSystemStatus {
    const NAME: &'static str = "get_system_status";
    const DESCRIPTION: &'static str =
        "The robot's id, current workspace and tool pose, the health and restart counts of \
         robotd's actors and the emergency-stop state.";
    type Args = NoArguments;
    type Data = Status;

    async fn run(
        registry: &Registry,
        _: NoArguments,
        _: CallHooks,
    ) -> Result<Reply<Status>, String> {
        let settings = registry.settings();
        let pose = match registry
            .inner
            .arm
            .request(&ArmCommand::GetPose, Duration::from_secs(5))
            .await
        {
            Ok(ArmReply::Ok { pose }) => pose,
            Ok(ArmReply::Error { error }) => {
                return Err(format!("❌ Error getting system status: {error}"))
            }
            Ok(other) => {
                return Err(format!(
                    "❌ Error getting system status: unexpected arm reply {other:?}"
                ))
            }
            Err(error) => {
                return Err(format!(
                    "❌ Error getting system status: the arm did not answer: {error}"
                ))
            }
        };
        let mut extra = match (settings.status)() {
            Value::Object(extra) => extra,
            _ => Map::new(),
        };
        // The runtime's extras never replace the tool's own fields.
        for own in ["robot_id", "workspace_id", "pose"] {
            extra.remove(own);
        }
        let status = Status {
            robot_id: settings.robot_id.clone(),
            workspace_id: settings.workspaces[0].id.clone(),
            pose: PoseJson {
                x: round3(pose.x_m),
                y: round3(pose.y_m),
                z: round3(pose.z_m),
                roll: round3(pose.roll_rad),
                pitch: round3(pose.pitch_rad),
                yaw: round3(pose.yaw_rad),
            },
            extra,
        };
        Ok(Reply::new(pretty(&status), status))
    }
}

#[cfg(test)]
mod tests {
    use super::round3;

    #[test]
    fn poses_are_rounded_without_negative_zero() {
        assert_eq!(round3(0.12345), 0.123);
        assert_eq!(round3(-0.0001).to_string(), "0");
    }
}
