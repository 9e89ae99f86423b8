//! The restart loop shared by in-process actors and child processes.
//!
//! A [`Worker`] knows how to start one incarnation, wait for it to end and stop it; the engine
//! owns everything else: status, events, metrics, safe state, cleanup, budget, backoff and
//! escalation. That keeps the rules identical for both kinds of children.

use std::any::Any;
use std::future::Future;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::sync::Arc;
use std::time::Duration;

use kameo::actor::{ActorRef, Spawn};
use kameo::error::Infallible;
use kameo::message::{Context, Message};
use kameo::Actor;
use tokio::sync::watch;
use tokio::time::Instant;

use super::error::{SupervisedError, SupervisionError};
use super::event::{SupervisionEvent, SupervisionObserver};
use super::hooks::{CleanupContext, CleanupFn, ErasedSafeState, CLEANUP_TIMEOUT};
use super::policy::{RestartBudget, SupervisionPolicy};
use super::watchdog;

/// One kind of child: an actor type or a command line.
pub(crate) trait Worker: Send + 'static {
    /// What callers use to reach a running incarnation (an `ActorRef`, a pid).
    type Handle: Clone + Send + Sync + 'static;

    /// Starts a new incarnation and returns once it is up (or failed to come up).
    fn start(&mut self) -> impl Future<Output = Result<Self::Handle, String>> + Send;

    /// Waits until the running incarnation ends. Must be cancel-safe.
    fn wait_exit(&mut self) -> impl Future<Output = Exit> + Send;

    /// Stops the running incarnation, if any: gracefully, then forcibly after `grace`.
    fn stop(&mut self, grace: Duration) -> impl Future<Output = ()> + Send;

    /// The process id of the incarnation that ended last, for the cleanup hook.
    fn last_pid(&self) -> Option<u32> {
        None
    }
}

/// How an incarnation ended.
#[derive(Clone, Debug)]
pub(crate) struct Exit {
    pub(crate) failed: bool,
    pub(crate) reason: String,
}

impl Exit {
    pub(crate) fn failed(reason: impl Into<String>) -> Self {
        Exit {
            failed: true,
            reason: reason.into(),
        }
    }

    pub(crate) fn normal(reason: impl Into<String>) -> Self {
        Exit {
            failed: false,
            reason: reason.into(),
        }
    }
}

/// What a supervised actor or process is doing right now.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum SupervisedState {
    /// Up and answering; `attempt` counts restarts since supervision began (0 = first start).
    Running { attempt: u32 },
    /// Down after `reason`; the supervisor is running the safe-state hook, cleaning up,
    /// backing off or starting the next incarnation.
    Restarting { reason: String },
    /// The restart budget is exhausted; the supervisor gave up and it stays down.
    BudgetExhausted,
    /// Shutting down on request.
    Stopping,
    /// Supervision ended; `reason` says how.
    Stopped { reason: String },
}

#[derive(Clone, Debug)]
pub(crate) enum Phase<H> {
    Running(H),
    Restarting,
    Exhausted,
    Stopping,
    Stopped(String),
}

#[derive(Clone, Debug)]
pub(crate) struct Death {
    pub(crate) generation: u64,
    pub(crate) failed: bool,
    pub(crate) reason: String,
}

/// The status every handle reads, published by the engine through a `watch` channel.
#[derive(Clone, Debug)]
pub(crate) struct Status<H> {
    /// Which incarnation `Phase::Running` refers to (0 = first start).
    pub(crate) generation: u64,
    pub(crate) phase: Phase<H>,
    pub(crate) last_death: Option<Death>,
    /// Set once supervision has ended.
    pub(crate) outcome: Option<Result<(), SupervisionError>>,
}

/// Everything about one supervisor that does not change while it runs.
pub(crate) struct Config {
    pub(crate) name: String,
    pub(crate) policy: SupervisionPolicy,
    pub(crate) observers: Vec<Arc<dyn SupervisionObserver>>,
    pub(crate) safe_state: Option<Arc<dyn ErasedSafeState>>,
    pub(crate) cleanup: Option<Arc<CleanupFn>>,
    pub(crate) escalation: Option<ActorRef<Escalator>>,
    pub(crate) stop_timeout: Duration,
}

impl Config {
    pub(crate) fn emit(&self, event: SupervisionEvent) {
        log_event(&event);
        for observer in &self.observers {
            if let Err(panic) = catch_unwind(AssertUnwindSafe(|| observer.on_event(&event))) {
                tracing::error!(
                    actor = %self.name,
                    panic = %panic_message(panic.as_ref()),
                    "a supervision observer panicked; the event was not fully delivered"
                );
            }
        }
    }

    async fn run_safe_state(&self, reason: &str) {
        let started = Instant::now();
        let (ok, detail) = match &self.safe_state {
            None => (true, "no safe-state hook configured".to_owned()),
            Some(hook) => {
                let limit = hook.timeout();
                // Its own task: a panicking hook is caught, a hanging one can be abandoned.
                let mut task = tokio::spawn(Arc::clone(hook).run(reason.to_owned()));
                match tokio::time::timeout(limit, &mut task).await {
                    Ok(Ok(Ok(()))) => (true, "safe state reached".to_owned()),
                    Ok(Ok(Err(err))) => (false, format!("the safe-state hook failed: {err}")),
                    Ok(Err(join)) if join.is_panic() => (
                        false,
                        format!(
                            "the safe-state hook panicked: {}",
                            panic_message(join.into_panic().as_ref())
                        ),
                    ),
                    Ok(Err(_)) => (false, "the safe-state hook was cancelled".to_owned()),
                    Err(_) => {
                        task.abort();
                        (
                            false,
                            format!("the safe-state hook did not finish within {limit:?}"),
                        )
                    }
                }
            }
        };
        self.emit(SupervisionEvent::SafeState {
            actor: self.name.clone(),
            ok,
            detail,
            took: started.elapsed(),
        });
    }

    async fn run_cleanup(&self, pid: Option<u32>, reason: &str) {
        let Some(cleanup) = &self.cleanup else {
            return;
        };
        let started = Instant::now();
        let context = CleanupContext {
            actor: self.name.clone(),
            pid,
            reason: reason.to_owned(),
        };
        let cleanup = Arc::clone(cleanup);
        // A blocking-pool thread: the hook may do file-system work (iceoryx2 cleanup does).
        let task = tokio::task::spawn_blocking(move || cleanup(&context));
        let (ok, detail) = match tokio::time::timeout(CLEANUP_TIMEOUT, task).await {
            Ok(Ok(Ok(()))) => (true, "cleaned up".to_owned()),
            Ok(Ok(Err(err))) => (false, format!("the cleanup hook failed: {err}")),
            Ok(Err(join)) if join.is_panic() => (
                false,
                format!(
                    "the cleanup hook panicked: {}",
                    panic_message(join.into_panic().as_ref())
                ),
            ),
            Ok(Err(_)) => (false, "the cleanup hook was cancelled".to_owned()),
            Err(_) => (
                false,
                format!("the cleanup hook did not finish within {CLEANUP_TIMEOUT:?}"),
            ),
        };
        self.emit(SupervisionEvent::Cleanup {
            actor: self.name.clone(),
            ok,
            detail,
            took: started.elapsed(),
        });
    }
}

fn log_event(event: &SupervisionEvent) {
    match event {
        SupervisionEvent::Failed { .. } => tracing::warn!(actor = event.actor(), "{event}"),
        SupervisionEvent::SafeState { ok: false, .. }
        | SupervisionEvent::Cleanup { ok: false, .. }
        | SupervisionEvent::BudgetExhausted { .. } => {
            tracing::error!(actor = event.actor(), "{event}")
        }
        _ => tracing::info!(actor = event.actor(), "{event}"),
    }
}

// ---- metrics bridge: the only place supervision touches `crate::metrics` ----

fn metric_actor_up(name: &str, up: bool) {
    crate::metrics::Metrics::global().actor_up(name, up);
}

fn metric_actor_restart(name: &str) {
    crate::metrics::Metrics::global().actor_restart(name);
}

fn metric_budget_exhausted(name: &str) {
    crate::metrics::Metrics::global().budget_exhausted(name);
}

// ---- escalation through a kameo link ----

/// A stand-in actor whose only job is to die the right way: it is linked to the parent given
/// to `Supervisor::escalate_to`, stops normally when supervision ends well, and panics with the
/// [`SupervisionError`] when it ends badly, so the parent's `on_link_died` sees
/// `ActorStopReason::Panicked(err)` with `err.downcast::<SupervisionError>()`.
pub(crate) struct Escalator;

impl Actor for Escalator {
    type Args = ();
    type Error = Infallible;

    fn name() -> &'static str {
        "robotd::supervision::Escalator"
    }

    async fn on_start(_args: (), _actor_ref: ActorRef<Self>) -> Result<Self, Self::Error> {
        Ok(Escalator)
    }
}

pub(crate) struct GiveUp(pub(crate) SupervisionError);

impl Message<GiveUp> for Escalator {
    type Reply = Result<(), SupervisionError>;

    async fn handle(&mut self, msg: GiveUp, _ctx: &mut Context<Self, Self::Reply>) -> Self::Reply {
        // An error reply to a `tell` stops the actor with `Panicked(err)`: the escalation.
        Err(msg.0)
    }
}

pub(crate) fn spawn_escalator() -> ActorRef<Escalator> {
    Escalator::spawn(())
}

// ---- the engine ----

/// Starts supervising a worker whose first incarnation is already running.
pub(crate) fn launch<W: Worker>(config: Config, worker: W, first: W::Handle) -> Core<W::Handle> {
    let (status_tx, status_rx) = watch::channel(Status {
        generation: 0,
        phase: Phase::Running(first),
        last_death: None,
        outcome: None,
    });
    let (shutdown_tx, shutdown_rx) = watch::channel(false);
    config.emit(SupervisionEvent::Started {
        actor: config.name.clone(),
        attempt: 0,
    });
    metric_actor_up(&config.name, true);
    let shared = Arc::new(Shared {
        name: config.name.clone(),
        notice_timeout: config.stop_timeout + Duration::from_secs(1),
        shutdown: shutdown_tx,
    });
    tokio::spawn(run(Arc::new(config), worker, status_tx, shutdown_rx));
    Core {
        shared,
        status: status_rx,
    }
}

async fn shutdown_requested(shutdown: &mut watch::Receiver<bool>) {
    // `Err` means every handle is gone: that is a shutdown request too.
    let _ = shutdown.wait_for(|requested| *requested).await;
}

async fn run<W: Worker>(
    config: Arc<Config>,
    mut worker: W,
    status: watch::Sender<Status<W::Handle>>,
    mut shutdown: watch::Receiver<bool>,
) {
    let name = config.name.as_str();
    let mut budget = RestartBudget::new(&config.policy);
    let mut generation: u64 = 0;
    // This loop's beat of the liveness watchdog, when one is installed (watchdog.rs).
    let mut ticker = watchdog::ticker(name);
    loop {
        let mut exit = loop {
            tokio::select! {
                biased;
                () = shutdown_requested(&mut shutdown) => {
                    status.send_modify(|s| s.phase = Phase::Stopping);
                    worker.stop(config.stop_timeout).await;
                    config.run_cleanup(worker.last_pid(), "shut down on request").await;
                    return finish(&config, &status, "shut down on request".to_owned(), Ok(())).await;
                }
                exit = worker.wait_exit() => break exit,
                () = watchdog::next_beat(&mut ticker) => watchdog::beat(&ticker).await,
            }
        };
        // The incarnation is gone. Handle its death; repeat if the restart itself fails.
        loop {
            metric_actor_up(name, false);
            status.send_modify(|s| {
                s.phase = Phase::Restarting;
                s.last_death = Some(Death {
                    generation,
                    failed: exit.failed,
                    reason: exit.reason.clone(),
                });
            });
            if exit.failed {
                config.emit(SupervisionEvent::Failed {
                    actor: name.to_owned(),
                    reason: exit.reason.clone(),
                });
            }
            // Safety first: nothing else happens before the hardware is safe (or we tried).
            config.run_safe_state(&exit.reason).await;
            config.run_cleanup(worker.last_pid(), &exit.reason).await;

            if !config.policy.restart.restarts_after(exit.failed) {
                let (why, outcome) = if exit.failed {
                    (
                        format!("failed and the restart policy is `never`: {}", exit.reason),
                        Err(SupervisionError::NotRestarted {
                            actor: name.to_owned(),
                            reason: exit.reason.clone(),
                        }),
                    )
                } else {
                    (
                        format!(
                            "{} (not a failure, so the `{:?}` policy does not restart it)",
                            exit.reason, config.policy.restart
                        ),
                        Ok(()),
                    )
                };
                return finish(&config, &status, why, outcome).await;
            }

            let attempt = match budget.take(Instant::now()) {
                Ok(attempt) => attempt,
                Err(restarts) => {
                    return exhausted(&config, &status, restarts, exit.reason).await;
                }
            };
            let backoff = config.policy.backoff_for(attempt);
            if !backoff.is_zero() {
                let wake = tokio::time::sleep(backoff);
                tokio::pin!(wake);
                loop {
                    tokio::select! {
                        biased;
                        () = shutdown_requested(&mut shutdown) => {
                            let why = "shut down on request while waiting to restart".to_owned();
                            return finish(&config, &status, why, Ok(())).await;
                        }
                        () = &mut wake => break,
                        () = watchdog::next_beat(&mut ticker) => watchdog::beat(&ticker).await,
                    }
                }
            }

            generation += 1;
            let started = tokio::select! {
                biased;
                () = shutdown_requested(&mut shutdown) => {
                    worker.stop(config.stop_timeout).await;
                    let why = "shut down on request while restarting".to_owned();
                    return finish(&config, &status, why, Ok(())).await;
                }
                started = worker.start() => started,
            };
            match started {
                Ok(handle) => {
                    // Events first, then the status that lets requests through: whoever sees
                    // the restarted actor answer has already been told it restarted.
                    let attempt = u32::try_from(generation).unwrap_or(u32::MAX);
                    config.emit(SupervisionEvent::Restarted {
                        actor: name.to_owned(),
                        attempt,
                        backoff,
                    });
                    metric_actor_restart(name);
                    config.emit(SupervisionEvent::Started {
                        actor: name.to_owned(),
                        attempt,
                    });
                    metric_actor_up(name, true);
                    status.send_modify(|s| {
                        s.generation = generation;
                        s.phase = Phase::Running(handle);
                    });
                    break;
                }
                Err(reason) => exit = Exit::failed(format!("restart failed: {reason}")),
            }
        }
    }
}

async fn exhausted<H>(
    config: &Config,
    status: &watch::Sender<Status<H>>,
    restarts: u32,
    last_reason: String,
) {
    let err = SupervisionError::BudgetExhausted {
        actor: config.name.clone(),
        restarts,
        window: config.policy.window,
        last_reason,
    };
    metric_actor_up(&config.name, false);
    status.send_modify(|s| {
        s.phase = Phase::Exhausted;
        s.outcome = Some(Err(err.clone()));
    });
    config.emit(SupervisionEvent::BudgetExhausted {
        actor: config.name.clone(),
        restarts,
        window: config.policy.window,
    });
    metric_budget_exhausted(&config.name);
    escalate(config, Err(err)).await;
}

async fn finish<H>(
    config: &Config,
    status: &watch::Sender<Status<H>>,
    why: String,
    outcome: Result<(), SupervisionError>,
) {
    metric_actor_up(&config.name, false);
    status.send_modify(|s| {
        s.phase = Phase::Stopped(why.clone());
        s.outcome = Some(outcome.clone());
    });
    config.emit(SupervisionEvent::Stopped {
        actor: config.name.clone(),
        reason: why,
    });
    escalate(config, outcome).await;
}

async fn escalate(config: &Config, outcome: Result<(), SupervisionError>) {
    let Some(escalator) = &config.escalation else {
        return;
    };
    // Either way the escalator stops, and the linked parent's `on_link_died` runs.
    match outcome {
        Ok(()) => {
            let _ = escalator.stop_gracefully().await;
        }
        Err(err) => {
            let _ = escalator.tell(GiveUp(err)).await;
        }
    }
}

// ---- the handle side ----

/// What every clone of a handle shares. Dropping the last one drops `shutdown`, which the
/// engine takes as a shutdown request.
pub(crate) struct Shared {
    pub(crate) name: String,
    /// How long a caller whose request died with the incarnation waits for the engine to
    /// notice the death (and say why) before answering anyway.
    notice_timeout: Duration,
    shutdown: watch::Sender<bool>,
}

/// The part of a handle that is the same for actors and processes.
pub(crate) struct Core<H> {
    pub(crate) shared: Arc<Shared>,
    pub(crate) status: watch::Receiver<Status<H>>,
}

impl<H> Clone for Core<H> {
    fn clone(&self) -> Self {
        Core {
            shared: Arc::clone(&self.shared),
            status: self.status.clone(),
        }
    }
}

impl<H: Clone> Core<H> {
    pub(crate) fn name(&self) -> &str {
        &self.shared.name
    }

    pub(crate) fn state(&self) -> SupervisedState {
        let s = self.status.borrow();
        match &s.phase {
            Phase::Running(_) => SupervisedState::Running {
                attempt: u32::try_from(s.generation).unwrap_or(u32::MAX),
            },
            Phase::Restarting => SupervisedState::Restarting {
                reason: s
                    .last_death
                    .as_ref()
                    .map(|d| d.reason.clone())
                    .unwrap_or_default(),
            },
            Phase::Exhausted => SupervisedState::BudgetExhausted,
            Phase::Stopping => SupervisedState::Stopping,
            Phase::Stopped(reason) => SupervisedState::Stopped {
                reason: reason.clone(),
            },
        }
    }

    /// The running incarnation, or why there is none. Never waits.
    pub(crate) fn current<E>(&self) -> Result<(u64, H), SupervisedError<E>> {
        let s = self.status.borrow();
        match &s.phase {
            Phase::Running(handle) => Ok((s.generation, handle.clone())),
            _ => Err(self.down_error(&s)),
        }
    }

    fn down_error<E>(&self, s: &Status<H>) -> SupervisedError<E> {
        let actor = self.shared.name.clone();
        match &s.phase {
            Phase::Running(_) | Phase::Restarting => SupervisedError::Restarting { actor },
            Phase::Exhausted => SupervisedError::BudgetExhausted { actor },
            Phase::Stopping => SupervisedError::Stopped {
                actor,
                reason: "shutting down".to_owned(),
            },
            Phase::Stopped(reason) => SupervisedError::Stopped {
                actor,
                reason: reason.clone(),
            },
        }
    }

    /// Waits (bounded) until the engine has noticed that incarnation `generation` is gone, so
    /// the answer to the caller reflects the supervisor's view, and returns how it died.
    async fn death_of(&self, generation: u64) -> Option<Death> {
        let mut rx = self.status.clone();
        let noticed =
            rx.wait_for(|s| s.generation != generation || !matches!(s.phase, Phase::Running(_)));
        // Drop the borrow at once: holding it would block the engine's next update.
        let _ =
            tokio::time::timeout(self.shared.notice_timeout, async { noticed.await.is_ok() }).await;
        let s = self.status.borrow();
        s.last_death
            .clone()
            .filter(|death| death.generation == generation)
    }

    /// The error for a request that was accepted by incarnation `generation` but got no
    /// reply because that incarnation stopped.
    pub(crate) async fn died_while_handling<E>(&self, generation: u64) -> SupervisedError<E> {
        match self.death_of(generation).await {
            Some(death) if death.failed => SupervisedError::ActorFailed {
                actor: self.shared.name.clone(),
                reason: death.reason,
            },
            Some(_) => self.down_error(&self.status.borrow()),
            None => {
                let s = self.status.borrow();
                match s.phase {
                    Phase::Stopping | Phase::Stopped(_) | Phase::Exhausted => self.down_error(&s),
                    _ => SupervisedError::ActorFailed {
                        actor: self.shared.name.clone(),
                        reason: "the request was dropped without a reply".to_owned(),
                    },
                }
            }
        }
    }

    /// The error for a request that never reached incarnation `generation` because it was
    /// already gone.
    pub(crate) async fn not_delivered<E>(&self, generation: u64) -> SupervisedError<E> {
        let _ = self.death_of(generation).await;
        self.down_error(&self.status.borrow())
    }

    pub(crate) async fn wait_ready(&self, timeout: Duration) -> Result<H, SupervisedError> {
        let mut rx = self.status.clone();
        let waited = tokio::time::timeout(timeout, async {
            match rx.wait_for(|s| !matches!(s.phase, Phase::Restarting)).await {
                Ok(s) => match &s.phase {
                    Phase::Running(handle) => Ok(handle.clone()),
                    _ => Err(self.down_error(&s)),
                },
                Err(_) => Err(SupervisedError::Stopped {
                    actor: self.shared.name.clone(),
                    reason: "the supervisor is gone".to_owned(),
                }),
            }
        })
        .await;
        waited.unwrap_or_else(|_| {
            Err(SupervisedError::Restarting {
                actor: self.shared.name.clone(),
            })
        })
    }

    pub(crate) async fn wait_stopped(&self) -> Result<(), SupervisionError> {
        let mut rx = self.status.clone();
        let outcome = match rx.wait_for(|s| s.outcome.is_some()).await {
            Ok(s) => s.outcome.clone(),
            Err(_) => None,
        };
        // `None`: the engine is gone without a word (it never is, short of a bug); take the
        // last status it published.
        outcome
            .or_else(|| rx.borrow().outcome.clone())
            .unwrap_or(Ok(()))
    }

    pub(crate) async fn shutdown(&self) -> Result<(), SupervisionError> {
        self.shared.shutdown.send_replace(true);
        self.wait_stopped().await
    }
}

/// The message of a panic payload (`&str` or `String`; anything else is named as such).
pub(crate) fn panic_message(payload: &(dyn Any + Send)) -> String {
    if let Some(s) = payload.downcast_ref::<&str>() {
        (*s).to_owned()
    } else if let Some(s) = payload.downcast_ref::<String>() {
        s.clone()
    } else {
        "a panic with a non-string payload".to_owned()
    }
}
