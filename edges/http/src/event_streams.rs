//! Event streams end when the service stops.
//!
//! An SSE response (`text/event-stream`: an MCP SSE session, the dashboard's live feeds) never
//! finishes on its own. A graceful shutdown waits for the responses in progress, so each client
//! still connected would hold `robotd serve` (and `systemctl stop`) for the whole grace period.
//! [`ends_at_shutdown`] wraps such a response's body so that it ends cleanly, with the last
//! chunk of a chunked body, as soon as shutdown is asked; every other response is left to
//! finish as before.

use axum::body::Body;
use axum::http::header::CONTENT_TYPE;
use axum::response::Response;
use bytes::Bytes;
use http_body::Frame;
use std::future::Future;
use std::pin::Pin;
use std::task::{Context, Poll};
use tokio::sync::watch;

/// `response`, whose body ends when `stopping` turns true if it is an event stream.
pub(crate) fn ends_at_shutdown(response: Response, stopping: watch::Receiver<bool>) -> Response {
    let is_event_stream = response
        .headers()
        .get(CONTENT_TYPE)
        .and_then(|value| value.to_str().ok())
        .is_some_and(|value| value.starts_with("text/event-stream"));
    if !is_event_stream {
        return response;
    }
    response.map(|body| {
        Body::new(UntilShutdown {
            body,
            stopped: Some(Box::pin(crate::connections::stopped_owned(stopping))),
        })
    })
}

/// A body that ends early when `stopped` completes.
struct UntilShutdown {
    body: Body,
    /// `None` once shutdown was seen (a completed future is not polled again).
    stopped: Option<Pin<Box<dyn Future<Output = ()> + Send>>>,
}

impl http_body::Body for UntilShutdown {
    type Data = Bytes;
    type Error = axum::Error;

    fn poll_frame(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
    ) -> Poll<Option<Result<Frame<Bytes>, axum::Error>>> {
        match self.stopped.as_mut() {
            None => return Poll::Ready(None),
            Some(stopped) => {
                if stopped.as_mut().poll(cx).is_ready() {
                    self.stopped = None;
                    return Poll::Ready(None);
                }
            }
        }
        Pin::new(&mut self.body).poll_frame(cx)
    }

    fn is_end_stream(&self) -> bool {
        self.stopped.is_none() || self.body.is_end_stream()
    }
}

#[cfg(test)]
mod tests {
    use crate::connections::{serve, ConnectionLimits, SHUTDOWN_GRACE};
    use axum::response::sse::{Event, Sse};
    use axum::routing::get;
    use axum::Router;
    use std::convert::Infallible;
    use std::time::{Duration, Instant};
    use tokio::io::{AsyncReadExt, AsyncWriteExt};
    use tokio::net::{TcpListener, TcpStream};
    use tokio::sync::oneshot;

    /// Reads from `stream` until `wanted` has arrived; what was read.
    async fn read_until(stream: &mut TcpStream, wanted: &str) -> String {
        let mut seen = Vec::new();
        let mut buffer = [0u8; 1024];
        while !String::from_utf8_lossy(&seen).contains(wanted) {
            let n = tokio::time::timeout(Duration::from_secs(5), stream.read(&mut buffer))
                .await
                .expect("the server went silent")
                .unwrap();
            assert!(
                n > 0,
                "closed before {wanted:?}: {}",
                String::from_utf8_lossy(&seen)
            );
            seen.extend_from_slice(&buffer[..n]);
        }
        String::from_utf8_lossy(&seen).into_owned()
    }

    #[tokio::test]
    async fn an_open_event_stream_ends_at_shutdown_and_a_slow_answer_still_finishes() {
        let slow_started = std::sync::Arc::new(tokio::sync::Notify::new());
        let in_handler = slow_started.clone();
        let app = Router::new()
            .route(
                "/events",
                get(|| async {
                    let first = futures::stream::once(async {
                        Ok::<_, Infallible>(Event::default().data("hello"))
                    });
                    Sse::new(futures::StreamExt::chain(first, futures::stream::pending()))
                }),
            )
            .route(
                "/slow",
                get(move || async move {
                    in_handler.notify_one();
                    tokio::time::sleep(Duration::from_millis(300)).await;
                    "done"
                }),
            );
        let listener = TcpListener::bind("127.0.0.1:0").await.unwrap();
        let address = listener.local_addr().unwrap();
        let (stop, stop_asked) = oneshot::channel::<()>();
        let server = tokio::spawn(serve(
            listener,
            app,
            ConnectionLimits::default(),
            async move {
                let _ = stop_asked.await;
            },
        ));

        let mut events = TcpStream::connect(address).await.unwrap();
        events
            .write_all(b"GET /events HTTP/1.1\r\nhost: x\r\n\r\n")
            .await
            .unwrap();
        read_until(&mut events, "data: hello").await;
        let mut slow = TcpStream::connect(address).await.unwrap();
        slow.write_all(b"GET /slow HTTP/1.1\r\nhost: x\r\n\r\n")
            .await
            .unwrap();
        slow_started.notified().await;

        let asked = Instant::now();
        stop.send(()).unwrap();
        read_until(&mut events, "0\r\n\r\n").await;
        let slow_answer = read_until(&mut slow, "done").await;
        assert!(slow_answer.starts_with("HTTP/1.1 200"), "{slow_answer}");
        server.await.unwrap().unwrap();
        let took = asked.elapsed();
        assert!(
            took < SHUTDOWN_GRACE / 2,
            "shutdown took {took:?}: the event stream held it (grace {SHUTDOWN_GRACE:?})"
        );
    }
}
