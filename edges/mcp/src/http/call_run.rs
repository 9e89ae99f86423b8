//! How a direct tool call runs: on its caller's task until handed over, never cut short.
//!
//! [`prepare`] turns a [`DirectCall`] into a [`CallRun`] (the call's future, which yields its
//! JSON-RPC response) and what its caller reads: the progress and answer messages
//! ([`Outgoing`]) and the [`RequestScope`] that cancels the call when the caller goes away.
//! The caller polls the run on its own task ([`CallRun::poll_here`]); dropping the run hands
//! it over to a task of its own, which finishes it and sends its answer, so a call whose
//! client went away still ends (cancelled, its motion stopped) and is logged. A call cancelled
//! before it started has no answer (`None`): the MCP spec asks that a cancelled request get
//! none, and this one did nothing to report.

use super::direct_call::DirectCall;
use crate::service::{progress_param, CallContext, McpService};
use crate::sessions::CallScopes;
use futures::FutureExt;
use rmcp::model::{
    CallToolResult, ErrorData, ProgressNotification, RequestId, ServerJsonRpcMessage,
    ServerNotification, ServerResult,
};
use robotd_tools::Progress;
use std::any::Any;
use std::future::Future;
use std::panic::AssertUnwindSafe;
use std::pin::Pin;
use std::sync::Arc;
use std::task::{Context, Poll};
use tokio::sync::mpsc;
use tokio_util::sync::CancellationToken;

/// What a direct call sends its answer with.
pub(super) enum Outgoing {
    /// A `notifications/progress` for the client.
    Progress(ServerJsonRpcMessage),
    /// The call's response (`None`: cancelled before it started, not answered); nothing
    /// follows.
    Answer(Option<ServerJsonRpcMessage>),
}

/// A direct call on its way: its messages arrive on `incoming`, and `scope` cancels it when
/// dropped before the answer was passed on.
pub(super) struct Started {
    pub(super) incoming: mpsc::UnboundedReceiver<Outgoing>,
    pub(super) scope: RequestScope,
}

/// The future of a direct call that yields its JSON-RPC response (`None`: not to be answered).
type CallFuture = Pin<Box<dyn Future<Output = Option<ServerJsonRpcMessage>> + Send>>;

/// A direct call that runs on its caller's task until it is handed over. Dropped unfinished
/// (handed over, or its caller went away), it goes on on a task of its own and sends its
/// answer to `answers`, so a call is never cut: a caller that went away has cancelled it
/// (through its [`RequestScope`]) by then, and the call still ends, stops its motion and is
/// logged.
pub(super) struct CallRun {
    future: Option<CallFuture>,
    answers: mpsc::UnboundedSender<Outgoing>,
}

impl CallRun {
    /// Runs the call on the caller's task; `Ready` with its response once it ended.
    pub(super) fn poll_here(&mut self, cx: &mut Context<'_>) -> Poll<Option<ServerJsonRpcMessage>> {
        let Some(future) = self.future.as_mut() else {
            return Poll::Pending;
        };
        let answer = std::task::ready!(future.as_mut().poll(cx));
        self.future = None;
        Poll::Ready(answer)
    }
}

impl CallRun {
    /// Sends the answer of a call that ended here after the progress it reported, so the
    /// caller reads them in order from its messages.
    pub(super) fn queue_answer(&self, answer: Option<ServerJsonRpcMessage>) {
        let _ = self.answers.send(Outgoing::Answer(answer));
    }
}

impl Drop for CallRun {
    fn drop(&mut self) {
        let Some(future) = self.future.take() else {
            return;
        };
        let answers = self.answers.clone();
        match tokio::runtime::Handle::try_current() {
            Ok(runtime) => {
                runtime.spawn(async move {
                    let _ = answers.send(Outgoing::Answer(future.await));
                });
            }
            // Only at shutdown, with no runtime left to run it on.
            Err(_) => tracing::warn!("a direct MCP tool call was dropped with its runtime"),
        }
    }
}

/// Prepares `call` of `session` on `service` (rmcp's handler is not involved) without running
/// it: the caller polls it, or drops it to run it on a task of its own.
pub(super) fn prepare(
    service: &McpService,
    scopes: &Arc<CallScopes>,
    session: &str,
    call: DirectCall,
) -> (CallRun, Started) {
    let DirectCall {
        id,
        params,
        progress,
    } = call;
    let request = id.to_string();
    // Looked up by the call as "its connection": dropping the scope (the client went away)
    // or a `notifications/cancelled` fires it.
    scopes.request(session, &request);
    let scope = RequestScope {
        scopes: scopes.clone(),
        session: session.to_owned(),
        request: request.clone(),
        answered: false,
    };
    let (outgoing, incoming) = mpsc::unbounded_channel();
    let report = progress.map(|token| {
        let outgoing = outgoing.clone();
        Box::new(move |step: Progress| {
            let notification = ServerNotification::ProgressNotification(ProgressNotification::new(
                progress_param(&token, step),
            ));
            let message = ServerJsonRpcMessage::notification(notification);
            // The receiver is gone only when the client went away; the call is cancelled.
            let _ = outgoing.send(Outgoing::Progress(message));
        }) as Box<dyn Fn(Progress) + Send + Sync>
    });
    let context = CallContext {
        session: Some(session.to_owned()),
        request_id: request,
        by_client: CancellationToken::new(),
        progress: report,
    };
    let service = service.clone();
    let future: CallFuture = Box::pin(async move {
        let outcome = AssertUnwindSafe(service.serve_call(params, context))
            .catch_unwind()
            .await;
        match outcome {
            Ok(served) if served.cancelled_before_start => None,
            Ok(served) => Some(response_to(id, Ok(served.result))),
            Err(panic) => Some(response_to(id, Err(panic))),
        }
    });
    let run = CallRun {
        future: Some(future),
        answers: outgoing,
    };
    (run, Started { incoming, scope })
}

/// The JSON-RPC response to request `id` from the call's outcome.
fn response_to(
    id: RequestId,
    outcome: Result<Result<CallToolResult, ErrorData>, Box<dyn Any + Send>>,
) -> ServerJsonRpcMessage {
    match outcome {
        Ok(Ok(result)) => {
            let mut result = ServerResult::CallToolResult(result);
            // A session opened with `initialize` is on a revision before 2026-07-28: rmcp
            // gives such peers this shape.
            result.strip_result_type_for_legacy_peer();
            result.strip_non_object_output_for_legacy_peer();
            ServerJsonRpcMessage::response(result, id)
        }
        Ok(Err(error)) => ServerJsonRpcMessage::error(error, Some(id)),
        Err(panic) => {
            let what = panic
                .downcast_ref::<&str>()
                .map(|s| (*s).to_owned())
                .or_else(|| panic.downcast_ref::<String>().cloned())
                .unwrap_or_default();
            tracing::error!(panic = %what, "MCP tool call panicked");
            let error = ErrorData::internal_error(
                format!("the tool call failed inside robotd: {what}"),
                None,
            );
            ServerJsonRpcMessage::error(error, Some(id))
        }
    }
}

/// The request's cancellation token while its answer is pending: dropped unanswered (the
/// client's connection went away), it cancels the call; either way it is forgotten.
pub(super) struct RequestScope {
    scopes: Arc<CallScopes>,
    session: String,
    request: String,
    answered: bool,
}

impl RequestScope {
    /// The message to send the client for `outgoing`; an answer marks the call answered
    /// (`None` for a call cancelled before it started: nothing to send, and nothing follows).
    pub(super) fn pass_on(&mut self, outgoing: Outgoing) -> Option<ServerJsonRpcMessage> {
        match outgoing {
            Outgoing::Progress(message) => Some(message),
            Outgoing::Answer(message) => {
                self.answered = true;
                message
            }
        }
    }

    /// The answer was passed on (the caller wrote it): dropping the scope no longer cancels.
    pub(super) fn mark_answered(&mut self) {
        self.answered = true;
    }

    /// Whether the answer was passed on.
    pub(super) fn answered(&self) -> bool {
        self.answered
    }
}

impl Drop for RequestScope {
    fn drop(&mut self) {
        if !self.answered {
            tracing::info!(session = %self.session, request = %self.request, "MCP client dropped the connection before the answer: cancelling the call");
        }
        self.scopes
            .end_request(&self.session, &self.request, !self.answered);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rmcp::model::ErrorData;

    #[tokio::test]
    async fn a_call_dropped_unfinished_goes_on_to_its_answer() {
        let (release, released) = tokio::sync::oneshot::channel::<()>();
        let (answers, mut incoming) = mpsc::unbounded_channel();
        let mut run = CallRun {
            future: Some(Box::pin(async move {
                let _ = released.await;
                let error = ErrorData::internal_error("the end", None);
                Some(ServerJsonRpcMessage::error(
                    error,
                    Some(RequestId::Number(3)),
                ))
            })),
            answers,
        };
        let polled = std::future::poll_fn(|cx| Poll::Ready(run.poll_here(cx))).await;
        assert!(polled.is_pending(), "the call cannot have ended yet");
        drop(run);
        release.send(()).expect("the call still runs");
        match incoming.recv().await {
            Some(Outgoing::Answer(Some(answer))) => {
                assert!(serde_json::to_string(&answer).unwrap().contains("the end"))
            }
            _ => panic!("the dropped call did not answer"),
        }
    }
}
