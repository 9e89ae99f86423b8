//! The liveness watchdog beats from inside the supervision loops: with every loop turning it
//! pings once per interval, and a loop that hangs stops the pings while the rest of the process
//! runs on. One test in this file: the watchdog is installed once per process.

use std::sync::atomic::{AtomicU32, Ordering};
use std::sync::mpsc;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use kameo::actor::ActorRef;
use kameo::error::Infallible;
use kameo::message::{Context, Message};
use kameo::Actor;
use robotd_runtime::supervision::{observer_fn, watchdog, SupervisionEvent, Supervisor};

const INTERVAL: Duration = Duration::from_millis(50);

struct Motor;

impl Actor for Motor {
    type Args = ();
    type Error = Infallible;

    async fn on_start(_: (), _: ActorRef<Self>) -> Result<Self, Self::Error> {
        Ok(Motor)
    }
}

struct Crash;

impl Message<Crash> for Motor {
    type Reply = ();

    async fn handle(&mut self, _: Crash, _: &mut Context<Self, Self::Reply>) {
        panic!("driver fault");
    }
}

/// Waits for the next ping, up to `limit`.
fn next_ping(pings: &mpsc::Receiver<Instant>, limit: Duration) -> Option<Instant> {
    pings.recv_timeout(limit).ok()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn pings_come_from_the_loops_at_the_interval_and_stop_when_one_loop_hangs() {
    let (ping_tx, pings) = mpsc::channel::<Instant>();
    let ping_tx = Mutex::new(ping_tx);
    watchdog::install(INTERVAL, move || {
        let _ = ping_tx.lock().unwrap().send(Instant::now());
    })
    .unwrap();
    assert!(
        watchdog::install(INTERVAL, || {}).is_err(),
        "once per process"
    );
    assert_eq!(watchdog::interval(), Some(INTERVAL));

    // The arm's observer blocks its supervision loop on the failure, until released: a
    // supervision loop that hangs inside synchronous code.
    let (blocked_tx, blocked) = mpsc::channel::<()>();
    let (release, released) = mpsc::channel::<()>();
    let released = Mutex::new(released);
    let blocked_tx = Mutex::new(blocked_tx);
    let arm = Supervisor::new("arm")
        .observer(observer_fn(move |event: &SupervisionEvent| {
            if matches!(event, SupervisionEvent::Failed { .. }) {
                let _ = blocked_tx.lock().unwrap().send(());
                let _ = released.lock().unwrap().recv();
            }
        }))
        .spawn_actor::<Motor>(|| ())
        .await
        .unwrap();
    let camera_events = Arc::new(AtomicU32::new(0));
    let counted = camera_events.clone();
    let _camera = Supervisor::new("camera")
        .observer(observer_fn(move |_: &SupervisionEvent| {
            counted.fetch_add(1, Ordering::SeqCst);
        }))
        .spawn_actor::<Motor>(|| ())
        .await
        .unwrap();

    // Both loops turn: one ping per interval, never faster.
    let pings_now = tokio::task::spawn_blocking(move || {
        let mut seen = Vec::new();
        while seen.len() < 8 {
            seen.push(next_ping(&pings, Duration::from_secs(5)).expect("a watchdog ping"));
        }
        (pings, seen)
    });
    let (pings, seen) = pings_now.await.unwrap();
    let gaps: Vec<Duration> = seen.windows(2).map(|w| w[1] - w[0]).collect();
    let total = seen[seen.len() - 1] - seen[1];
    let mean = total / (seen.len() as u32 - 2);
    assert!(
        mean >= INTERVAL * 8 / 10 && mean <= INTERVAL * 3,
        "mean gap {mean:?}, gaps {gaps:?}"
    );
    assert!(
        gaps.iter().all(|gap| *gap >= INTERVAL / 2),
        "a ping came faster than the interval allows: {gaps:?}"
    );

    // The arm crashes and its loop hangs in its observer: the pings stop (at most one round
    // already under way completes), though the camera's loop still beats.
    arm.tell(Crash).await.unwrap();
    let (pings, after_hang) = tokio::task::spawn_blocking(move || {
        blocked
            .recv_timeout(Duration::from_secs(5))
            .expect("the arm's loop reached its observer");
        // Pings sent before the loop hung are not the point.
        while pings.try_recv().is_ok() {}
        let mut after = 0;
        while next_ping(&pings, INTERVAL * 12).is_some() {
            after += 1;
            if after > 1 {
                break;
            }
        }
        (pings, after)
    })
    .await
    .unwrap();
    assert!(after_hang <= 1, "{after_hang} pings while a loop hung");
    assert_eq!(watchdog::waiting_for(), vec!["arm".to_owned()]);

    // The loop is released: the pings come back.
    release.send(()).unwrap();
    let resumed = tokio::task::spawn_blocking(move || next_ping(&pings, Duration::from_secs(5)))
        .await
        .unwrap();
    assert!(
        resumed.is_some(),
        "the pings resumed once the loop turned again"
    );
}
