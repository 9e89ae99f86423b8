//! The gripper actor: opens, closes and reports whether it really holds something.
//!
//! Every reply carries the gripper's real state afterwards (`holding` = the fingers stopped on
//! an object before closing fully), so a pick can report its real outcome. After every command
//! the state is also published on `gripper/state`.

use kameo::prelude::*;
use robotd_driver::{DriverError, GripperDriver, GripperStatus};
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

/// Puts the gripper on the bus: the actor under `supervisor` (its safe state is to hold
/// still: a real gripper keeps its grip), `gripper/command` and `gripper/state`. Returns the
/// actor and its serving task.
pub async fn start(
    bus: &robotd_runtime::bus::Bus,
    supervisor: robotd_runtime::supervision::Supervisor,
    driver: Arc<dyn GripperDriver>,
) -> Result<
    (
        robotd_runtime::supervision::Supervised<GripperActor>,
        tokio::task::JoinHandle<()>,
    ),
    robotd_runtime::host::ActorStartError,
> {
    use robotd_runtime::catalog::{GRIPPER_COMMAND, GRIPPER_STATE};
    let state = Arc::new(bus.publisher(&GRIPPER_STATE)?);
    let actor = supervisor
        .spawn_actor::<GripperActor>(move || GripperActor::new(driver.clone(), Some(state.clone())))
        .await?;
    let server = bus.server(&GRIPPER_COMMAND)?;
    let serving = actor.clone();
    let task = tokio::spawn(async move {
        if let Err(error) = robotd_runtime::host::serve_supervised(server, serving).await {
            tracing::error!(%error, "gripper/command stopped serving");
        }
    });
    Ok((actor, task))
}
