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
//! - **Streamable HTTP** at `/mcp`: rmcp's own service.
//! - **Guard** (every route): a bearer token when one is configured (401 otherwise), `Origin`
//!   headers that are not local (or configured) refused with 403 — DNS-rebinding protection —
//!   and a request-body limit (413).

use crate::service::McpService;
use crate::sessions::{CallScopes, ClosingSessions};
use axum::body::Bytes;
use axum::extract::{DefaultBodyLimit, Query, Request, State};
use axum::http::{header, HeaderMap, StatusCode};
use axum::middleware::{self, Next};
use axum::response::sse::{Event, KeepAlive, Sse};
use axum::response::{IntoResponse, Response};
use axum::routing::{get, post};
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

/// How the HTTP side is protected.
#[derive(Debug, Clone)]
pub struct HttpGuard {
    /// Required `Authorization: Bearer <token>`; `None` = no token (loopback only).
    pub token: Option<String>,
    /// Largest request body accepted, bytes.
    pub max_body_bytes: usize,
    /// Extra `Origin` values accepted besides local ones (e.g. `https://lab.example.org`).
    pub allowed_origins: Vec<String>,
}

impl Default for HttpGuard {
    fn default() -> Self {
        Self {
            token: None,
            max_body_bytes: 1024 * 1024,
            allowed_origins: Vec::new(),
        }
    }
}

/// Why the edge refuses to start.
#[derive(Debug, thiserror::Error)]
pub enum StartError {
    /// A non-loopback address without a token would give the robot to anyone on the network.
    #[error(
        "refusing to serve MCP on {bind} without a bearer token: a non-loopback address \
         exposes the robot to the network. Set [mcp] token (or ROBOTD_MCP__TOKEN), or bind \
         127.0.0.1"
    )]
    TokenRequired {
        /// The address asked for.
        bind: SocketAddr,
    },
}

/// Checks that `bind` may be served with `guard`.
pub fn check_bind(bind: SocketAddr, guard: &HttpGuard) -> Result<(), StartError> {
    if !bind.ip().is_loopback() && guard.token.as_deref().is_none_or(str::is_empty) {
        return Err(StartError::TokenRequired { bind });
    }
    Ok(())
}

/// Whether an `Origin` header value names this machine.
fn origin_is_local(origin: &str) -> bool {
    let Some((scheme, rest)) = origin.split_once("://") else {
        return false;
    };
    if scheme != "http" && scheme != "https" {
        return false;
    }
    let host = if let Some(v6) = rest.strip_prefix('[') {
        v6.split(']').next().unwrap_or("")
    } else {
        rest.split(':').next().unwrap_or("")
    };
    matches!(host, "localhost" | "127.0.0.1" | "::1")
}

fn constant_time_eq(a: &[u8], b: &[u8]) -> bool {
    a.len() == b.len() && a.iter().zip(b).fold(0u8, |acc, (x, y)| acc | (x ^ y)) == 0
}

async fn guard(State(guard): State<Arc<HttpGuard>>, request: Request, next: Next) -> Response {
    let headers = request.headers();
    if let Some(origin) = headers.get(header::ORIGIN) {
        let origin = origin.to_str().unwrap_or("");
        if !origin_is_local(origin) && !guard.allowed_origins.iter().any(|o| o == origin) {
            tracing::warn!(origin, "MCP request with a foreign Origin refused");
            return (
                StatusCode::FORBIDDEN,
                "Forbidden: Origin not allowed (robotd serves MCP to local clients; add the \
                 origin to [mcp] allowed_origins to allow it)",
            )
                .into_response();
        }
    }
    if let Some(token) = guard.token.as_deref() {
        let given = headers
            .get(header::AUTHORIZATION)
            .and_then(|v| v.to_str().ok())
            .and_then(|v| v.strip_prefix("Bearer "))
            .unwrap_or("");
        if !constant_time_eq(given.as_bytes(), token.as_bytes()) {
            return (
                StatusCode::UNAUTHORIZED,
                [(header::WWW_AUTHENTICATE, "Bearer")],
                "Unauthorized: send Authorization: Bearer <token>",
            )
                .into_response();
        }
    }
    let too_long = headers
        .get(header::CONTENT_LENGTH)
        .and_then(|v| v.to_str().ok())
        .and_then(|v| v.parse::<usize>().ok())
        .is_some_and(|n| n > guard.max_body_bytes);
    if too_long {
        return (
            StatusCode::PAYLOAD_TOO_LARGE,
            format!(
                "Payload Too Large: requests are limited to {} bytes",
                guard.max_body_bytes
            ),
        )
            .into_response();
    }
    next.run(request).await
}

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

async fn open_sse(State(state): State<SseState>) -> Response {
    let id = new_session_id();
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
            .serve_with_ct((to_client, from_client), shutdown.child_token())
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
    headers: HeaderMap,
    body: Bytes,
) -> Response {
    let Some(id) = query.session_id else {
        return (StatusCode::BAD_REQUEST, "session_id is required").into_response();
    };
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

/// `routes` behind the MCP edge's guard (bearer token off loopback, Origin checks, body
/// limit), for other APIs on the same port.
pub fn guarded(routes: Router, guard_settings: HttpGuard) -> Router {
    let limit = guard_settings.max_body_bytes;
    routes
        .layer(DefaultBodyLimit::max(limit))
        .layer(middleware::from_fn_with_state(
            Arc::new(guard_settings),
            guard,
        ))
}

/// The MCP routes (`/sse`, `/messages/`, `/mcp`) behind the guard. `shutdown` ends every
/// session.
pub fn router(
    service: McpService,
    guard_settings: HttpGuard,
    shutdown: CancellationToken,
) -> Router {
    let limit = guard_settings.max_body_bytes;
    // Host checks would refuse a client that reaches a non-loopback bind by its address; the
    // bearer token protects those binds instead, and Origin is checked by the guard.
    let config = StreamableHttpServerConfig::default()
        .with_allowed_hosts(Vec::<String>::new())
        .with_max_request_body_bytes(limit)
        .with_cancellation_token(shutdown.child_token());
    let streamable_service = service.for_transport("streamable_http");
    let streamable = StreamableHttpService::new(
        move || Ok(streamable_service.clone()),
        Arc::new(ClosingSessions::new(service.scopes())),
        config,
    );
    let state = SseState {
        service,
        sessions: SessionMap::default(),
        shutdown,
    };
    Router::new()
        .route("/sse", get(open_sse))
        .route("/messages/", post(post_message))
        .route("/messages", post(post_message))
        .with_state(state)
        .nest_service("/mcp", streamable)
        .layer(DefaultBodyLimit::max(limit))
        .layer(middleware::from_fn_with_state(
            Arc::new(guard_settings),
            guard,
        ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn local_origins_only() {
        for ok in [
            "http://localhost:6274",
            "http://127.0.0.1",
            "https://[::1]:8000",
        ] {
            assert!(origin_is_local(ok), "{ok}");
        }
        for bad in [
            "http://evil.example.com",
            "http://127.0.0.1.evil.com",
            "null",
            "file://localhost",
            "http://localhost.evil.com:80",
        ] {
            assert!(!origin_is_local(bad), "{bad}");
        }
    }

    #[test]
    fn non_loopback_binds_need_a_token() {
        let open: SocketAddr = "0.0.0.0:8000".parse().unwrap();
        let local: SocketAddr = "127.0.0.1:8000".parse().unwrap();
        let mut guard = HttpGuard::default();
        assert!(check_bind(local, &guard).is_ok());
        let e = check_bind(open, &guard).unwrap_err().to_string();
        // The server reads its token through the configuration's environment layer
        // (`ROBOTD_MCP__TOKEN`, double underscore); naming anything else sends users astray.
        assert!(e.contains("(or ROBOTD_MCP__TOKEN)"), "{e}");
        guard.token = Some("s3cret".into());
        assert!(check_bind(open, &guard).is_ok());
        assert!(constant_time_eq(b"abc", b"abc"));
        assert!(!constant_time_eq(b"abc", b"abd"));
        assert!(!constant_time_eq(b"abc", b"ab"));
    }
}
