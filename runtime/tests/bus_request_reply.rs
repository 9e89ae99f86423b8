//! Request-response services: replies, faults, lost servers, timeouts — never silence.

mod common;

use robotd_protocol::diagnostics::{Ping, Pong};
use robotd_protocol::envelope::Message;
use robotd_runtime::bus::{BusError, Fault, FaultKind, Service};
use serde::{Deserialize, Serialize};
use std::sync::atomic::{AtomicU32, Ordering};
use std::sync::Arc;
use std::time::Duration;

const ECHO: Service<Ping, Pong> = Service::new("echo");
const SECOND: Duration = Duration::from_secs(1);

fn ping(seq: u64) -> Ping {
    Ping {
        seq,
        payload: vec![seq as u8; 64],
    }
}

fn pong(ping: Ping) -> Pong {
    Pong {
        seq: ping.seq,
        payload: ping.payload,
        served_by_pid: std::process::id(),
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn requests_get_their_own_replies() {
    let bus = common::fresh_bus("rpc");
    let mut server = bus.server(&ECHO).unwrap();
    tokio::spawn(async move { server.serve(|p| async move { Ok(pong(p)) }).await });
    let client = bus.client(&ECHO).unwrap();
    for seq in 0..500 {
        let reply = client.request(&ping(seq), SECOND).await.unwrap();
        assert_eq!(reply.seq, seq);
        assert_eq!(reply.payload, vec![seq as u8; 64]);
    }
}

/// The `robotd_bus_latency_seconds_count` of `topic` in the process's metrics.
fn latency_count(topic: &str) -> f64 {
    common::metric_sum("robotd_bus_latency_seconds_count", topic)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_time_a_request_waited_for_its_server_is_measured() {
    const TIMED: Service<Ping, Pong> = Service::new("timed_echo");
    let bus = common::fresh_bus("rpc");
    let mut server = bus.server(&TIMED).unwrap();
    tokio::spawn(async move { server.serve(|p| async move { Ok(pong(p)) }).await });
    let client = bus.client(&TIMED).unwrap();
    let before = latency_count("timed_echo/requests");
    for seq in 0..5 {
        client.request(&ping(seq), SECOND).await.unwrap();
    }
    assert_eq!(latency_count("timed_echo/requests") - before, 5.0);
    assert!(latency_count("timed_echo/round_trip") >= 5.0);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn concurrent_clients_are_all_answered() {
    let bus = common::fresh_bus("rpc");
    let mut server = bus.server(&ECHO).unwrap();
    tokio::spawn(async move { server.serve(|p| async move { Ok(pong(p)) }).await });
    let mut tasks = Vec::new();
    for c in 0..8u64 {
        let client = bus.client(&ECHO).unwrap();
        tasks.push(tokio::spawn(async move {
            for i in 0..100 {
                let seq = c * 1000 + i;
                assert_eq!(client.request(&ping(seq), SECOND).await.unwrap().seq, seq);
            }
        }));
    }
    for task in tasks {
        task.await.unwrap();
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn no_server_is_an_error_not_a_hang() {
    let bus = common::fresh_bus("rpc");
    let client = bus.client(&ECHO).unwrap();
    let error = client.request(&ping(1), SECOND).await.unwrap_err();
    assert!(matches!(error, BusError::NoServer { .. }), "{error}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_panicking_handler_fails_that_request_once_and_serving_goes_on() {
    let bus = common::fresh_bus("rpc");
    let mut server = bus.server(&ECHO).unwrap();
    let executions = Arc::new(AtomicU32::new(0));
    let counter = executions.clone();
    tokio::spawn(async move {
        server
            .serve(move |p| {
                let counter = counter.clone();
                async move {
                    counter.fetch_add(1, Ordering::SeqCst);
                    if p.seq == 13 {
                        panic!("unlucky request");
                    }
                    Ok(pong(p))
                }
            })
            .await
    });
    let client = bus.client(&ECHO).unwrap();
    let error = client.request(&ping(13), SECOND).await.unwrap_err();
    match &error {
        BusError::Remote { fault, .. } => {
            assert_eq!(fault.kind, FaultKind::ActorFailed);
            assert!(fault.message.contains("unlucky request"), "{error}");
        }
        other => panic!("expected a fault, got {other}"),
    }
    assert_eq!(client.request(&ping(14), SECOND).await.unwrap().seq, 14);
    assert_eq!(
        executions.load(Ordering::SeqCst),
        2,
        "the failed request ran exactly once"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn handler_faults_reach_the_caller() {
    let bus = common::fresh_bus("rpc");
    let mut server = bus.server(&ECHO).unwrap();
    tokio::spawn(async move {
        server
            .serve(|_p| async move {
                Err::<Pong, _>(Fault::new(FaultKind::Unavailable, "arm is restarting"))
            })
            .await
    });
    let client = bus.client(&ECHO).unwrap();
    let error = client.request(&ping(1), SECOND).await.unwrap_err();
    assert!(error.to_string().contains("arm is restarting"), "{error}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_request_dropped_by_the_server_is_answered_with_a_fault() {
    let bus = common::fresh_bus("rpc");
    let mut server = bus.server(&ECHO).unwrap();
    tokio::spawn(async move {
        let incoming = server.next().await.unwrap();
        drop(incoming); // lost track of the request without answering
        let _ = server.next().await; // ...and went on serving
    });
    let client = bus.client(&ECHO).unwrap();
    let error = client
        .request(&ping(1), Duration::from_secs(5))
        .await
        .unwrap_err();
    match error {
        BusError::Remote { fault, .. } => assert_eq!(fault.kind, FaultKind::Dropped),
        other => panic!("expected a dropped-request fault, got {other}"),
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_slow_server_times_out() {
    let bus = common::fresh_bus("rpc");
    let mut server = bus.server(&ECHO).unwrap();
    tokio::spawn(async move {
        server
            .serve(|p| async move {
                tokio::time::sleep(Duration::from_millis(500)).await;
                Ok(pong(p))
            })
            .await
    });
    let client = bus.client(&ECHO).unwrap();
    let error = client
        .request(&ping(1), Duration::from_millis(100))
        .await
        .unwrap_err();
    assert!(
        matches!(
            error,
            BusError::Timeout {
                timeout_ms: 100,
                ..
            }
        ),
        "{error}"
    );
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
struct NotAPing {
    words: Vec<String>,
}
impl Message for NotAPing {
    const TYPE: &'static str = "test.not_a_ping";
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_malformed_request_gets_a_bad_request_fault_and_the_server_survives() {
    let bus = common::fresh_bus("rpc");
    let mut server = bus.server(&ECHO).unwrap();
    tokio::spawn(async move { server.serve(|p| async move { Ok(pong(p)) }).await });
    let wrong: Service<NotAPing, Pong> = Service::new("echo");
    let wrong_client = bus.client(&wrong).unwrap();
    let error = wrong_client
        .request(
            &NotAPing {
                words: vec!["hi".into()],
            },
            SECOND,
        )
        .await
        .unwrap_err();
    match error {
        BusError::Remote { fault, .. } => assert_eq!(fault.kind, FaultKind::BadRequest),
        other => panic!("expected a bad-request fault, got {other}"),
    }
    let client = bus.client(&ECHO).unwrap();
    assert_eq!(client.request(&ping(2), SECOND).await.unwrap().seq, 2);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_service_has_exactly_one_server() {
    let bus = common::fresh_bus("rpc");
    let _first = bus.server(&ECHO).unwrap();
    let error = bus.server(&ECHO).unwrap_err();
    assert!(matches!(error, BusError::Setup { .. }), "{error}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_request_that_timed_out_is_never_executed_later() {
    let bus = common::fresh_bus("rpc");
    let mut server = bus.server(&ECHO).unwrap();
    let executions = Arc::new(AtomicU32::new(0));
    let counter = executions.clone();
    let started = Arc::new(tokio::sync::Notify::new());
    let started_tx = started.clone();
    tokio::spawn(async move {
        server
            .serve(move |p| {
                let counter = counter.clone();
                let started = started_tx.clone();
                async move {
                    counter.fetch_add(1, Ordering::SeqCst);
                    if p.seq == 1 {
                        started.notify_one();
                        tokio::time::sleep(Duration::from_millis(400)).await;
                    }
                    Ok(pong(p))
                }
            })
            .await
    });
    let slow = bus.client(&ECHO).unwrap();
    let impatient = bus.client(&ECHO).unwrap();
    let busy = tokio::spawn(async move { slow.request(&ping(1), SECOND).await });
    // The server is now busy with request 1.
    tokio::time::timeout(SECOND, started.notified())
        .await
        .expect("the server took request 1");
    let error = impatient
        .request(&ping(2), Duration::from_millis(100))
        .await
        .unwrap_err();
    assert!(matches!(error, BusError::Timeout { .. }), "{error}");
    assert_eq!(busy.await.unwrap().unwrap().seq, 1);
    // The server reached request 2 after its caller gave up: refused, not executed.
    assert_eq!(impatient.request(&ping(3), SECOND).await.unwrap().seq, 3);
    assert_eq!(
        executions.load(Ordering::SeqCst),
        2,
        "requests 1 and 3 ran; 2 did not"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_reply_too_large_to_send_is_a_fault_and_serving_goes_on() {
    let bus = common::fresh_bus("rpc");
    let mut server = bus.server(&ECHO).unwrap();
    tokio::spawn(async move {
        server
            .serve(|p| async move {
                let mut reply = pong(p);
                if reply.seq == 1 {
                    reply.payload = vec![0; 2 * 1024 * 1024];
                }
                Ok(reply)
            })
            .await
    });
    let client = bus.client(&ECHO).unwrap();
    match client.request(&ping(1), SECOND).await.unwrap_err() {
        BusError::Remote { fault, .. } => assert_eq!(fault.kind, FaultKind::ReplyFailed),
        other => panic!("expected a reply-failed fault, got {other}"),
    }
    assert_eq!(client.request(&ping(2), SECOND).await.unwrap().seq, 2);
}

fn open_fds() -> usize {
    std::fs::read_dir("/proc/self/fd").map_or(0, |d| d.count())
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn short_lived_clients_leave_nothing_behind() {
    let bus = common::fresh_bus("rpc");
    let mut server = bus.server(&ECHO).unwrap();
    tokio::spawn(async move { server.serve(|p| async move { Ok(pong(p)) }).await });
    let round = |n: u64| {
        let bus = bus.clone();
        async move {
            for seq in 0..n {
                let client = bus.client(&ECHO).unwrap();
                assert_eq!(client.request(&ping(seq), SECOND).await.unwrap().seq, seq);
            }
        }
    };
    round(10).await;
    let before = open_fds();
    round(140).await; // more clients than a service admits at once, one after the other
    let grown = open_fds().saturating_sub(before);
    assert!(
        grown < 100,
        "{grown} descriptors more after 140 short-lived clients"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_client_waiting_for_its_server_is_woken_when_it_attaches() {
    let bus = common::fresh_bus("rpc");
    let client = bus.client(&ECHO).unwrap();
    let started = std::time::Instant::now();
    assert!(!client.wait_for_server(Duration::from_millis(100)).await);
    assert!(started.elapsed() >= Duration::from_millis(100));

    let server_bus = bus.clone();
    tokio::spawn(async move {
        tokio::time::sleep(Duration::from_millis(100)).await;
        let mut server = server_bus.server(&ECHO).unwrap();
        server.serve(|p| async move { Ok(pong(p)) }).await
    });
    let started = std::time::Instant::now();
    assert!(client.wait_for_server(Duration::from_secs(5)).await);
    assert!(
        started.elapsed() < Duration::from_secs(2),
        "{:?}",
        started.elapsed()
    );
    assert_eq!(client.request(&ping(1), SECOND).await.unwrap().seq, 1);
}
