//! The MCP edge's HTTP side: legacy HTTP+SSE and streamable HTTP on one port, behind one
//! guard.
//!
//! - **Legacy HTTP+SSE** (protocol 2024-11-05; what clients that hard-code
//!   `http://127.0.0.1:8000/sse` speak): `GET /sse` opens an event stream whose first event,
//!   `endpoint`, names `/messages/?session_id=<id>`; the client POSTs each JSON-RPC message
//!   there (answered `202 Accepted`) and reads the replies as `message` events on the stream.
//!   rmcp 3 ships no server for it, so robotd implements it here: each stream is one rmcp
//!   session fed through a pair of channels. Closing the stream ends the session and cancels
//!   its calls (a motion in flight stops).
//! - **Streamable HTTP** at `/mcp`: rmcp's own service, with a body that is not JSON
//!   answered 400 / `-32700` and one that is not a JSON-RPC message 400 / `-32600` (rmcp
//!   would say 415).
//!
//! Each session is bound to the client that opened it ([`crate::owner`]) and served through
//! [`crate::gate`] (no request before `notifications/initialized`). The port's guard (token,
//! Host, Origin, body size) is the HTTP edge's: `robotd_http::guard`, around every route.

use crate::gate::{gated, invalid_params, is_mcp_method};
use crate::owner::SessionOwner;
use crate::service::McpService;
use crate::sessions::{CallScopes, ClosingSessions};
use axum::body::Bytes;
use axum::extract::{ConnectInfo, DefaultBodyLimit, Query, Request, State};
use axum::http::{header, HeaderMap, StatusCode};
use axum::middleware::{self, Next};
use axum::response::sse::{Event, KeepAlive, Sse};
use axum::response::{IntoResponse, Response};
use axum::routing::{get, post};
use axum::Extension;
use axum::Router;
use futures::channel::mpsc;
use futures::{SinkExt, Stream, StreamExt};
use rmcp::model::{ClientJsonRpcMessage, ServerJsonRpcMessage};
use rmcp::transport::streamable_http_server::{StreamableHttpServerConfig, StreamableHttpService};
use rmcp::ServiceExt;
use std::collections::HashMap;
use std::net::SocketAddr;
use std::pin::Pin;
use std::sync::{Arc, Mutex};
use std::task::{Context, Poll};
use std::time::Duration;
use tokio_util::sync::CancellationToken;

type SessionMap = Arc<Mutex<HashMap<String, mpsc::Sender<ClientJsonRpcMessage>>>>;

#[derive(Clone)]
struct SseState {
    service: McpService,
    sessions: SessionMap,
    shutdown: CancellationToken,
}

/// The event stream of one SSE session; dropping it (the client went away) ends the session.
struct SessionStream {
    id: String,
    sessions: SessionMap,
    scopes: Arc<CallScopes>,
    inner: Pin<Box<dyn Stream<Item = Result<Event, std::convert::Infallible>> + Send>>,
}

impl Stream for SessionStream {
    type Item = Result<Event, std::convert::Infallible>;
    fn poll_next(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<Option<Self::Item>> {
        self.inner.as_mut().poll_next(cx)
    }
}

impl Drop for SessionStream {
    fn drop(&mut self) {
        // The client went away: whatever its calls started must stop.
        self.scopes.close_session(&self.id);
        self.sessions
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .remove(&self.id);
        tracing::debug!(session = %self.id, "SSE session closed");
    }
}

fn new_session_id() -> String {
    use rand::RngCore;
    let mut bytes = [0u8; 16];
    rand::rng().fill_bytes(&mut bytes);
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

async fn open_sse(State(state): State<SseState>, request: Request) -> Response {
    let id = new_session_id();
    let owner = SessionOwner::of(request.headers(), request.extensions());
    state.service.scopes().bind_owner(&id, owner);
    let (to_server, from_client) = mpsc::channel::<ClientJsonRpcMessage>(64);
    let (to_client, from_server) = mpsc::channel::<ServerJsonRpcMessage>(64);
    state
        .sessions
        .lock()
        .unwrap_or_else(|e| e.into_inner())
        .insert(id.clone(), to_server);
    let service = state.service.for_sse_session(&id);
    let session = id.clone();
    let shutdown = state.shutdown.clone();
    tokio::spawn(async move {
        match service
            .serve_with_ct(gated((to_client, from_client)), shutdown.child_token())
            .await
        {
            Ok(running) => {
                if let Err(error) = running.waiting().await {
                    tracing::debug!(%session, %error, "SSE session ended");
                }
            }
            Err(error) => tracing::info!(%session, %error, "SSE session did not initialise"),
        }
    });
    tracing::debug!(session = %id, "SSE session opened");
    let endpoint = Event::default()
        .event("endpoint")
        .data(format!("/messages/?session_id={id}"));
    let messages = from_server.map(|message| {
        let data = serde_json::to_string(&message)
            .unwrap_or_else(|e| format!("{{\"error\":\"unserialisable message: {e}\"}}"));
        Ok(Event::default().event("message").data(data))
    });
    let stream = SessionStream {
        id,
        sessions: state.sessions.clone(),
        scopes: state.service.scopes(),
        inner: Box::pin(futures::stream::once(async move { Ok(endpoint) }).chain(messages)),
    };
    Sse::new(stream)
        // A comment every second: the server only learns that a client went away when a
        // write fails, and the calls of a client that went away must stop soon.
        .keep_alive(KeepAlive::new().interval(Duration::from_secs(1)))
        .into_response()
}

#[derive(serde::Deserialize)]
struct SessionQuery {
    session_id: Option<String>,
}

async fn post_message(
    State(state): State<SseState>,
    Query(query): Query<SessionQuery>,
    connection: Option<Extension<ConnectInfo<SocketAddr>>>,
    headers: HeaderMap,
    body: Bytes,
) -> Response {
    let Some(id) = query.session_id else {
        return (StatusCode::BAD_REQUEST, "session_id is required").into_response();
    };
    let mut extensions = axum::http::Extensions::new();
    if let Some(Extension(info)) = connection {
        extensions.insert(info);
    }
    if !state
        .service
        .scopes()
        .owned_by(&id, &SessionOwner::of(&headers, &extensions))
    {
        tracing::warn!(session = %id, "post into another client's SSE session refused");
        return (StatusCode::NOT_FOUND, "Could not find session").into_response();
    }
    let is_json = headers
        .get(header::CONTENT_TYPE)
        .and_then(|v| v.to_str().ok())
        .is_none_or(|v| v.starts_with("application/json"));
    if !is_json {
        return (
            StatusCode::UNSUPPORTED_MEDIA_TYPE,
            "Content-Type must be application/json",
        )
            .into_response();
    }
    let sender = state
        .sessions
        .lock()
        .unwrap_or_else(|e| e.into_inner())
        .get(&id)
        .cloned();
    let Some(mut sender) = sender else {
        return (StatusCode::NOT_FOUND, "Could not find session").into_response();
    };
    let message: ClientJsonRpcMessage = match serde_json::from_slice(&body) {
        Ok(m) => m,
        Err(error) => {
            return (
                StatusCode::BAD_REQUEST,
                format!("Could not parse message: {error}"),
            )
                .into_response()
        }
    };
    match sender.send(message).await {
        Ok(()) => (StatusCode::ACCEPTED, "Accepted").into_response(),
        Err(_) => (StatusCode::NOT_FOUND, "Could not find session").into_response(),
    }
}

/// The MCP routes (`/sse`, `/messages/`, `/mcp`), accepting bodies up to `max_body_bytes`.
/// `shutdown` ends every session. Serve them behind `robotd_http::guard` (the HTTP edge does).
pub fn router(service: McpService, max_body_bytes: usize, shutdown: CancellationToken) -> Router {
    // Host is checked by the port's guard, for every route; rmcp's own check would refuse a
    // client that reaches a non-loopback bind by its address.
    let config = StreamableHttpServerConfig::default()
        .with_allowed_hosts(Vec::<String>::new())
        .with_max_request_body_bytes(max_body_bytes)
        .with_cancellation_token(shutdown.child_token());
    let streamable_service = service.for_transport("streamable_http");
    let streamable = StreamableHttpService::new(
        move || Ok(streamable_service.clone()),
        Arc::new(ClosingSessions::new(service.scopes())),
        config,
    );
    let scopes = service.scopes();
    let state = SseState {
        service,
        sessions: SessionMap::default(),
        shutdown,
    };
    let streamable =
        Router::new()
            .fallback_service(streamable)
            .layer(middleware::from_fn_with_state(
                (scopes, max_body_bytes),
                streamable_checks,
            ));
    Router::new()
        .route("/sse", get(open_sse))
        .route("/messages/", post(post_message))
        .route("/messages", post(post_message))
        .with_state(state)
        .nest_service("/mcp", streamable)
        .layer(DefaultBodyLimit::max(max_body_bytes))
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

/// Around rmcp's streamable-HTTP service: reads each POST body once to answer what is not
/// JSON-RPC per the spec, refuses requests naming another client's session, and binds new
/// sessions to their client.
async fn streamable_checks(
    State((scopes, max_body_bytes)): State<(Arc<CallScopes>, usize)>,
    request: Request,
    next: Next,
) -> Response {
    let owner = SessionOwner::of(request.headers(), request.extensions());
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
    let request = if request.method() == axum::http::Method::POST {
        let (parts, body) = request.into_parts();
        let bytes = match axum::body::to_bytes(body, max_body_bytes).await {
            Ok(bytes) => bytes,
            Err(error) => {
                return (
                    StatusCode::PAYLOAD_TOO_LARGE,
                    format!("Payload Too Large: {error}"),
                )
                    .into_response()
            }
        };
        let value = match serde_json::from_slice::<serde_json::Value>(&bytes) {
            Ok(value) => value,
            Err(error) => {
                return json_rpc_refusal(
                    -32700,
                    format!("Parse error: the body is not JSON: {error}"),
                )
            }
        };
        if let Err(error) = serde_json::from_value::<ClientJsonRpcMessage>(value.clone()) {
            // A request to an MCP method whose params are not even an object (`[1, 2]`).
            let method = value["method"].as_str().filter(|m| is_mcp_method(m));
            if let (Some(method), Some(id)) = (method, value.get("id")) {
                let error = invalid_params(method);
                let body = serde_json::json!({"jsonrpc": "2.0", "id": id, "error": error});
                return axum::Json(body).into_response();
            }
            return json_rpc_refusal(
                -32600,
                format!("Invalid Request: not a JSON-RPC message of an MCP client: {error}"),
            );
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
