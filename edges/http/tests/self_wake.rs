//! hyper's connection task wakes itself once per request with a body; served through
//! `InlineSelfWakes`, that wake-up no longer reaches the scheduler.
//!
//! The first test pins hyper's behaviour down: if a later hyper stops waking the connection
//! for nothing, it fails, and `InlineSelfWakes` can go.

use hyper_util::rt::TokioIo;
use robotd_http::self_wake::InlineSelfWakes;
use std::future::Future;
use std::pin::Pin;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::task::{Context, Poll, Wake, Waker};
use tokio::io::{AsyncReadExt, AsyncWriteExt};

/// Counts the wake-ups its future gives itself while being polled, and passes every wake-up on.
struct CountSelfWakes<F> {
    future: Pin<Box<F>>,
    shared: Arc<Counter>,
}

#[derive(Default)]
struct Counter {
    polling: AtomicBool,
    self_wakes: AtomicUsize,
    task: Mutex<Option<Waker>>,
}

impl Wake for Counter {
    fn wake(self: Arc<Self>) {
        self.wake_by_ref();
    }
    fn wake_by_ref(self: &Arc<Self>) {
        if self.polling.load(Ordering::SeqCst) {
            self.self_wakes.fetch_add(1, Ordering::SeqCst);
        }
        if let Some(task) = self.task.lock().unwrap().as_ref() {
            task.wake_by_ref();
        }
    }
}

impl<F: Future> Future for CountSelfWakes<F> {
    type Output = F::Output;
    fn poll(self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<F::Output> {
        let this = self.get_mut();
        *this.shared.task.lock().unwrap() = Some(cx.waker().clone());
        let waker = Waker::from(this.shared.clone());
        this.shared.polling.store(true, Ordering::SeqCst);
        let polled = this.future.as_mut().poll(&mut Context::from_waker(&waker));
        this.shared.polling.store(false, Ordering::SeqCst);
        polled
    }
}

/// Serves 3 POSTs with a body on one connection; returns the connection's self-wake-ups.
async fn self_wakes_serving_posts(inline: bool) -> usize {
    let (mut client, server) = tokio::io::duplex(64 * 1024);
    let service = hyper::service::service_fn(
        |request: hyper::Request<hyper::body::Incoming>| async move {
            let body = axum::body::to_bytes(axum::body::Body::new(request.into_body()), 1 << 20)
                .await
                .expect("the body arrives");
            Ok::<_, std::convert::Infallible>(hyper::Response::new(axum::body::Body::from(body)))
        },
    );
    let connection =
        hyper::server::conn::http1::Builder::new().serve_connection(TokioIo::new(server), service);
    let counter = Arc::new(Counter::default());
    let served: Pin<Box<dyn Future<Output = _> + Send>> = if inline {
        Box::pin(InlineSelfWakes::new(connection))
    } else {
        Box::pin(connection)
    };
    let task = tokio::spawn(CountSelfWakes {
        future: Box::pin(served),
        shared: counter.clone(),
    });
    for i in 0..3 {
        let body = format!("{{\"call\":{i}}}");
        let request = format!(
            "POST /mcp HTTP/1.1\r\nhost: localhost\r\ncontent-type: application/json\r\n\
             content-length: {}\r\n\r\n{body}",
            body.len()
        );
        client.write_all(request.as_bytes()).await.unwrap();
        let mut answer = Vec::new();
        while !answer.ends_with(body.as_bytes()) {
            let mut chunk = [0u8; 1024];
            let n = client.read(&mut chunk).await.unwrap();
            assert!(n > 0, "the connection closed before its answer");
            answer.extend_from_slice(&chunk[..n]);
        }
        assert!(
            answer.starts_with(b"HTTP/1.1 200 OK"),
            "{}",
            String::from_utf8_lossy(&answer)
        );
    }
    drop(client);
    task.await.unwrap().expect("the connection ends cleanly");
    counter.self_wakes.load(Ordering::SeqCst)
}

#[tokio::test(flavor = "current_thread")]
async fn hyper_wakes_a_connection_once_per_request_body() {
    assert_eq!(self_wakes_serving_posts(false).await, 3);
}

#[tokio::test(flavor = "current_thread")]
async fn served_inline_the_wake_ups_stay_inside_the_poll() {
    assert_eq!(self_wakes_serving_posts(true).await, 0);
}
