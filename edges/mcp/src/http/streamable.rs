//! Checks around rmcp's streamable-HTTP service (`/mcp`).
//!
//! rmcp answers a body it cannot read with 415 and knows nothing of who opened a session. In
//! front of it, each POST body is read once (within the size limit) and:
//!
//! - a body that is not JSON is answered 400 / `-32700`, JSON that is not a JSON-RPC message
//!   400 / `-32600`, and a request to an MCP method with params that are not even an object
//!   `-32602`;
//! - a request naming another client's session is answered 404, like an unknown session;
//! - a new session is refused with 503 when `mcp.max_sessions` are open, and otherwise bound
//!   to its client once rmcp names it in `Mcp-Session-Id`;
//! - a `tools/call` in an initialized session is run here, without rmcp's session pipeline
//!   ([`super::direct_call`]), and a `notifications/cancelled` cancels the call it names on
//!   either path.

use super::direct_call::{cancel_named, DirectCall, DirectCalls};
use super::SessionCap;
use crate::gate::{invalid_params, is_mcp_method};
use crate::owner::SessionOwner;
use crate::sessions::CallScopes;
use axum::extract::{Request, State};
use axum::http::StatusCode;
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};
use rmcp::model::ClientJsonRpcMessage;
use std::sync::Arc;

/// What the checks need.
#[derive(Clone)]
pub(super) struct StreamableChecks {
    pub(super) scopes: Arc<CallScopes>,
    pub(super) max_body_bytes: usize,
    pub(super) cap: SessionCap,
    /// Answers plain tool calls without rmcp's session pipeline; `None` sends all to rmcp.
    pub(super) direct: Option<DirectCalls>,
}

/// A JSON-RPC error reply with no id (the request's could not be read), as HTTP 400.
fn json_rpc_refusal(code: i32, message: String) -> Response {
    let body = serde_json::json!({
        "jsonrpc": "2.0",
        "id": null,
        "error": {"code": code, "message": message},
    });
    (StatusCode::BAD_REQUEST, axum::Json(body)).into_response()
}

/// The answer to a POST body that is not a JSON-RPC message of an MCP client.
fn refusal_of(bytes: &[u8], error: serde_json::Error) -> Response {
    let value = match serde_json::from_slice::<serde_json::Value>(bytes) {
        Ok(value) => value,
        Err(error) => {
            return json_rpc_refusal(
                -32700,
                format!("Parse error: the body is not JSON: {error}"),
            )
        }
    };
    // A request to an MCP method whose params are not even an object (`[1, 2]`).
    let method = value["method"].as_str().filter(|m| is_mcp_method(m));
    if let (Some(method), Some(id)) = (method, value.get("id")) {
        let error = invalid_params(method);
        let body = serde_json::json!({"jsonrpc": "2.0", "id": id, "error": error});
        return axum::Json(body).into_response();
    }
    json_rpc_refusal(
        -32600,
        format!("Invalid Request: not a JSON-RPC message of an MCP client: {error}"),
    )
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
        cap,
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
            return (StatusCode::NOT_FOUND, "Not Found: Session not found").into_response();
        }
    }
    if session.is_none() && request.method() == axum::http::Method::POST {
        if let Some(full) = cap.refusal().await {
            return full;
        }
    }
    let request = if request.method() == axum::http::Method::POST {
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
        // The happy path parses once; a body that is not a client message is parsed again
        // only to say what is wrong with it.
        let message = match serde_json::from_slice::<ClientJsonRpcMessage>(&bytes) {
            Ok(message) => message,
            Err(error) => return refusal_of(&bytes, error),
        };
        if let Some(session) = &session {
            cancel_named(&scopes, session, &message);
            if let Some(direct) = &direct {
                if let Some(call) = DirectCall::of(&parts.headers, message) {
                    if direct.sessions.takes_direct_calls(session).await {
                        return direct.answer(session, call).await;
                    }
                }
            }
        }
        Request::from_parts(parts, axum::body::Body::from(bytes))
    } else {
        request
    };
    let response = next.run(request).await;
    if session.is_none() {
        if let Some(id) = response
            .headers()
            .get("mcp-session-id")
            .and_then(|v| v.to_str().ok())
        {
            scopes.bind_owner(id, owner);
        }
    }
    response
}
