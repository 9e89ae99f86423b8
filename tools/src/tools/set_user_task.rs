//! `set_user_task`: show the user's current task over the camera video.

use super::{Reply, Tool};
use crate::args;
use crate::{CallHooks, Registry};
use robotd_protocol::speech::{OverlayKind, TextOverlay};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

pub(crate) struct SetUserTask;

/// The arguments of `set_user_task`.
#[derive(Debug, Deserialize, JsonSchema)]
pub(crate) struct Args {
    /// The user's task, shown over the video (at most 2000 characters).
    #[schemars(length(min = 1, max = 2000))]
    #[serde(deserialize_with = "args::text")]
    task: String,
}

/// The data of `set_user_task`.
#[derive(Debug, Serialize, JsonSchema)]
pub(crate) struct Data {
    /// The task shown.
    task: String,
}

impl Tool for SetUserTask {
    const NAME: &'static str = "set_user_task";
    const DESCRIPTION: &'static str = "Show the user's current task over the camera video.";
    type Args = Args;
    type Data = Data;

    async fn run(registry: &Registry, a: Args, _: CallHooks) -> Result<Reply<Data>, String> {
        let task = a.task;
        let mut overlay = TextOverlay::new(task.clone(), OverlayKind::UserTask);
        overlay.tool_name = Some(Self::NAME.into());
        let publisher = registry
            .inner
            .overlay
            .lock()
            .unwrap_or_else(|e| e.into_inner());
        match publisher.publish(&overlay) {
            Ok(_) => Ok(Reply::new(
                format!("✓ User task set: {task}"),
                Data { task },
            )),
            Err(error) => Err(format!("❌ Error setting the user task: {error}")),
        }
    }
}
