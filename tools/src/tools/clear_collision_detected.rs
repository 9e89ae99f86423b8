//! `clear_collision_detected`: clear the arm's collision-detected flag (a skill without arguments).

use super::{Done, NoArguments, Reply, Tool};
use crate::skill::run_skill;
use crate::{CallHooks, Registry};
use robotd_protocol::skills::Skill;

pub(crate) struct ClearCollisionDetected;

impl Tool for ClearCollisionDetected {
    const NAME: &'static str = "clear_collision_detected";
    const DESCRIPTION: &'static str =
        "Clear the arm's collision-detected flag so that it can move again.";
    const MOVES_ARM: bool = false;
    type Args = NoArguments;
    type Data = Done;

    async fn run(
        registry: &Registry,
        _: NoArguments,
        hooks: CallHooks,
    ) -> Result<Reply<Done>, String> {
        match run_skill(registry, Skill::ClearCollision, &hooks).await {
            Ok(_) => Ok(Reply::new("✓ Collision detection flag cleared", Done {})),
            Err(failure) => Err(format!(
                "❌ Error clearing collision flag: {}",
                failure.reason()
            )),
        }
    }
}
