//! `move2observation_pose`: move the arm to where the camera sees a whole workspace.

use super::{Reply, Tool};
use crate::args;
use crate::skill::run_skill;
use crate::{CallHooks, Registry};
use robotd_protocol::skills::Skill;
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

pub(crate) struct Move2ObservationPose;

/// The arguments of `move2observation_pose`.
#[derive(Debug, Deserialize, JsonSchema)]
pub(crate) struct Args {
    /// Workspace id, e.g. "niryo_ws".
    #[schemars(length(min = 1, max = 100))]
    #[serde(deserialize_with = "args::text")]
    workspace_id: String,
}

/// The data of `move2observation_pose`.
#[derive(Debug, Serialize, JsonSchema)]
pub(crate) struct Data {
    /// The workspace the arm now observes.
    workspace_id: String,
}

impl Tool for Move2ObservationPose {
    const NAME: &'static str = "move2observation_pose";
    const DESCRIPTION: &'static str =
        "Move the arm to the observation pose of a workspace, from where the camera sees the \
         whole workspace.";
    const MOVES_ARM: bool = true;
    type Args = Args;
    type Data = Data;

    async fn run(registry: &Registry, a: Args, hooks: CallHooks) -> Result<Reply<Data>, String> {
        let ws = a.workspace_id;
        let skill = Skill::GoToObservationPose {
            workspace_id: ws.clone(),
        };
        match run_skill(registry, skill, &hooks).await {
            Ok(_) => Ok(Reply::new(
                format!("✓ Moved to observation pose for workspace '{ws}'"),
                Data { workspace_id: ws },
            )),
            Err(failure) => Err(format!(
                "❌ Error moving to observation pose: {}",
                failure.reason()
            )),
        }
    }
}
