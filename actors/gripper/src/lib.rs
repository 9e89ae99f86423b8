//! The gripper actor: opens, closes and reports whether it really holds something.
//!
//! Every reply carries the gripper's real state afterwards (`holding` = the fingers stopped on
//! an object before closing fully), so a pick can report its real outcome. After every command
//! the state is also published on `gripper/state`.
//!
//! Commands that move the fingers pass the safety policy first ([`robotd_safety::Safety`]):
//! refused while the emergency stop is engaged, beyond the origin's rate limit or without a
//! required approval, and recorded in the audit log with their outcome. The actor itself only
//! takes [`Admitted`] commands (which carry the policy's admission) and [`ReadState`]; right
//! before the driver call it asks the policy for the [`robotd_safety::Permit`] the driver
//! needs, which checks the e-stop once more: an e-stop engaged while a command waited for
//! the actor stops it.

use kameo::prelude::*;
use robotd_driver::{Close, DriverError, GripperDriver, GripperStatus, Open, SetWidth};
use robotd_protocol::gripper::{GripperCommand, GripperError, GripperReply, GripperState};
use robotd_protocol::validate::Validate;
use robotd_runtime::bus::{BusError, Publisher, Server};
use robotd_runtime::host::fault_from;
use robotd_runtime::supervision::Supervised;
use robotd_safety::{Admission, Outcome, Safety, Violation};
use std::convert::Infallible;
use std::sync::Arc;
use tracing::Instrument;

/// The supervised gripper actor.
#[derive(Actor)]
pub struct GripperActor {
    driver: Arc<dyn GripperDriver>,
    safety: Safety,
    state: Option<Arc<Publisher<GripperState>>>,
}

impl GripperActor {
    /// An actor driving `driver` with the permits of `safety`, publishing its state on
    /// `state` when given.
    pub fn new(
        driver: Arc<dyn GripperDriver>,
        safety: Safety,
        state: Option<Arc<Publisher<GripperState>>>,
    ) -> Self {
        Self {
            driver,
            safety,
            state,
        }
    }

    async fn run(
        &mut self,
        command: GripperCommand,
        admission: Option<&Admission>,
    ) -> Result<GripperStatus, GripperError> {
        command.validate()?;
        let safety = &self.safety;
        let refused = |violation| refusal(safety, violation);
        let status = match (command, admission) {
            (GripperCommand::GetState, _) => self.driver.status(),
            (_, None) => {
                return Err(GripperError::InvalidCommand {
                    reason: "a gripper motion needs the safety policy's admission".into(),
                })
            }
            (GripperCommand::Open, Some(admission)) => {
                let permit = safety.permit_gripper(admission, Open).map_err(refused)?;
                self.driver.open(permit).await
            }
            (GripperCommand::Close, Some(admission)) => {
                let permit = safety.permit_gripper(admission, Close).map_err(refused)?;
                self.driver.close(permit).await
            }
            (GripperCommand::SetWidth { width_m }, Some(admission)) => {
                let max_m = self.driver.max_width_m();
                if width_m > max_m {
                    return Err(GripperError::InvalidWidth { width_m, max_m });
                }
                let permit = safety
                    .permit_gripper(admission, SetWidth { width_m })
                    .map_err(refused)?;
                self.driver.set_width(permit).await
            }
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

/// A gripper command the safety policy admitted: the only message that moves the fingers.
#[derive(Debug, Clone)]
pub struct Admitted {
    /// The command.
    pub command: GripperCommand,
    /// The policy's admission (only [`Safety::admit`] makes one).
    pub admission: Admission,
}

/// Reads the gripper's state (moves nothing).
#[derive(Debug, Clone, Copy)]
pub struct ReadState;

fn reply(result: Result<GripperStatus, GripperError>) -> GripperReply {
    match result {
        Ok(status) => GripperReply::State {
            holding: status.holding,
            width_m: status.width_m,
        },
        Err(error) => GripperReply::from(error),
    }
}

impl Message<Admitted> for GripperActor {
    type Reply = Result<GripperReply, Infallible>;

    async fn handle(&mut self, work: Admitted, _: &mut Context<Self, Self::Reply>) -> Self::Reply {
        Ok(reply(self.run(work.command, Some(&work.admission)).await))
    }
}

impl Message<ReadState> for GripperActor {
    type Reply = Result<GripperReply, Infallible>;

    async fn handle(&mut self, _: ReadState, _: &mut Context<Self, Self::Reply>) -> Self::Reply {
        Ok(reply(self.run(GripperCommand::GetState, None).await))
    }
}

/// The gripper error of a policy refusal: the e-stop keeps its own error kind.
fn refusal(safety: &Safety, violation: Violation) -> GripperError {
    match safety.estop() {
        Some(reason) if violation.limit == "estop" => GripperError::EStopped { reason },
        _ => GripperError::Refused {
            limit: violation.limit.to_owned(),
            reason: violation.reason,
        },
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
                return actor.ask(ReadState).await.map_err(fault_from);
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
                Err(violation) => return Ok(GripperReply::from(refusal(&safety, violation))),
            };
            let reply = actor
                .ask(Admitted {
                    command,
                    admission: admission.clone(),
                })
                .await
                .map_err(fault_from);
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
    use robotd_topics::{GRIPPER_COMMAND, GRIPPER_STATE};
    let state = Arc::new(bus.publisher(&GRIPPER_STATE)?);
    let policy = safety.clone();
    let actor = supervisor
        .spawn_actor::<GripperActor>(move || {
            GripperActor::new(driver.clone(), policy.clone(), Some(state.clone()))
        })
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
