//! The gripper actor: opens, closes and reports whether it really holds something.
//!
//! Every reply carries the gripper's real state afterwards (`holding` = the fingers stopped on
//! an object before closing fully), so a pick can report its real outcome. After every command
//! the state is also published on `gripper/state`.
//!
//! Commands that move the fingers pass the safety policy first ([`robotd_safety::Safety`]):
//! refused while the emergency stop is engaged, beyond the client's rate limit or without a
//! required approval, and recorded in the audit log with their outcome.

use kameo::prelude::*;
use robotd_driver::{DriverError, GripperDriver, GripperStatus};
use robotd_protocol::gripper::{GripperCommand, GripperError, GripperReply, GripperState};
use robotd_protocol::validate::Validate;
use robotd_runtime::bus::{BusError, Publisher, Server};
use robotd_runtime::host::fault_from;
use robotd_runtime::supervision::Supervised;
use robotd_safety::{Outcome, Safety};
use std::convert::Infallible;
use std::sync::Arc;
use tracing::Instrument;

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

/// Serves `gripper/command` until the bus fails: `GetState` at once through the actor, finger
/// motions only once the safety policy admitted them.
pub async fn serve_gripper(
    mut server: Server<GripperCommand, GripperReply>,
    actor: Supervised<GripperActor>,
    safety: Safety,
) -> Result<(), BusError> {
    loop {
        let incoming = server.next().await?;
        let origin = incoming.origin.clone();
        let (envelope, pending) = incoming.split();
        let span = tracing::info_span!("actor.handle", actor = actor.name());
        robotd_runtime::telemetry::set_parent_from(&span, &envelope.trace);
        let command = envelope.body;
        let reply = async {
            if matches!(command, GripperCommand::GetState) {
                return actor.ask(command).await.map_err(fault_from);
            }
            let action = match command {
                GripperCommand::Open => "open",
                GripperCommand::Close => "close",
                GripperCommand::SetWidth { .. } => "set_width",
                GripperCommand::GetState => "get_state",
            };
            let arguments = serde_json::to_value(&command).unwrap_or_default();
            let admission = match safety.admit(&origin, "gripper", action, arguments).await {
                Ok(admission) => admission,
                Err(violation) => {
                    let error = match safety.estop() {
                        Some(reason) if violation.limit == "estop" => {
                            GripperError::EStopped { reason }
                        }
                        _ => GripperError::Refused {
                            limit: violation.limit.to_owned(),
                            reason: violation.reason,
                        },
                    };
                    return Ok(GripperReply::from(error));
                }
            };
            let reply = actor.ask(command).await.map_err(fault_from);
            let failure = match &reply {
                Ok(GripperReply::Error { error }) => Some(error.to_string()),
                Ok(_) => None,
                Err(fault) => Some(fault.to_string()),
            };
            let outcome = match &failure {
                Some(reason) => Outcome::Failed { reason },
                None => Outcome::Done,
            };
            safety.finish(&admission, outcome);
            reply
        }
        .instrument(span.clone())
        .await;
        let _in_span = span.enter();
        if let Err(error) = server.respond(pending, reply) {
            tracing::warn!(%error, "could not send a gripper reply");
        }
    }
}

/// Puts the gripper on the bus: the actor under `supervisor` (its safe state is to hold
/// still: a real gripper keeps its grip), `gripper/command` behind the safety policy, and
/// `gripper/state`. Returns the actor and its serving task.
pub async fn start(
    bus: &robotd_runtime::bus::Bus,
    supervisor: robotd_runtime::supervision::Supervisor,
    driver: Arc<dyn GripperDriver>,
    safety: Safety,
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
        if let Err(error) = serve_gripper(server, serving, safety).await {
            tracing::error!(%error, "gripper/command stopped serving");
        }
    });
    Ok((actor, task))
}
