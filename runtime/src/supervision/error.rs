//! The errors of supervision, one enum per operation.

use std::time::Duration;

use kameo::error::Infallible;

/// Why a request sent through a [`Supervised`](super::Supervised) handle got no reply.
///
/// Only [`Handler`](Self::Handler) comes from the actor itself; every other variant is the
/// supervisor telling you what happened to the request. No variant ever means "it was sent
/// again": supervision never retries a request.
#[derive(Debug, thiserror::Error)]
pub enum SupervisedError<E = Infallible> {
    /// The actor died while it was handling this very request (typically a panic in the
    /// handler). The request was not retried; it may have been partly carried out.
    #[error(
        "`{actor}` died while handling this request ({reason}); the request was not retried and \
         may have been partly carried out: check the hardware's state before sending it again"
    )]
    ActorFailed { actor: String, reason: String },
    /// The actor is down and being restarted (safe state, backoff). The request was not
    /// delivered, so it is safe to send again once [`wait_ready`](super::Supervised::wait_ready)
    /// returns.
    #[error(
        "`{actor}` is restarting after a failure and did not receive this request; send it again \
         after `wait_ready()` returns, or report the actor as busy"
    )]
    Restarting { actor: String },
    /// The supervisor gave up: the restart budget is exhausted and the actor stays down.
    /// The request was not delivered.
    #[error(
        "`{actor}` is down for good: its restart budget is exhausted, so this request was not \
         delivered; look at its logged failures, fix the cause and restart it (or robotd)"
    )]
    BudgetExhausted { actor: String },
    /// The actor was stopped (shutdown, or not restarted by its policy). The request was not
    /// delivered.
    #[error("`{actor}` is stopped ({reason}); this request was not delivered")]
    Stopped { actor: String, reason: String },
    /// No reply within the timeout given to `ask_timeout`. The request was not cancelled: the
    /// actor may still carry it out.
    #[error(
        "`{actor}` did not reply within {after:?}; the request was not cancelled and may still \
         be carried out"
    )]
    Timeout { actor: String, after: Duration },
    /// The actor's handler returned an error (its reply type is a `Result`).
    #[error("`{actor}` refused the request: {error}")]
    Handler { actor: String, error: E },
}

impl<E> SupervisedError<E> {
    /// The name of the supervised actor.
    pub fn actor(&self) -> &str {
        match self {
            SupervisedError::ActorFailed { actor, .. }
            | SupervisedError::Restarting { actor }
            | SupervisedError::BudgetExhausted { actor }
            | SupervisedError::Stopped { actor, .. }
            | SupervisedError::Timeout { actor, .. }
            | SupervisedError::Handler { actor, .. } => actor,
        }
    }

    /// True when the request certainly never reached the actor, so sending it again cannot
    /// execute it twice (it may still fail again).
    pub fn not_delivered(&self) -> bool {
        matches!(
            self,
            SupervisedError::Restarting { .. }
                | SupervisedError::BudgetExhausted { .. }
                | SupervisedError::Stopped { .. }
        )
    }

    /// Converts an error that carries no handler error into one for another handler error
    /// type. `Handler` errors are passed to `f`.
    pub fn map_handler<F>(self, f: impl FnOnce(E) -> F) -> SupervisedError<F> {
        match self {
            SupervisedError::ActorFailed { actor, reason } => {
                SupervisedError::ActorFailed { actor, reason }
            }
            SupervisedError::Restarting { actor } => SupervisedError::Restarting { actor },
            SupervisedError::BudgetExhausted { actor } => {
                SupervisedError::BudgetExhausted { actor }
            }
            SupervisedError::Stopped { actor, reason } => {
                SupervisedError::Stopped { actor, reason }
            }
            SupervisedError::Timeout { actor, after } => SupervisedError::Timeout { actor, after },
            SupervisedError::Handler { actor, error } => SupervisedError::Handler {
                actor,
                error: f(error),
            },
        }
    }
}

/// Why supervision could not begin: the first start failed.
///
/// A first start that fails is a configuration or wiring problem (wrong serial port, missing
/// binary), not a crash, so it is reported to the caller instead of being retried; nothing is
/// left running.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum SpawnError {
    /// The actor's args factory or `on_start` failed, or the process could not be spawned.
    #[error(
        "`{actor}` failed to start: {reason}; nothing was started: check its configuration, the \
         command path and that the hardware is connected"
    )]
    FirstStart { actor: String, reason: String },
}

/// How supervision ended when it did not end well: the escalation.
///
/// Returned by `wait_stopped()` on the handles, and, with
/// [`Supervisor::escalate_to`](super::Supervisor::escalate_to), delivered to the parent actor's
/// `on_link_died` as `ActorStopReason::Panicked(err)`, where `err.downcast::<SupervisionError>()`
/// gives it back.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum SupervisionError {
    /// The restart budget was used up and the supervisor gave up.
    #[error(
        "gave up on `{actor}`: {restarts} restarts within {window:?} used up its restart budget \
         (last failure: {last_reason}); fix the cause, or raise max_restarts / window in \
         [supervision]"
    )]
    BudgetExhausted {
        actor: String,
        restarts: u32,
        window: Duration,
        last_reason: String,
    },
    /// The child failed and its restart policy is `never`.
    #[error(
        "`{actor}` failed and its restart policy is `never` ({reason}); restart it by hand once \
         the cause is fixed"
    )]
    NotRestarted { actor: String, reason: String },
}

impl SupervisionError {
    /// The name of the supervised actor or process.
    pub fn actor(&self) -> &str {
        match self {
            SupervisionError::BudgetExhausted { actor, .. }
            | SupervisionError::NotRestarted { actor, .. } => actor,
        }
    }
}
