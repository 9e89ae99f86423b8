//! The restart budget and backoff: restarts are spaced out exponentially, and a failure the
//! budget does not cover makes the supervisor give up, report it and escalate.

use std::ops::ControlFlow;
use std::sync::atomic::{AtomicU32, Ordering};
use std::sync::Arc;
use std::time::Duration;

use kameo::actor::{ActorId, ActorRef, Spawn, WeakActorRef};
use kameo::error::{ActorStopReason, Infallible};
use kameo::message::{Context, Message};
use kameo::Actor;
use robotd_runtime::supervision::{
    RestartPolicy, SupervisedError, SupervisedState, SupervisionError, SupervisionEvent,
    SupervisionPolicy, Supervisor,
};
use tokio::sync::mpsc::{unbounded_channel, UnboundedReceiver, UnboundedSender};
use tokio::time::Instant;

const WAIT: Duration = Duration::from_secs(2);

struct Flaky {
    instance: u32,
}

impl Actor for Flaky {
    type Args = Arc<AtomicU32>;
    type Error = Infallible;

    async fn on_start(starts: Arc<AtomicU32>, _: ActorRef<Self>) -> Result<Self, Self::Error> {
        Ok(Flaky {
            instance: starts.fetch_add(1, Ordering::SeqCst),
        })
    }
}

struct Crash;

impl Message<Crash> for Flaky {
    type Reply = ();

    async fn handle(&mut self, _: Crash, _: &mut Context<Self, Self::Reply>) {
        panic!("motor driver fault");
    }
}

struct WhoAreYou;

impl Message<WhoAreYou> for Flaky {
    type Reply = u32;

    async fn handle(&mut self, _: WhoAreYou, _: &mut Context<Self, Self::Reply>) -> u32 {
        self.instance
    }
}

/// Collects events, stamped with (tokio) time of arrival.
struct Events(UnboundedReceiver<SupervisionEvent>);

impl Events {
    async fn until(
        &mut self,
        stop: impl Fn(&SupervisionEvent) -> bool,
    ) -> Vec<(Instant, SupervisionEvent)> {
        let mut seen = Vec::new();
        loop {
            let event = tokio::time::timeout(WAIT, self.0.recv())
                .await
                .expect("timed out waiting for a supervision event")
                .expect("the supervisor dropped its observer");
            let done = stop(&event);
            seen.push((Instant::now(), event));
            if done {
                return seen;
            }
        }
    }

    async fn until_kind(&mut self, kind: &str) -> Vec<(Instant, SupervisionEvent)> {
        self.until(|e| e.kind() == kind).await
    }
}

async fn spawn_flaky(
    policy: SupervisionPolicy,
) -> (
    robotd_runtime::supervision::Supervised<Flaky>,
    Events,
    Arc<AtomicU32>,
) {
    let (tx, rx) = unbounded_channel();
    let starts = Arc::new(AtomicU32::new(0));
    let args = starts.clone();
    let handle = Supervisor::new("arm")
        .policy(policy)
        .observer(tx)
        .safe_state(())
        .spawn_actor::<Flaky>(move || args.clone())
        .await
        .unwrap();
    (handle, Events(rx), starts)
}

fn policy(max_restarts: u32, window: Duration, initial_ms: u64) -> SupervisionPolicy {
    SupervisionPolicy {
        max_restarts,
        window,
        backoff_initial: Duration::from_millis(initial_ms),
        backoff_max: Duration::from_secs(5),
        backoff_multiplier: 2.0,
        restart: RestartPolicy::Permanent,
    }
}

#[test]
fn backoff_for_grows_exponentially_up_to_the_cap() {
    let p = SupervisionPolicy::default();
    assert_eq!(p.backoff_for(0), Duration::ZERO);
    assert_eq!(p.backoff_for(1), Duration::from_millis(10));
    assert_eq!(p.backoff_for(2), Duration::from_millis(20));
    assert_eq!(p.backoff_for(3), Duration::from_millis(40));
    assert_eq!(p.backoff_for(9), Duration::from_millis(2560));
    assert_eq!(p.backoff_for(10), Duration::from_secs(5));
    assert_eq!(p.backoff_for(1000), Duration::from_secs(5));
    let tripling = SupervisionPolicy {
        backoff_initial: Duration::from_millis(1),
        backoff_multiplier: 3.0,
        backoff_max: Duration::from_millis(100),
        ..p
    };
    let got: Vec<_> = (1..=6)
        .map(|a| tripling.backoff_for(a).as_millis())
        .collect();
    assert_eq!(got, [1, 3, 9, 27, 81, 100]);
}

/// Virtual time: the backoff sleeps are the only thing that takes time, so the gap between a
/// failure and the next start is exactly the backoff.
#[tokio::test(start_paused = true)]
async fn consecutive_failures_back_off_exponentially() {
    let (arm, mut events, _) = spawn_flaky(policy(10, Duration::from_secs(60), 100)).await;
    events.until_kind("started").await;
    let mut gaps = Vec::new();
    for attempt in 1..=4u32 {
        assert!(matches!(
            arm.ask(Crash).await,
            Err(SupervisedError::ActorFailed { .. })
        ));
        let seen = events
            .until(|e| matches!(e, SupervisionEvent::Started { attempt: a, .. } if *a == attempt))
            .await;
        let failed_at = seen.iter().find(|(_, e)| e.kind() == "failed").unwrap().0;
        let started_at = seen.last().unwrap().0;
        let backoff = seen
            .iter()
            .find_map(|(_, e)| match e {
                SupervisionEvent::Restarted { backoff, .. } => Some(*backoff),
                _ => None,
            })
            .unwrap();
        gaps.push((started_at - failed_at, backoff));
    }
    let expected = [100, 200, 400, 800].map(Duration::from_millis);
    for ((gap, backoff), want) in gaps.iter().zip(expected) {
        assert_eq!(*backoff, want, "reported backoff");
        assert!(
            *gap >= want && *gap < want + Duration::from_millis(5),
            "gap {gap:?} for {want:?}"
        );
    }
    assert_eq!(arm.ask(WhoAreYou).await.unwrap(), 4);
}

/// Real time, generous bounds: each restart waits at least its backoff, and the waits grow.
#[tokio::test]
async fn backoff_is_real_time_between_restarts() {
    let (arm, mut events, _) = spawn_flaky(policy(10, Duration::from_secs(60), 20)).await;
    events.until_kind("started").await;
    let mut gaps = Vec::new();
    for attempt in 1..=3u32 {
        let crashed = std::time::Instant::now();
        assert!(arm.ask(Crash).await.is_err());
        events
            .until(|e| matches!(e, SupervisionEvent::Started { attempt: a, .. } if *a == attempt))
            .await;
        gaps.push(crashed.elapsed());
    }
    for (gap, want) in gaps.iter().zip([20, 40, 80].map(Duration::from_millis)) {
        assert!(*gap >= want, "{gap:?} < {want:?}");
        assert!(
            *gap < want + Duration::from_millis(500),
            "{gap:?} far above {want:?}"
        );
    }
}

#[tokio::test]
async fn exhausted_budget_gives_up_reports_and_fails_requests() {
    let (arm, mut events, starts) = spawn_flaky(policy(3, Duration::from_secs(60), 1)).await;
    for _ in 0..4 {
        assert!(matches!(
            arm.ask(Crash).await,
            Err(SupervisedError::ActorFailed { .. })
        ));
        // wait until the supervisor is done with this failure before crashing again
        let _ = arm.wait_ready(WAIT).await;
    }
    let seen = events.until_kind("budget_exhausted").await;
    let kinds: Vec<_> = seen.iter().map(|(_, e)| e.kind()).collect();
    assert_eq!(kinds.iter().filter(|k| **k == "failed").count(), 4);
    assert_eq!(kinds.iter().filter(|k| **k == "restarted").count(), 3);
    assert_eq!(
        &kinds[kinds.len() - 3..],
        ["failed", "safe_state", "budget_exhausted"]
    );
    let last = &seen.last().unwrap().1;
    assert!(last.budget_exhausted());
    assert_eq!(
        *last,
        SupervisionEvent::BudgetExhausted {
            actor: "arm".into(),
            restarts: 3,
            window: Duration::from_secs(60)
        }
    );

    assert_eq!(arm.state(), SupervisedState::BudgetExhausted);
    let err = arm.ask(WhoAreYou).await.unwrap_err();
    assert!(
        matches!(err, SupervisedError::BudgetExhausted { .. }),
        "{err}"
    );
    assert!(err.to_string().contains("restart budget is exhausted"));
    assert!(matches!(
        arm.wait_ready(WAIT).await,
        Err(SupervisedError::BudgetExhausted { .. })
    ));
    match arm.wait_stopped().await {
        Err(SupervisionError::BudgetExhausted {
            actor,
            restarts,
            last_reason,
            ..
        }) => {
            assert_eq!((actor.as_str(), restarts), ("arm", 3));
            assert!(last_reason.contains("motor driver fault"), "{last_reason}");
        }
        other => panic!("expected the escalation, got {other:?}"),
    }
    assert_eq!(starts.load(Ordering::SeqCst), 4, "1 start + 3 restarts");

    // The process (and its runtime) keep going: a new supervisor works fine.
    let (other, _events, _) = spawn_flaky(policy(3, Duration::from_secs(60), 1)).await;
    assert_eq!(other.ask(WhoAreYou).await.unwrap(), 0);
}

#[tokio::test(start_paused = true)]
async fn restarts_leave_the_budget_as_the_window_slides() {
    let (arm, mut events, _) = spawn_flaky(policy(1, Duration::from_millis(100), 1)).await;
    assert!(arm.ask(Crash).await.is_err());
    arm.wait_ready(WAIT).await.unwrap();
    assert_eq!(arm.ask(WhoAreYou).await.unwrap(), 1);

    // After a quiet window the budget is whole again, and the backoff starts over.
    tokio::time::advance(Duration::from_millis(150)).await;
    assert!(arm.ask(Crash).await.is_err());
    arm.wait_ready(WAIT).await.unwrap();
    assert_eq!(arm.ask(WhoAreYou).await.unwrap(), 2);
    let seen = events
        .until(|e| matches!(e, SupervisionEvent::Started { attempt: 2, .. }))
        .await;
    let backoffs: Vec<_> = seen
        .iter()
        .filter_map(|(_, e)| match e {
            SupervisionEvent::Restarted { backoff, .. } => Some(*backoff),
            _ => None,
        })
        .collect();
    assert_eq!(backoffs, [Duration::from_millis(1); 2]);

    // A second failure within the window is one too many.
    assert!(arm.ask(Crash).await.is_err());
    events.until_kind("budget_exhausted").await;
    assert_eq!(arm.state(), SupervisedState::BudgetExhausted);
}

#[tokio::test]
async fn never_policy_escalates_the_first_failure() {
    let (arm, mut events, _) = spawn_flaky(SupervisionPolicy {
        restart: RestartPolicy::Never,
        ..policy(5, Duration::from_secs(60), 1)
    })
    .await;
    assert!(arm.ask(Crash).await.is_err());
    let seen = events.until_kind("stopped").await;
    let kinds: Vec<_> = seen.iter().map(|(_, e)| e.kind()).collect();
    assert_eq!(kinds, ["started", "failed", "safe_state", "stopped"]);
    assert!(matches!(
        arm.wait_stopped().await,
        Err(SupervisionError::NotRestarted { .. })
    ));
    assert!(matches!(
        arm.ask(WhoAreYou).await,
        Err(SupervisedError::Stopped { .. })
    ));
}

/// A parent that reports how its linked children died.
struct Parent {
    deaths: UnboundedSender<ActorStopReason>,
}

impl Actor for Parent {
    type Args = UnboundedSender<ActorStopReason>;
    type Error = Infallible;

    async fn on_start(deaths: Self::Args, _: ActorRef<Self>) -> Result<Self, Self::Error> {
        Ok(Parent { deaths })
    }

    async fn on_link_died(
        &mut self,
        _: WeakActorRef<Self>,
        _: ActorId,
        reason: ActorStopReason,
    ) -> Result<ControlFlow<ActorStopReason>, Self::Error> {
        let _ = self.deaths.send(reason);
        Ok(ControlFlow::Continue(()))
    }
}

#[tokio::test]
async fn an_exhausted_budget_escalates_to_the_parent_through_a_kameo_link() {
    let (deaths_tx, mut deaths) = unbounded_channel();
    let parent = Parent::spawn(deaths_tx);
    let starts = Arc::new(AtomicU32::new(0));
    let args = starts.clone();
    let arm = Supervisor::new("arm")
        .policy(policy(0, Duration::from_secs(60), 1))
        .escalate_to(&parent)
        .spawn_actor::<Flaky>(move || args.clone())
        .await
        .unwrap();
    assert!(arm.ask(Crash).await.is_err());
    let reason = tokio::time::timeout(WAIT, deaths.recv())
        .await
        .expect("the parent heard nothing")
        .unwrap();
    let ActorStopReason::Panicked(err) = reason else {
        panic!("expected Panicked, got {reason:?}");
    };
    match err.downcast::<SupervisionError>() {
        Some(SupervisionError::BudgetExhausted {
            actor, restarts: 0, ..
        }) => assert_eq!(actor, "arm"),
        other => panic!("expected the budget error, got {other:?}"),
    }
    assert!(parent.is_alive());
}

#[tokio::test]
async fn a_clean_shutdown_tells_the_parent_normally() {
    let (deaths_tx, mut deaths) = unbounded_channel();
    let parent = Parent::spawn(deaths_tx);
    let starts = Arc::new(AtomicU32::new(0));
    let args = starts.clone();
    let arm = Supervisor::new("arm")
        .escalate_to(&parent)
        .spawn_actor::<Flaky>(move || args.clone())
        .await
        .unwrap();
    arm.shutdown().await.unwrap();
    let reason = tokio::time::timeout(WAIT, deaths.recv())
        .await
        .unwrap()
        .unwrap();
    assert!(matches!(reason, ActorStopReason::Normal), "{reason:?}");
}
