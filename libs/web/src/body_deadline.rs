//! A deadline for a request's body: the whole body must arrive within the connection's idle
//! timeout after its head.
//!
//! hyper times a request's head ([`crate::connections`]), not its body, so a client that sends
//! a complete head announcing 100 bytes and then one byte a minute would hold its connection
//! (and a handler waiting for the body) forever. [`DeadlineBody`] fails such a body with an
//! error that says why; the handler answers it as a bad request and the connection closes.
//!
//! The clock starts at the first read that finds the body not yet there, so a body that has
//! already arrived (almost every request) costs no timer.

use axum::body::Body;
use http_body::Frame;
use std::future::Future;
use std::pin::Pin;
use std::task::{Context, Poll};
use std::time::Duration;
use tokio::time::{Instant, Sleep};

/// A request body that fails once `limit` has passed since the first read had to wait.
pub struct DeadlineBody {
    inner: Body,
    limit: Duration,
    deadline: Option<Pin<Box<Sleep>>>,
}

impl DeadlineBody {
    /// Wraps `inner`, allowing it `limit` to arrive.
    pub fn new(inner: Body, limit: Duration) -> Self {
        Self {
            inner,
            limit,
            deadline: None,
        }
    }
}

/// The error of a body that did not arrive in time.
#[derive(Debug, thiserror::Error)]
#[error(
    "the request body did not arrive within {0} s of its head (http.idle_timeout_s); \
     send the whole body at once"
)]
pub struct BodyTooSlow(u64);

/// Whether `error` (or one of its causes) is a body that did not arrive in time: the answer
/// is then `408 Request Timeout`, not a complaint about the body's size or content.
pub fn is_too_slow(error: &(dyn std::error::Error + 'static)) -> bool {
    let mut cause = Some(error);
    while let Some(error) = cause {
        if error.is::<BodyTooSlow>() {
            return true;
        }
        cause = error.source();
    }
    false
}

impl http_body::Body for DeadlineBody {
    type Data = bytes::Bytes;
    type Error = axum::Error;

    fn poll_frame(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
    ) -> Poll<Option<Result<Frame<Self::Data>, Self::Error>>> {
        let this = &mut *self;
        if let Poll::Ready(frame) = Pin::new(&mut this.inner).poll_frame(cx) {
            return Poll::Ready(frame);
        }
        let limit = this.limit;
        let deadline = this
            .deadline
            .get_or_insert_with(|| Box::pin(tokio::time::sleep_until(Instant::now() + limit)));
        match deadline.as_mut().poll(cx) {
            Poll::Ready(()) => {
                Poll::Ready(Some(Err(axum::Error::new(BodyTooSlow(limit.as_secs())))))
            }
            Poll::Pending => Poll::Pending,
        }
    }

    fn is_end_stream(&self) -> bool {
        self.inner.is_end_stream()
    }

    fn size_hint(&self) -> http_body::SizeHint {
        self.inner.size_hint()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use http_body::Body as _;

    fn poll_once(
        body: &mut DeadlineBody,
    ) -> Poll<Option<Result<Frame<bytes::Bytes>, axum::Error>>> {
        let waker = std::task::Waker::noop();
        let mut cx = Context::from_waker(waker);
        Pin::new(body).poll_frame(&mut cx)
    }

    #[tokio::test(start_paused = true)]
    async fn a_body_that_has_arrived_is_read_and_a_trickling_one_fails_at_the_deadline() {
        let mut whole = DeadlineBody::new(Body::from("{}"), Duration::from_secs(2));
        match poll_once(&mut whole) {
            Poll::Ready(Some(Ok(frame))) => assert_eq!(frame.into_data().unwrap(), "{}"),
            other => panic!("expected the body, got {other:?}"),
        }
        assert!(
            whole.deadline.is_none(),
            "no timer for a body already there"
        );

        // A body whose sender never sends the rest.
        let stream = futures::stream::pending::<Result<bytes::Bytes, std::io::Error>>();
        let mut slow = DeadlineBody::new(Body::from_stream(stream), Duration::from_secs(2));
        assert!(poll_once(&mut slow).is_pending());
        tokio::time::sleep(Duration::from_millis(1900)).await;
        assert!(poll_once(&mut slow).is_pending(), "not before the deadline");
        tokio::time::sleep(Duration::from_millis(200)).await;
        match poll_once(&mut slow) {
            Poll::Ready(Some(Err(error))) if is_too_slow(&error) => {
                assert!(error.to_string().contains("within 2 s"), "{error}")
            }
            other => panic!("expected the deadline error, got {other:?}"),
        }
    }
}
