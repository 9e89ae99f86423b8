//! Hosting: a supervised in-process actor serving a bus service.
//!
//! An actor inside robotd is a kameo actor run by a [`Supervisor`](crate::supervision::Supervisor);
//! other actors reach it only through the bus. [`serve_supervised`] is the glue: it takes each
//! request from a bus [`Server`], asks the actor, and turns what supervision reports into the
//! caller's answer — the reply, or a [`Fault`] that says whether the actor died handling the
//! request ([`FaultKind::ActorFailed`], never retried), is restarting or down for good
//! ([`FaultKind::Unavailable`]), or refused it ([`FaultKind::Refused`]). The same actor code can
//! run in its own process instead: there it serves the same service name, and callers cannot
//! tell the difference.
//!
//! ```text
//! let arm = Supervisor::new("arm").safe_state(stop_the_arm).spawn_actor::<Arm>(|| args).await?;
//! let server = bus.server(&ARM_COMMAND)?;
//! tokio::spawn(serve_supervised(server, arm));
//! ```

use crate::bus::{BusError, Fault, FaultKind, Server};
use crate::supervision::{Supervised, SupervisedError};
use kameo::reply::Reply;
use kameo::Actor;
use robotd_protocol::envelope::Message;
use std::fmt::Display;
use tracing::Instrument;

/// Serves `server`'s requests with `actor`, one at a time, until the bus fails.
///
/// Each request is handled in a span that continues the caller's trace.
pub async fn serve_supervised<A, Req, Resp>(
    mut server: Server<Req, Resp>,
    actor: Supervised<A>,
) -> Result<(), BusError>
where
    A: Actor + kameo::message::Message<Req>,
    <A as kameo::message::Message<Req>>::Reply: Reply<Ok = Resp>,
    <<A as kameo::message::Message<Req>>::Reply as Reply>::Error: Display,
    Req: Message + Send + 'static,
    Resp: Message,
{
    loop {
        let (envelope, pending) = server.next().await?.split();
        let span = tracing::info_span!("actor.handle", actor = actor.name());
        crate::telemetry::set_parent_from(&span, &envelope.trace);
        let outcome = actor
            .ask(envelope.body)
            .instrument(span.clone())
            .await
            .map_err(fault_from);
        let _in_span = span.enter();
        if let Err(error) = server.respond(pending, outcome) {
            tracing::warn!(actor = actor.name(), %error, "could not send a reply");
        }
    }
}

/// What a caller on the bus is told about a request supervision could not complete.
pub fn fault_from<E: Display>(error: SupervisedError<E>) -> Fault {
    let kind = match &error {
        SupervisedError::ActorFailed { .. } => FaultKind::ActorFailed,
        SupervisedError::Handler { .. } => FaultKind::Refused,
        SupervisedError::Restarting { .. }
        | SupervisedError::BudgetExhausted { .. }
        | SupervisedError::Stopped { .. }
        | SupervisedError::Timeout { .. } => FaultKind::Unavailable,
    };
    Fault::new(kind, error.to_string())
}

/// Why an in-process actor could not be put on the bus.
#[derive(Debug, thiserror::Error)]
pub enum ActorStartError {
    /// A bus port (service, topic) could not be created.
    #[error("bus: {0}")]
    Bus(#[from] crate::bus::BusError),
    /// The actor failed its first start (reported, not retried).
    #[error(transparent)]
    Spawn(#[from] crate::supervision::SpawnError),
}
