//! `calibrate`: calibrate the arm's joints (a skill without arguments).

use super::{Done, NoArguments, Reply, Tool};
use crate::skill::run_skill;
use crate::{CallHooks, Registry};
use robotd_protocol::skills::Skill;

pub(crate) struct Calibrate;

impl Tool for Calibrate {
    const NAME: &'static str = "calibrate";
    const DESCRIPTION: &'static str =
        "Calibrate the arm's joints (needed after power-up on a real Ned2).";
    const MOVES_ARM: bool = true;
    type Args = NoArguments;
    type Data = Done;

    async fn run(
        registry: &Registry,
        _: NoArguments,
        hooks: CallHooks,
    ) -> Result<Reply<Done>, String> {
        match run_skill(registry, Skill::Calibrate, &hooks).await {
            Ok(_) => Ok(Reply::new(
                "✓ Robot calibration completed successfully",
                Done {},
            )),
            Err(failure) => Err(format!("❌ Robot calibration failed: {}", failure.reason())),
        }
    }
}
