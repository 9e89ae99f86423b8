//! In-process actors: kameo actors restarted as fresh instances behind a stable handle.

use std::fmt;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::sync::Arc;
use std::time::Duration;

use kameo::actor::{ActorRef, Spawn};
use kameo::error::{ActorStopReason, HookError, PanicError, SendError};
use kameo::message::Message;
use kameo::{Actor, Reply};
use tokio::task::JoinHandle;

use super::engine::{panic_message, Core, Exit, SupervisedState, Worker};
use super::error::{SupervisedError, SupervisionError};

type ActorTask<A> = JoinHandle<Result<(A, ActorStopReason), PanicError>>;

/// Starts fresh instances of `A` from its args factory and watches their tasks.
pub(crate) struct ActorWorker<A: Actor> {
    pub(crate) args: Arc<dyn Fn() -> A::Args + Send + Sync>,
    pub(crate) current: Option<(ActorRef<A>, ActorTask<A>)>,
}

impl<A: Actor> ActorWorker<A> {
    pub(crate) fn new(args: Arc<dyn Fn() -> A::Args + Send + Sync>) -> Self {
        ActorWorker {
            args,
            current: None,
        }
    }
}

/// Turns what the actor's task returned into an [`Exit`]. The actor's state comes back here,
/// so its `Drop` runs here too: under `catch_unwind`, so a panicking `Drop` is a reported
/// failure instead of a dead supervisor.
fn classify<A: Actor>(
    joined: Result<Result<(A, ActorStopReason), PanicError>, tokio::task::JoinError>,
) -> Exit {
    match joined {
        Ok(Ok((actor, reason))) => {
            let exit = match reason {
                ActorStopReason::Normal => Exit::normal("stopped itself normally"),
                ActorStopReason::Panicked(err) => Exit::failed(err.to_string()),
                other => Exit::failed(other.to_string()),
            };
            match catch_unwind(AssertUnwindSafe(move || drop(actor))) {
                Ok(()) => exit,
                Err(panic) => Exit::failed(format!(
                    "{}, then its Drop panicked: {}",
                    exit.reason,
                    panic_message(panic.as_ref())
                )),
            }
        }
        Ok(Err(err)) => Exit::failed(err.to_string()),
        Err(join) if join.is_panic() => Exit::failed(format!(
            "the actor's task panicked: {}",
            panic_message(join.into_panic().as_ref())
        )),
        Err(_) => Exit::failed("the actor's task was cancelled (is the runtime shutting down?)"),
    }
}

impl<A: Actor> Worker for ActorWorker<A> {
    type Handle = ActorRef<A>;

    async fn start(&mut self) -> Result<ActorRef<A>, String> {
        let args = catch_unwind(AssertUnwindSafe(|| (self.args)())).map_err(|panic| {
            format!(
                "the args factory panicked: {}",
                panic_message(panic.as_ref())
            )
        })?;
        let prepared = A::prepare();
        let actor_ref = prepared.actor_ref().clone();
        let task = prepared.spawn(args);
        self.current = Some((actor_ref.clone(), task));
        let started = actor_ref
            .wait_for_startup_with_result(|res| match res {
                Ok(()) => Ok(()),
                Err(HookError::Error(err)) => Err(format!("on_start returned an error: {err:?}")),
                Err(HookError::Panicked(err)) => Err(format!("on_start failed: {err}")),
            })
            .await;
        match started {
            Ok(()) => Ok(actor_ref),
            Err(reason) => {
                // The task ends on its own after a failed start; reap it so nothing lingers.
                if let Some((_, task)) = self.current.take() {
                    let exit = classify(task.await);
                    if exit.reason != reason {
                        tracing::debug!(reason = %exit.reason, "actor task after failed start");
                    }
                }
                Err(reason)
            }
        }
    }

    async fn wait_exit(&mut self) -> Exit {
        let Some((_, task)) = self.current.as_mut() else {
            return Exit::failed("no incarnation was running");
        };
        let joined = task.await;
        self.current = None;
        classify(joined)
    }

    async fn stop(&mut self, grace: Duration) {
        let Some((actor_ref, mut task)) = self.current.take() else {
            return;
        };
        let graceful = tokio::time::timeout(grace, async {
            let _ = actor_ref.stop_gracefully().await;
            (&mut task).await
        })
        .await;
        let joined = match graceful {
            Ok(joined) => joined,
            Err(_) => {
                tracing::warn!(
                    actor = A::name(),
                    "did not stop within {grace:?}, killing it"
                );
                actor_ref.kill();
                task.await
            }
        };
        let exit = classify(joined);
        tracing::debug!(actor = A::name(), reason = %exit.reason, "stopped by its supervisor");
    }
}

/// The handle to a supervised in-process actor: the stable address of an actor whose
/// instances come and go.
///
/// Cheap to clone; all clones reach whichever instance is current, and after a restart the
/// same handle reaches the new one. Dropping the last clone shuts the supervisor down and
/// stops the actor.
///
/// Requests are never queued across a restart and never retried: while the actor is down,
/// [`ask`](Self::ask) fails at once with [`SupervisedError::Restarting`] (fail fast, so a
/// caller driving hardware decides itself whether to wait with [`wait_ready`](Self::wait_ready)
/// and send again). A request the actor was handling when it died gets
/// [`SupervisedError::ActorFailed`].
pub struct Supervised<A: Actor> {
    pub(crate) core: Core<ActorRef<A>>,
}

impl<A: Actor> Clone for Supervised<A> {
    fn clone(&self) -> Self {
        Supervised {
            core: self.core.clone(),
        }
    }
}

impl<A: Actor> fmt::Debug for Supervised<A> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Supervised")
            .field("actor", &self.name())
            .field("state", &self.state())
            .finish()
    }
}

type AskResult<A, M> = Result<
    <<A as Message<M>>::Reply as Reply>::Ok,
    SupervisedError<<<A as Message<M>>::Reply as Reply>::Error>,
>;

impl<A: Actor> Supervised<A> {
    /// The name given to the supervisor (used in events, metrics and errors).
    pub fn name(&self) -> &str {
        self.core.name()
    }

    /// What the actor is doing right now.
    pub fn state(&self) -> SupervisedState {
        self.core.state()
    }

    /// Sends `msg` to the current instance and waits for the reply.
    ///
    /// Errors: [`Restarting`](SupervisedError::Restarting), [`BudgetExhausted`](SupervisedError::BudgetExhausted)
    /// or [`Stopped`](SupervisedError::Stopped) when the request was not delivered;
    /// [`ActorFailed`](SupervisedError::ActorFailed) when the instance died while handling it;
    /// [`Handler`](SupervisedError::Handler) when the handler returned an error.
    pub async fn ask<M>(&self, msg: M) -> AskResult<A, M>
    where
        A: Message<M>,
        M: Send + 'static,
    {
        let (generation, actor_ref) = self.core.current()?;
        let reply = actor_ref.ask(msg).await;
        self.map_reply(generation, reply, None).await
    }

    /// Like [`ask`](Self::ask), but gives up waiting for the reply after `timeout` with
    /// [`SupervisedError::Timeout`]. The request is not cancelled: the actor may still
    /// carry it out.
    pub async fn ask_timeout<M>(&self, msg: M, timeout: Duration) -> AskResult<A, M>
    where
        A: Message<M>,
        M: Send + 'static,
    {
        let (generation, actor_ref) = self.core.current()?;
        let reply = actor_ref.ask(msg).reply_timeout(timeout).await;
        self.map_reply(generation, reply, Some(timeout)).await
    }

    /// Sends `msg` without waiting for it to be handled. An error means it was not delivered;
    /// `Ok` means it was queued, not that it was handled (if the instance dies first, the
    /// message is dropped with it, never handed to the next instance).
    pub async fn tell<M>(&self, msg: M) -> Result<(), SupervisedError>
    where
        A: Message<M>,
        M: Send + 'static,
    {
        let (generation, actor_ref) = self.core.current()?;
        match actor_ref.tell(msg).await {
            Ok(()) => Ok(()),
            Err(_) => Err(self.core.not_delivered(generation).await),
        }
    }

    async fn map_reply<M, T, E>(
        &self,
        generation: u64,
        reply: Result<T, SendError<M, E>>,
        timeout: Option<Duration>,
    ) -> Result<T, SupervisedError<E>> {
        match reply {
            Ok(value) => Ok(value),
            Err(SendError::HandlerError(error)) => Err(SupervisedError::Handler {
                actor: self.name().to_owned(),
                error,
            }),
            Err(SendError::Timeout(_)) => Err(SupervisedError::Timeout {
                actor: self.name().to_owned(),
                after: timeout.unwrap_or_default(),
            }),
            // The reply sender was dropped: the instance died with the request in hand.
            Err(SendError::ActorStopped) => Err(self.core.died_while_handling(generation).await),
            // The request never reached a live instance (or was bounced back unhandled).
            Err(
                SendError::ActorNotRunning(_)
                | SendError::ActorRestarting(_)
                | SendError::MailboxFull(_),
            ) => Err(self.core.not_delivered(generation).await),
        }
    }

    /// Waits up to `timeout` until the actor is running, and fails at once if the supervisor
    /// gave up or stopped. Use it to wait out a restart before sending a request again.
    pub async fn wait_ready(&self, timeout: Duration) -> Result<(), SupervisedError> {
        self.core.wait_ready(timeout).await.map(|_| ())
    }

    /// The current instance's `ActorRef`, for things that need the raw kameo address (links,
    /// `attach_stream`). It goes stale at the next restart; prefer the handle's methods.
    pub fn actor_ref(&self) -> Option<ActorRef<A>> {
        self.core
            .current::<()>()
            .ok()
            .map(|(_, actor_ref)| actor_ref)
    }

    /// Waits until supervision ends: `Ok` after a shutdown or a normal exit under a transient
    /// policy, `Err` when the supervisor gave up (the escalation).
    pub async fn wait_stopped(&self) -> Result<(), SupervisionError> {
        self.core.wait_stopped().await
    }

    /// Stops the actor (gracefully, then killed after the stop timeout) and ends supervision;
    /// the safe-state hook does not run for a requested stop. Returns how supervision ended.
    pub async fn shutdown(&self) -> Result<(), SupervisionError> {
        self.core.shutdown().await
    }
}
