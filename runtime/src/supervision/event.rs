//! What a supervisor reports: one [`SupervisionEvent`] per step, delivered to observers.

use std::fmt;
use std::time::Duration;

/// One step in the life of a supervised actor or process.
///
/// A crash and restart produces, in this order:
/// `Failed` → `SafeState` → `Cleanup` (if a cleanup hook is set) → `Restarted` → `Started`.
/// A crash the budget does not cover ends with `BudgetExhausted` instead of `Restarted`;
/// a normal exit skips `Failed`; a stop for good (shutdown, policy) ends with `Stopped`.
#[derive(Clone, Debug, PartialEq)]
pub enum SupervisionEvent {
    /// An incarnation is up and answering. `attempt` 0 is the first start, then 1, 2, … for
    /// every restart since supervision began.
    Started { actor: String, attempt: u32 },
    /// The incarnation died abnormally: a panic (in a handler, `on_start`, `on_stop`, `Drop`),
    /// an error from a hook, a non-zero exit status or a signal.
    Failed { actor: String, reason: String },
    /// The safe-state hook ran (it runs after every stop that the supervisor did not ask for,
    /// before any restart). `ok` is false if it returned an error, panicked or timed out;
    /// `detail` says which.
    SafeState {
        actor: String,
        ok: bool,
        detail: String,
        took: Duration,
    },
    /// The restart-cleanup hook ran (e.g. removing a dead process's iceoryx2 resources).
    Cleanup {
        actor: String,
        ok: bool,
        detail: String,
        took: Duration,
    },
    /// A new incarnation was started after waiting `backoff`; `attempt` as in `Started`.
    Restarted {
        actor: String,
        attempt: u32,
        backoff: Duration,
    },
    /// The restart budget is used up: `restarts` restarts happened within `window`, and the
    /// supervisor gave up. The actor stays down; the failure is escalated.
    BudgetExhausted {
        actor: String,
        restarts: u32,
        window: Duration,
    },
    /// Supervision ended without exhausting the budget: shut down on request, a normal exit
    /// under a transient policy, or a failure under the `never` policy (`reason` says which).
    Stopped { actor: String, reason: String },
}

impl SupervisionEvent {
    /// The supervised actor's or process's name.
    pub fn actor(&self) -> &str {
        match self {
            SupervisionEvent::Started { actor, .. }
            | SupervisionEvent::Failed { actor, .. }
            | SupervisionEvent::SafeState { actor, .. }
            | SupervisionEvent::Cleanup { actor, .. }
            | SupervisionEvent::Restarted { actor, .. }
            | SupervisionEvent::BudgetExhausted { actor, .. }
            | SupervisionEvent::Stopped { actor, .. } => actor,
        }
    }

    /// A short, stable name for the kind of event (for bus topics, metric labels and logs).
    pub fn kind(&self) -> &'static str {
        match self {
            SupervisionEvent::Started { .. } => "started",
            SupervisionEvent::Failed { .. } => "failed",
            SupervisionEvent::SafeState { .. } => "safe_state",
            SupervisionEvent::Cleanup { .. } => "cleanup",
            SupervisionEvent::Restarted { .. } => "restarted",
            SupervisionEvent::BudgetExhausted { .. } => "budget_exhausted",
            SupervisionEvent::Stopped { .. } => "stopped",
        }
    }

    /// True for the event that reports that the supervisor gave up.
    pub fn budget_exhausted(&self) -> bool {
        matches!(self, SupervisionEvent::BudgetExhausted { .. })
    }
}

impl fmt::Display for SupervisionEvent {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SupervisionEvent::Started { actor, attempt } => {
                write!(f, "{actor}: started (attempt {attempt})")
            }
            SupervisionEvent::Failed { actor, reason } => write!(f, "{actor}: failed: {reason}"),
            SupervisionEvent::SafeState {
                actor,
                ok,
                detail,
                took,
            } => {
                let outcome = if *ok { "reached" } else { "NOT reached" };
                write!(f, "{actor}: safe state {outcome} in {took:?}: {detail}")
            }
            SupervisionEvent::Cleanup {
                actor,
                ok,
                detail,
                took,
            } => {
                let outcome = if *ok { "done" } else { "FAILED" };
                write!(f, "{actor}: restart cleanup {outcome} in {took:?}: {detail}")
            }
            SupervisionEvent::Restarted {
                actor,
                attempt,
                backoff,
            } => write!(f, "{actor}: restarted (attempt {attempt}) after {backoff:?}"),
            SupervisionEvent::BudgetExhausted {
                actor,
                restarts,
                window,
            } => write!(
                f,
                "{actor}: restart budget exhausted ({restarts} restarts within {window:?}), giving up"
            ),
            SupervisionEvent::Stopped { actor, reason } => write!(f, "{actor}: stopped: {reason}"),
        }
    }
}

/// Receives every [`SupervisionEvent`] of the supervisors it is given to.
///
/// Called synchronously from the supervisor's task, in event order: keep it short and never
/// block (forward into a channel, bump a counter). A panicking observer is caught and logged;
/// it does not disturb supervision.
///
/// Implemented for `tokio::sync::mpsc::UnboundedSender<SupervisionEvent>` (forwards a clone),
/// `Arc<T>` of an observer, and closures wrapped with [`observer_fn`].
pub trait SupervisionObserver: Send + Sync + 'static {
    /// Called once per event.
    fn on_event(&self, event: &SupervisionEvent);
}

impl SupervisionObserver for tokio::sync::mpsc::UnboundedSender<SupervisionEvent> {
    fn on_event(&self, event: &SupervisionEvent) {
        // A closed receiver means nobody listens any more; that is not a supervision problem.
        let _ = self.send(event.clone());
    }
}

impl<T: SupervisionObserver + ?Sized> SupervisionObserver for std::sync::Arc<T> {
    fn on_event(&self, event: &SupervisionEvent) {
        (**self).on_event(event);
    }
}

/// An observer made from a closure; see [`observer_fn`].
pub struct FnObserver<F>(F);

impl<F> fmt::Debug for FnObserver<F> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("FnObserver")
    }
}

impl<F> SupervisionObserver for FnObserver<F>
where
    F: Fn(&SupervisionEvent) + Send + Sync + 'static,
{
    fn on_event(&self, event: &SupervisionEvent) {
        (self.0)(event);
    }
}

/// Wraps a closure as a [`SupervisionObserver`].
///
/// ```
/// use robotd_runtime::supervision::{observer_fn, SupervisionEvent};
///
/// let log = observer_fn(|event: &SupervisionEvent| eprintln!("{event}"));
/// # let _ = log;
/// ```
pub fn observer_fn<F>(f: F) -> FnObserver<F>
where
    F: Fn(&SupervisionEvent) + Send + Sync + 'static,
{
    FnObserver(f)
}
