//! `tools/call` run without rmcp's session pipeline, on streamable HTTP and legacy SSE.
//!
//! rmcp hands every request of a streamable-HTTP session to the session's worker task, which
//! passes it to the service loop, which runs it on a task of its own and sends the answer back
//! through the worker onto an event stream; a legacy-SSE request crosses the service loop the
//! same way. On a two-CPU machine those hand-overs cost a cheap tool call about 100 µs
//! (BENCHMARKS.md). The common case is run here instead: a `tools/call` in an open, initialized
//! session, whose `_meta` holds at most a progress token, from a client of a protocol revision
//! whose requests rmcp checks no further than their session. The call runs through the same
//! [`McpService::serve_call`] as rmcp's handler (same registry call, call log, trace id,
//! cancellation). On streamable HTTP it runs on the request's own task until it ends, reports
//! progress or has run [`STREAM_AFTER`], then on a task of its own; on legacy SSE on the task
//! that writes its answer onto the session's stream until it reports progress
//! ([`run_onto_stream`]). Either way a call whose client went away is cancelled, never cut
//! short ([`super::call_run`]).
//!
//! How the answer goes out: on legacy SSE, onto the session's event stream as always
//! (`super::sse`). On streamable HTTP, a call that ends within [`STREAM_AFTER`] without
//! reporting progress (every cheap tool) is answered as one `application/json` body; otherwise
//! the answer is an event stream with keep-alives: the `notifications/progress` events (when
//! the client gave a progress token), then the result. The MCP spec lets a server answer a
//! request either way.
//!
//! What the direct path keeps of rmcp's pipeline, each in its own place:
//! - **the session order**: only a session whose gate ([`crate::gate`]) saw
//!   `notifications/initialized` and that rmcp still holds takes direct calls
//!   ([`ClosingSessions::takes_direct_calls`]);
//! - **the idle timeout**: a direct call counts as activity of its session like any request
//!   (the `/mcp` checks and `/messages/` tell [`super::places`]);
//! - **cancellation**: a `notifications/cancelled` naming the call, the session closing and
//!   the client's connection dropping each cancel it ([`cancel_named`], [`CallScopes`]); a
//!   call dropped by its request's task goes on on a task of its own, so a dropped connection
//!   stops the motion and the call still ends and is logged. A call cancelled before it
//!   started (it waited behind another client's motion) gets no answer, as the MCP spec asks
//!   of a cancelled request: on streamable HTTP its event stream ends without one, on legacy
//!   SSE nothing goes onto the stream ([`super::call_run`]);
//! - **rmcp's checks**: a request with anything rmcp would look at more closely (an `Accept`
//!   with weights, a protocol-version header of the 2026-07-28 revision or unknown, `_meta`
//!   beyond a progress token, input responses) is left to rmcp, which answers it as before.
//!
//! `mcp.direct_tool_calls = false` sends every call through rmcp.

use super::call_run::{prepare, Outgoing, Started};
use super::sse_transport::queue;
use crate::service::McpService;
use crate::sessions::{CallScopes, ClosingSessions};
use axum::http::{header, HeaderMap, StatusCode};
use axum::response::sse::{Event, KeepAlive, Sse};
use axum::response::{IntoResponse, Response};
use rmcp::model::{
    CallToolRequestParams, ClientJsonRpcMessage, ClientNotification, ClientRequest, GetMeta,
    JsonRpcMessage, ProgressToken, ProtocolVersion, RequestId, ServerJsonRpcMessage,
};
use std::convert::Infallible;
use std::sync::Arc;
use std::time::Duration;

/// A call still running after this is answered as an event stream, whose keep-alives hold
/// the client's read timeout off (a motion can take minutes; an HTTP client waiting for a
/// JSON body may give up after 30 s).
const STREAM_AFTER: Duration = Duration::from_millis(500);

/// Keep-alive comment interval of an answer's event stream (rmcp's default).
const KEEP_ALIVE: Duration = Duration::from_secs(15);

/// What answers direct calls.
#[derive(Clone)]
pub(super) struct DirectCalls {
    pub(super) service: McpService,
    pub(super) sessions: Arc<ClosingSessions>,
    pub(super) scopes: Arc<CallScopes>,
}

/// A `tools/call` that may be run directly, as far as its headers and body tell.
pub(super) struct DirectCall {
    pub(super) id: RequestId,
    pub(super) params: CallToolRequestParams,
    /// The client's progress token: its skill's steps become `notifications/progress`.
    pub(super) progress: Option<ProgressToken>,
}

impl DirectCall {
    /// The call in `message`, when nothing in it or in `headers` needs rmcp's own handling.
    pub(super) fn of(headers: &HeaderMap, message: ClientJsonRpcMessage) -> Option<Self> {
        if !plain_headers(headers) {
            return None;
        }
        Self::in_message(message)
    }

    /// The call in `message` (legacy SSE: rmcp checks no headers there), when its `_meta`
    /// holds at most a progress token.
    pub(super) fn in_message(message: ClientJsonRpcMessage) -> Option<Self> {
        let JsonRpcMessage::Request(request) = message else {
            return None;
        };
        let request_meta = request.request.get_meta().clone();
        let ClientRequest::CallToolRequest(call) = request.request else {
            return None;
        };
        let params = call.params;
        let only_progress =
            |meta: &rmcp::model::RequestMetaObject| meta.keys().all(|key| key == "progressToken");
        let plain = only_progress(&request_meta)
            && params.meta.as_ref().is_none_or(only_progress)
            && params.input_responses.is_none()
            && params.request_state.is_none();
        let progress = request_meta.get_progress_token().or_else(|| {
            params
                .meta
                .as_ref()
                .and_then(|meta| meta.get_progress_token())
        });
        plain.then_some(Self {
            id: request.id,
            params,
            progress,
        })
    }
}

/// Whether rmcp would check nothing in `headers` beyond what the direct path does: both
/// media types accepted without weights, a JSON body, and no protocol version, or a known
/// one older than the revision whose requests carry further headers.
fn plain_headers(headers: &HeaderMap) -> bool {
    let accept = headers
        .get_all(header::ACCEPT)
        .iter()
        .filter_map(|v| v.to_str().ok())
        .collect::<Vec<_>>()
        .join(",");
    let accepts = |essence: &str| {
        accept
            .split(',')
            .any(|part| part.trim().eq_ignore_ascii_case(essence))
    };
    if !accepts("application/json") || !accepts("text/event-stream") {
        return false;
    }
    let json_body = headers
        .get(header::CONTENT_TYPE)
        .and_then(|v| v.to_str().ok())
        .is_some_and(|v| {
            let essence = v.split_once(';').map_or(v, |(essence, _)| essence);
            essence.trim().eq_ignore_ascii_case("application/json")
        });
    let version_ok = match headers.get("mcp-protocol-version") {
        None => true,
        Some(value) => value.to_str().is_ok_and(|version| {
            version < ProtocolVersion::STANDARD_HEADERS.as_str()
                && ProtocolVersion::KNOWN_VERSIONS
                    .iter()
                    .any(|known| known.as_str() == version)
        }),
    };
    json_body && version_ok
}

/// A `notifications/cancelled` in `session` cancels the call it names, whichever path runs
/// it (rmcp cancels its own calls too; a call sees the first of the two). A call not seen yet
/// (its request is still on its way) starts cancelled ([`CallScopes::cancel_request`]).
pub(super) fn cancel_named(scopes: &CallScopes, session: &str, message: &ClientJsonRpcMessage) {
    if let JsonRpcMessage::Notification(n) = message {
        if let ClientNotification::CancelledNotification(cancelled) = &n.notification {
            let Some(request) = cancelled
                .params
                .request_id
                .as_ref()
                .map(|id| id.to_string())
            else {
                return;
            };
            if scopes.cancel_request(session, &request) {
                tracing::info!(%session, %request, "MCP client cancelled its call");
            }
        }
    }
}

/// Runs `call` of `session` on `service` for a legacy-SSE session (on a task spawned for it)
/// and writes its progress and answer onto the session's stream `to_client`. Runs the call on
/// this task until it reports progress, then on a task of its own: a progress event waiting
/// for a slow reader does not hold the call up. A stream that is gone (the session closed)
/// drops the call's scope unanswered, which cancels the call.
pub(super) async fn run_onto_stream(
    service: &McpService,
    scopes: &Arc<CallScopes>,
    session: &str,
    call: DirectCall,
    to_client: super::sse::SharedSender<ServerJsonRpcMessage>,
) {
    let (mut run, started) = prepare(service, scopes, session, call);
    let Started {
        mut incoming,
        mut scope,
    } = started;
    let mut next = tokio::select! {
        biased;
        answer = std::future::poll_fn(|cx| run.poll_here(cx)) => match incoming.try_recv() {
            // It reported progress as it ended: the progress goes first, then the answer.
            Ok(progress) => {
                run.queue_answer(answer);
                progress
            }
            Err(_) => Outgoing::Answer(answer),
        },
        Some(progress) = incoming.recv() => progress,
    };
    // Handed over, when it still runs.
    drop(run);
    loop {
        // A call cancelled before it started: nothing goes onto the stream.
        let Some(message) = scope.pass_on(next) else {
            return;
        };
        let written = queue(&mut *to_client.lock().await, message).await;
        if written.is_err() || scope.answered() {
            return;
        }
        next = match incoming.recv().await {
            Some(outgoing) => outgoing,
            None => return,
        };
    }
}

impl DirectCalls {
    /// Runs `call` in `session`; answers it as one JSON body, or as an event stream once the
    /// call reports progress or runs longer than [`STREAM_AFTER`].
    ///
    /// The call runs on this request's task until then: a cheap call is answered with no
    /// hand-over between tasks (on two CPUs each costs a wake-up of the other one). From the
    /// first progress or [`STREAM_AFTER`] on, it goes on on a task of its own.
    pub(super) async fn answer(&self, session: &str, call: DirectCall) -> Response {
        let (mut run, started) = prepare(&self.service, &self.scopes, session, call);
        let Started {
            mut incoming,
            mut scope,
        } = started;
        let stream_after = tokio::time::sleep(STREAM_AFTER);
        let first = tokio::select! {
            biased;
            answer = std::future::poll_fn(|cx| run.poll_here(cx)) => match incoming.try_recv() {
                Err(_) => {
                    scope.mark_answered();
                    return match answer {
                        Some(answer) => json_body(&answer),
                        // Cancelled before it started: an event stream without an answer.
                        None => Sse::new(futures::stream::empty::<Result<Event, Infallible>>())
                            .into_response(),
                    };
                }
                // It reported progress as it ended: an event stream, the progress first.
                Ok(progress) => {
                    run.queue_answer(answer);
                    Some(progress)
                }
            },
            Some(progress) = incoming.recv() => Some(progress),
            () = stream_after => None,
        };
        // Handed over: the call goes on on a task of its own.
        drop(run);
        // From here the stream owns the scope: dropped unanswered, it cancels the call.
        let events = futures::stream::unfold(
            (first, incoming, scope),
            |(first, mut incoming, mut scope)| async move {
                if scope.answered() {
                    return None;
                }
                let message = match first {
                    Some(first) => first,
                    None => incoming.recv().await?,
                };
                // None for a call cancelled before it started: the stream ends unanswered.
                let message = scope.pass_on(message)?;
                Some((event(&message), (None, incoming, scope)))
            },
        );
        Sse::new(events)
            .keep_alive(KeepAlive::new().interval(KEEP_ALIVE))
            .into_response()
    }
}

/// `message` as the whole body of the answer.
fn json_body(message: &ServerJsonRpcMessage) -> Response {
    match serde_json::to_vec(message) {
        Ok(body) => (
            StatusCode::OK,
            [(header::CONTENT_TYPE, "application/json")],
            body,
        )
            .into_response(),
        Err(error) => (
            StatusCode::INTERNAL_SERVER_ERROR,
            format!("Internal Server Error: the answer could not be written as JSON: {error}"),
        )
            .into_response(),
    }
}

/// `message` as one event of an answer's event stream.
fn event(message: &ServerJsonRpcMessage) -> Result<Event, Infallible> {
    let data = serde_json::to_string(message).unwrap_or_else(|error| {
        tracing::error!(%error, "an MCP message could not be written as JSON");
        String::from("{}")
    });
    Ok(Event::default().event("message").data(data))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn headers(pairs: &[(&'static str, &'static str)]) -> HeaderMap {
        let mut map = HeaderMap::new();
        for (name, value) in pairs {
            map.append(*name, value.parse().unwrap());
        }
        map
    }

    fn message(value: serde_json::Value) -> ClientJsonRpcMessage {
        serde_json::from_value(value).unwrap()
    }

    const PLAIN: &[(&str, &str)] = &[
        ("accept", "application/json, text/event-stream"),
        ("content-type", "application/json"),
        ("mcp-protocol-version", "2025-06-18"),
    ];

    fn call() -> serde_json::Value {
        serde_json::json!({"jsonrpc": "2.0", "id": 7, "method": "tools/call",
            "params": {"name": "get_workspace_coordinate_from_point",
                       "arguments": {"workspace_id": "niryo_ws", "point": "center point"}}})
    }

    #[test]
    fn a_plain_tool_call_is_taken() {
        let taken = DirectCall::of(&headers(PLAIN), message(call())).expect("taken");
        assert_eq!(taken.id.to_string(), "7");
        assert_eq!(taken.params.name, "get_workspace_coordinate_from_point");
        assert!(taken.progress.is_none());
        let mut no_version = headers(PLAIN);
        no_version.remove("mcp-protocol-version");
        assert!(DirectCall::of(&no_version, message(call())).is_some());
        let mut progress = call();
        progress["params"]["_meta"] = serde_json::json!({"progressToken": "p1"});
        let taken = DirectCall::of(&headers(PLAIN), message(progress)).expect("taken");
        assert_eq!(
            serde_json::to_value(taken.progress.expect("a token")).unwrap(),
            serde_json::json!("p1")
        );
    }

    #[test]
    fn anything_rmcp_checks_further_is_left_to_it() {
        let with = |name: &'static str, value: &'static str| {
            let mut map = headers(PLAIN);
            map.insert(name, value.parse().unwrap());
            DirectCall::of(&map, message(call())).is_some()
        };
        assert!(!with("accept", "application/json"), "no event stream");
        assert!(
            !with("accept", "application/json, text/event-stream;q=0"),
            "weights"
        );
        assert!(!with("content-type", "text/plain"));
        assert!(!with("mcp-protocol-version", "2026-07-28"), "newer rules");
        assert!(!with("mcp-protocol-version", "1999-01-01"), "unknown");
        let mut traced = call();
        traced["params"]["_meta"] = serde_json::json!({"progressToken": 1, "traceparent": "00-x"});
        assert!(DirectCall::of(&headers(PLAIN), message(traced)).is_none());
        let ping = serde_json::json!({"jsonrpc": "2.0", "id": 1, "method": "ping"});
        assert!(DirectCall::of(&headers(PLAIN), message(ping)).is_none());
        let list = serde_json::json!({"jsonrpc": "2.0", "id": 1, "method": "tools/list"});
        assert!(DirectCall::of(&headers(PLAIN), message(list)).is_none());
    }

    #[test]
    fn a_cancellation_reaches_the_call_it_names_only() {
        let scopes = CallScopes::default();
        let seven = scopes.request("s1", "7");
        let eight = scopes.request("s1", "8");
        let other_session = scopes.request("s2", "7");
        let cancelled = serde_json::json!({"jsonrpc": "2.0", "method": "notifications/cancelled",
            "params": {"requestId": 7, "reason": "user"}});
        cancel_named(&scopes, "s1", &message(cancelled));
        assert!(seven.is_cancelled());
        assert!(!eight.is_cancelled());
        assert!(!other_session.is_cancelled());
    }
}
