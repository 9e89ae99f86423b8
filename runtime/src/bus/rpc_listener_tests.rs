//! Tests of how a request client waits: for its server, and for replies after a lost wake-up.

use crate::bus::wake::subscribed_event;
use crate::bus::{Bus, BusOptions, Service};
use robotd_protocol::diagnostics::{Ping, Pong};
use std::time::Duration;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_client_listens_for_its_server_only_while_it_waits() {
    const ECHO: Service<Ping, Pong> = Service::new("listening-echo");
    let namespace = format!("test-attached-{}", std::process::id());
    let bus = Bus::open(BusOptions::new(&namespace, "attached")).unwrap();
    let event = subscribed_event(&ECHO.requests().name);
    let listeners = || crate::bus::pubsub::tests::listeners(&bus, &event);
    let client = bus.client(&ECHO).unwrap();
    assert_eq!(
        listeners(),
        0,
        "a client that does not wait holds no listener"
    );
    let waiting = client.wait_for_server(Duration::from_secs(5));
    tokio::pin!(waiting);
    // Poll the wait once: it finds no server and starts listening.
    assert!(futures_poll_once(waiting.as_mut()).await.is_none());
    assert_eq!(listeners(), 1);
    let _server = bus.server(&ECHO).unwrap();
    assert!(waiting.await, "woken when the server attached");
    assert_eq!(listeners(), 0, "the listener is gone once the wait ends");
}

/// A client whose reply listener lost a wake-up (a notification consumed before tokio saw
/// its datagram) still gets every later reply at once. Before `Wake::rearm`, each reply
/// after such a loss waited for the 250 ms liveness check, for good: 64 MCP clients got
/// 120 calls/s instead of 5,000.
#[tokio::test(flavor = "current_thread")]
async fn a_lost_wake_up_does_not_slow_the_replies_after_it() {
    const ECHO: Service<Ping, Pong> = Service::new("lost-wake-echo");
    let namespace = format!("test-lost-wake-{}", std::process::id());
    let bus = Bus::open(BusOptions::new(&namespace, "lost")).unwrap();
    let mut server = bus.server(&ECHO).unwrap();
    tokio::spawn(async move {
        server
            .serve(|p: Ping| async move {
                Ok(Pong {
                    seq: p.seq,
                    payload: p.payload,
                    served_by_pid: 0,
                })
            })
            .await
    });
    // The client in another node, as in another process: its wake-ups come as datagrams.
    let client_bus = Bus::open(BusOptions::new(&namespace, "lost-client")).unwrap();
    let client = client_bus.client(&ECHO).unwrap();
    assert!(client.wait_for_server(Duration::from_secs(5)).await);
    crate::bus::pubsub::tests::lose_a_wake_up(&bus, &*client.replies.lock().await);
    let started = std::time::Instant::now();
    for seq in 0..20 {
        let ping = Ping {
            seq,
            payload: vec![],
        };
        let pong = client.request(&ping, Duration::from_secs(5)).await.unwrap();
        assert_eq!(pong.seq, seq);
    }
    // 20 liveness checks would be 5 s; 20 round trips take milliseconds.
    let took = started.elapsed();
    assert!(
        took < Duration::from_millis(2_500),
        "20 requests took {took:?}"
    );
}

/// Polls `future` once; `Some` if it finished.
async fn futures_poll_once<F: std::future::Future + Unpin>(mut future: F) -> Option<F::Output> {
    std::future::poll_fn(|context| {
        std::task::Poll::Ready(match std::pin::Pin::new(&mut future).poll(context) {
            std::task::Poll::Ready(output) => Some(output),
            std::task::Poll::Pending => None,
        })
    })
    .await
}
