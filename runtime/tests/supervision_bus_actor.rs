//! An in-process actor under supervision, serving a bus service: a panic fails only the request
//! in hand (once, never retried), the safe-state hook runs before the restart, and the restarted
//! actor answers on the same service.

mod common;

use kameo::error::Infallible;
use kameo::message::{Context, Message};
use kameo::Actor;
use robotd_protocol::diagnostics::{Ping, Pong};
use robotd_runtime::bus::{BusError, FaultKind, Service};
use robotd_runtime::host::serve_supervised;
use robotd_runtime::supervision::{safe_state_fn, SupervisionEvent, SupervisionPolicy, Supervisor};
use std::sync::atomic::{AtomicU32, Ordering};
use std::sync::Arc;
use std::time::Duration;

const ARMISH: Service<Ping, Pong> = Service::new("armish/command");

/// Stands in for a hardware actor: counts what it handles, panics on request 13.
struct Armish {
    handled: Arc<AtomicU32>,
}

impl Actor for Armish {
    type Args = Arc<AtomicU32>;
    type Error = Infallible;

    async fn on_start(
        handled: Self::Args,
        _: kameo::actor::ActorRef<Self>,
    ) -> Result<Self, Self::Error> {
        Ok(Armish { handled })
    }
}

impl Message<Ping> for Armish {
    type Reply = Result<Pong, String>;

    async fn handle(&mut self, ping: Ping, _: &mut Context<Self, Self::Reply>) -> Self::Reply {
        self.handled.fetch_add(1, Ordering::SeqCst);
        match ping.seq {
            13 => panic!("motor driver fault"),
            99 => Err("target out of reach".into()),
            seq => Ok(Pong {
                seq,
                payload: ping.payload,
                served_by_pid: std::process::id(),
            }),
        }
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_panicking_actor_fails_the_request_in_hand_is_made_safe_and_serves_again() {
    let bus = common::fresh_bus("host");
    let handled = Arc::new(AtomicU32::new(0));
    let made_safe = Arc::new(AtomicU32::new(0));
    let (events_tx, mut events) = tokio::sync::mpsc::unbounded_channel();
    let safe = made_safe.clone();
    let counter = handled.clone();
    let actor = Supervisor::new("armish")
        .policy(SupervisionPolicy {
            backoff_initial: Duration::from_millis(5),
            ..SupervisionPolicy::default()
        })
        .observer(events_tx)
        .safe_state(safe_state_fn(Duration::from_secs(1), move |_reason| {
            let safe = safe.clone();
            async move {
                safe.fetch_add(1, Ordering::SeqCst);
                Ok(())
            }
        }))
        .spawn_actor::<Armish>(move || counter.clone())
        .await
        .unwrap();
    tokio::spawn(serve_supervised(
        bus.server(&ARMISH).unwrap(),
        actor.clone(),
    ));
    let client = bus.client(&ARMISH).unwrap();
    let ping = |seq| Ping {
        seq,
        payload: vec![],
    };

    assert_eq!(
        client
            .request(&ping(1), Duration::from_secs(1))
            .await
            .unwrap()
            .seq,
        1
    );
    match client.request(&ping(13), Duration::from_secs(1)).await {
        Err(BusError::Remote { fault, .. }) => {
            assert_eq!(fault.kind, FaultKind::ActorFailed);
            assert!(fault.message.contains("not retried"), "{}", fault.message);
        }
        other => panic!("expected an actor-failed fault, got {other:?}"),
    }
    actor.wait_ready(Duration::from_secs(2)).await.unwrap();
    assert_eq!(
        client
            .request(&ping(14), Duration::from_secs(1))
            .await
            .unwrap()
            .seq,
        14
    );
    match client.request(&ping(99), Duration::from_secs(1)).await {
        Err(BusError::Remote { fault, .. }) => {
            assert_eq!(fault.kind, FaultKind::Refused);
            assert!(
                fault.message.contains("target out of reach"),
                "{}",
                fault.message
            );
        }
        other => panic!("expected a refusal, got {other:?}"),
    }

    assert_eq!(
        handled.load(Ordering::SeqCst),
        4,
        "request 13 ran once, not again"
    );
    assert_eq!(
        made_safe.load(Ordering::SeqCst),
        1,
        "the safe-state hook ran once"
    );
    let mut kinds = Vec::new();
    while let Ok(event) = events.try_recv() {
        kinds.push(event.kind());
        if let SupervisionEvent::Restarted { attempt, .. } = event {
            assert_eq!(attempt, 1);
        }
    }
    let position = |kind: &str| kinds.iter().position(|k| *k == kind);
    assert!(
        position("safe_state") < position("restarted") && position("safe_state").is_some(),
        "safe state before restart: {kinds:?}"
    );
}
