//! Checks around rmcp's streamable-HTTP service (`/mcp`).
//!
//! rmcp answers a body it cannot read with 415 and knows nothing of who opened a session. In
//! front of it, each POST body is read once (within the size limit) and:
//!
//! - a body that is not JSON is answered 400 / `-32700`, one whose JSON-RPC envelope is wrong
//!   400 / `-32600` saying what is wrong, with the id as sent, and a request to an MCP method
//!   with params that do not fit it `-32602` ([`super::envelope`]);
//! - a request naming another client's session, or one that is not open, is answered 404 —
//!   `DELETE` included;
//! - an `initialize` that would open a session takes a place first ([`super::places`]): 503
//!   with `Retry-After` when there is none; the session is bound to its client once rmcp names
//!   it in `Mcp-Session-Id`, and closed when its place expires or its client gives it up;
//! - every request counts as activity of its session, a request other than `initialize` as a
//!   call (a session without one is closed after `mcp.unused_session_timeout_s`);
//! - a `tools/call` in an initialized session is run here, without rmcp's session pipeline
//!   ([`super::direct_call`]), and a `notifications/cancelled` cancels the call it names on
//!   either path.

use super::direct_call::{cancel_named, DirectCall, DirectCalls};
use super::envelope::BadMessage;
use super::places::{SessionPlaces, Transport};
use crate::owner::SessionOwner;
use crate::sessions::{CallScopes, ClosingSessions};
use axum::extract::{Request, State};
use axum::http::{Method, StatusCode};
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};
use rmcp::model::{ClientJsonRpcMessage, ClientRequest, JsonRpcMessage};
use std::sync::Arc;

/// What the checks need.
#[derive(Clone)]
pub(super) struct StreamableChecks {
    pub(super) scopes: Arc<CallScopes>,
    pub(super) max_body_bytes: usize,
    pub(super) places: Arc<SessionPlaces>,
    pub(super) sessions: Arc<ClosingSessions>,
    /// Answers plain tool calls without rmcp's session pipeline; `None` sends all to rmcp.
    pub(super) direct: Option<DirectCalls>,
}

/// Whether `message` is a request other than `initialize`: a call that puts its session in
/// use.
pub(super) fn is_call(message: &ClientJsonRpcMessage) -> bool {
    matches!(message, JsonRpcMessage::Request(r)
        if !matches!(r.request, ClientRequest::InitializeRequest(_)))
}

fn session_not_found() -> Response {
    (StatusCode::NOT_FOUND, "Not Found: Session not found").into_response()
}

/// Around rmcp's streamable-HTTP service: reads each POST body once to answer what is not
/// JSON-RPC per the spec, refuses requests naming another client's session, and binds new
/// sessions to their client.
pub(super) async fn streamable_checks(
    State(checks): State<StreamableChecks>,
    request: Request,
    next: Next,
) -> Response {
    let StreamableChecks {
        scopes,
        max_body_bytes,
        places,
        sessions,
        direct,
    } = checks;
    let owner = SessionOwner::of(
        request.headers(),
        request.uri().query(),
        request.extensions(),
    );
    let session = request
        .headers()
        .get("mcp-session-id")
        .and_then(|v| v.to_str().ok())
        .map(str::to_owned);
    if let Some(id) = &session {
        if !scopes.owned_by(id, &owner) {
            tracing::warn!(session = %id, "request into another client's MCP session refused");
            return session_not_found();
        }
        // Closed, expired, given up or never opened: 404 on every method (rmcp would answer
        // a DELETE of an unknown session 202).
        if !places.contains(id) {
            return session_not_found();
        }
    }
    if request.method() != Method::POST {
        if let Some(id) = &session {
            places.touch(id, false);
        }
        return next.run(request).await;
    }
    let (parts, body) = request.into_parts();
    let bytes = match axum::body::to_bytes(body, max_body_bytes).await {
        Ok(bytes) => bytes,
        Err(error) if robotd_web::body_deadline::is_too_slow(&error) => {
            return (
                StatusCode::REQUEST_TIMEOUT,
                format!("Request Timeout: {error}"),
            )
                .into_response()
        }
        Err(error) => {
            return (
                StatusCode::PAYLOAD_TOO_LARGE,
                format!("Payload Too Large: {error}"),
            )
                .into_response()
        }
    };
    // The happy path parses once; a body that is not a client message is parsed again only
    // to say what is wrong with it.
    let message = match serde_json::from_slice::<ClientJsonRpcMessage>(&bytes) {
        Ok(message) => message,
        Err(error) => return BadMessage::of(&bytes, &error, StatusCode::OK).into_response(),
    };
    let Some(session) = session else {
        let opens = matches!(&message, JsonRpcMessage::Request(r)
            if matches!(r.request, ClientRequest::InitializeRequest(_)));
        let ticket = match opens.then(|| places.admit(owner)).transpose() {
            Ok(ticket) => ticket,
            Err(refusal) => return super::refusal_response(&refusal),
        };
        let request = Request::from_parts(parts, axum::body::Body::from(bytes));
        let response = next.run(request).await;
        let opened = response
            .headers()
            .get("mcp-session-id")
            .and_then(|v| v.to_str().ok());
        if let (Some(ticket), Some(id)) = (ticket, opened) {
            scopes.bind_owner(id, owner);
            ticket.open(id, Transport::Streamable);
            // Closed by robotd when its place expires or its client gives it up.
            let closed = places.closed(id);
            let id = id.to_owned();
            tokio::spawn(async move {
                closed.await;
                sessions.close_if_open(&id).await;
            });
        }
        return response;
    };
    places.touch(&session, is_call(&message));
    cancel_named(&scopes, &session, &message);
    if let Some(direct) = &direct {
        if let Some(call) = DirectCall::of(&parts.headers, message) {
            if direct.sessions.takes_direct_calls(&session).await {
                return direct.answer(&session, call).await;
            }
        }
    }
    next.run(Request::from_parts(parts, axum::body::Body::from(bytes)))
        .await
}
