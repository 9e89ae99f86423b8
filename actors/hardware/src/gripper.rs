//! The gripper actor: opens, closes and reports whether it really holds something.
//!
//! Every reply carries the gripper's real state afterwards (`holding` = the fingers stopped on
//! an object before closing fully), so a pick can report its real outcome. After every command
//! the state is also published on `gripper/state`.

use crate::driver::{DriverError, GripperDriver, GripperStatus};
use kameo::prelude::*;
use robotd_protocol::gripper::{GripperCommand, GripperError, GripperReply, GripperState};
use robotd_protocol::validate::Validate;
use robotd_runtime::bus::Publisher;
use std::convert::Infallible;
use std::sync::Arc;

/// The supervised gripper actor.
#[derive(Actor)]
pub struct GripperActor {
    driver: Arc<dyn GripperDriver>,
    state: Option<Arc<Publisher<GripperState>>>,
}

impl GripperActor {
    /// An actor driving `driver`, publishing its state on `state` when given.
    pub fn new(
        driver: Arc<dyn GripperDriver>,
        state: Option<Arc<Publisher<GripperState>>>,
    ) -> Self {
        Self { driver, state }
    }

    async fn run(&mut self, command: GripperCommand) -> Result<GripperStatus, GripperError> {
        command.validate()?;
        let status = match command {
            GripperCommand::Open => self.driver.open().await,
            GripperCommand::Close => self.driver.close().await,
            GripperCommand::SetWidth { width_m } => {
                let max_m = self.driver.max_width_m();
                if width_m > max_m {
                    return Err(GripperError::InvalidWidth { width_m, max_m });
                }
                self.driver.set_width(width_m).await
            }
            GripperCommand::GetState => self.driver.status(),
        }
        .map_err(gripper_error)?;
        if let Some(publisher) = &self.state {
            let state = GripperState {
                holding: status.holding,
                width_m: status.width_m,
                moving: false,
            };
            if let Err(error) = publisher.publish(&state) {
                tracing::warn!(%error, "publishing the gripper state");
            }
        }
        Ok(status)
    }
}

impl Message<GripperCommand> for GripperActor {
    type Reply = Result<GripperReply, Infallible>;

    async fn handle(
        &mut self,
        command: GripperCommand,
        _: &mut Context<Self, Self::Reply>,
    ) -> Self::Reply {
        Ok(match self.run(command).await {
            Ok(status) => GripperReply::State {
                holding: status.holding,
                width_m: status.width_m,
            },
            Err(error) => GripperReply::from(error),
        })
    }
}

/// The gripper error of a driver error.
pub fn gripper_error(error: DriverError) -> GripperError {
    match error {
        DriverError::OutOfRange(reason) => GripperError::InvalidCommand { reason },
        other => GripperError::Driver {
            message: other.to_string(),
        },
    }
}
