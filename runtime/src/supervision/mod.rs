//! Supervision: keeping hardware actors alive, and safe, when they fail.
//!
//! The arm, gripper and camera actors talk to real hardware, and sooner or later one of them
//! fails: a driver panics on an encoder value it did not expect, a serial link drops, a camera
//! process segfaults. A supervisor turns such a failure into a short, bounded and reported
//! recovery, instead of a dead service or, worse, an arm that keeps moving while nobody drives
//! it.
//!
//! # The ideas
//!
//! **Safe state first.** When an actor dies, whatever it was doing to the hardware is left
//! half done: the arm may still be travelling towards a target nobody watches any more. So
//! before anything else (before cleanup, before waiting, before restarting) the supervisor
//! runs a *safe-state hook*: stop the motion, hold position. The hook belongs to the spec
//! side, not to the actor, because the actor's state died with it (or is exactly what went
//! wrong); it has its own timeout, and its outcome is reported either way.
//!
//! **Backoff and a budget.** Restarting cures transient faults, often within milliseconds.
//! A fault that comes straight back (an unplugged cable, a wrong port in the config) would
//! instead become a crash loop that hammers the hardware and floods the logs. Backoff spaces
//! the restarts out (10 ms, 20 ms, 40 ms, … up to 5 s by default), and the budget says when
//! restarting is not helping: more than `max_restarts` restarts within `window` (5 in 60 s by
//! default) and the supervisor gives up, leaves the actor down, reports
//! [`SupervisionEvent::BudgetExhausted`] and escalates to whoever owns it.
//!
//! **No retries.** A request that was in flight when the actor died gets an error, never a
//! silent retry: for a robot, "move 10 cm" done twice is a different command, so only the
//! caller may decide to send it again. [`SupervisedError`] says what happened to the request:
//! [`ActorFailed`](SupervisedError::ActorFailed) (it died handling it; it may have been partly
//! carried out), [`Restarting`](SupervisedError::Restarting) (not delivered, the actor is
//! being restarted; fail fast rather than queue), [`BudgetExhausted`](SupervisedError::BudgetExhausted)
//! or [`Stopped`](SupervisedError::Stopped) (not delivered, and it will not come back by itself).
//!
//! **Same rules in and out of process.** A kameo actor inside robotd ([`Supervisor::spawn_actor`])
//! and a child process ([`Supervisor::spawn_process`]) are supervised by the same engine: the
//! same [`SupervisionPolicy`], hooks and events. A process additionally gets an
//! `on_restart_cleanup` hook (e.g. to remove a dead node's iceoryx2 resources) that runs after
//! the safe-state hook and before the restart, and it is killed when supervision ends.
//!
//! **Everything is reported.** Each step is a [`SupervisionEvent`] delivered to the
//! [`SupervisionObserver`]s (robotd bridges them to the bus), logged with `tracing`, and
//! counted in [`Metrics::global()`](crate::metrics::Metrics::global) (`actor_up`,
//! `actor_restart`, `budget_exhausted`). One crash and restart reads:
//! `Failed` → `SafeState` → `Cleanup` (if a cleanup hook is set) → `Restarted` → `Started`.
//!
//! **Proof of life.** With a [`watchdog`] installed (robotd does when systemd asks for one),
//! every supervision loop beats while it waits, and a ping goes out only when all of them
//! have: a hung loop silences the pings, so the service manager restarts the service.
//!
//! # Restarts in kameo terms
//!
//! kameo's own supervision restarts a child in place, immediately, with no hook in between;
//! robotd needs a safe state and a backoff *before* the restart. So the supervisor here starts
//! every incarnation as a fresh, unlinked kameo actor, watches its task, and publishes the
//! current `ActorRef` behind a stable [`Supervised`] handle. Escalation fits kameo's links:
//! with [`Supervisor::escalate_to`], the parent's `on_link_died` sees
//! `ActorStopReason::Panicked(err)` when the supervisor gives up, and
//! `err.downcast::<SupervisionError>()` says why (the default `on_link_died` then stops the
//! parent too, as in Erlang). Without a parent, [`Supervised::wait_stopped`] returns the same
//! [`SupervisionError`].
//!
//! # Panics
//!
//! A panic in an actor never takes robotd down: kameo catches panics in handlers and in
//! `on_start`, `on_stop` and `on_panic`; the actor's state is dropped by the supervisor under
//! `catch_unwind`, so a panicking `Drop` is a reported failure; hooks and observers run
//! isolated too. This relies on `panic = "unwind"` (Rust's default): a build with
//! `panic = "abort"` turns every panic into a process exit, and a panic *while already
//! unwinding* (a `Drop` that panics during a handler's panic) aborts the process whatever
//! anyone does.
//!
//! # Example
//!
//! ```
//! use std::time::Duration;
//! use kameo::prelude::*;
//! use robotd_runtime::supervision::{safe_state_fn, SupervisedError, SupervisionPolicy, Supervisor};
//!
//! #[derive(Actor)]
//! struct Arm {
//!     moves: u32,
//! }
//!
//! struct MoveTo(f64);
//!
//! impl Message<MoveTo> for Arm {
//!     type Reply = Result<u32, String>;
//!
//!     async fn handle(&mut self, MoveTo(x): MoveTo, _: &mut Context<Self, Self::Reply>) -> Self::Reply {
//!         if x > 1.0 {
//!             panic!("encoder fault"); // a bug in the driver
//!         }
//!         self.moves += 1;
//!         Ok(self.moves)
//!     }
//! }
//!
//! # #[tokio::main(flavor = "current_thread")]
//! # async fn main() -> Result<(), Box<dyn std::error::Error>> {
//! let (events, mut seen) = tokio::sync::mpsc::unbounded_channel();
//! let arm = Supervisor::new("arm")
//!     .policy(SupervisionPolicy::default())
//!     .safe_state(safe_state_fn(Duration::from_millis(500), |reason: String| async move {
//!         // stop the motors through a connection the actor does not own
//!         let _ = reason;
//!         Ok(())
//!     }))
//!     .observer(events)
//!     .spawn_actor::<Arm>(|| Arm { moves: 0 })
//!     .await?;
//!
//! assert_eq!(arm.ask(MoveTo(0.5)).await?, 1);
//!
//! // The handler panics: this request fails, and is not retried.
//! let failed = arm.ask(MoveTo(2.0)).await;
//! assert!(matches!(failed, Err(SupervisedError::ActorFailed { .. })));
//!
//! // The same handle reaches the fresh instance once it is back.
//! arm.wait_ready(Duration::from_secs(1)).await?;
//! assert_eq!(arm.ask(MoveTo(0.5)).await?, 1);
//!
//! let kinds: Vec<_> = std::iter::from_fn(|| seen.try_recv().ok()).map(|e| e.kind()).collect();
//! assert_eq!(kinds, ["started", "failed", "safe_state", "restarted", "started"]);
//! # Ok(()) }
//! ```

mod actor;
mod engine;
mod error;
mod event;
mod hooks;
mod latency;
mod policy;
mod process;
pub mod watchdog;

use std::fmt;
use std::future::Future;
use std::pin::Pin;
use std::sync::Arc;
use std::time::Duration;

use kameo::actor::ActorRef;
use kameo::Actor;
use tokio::process::Command;

pub use actor::Supervised;
pub use engine::SupervisedState;
pub use error::{SpawnError, SupervisedError, SupervisionError};
pub use event::{observer_fn, FnObserver, SupervisionEvent, SupervisionObserver};
pub use hooks::{
    safe_state_fn, CleanupContext, FnSafeState, SafeState, CLEANUP_TIMEOUT,
    DEFAULT_SAFE_STATE_TIMEOUT,
};
pub use latency::measure_restart_latency;
pub use policy::{RestartPolicy, SupervisionPolicy};
pub use process::SupervisedProcess;

use engine::{Config, Core, Escalator, Worker};
use hooks::{CleanupFn, ErasedSafeState};

/// How long a requested stop waits for an actor (or a child after SIGTERM) before killing it,
/// unless [`Supervisor::stop_timeout`] says otherwise.
pub const DEFAULT_STOP_TIMEOUT: Duration = Duration::from_secs(2);

type LinkParent =
    Box<dyn FnOnce(ActorRef<Escalator>) -> Pin<Box<dyn Future<Output = ()> + Send>> + Send>;

/// Sets up one supervisor: name, policy, hooks, observers; then spawns what it supervises.
///
/// ```
/// # use robotd_runtime::supervision::{Supervisor, SupervisionPolicy, RestartPolicy};
/// # #[tokio::main(flavor = "current_thread")]
/// # async fn main() -> Result<(), Box<dyn std::error::Error>> {
/// let camera = Supervisor::new("camera")
///     .policy(SupervisionPolicy { restart: RestartPolicy::Transient, ..Default::default() })
///     .on_restart_cleanup(|dead| {
///         // e.g. remove the dead node's iceoryx2 resources
///         let _ = dead.pid;
///         Ok(())
///     })
///     .spawn_process(|| {
///         let mut command = tokio::process::Command::new("sleep");
///         command.arg("30");
///         command
///     })
///     .await?;
/// assert!(camera.pid().is_some());
/// camera.stop().await?; // SIGTERM, then SIGKILL after the stop timeout
/// # Ok(()) }
/// ```
#[must_use = "a supervisor does nothing until `spawn_actor` or `spawn_process` is awaited"]
pub struct Supervisor {
    name: String,
    policy: SupervisionPolicy,
    observers: Vec<Arc<dyn SupervisionObserver>>,
    safe_state: Option<Arc<dyn ErasedSafeState>>,
    cleanup: Option<Arc<CleanupFn>>,
    link_parent: Option<LinkParent>,
    stop_timeout: Duration,
}

impl fmt::Debug for Supervisor {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Supervisor")
            .field("name", &self.name)
            .field("policy", &self.policy)
            .field("observers", &self.observers.len())
            .field("safe_state", &self.safe_state.is_some())
            .field("cleanup", &self.cleanup.is_some())
            .field("escalates", &self.link_parent.is_some())
            .field("stop_timeout", &self.stop_timeout)
            .finish()
    }
}

impl Supervisor {
    /// A supervisor named `name` (the name appears in events, metrics labels and errors),
    /// with the default policy, no hooks and no observers.
    pub fn new(name: impl Into<String>) -> Self {
        Supervisor {
            name: name.into(),
            policy: SupervisionPolicy::default(),
            observers: Vec::new(),
            safe_state: None,
            cleanup: None,
            link_parent: None,
            stop_timeout: DEFAULT_STOP_TIMEOUT,
        }
    }

    /// The restart policy, budget and backoff.
    pub fn policy(mut self, policy: SupervisionPolicy) -> Self {
        self.policy = policy;
        self
    }

    /// Adds an observer of this supervisor's events (may be called more than once).
    pub fn observer(mut self, observer: impl SupervisionObserver) -> Self {
        self.observers.push(Arc::new(observer));
        self
    }

    /// The hook that drives the hardware to a safe state after every stop the supervisor did
    /// not ask for, before anything else. Without one, a `SafeState` event still reports that
    /// none is configured.
    pub fn safe_state(mut self, hook: impl SafeState) -> Self {
        self.safe_state = Some(Arc::new(hook));
        self
    }

    /// A hook run after every death of an incarnation (and after a requested stop), after the
    /// safe-state hook and before any restart, on a blocking-pool thread, bounded by
    /// [`CLEANUP_TIMEOUT`]. For child processes this is where a dead node's iceoryx2
    /// resources are removed; the context carries the dead process's pid.
    pub fn on_restart_cleanup<F>(mut self, cleanup: F) -> Self
    where
        F: Fn(&CleanupContext) -> Result<(), String> + Send + Sync + 'static,
    {
        self.cleanup = Some(Arc::new(cleanup));
        self
    }

    /// Escalates to a parent actor through a kameo link: when supervision ends, the parent's
    /// `on_link_died` runs, with `ActorStopReason::Panicked(err)` if the supervisor gave up
    /// (`err.downcast::<SupervisionError>()` says why) and `Normal` otherwise.
    pub fn escalate_to<P: Actor>(mut self, parent: &ActorRef<P>) -> Self {
        let parent = parent.clone();
        self.link_parent = Some(Box::new(move |escalator: ActorRef<Escalator>| {
            Box::pin(async move { parent.link(&escalator).await })
        }));
        self
    }

    /// How long a requested stop waits before killing (default [`DEFAULT_STOP_TIMEOUT`]).
    pub fn stop_timeout(mut self, timeout: Duration) -> Self {
        self.stop_timeout = timeout;
        self
    }

    /// Starts the actor `A` (each incarnation gets fresh args from `args`) and supervises it.
    ///
    /// Returns once the first instance's `on_start` succeeded. If it fails, nothing keeps
    /// running and the error says why: a first start that fails is a configuration problem,
    /// not a crash to recover from.
    pub async fn spawn_actor<A: Actor>(
        self,
        args: impl Fn() -> A::Args + Send + Sync + 'static,
    ) -> Result<Supervised<A>, SpawnError> {
        let worker = actor::ActorWorker::<A>::new(Arc::new(args));
        let core = self.start(worker).await?;
        Ok(Supervised { core })
    }

    /// Starts the child process built by `command` (called again for every restart; the
    /// supervisor sets `kill_on_drop`) and supervises it. Status 0 is a normal exit, anything
    /// else (a non-zero status, a signal) a failure.
    ///
    /// Returns once the first child was spawned, or the spawn error.
    pub async fn spawn_process(
        self,
        command: impl Fn() -> Command + Send + Sync + 'static,
    ) -> Result<SupervisedProcess, SpawnError> {
        let worker = process::ProcessWorker::new(Arc::new(command));
        let core = self.start(worker).await?;
        Ok(SupervisedProcess { core })
    }

    async fn start<W: Worker>(self, mut worker: W) -> Result<Core<W::Handle>, SpawnError> {
        let first = worker
            .start()
            .await
            .map_err(|reason| SpawnError::FirstStart {
                actor: self.name.clone(),
                reason,
            })?;
        let escalation = match self.link_parent {
            Some(link_parent) => {
                let escalator = engine::spawn_escalator();
                link_parent(escalator.clone()).await;
                Some(escalator)
            }
            None => None,
        };
        let config = Config {
            name: self.name,
            policy: self.policy,
            observers: self.observers,
            safe_state: self.safe_state,
            cleanup: self.cleanup,
            escalation,
            stop_timeout: self.stop_timeout,
        };
        Ok(engine::launch(config, worker, first))
    }
}
