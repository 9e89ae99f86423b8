//! The MCP edge's HTTP side: legacy HTTP+SSE (`sse`) and streamable HTTP (rmcp's service
//! at `/mcp`, with `streamable` checks in front) on one port.
//!
//! Each session is bound to the client that opened it ([`crate::owner`]) and served through
//! [`crate::gate`] (no request before `notifications/initialized`). The sessions of both
//! transports share [`RouterOptions::max_sessions`] places, one client at most
//! [`RouterOptions::max_sessions_per_client`] of them; a session that made no call ends after
//! [`RouterOptions::unused_timeout`], a streamable-HTTP session idle for
//! [`RouterOptions::idle_timeout`] too, its calls cancelled; a refused session gets 503 with
//! the time until a place frees by itself (`places`). The JSON-RPC envelope of every posted
//! message is checked on both transports (`envelope`). The port's guard (token, Host, Origin,
//! body size) is the HTTP edge's: `robotd_http::guard`, around every route.

mod call_run;
mod direct_call;
mod envelope;
pub(crate) mod places;
mod sse;
mod sse_transport;
mod streamable;

use crate::service::McpService;
use crate::sessions::ClosingSessions;
use axum::extract::DefaultBodyLimit;
use axum::http::{header, StatusCode};
use axum::middleware;
use axum::response::{IntoResponse, Response};
use axum::routing::{get, post};
use axum::Router;
use places::{PlaceLimits, SessionPlaces};
use rmcp::transport::streamable_http_server::{StreamableHttpServerConfig, StreamableHttpService};
use std::sync::Arc;
use std::time::Duration;
use tokio_util::sync::CancellationToken;

/// Limits of the MCP routes (from `[mcp]`).
#[derive(Debug, Clone, Copy)]
pub struct RouterOptions {
    /// Largest request body, bytes.
    pub max_body_bytes: usize,
    /// Most sessions open at once, SSE and streamable HTTP together.
    pub max_sessions: usize,
    /// Most sessions one client (address and token) holds at once.
    pub max_sessions_per_client: usize,
    /// A session that made no call is closed this long after it opened.
    pub unused_timeout: Duration,
    /// A streamable-HTTP session without a request for this long is closed.
    pub idle_timeout: Duration,
    /// Run streamable-HTTP tool calls without rmcp's session pipeline (`direct_call`).
    pub direct_tool_calls: bool,
}

impl Default for RouterOptions {
    fn default() -> Self {
        Self {
            max_body_bytes: 1024 * 1024,
            max_sessions: 100,
            max_sessions_per_client: 80,
            unused_timeout: Duration::from_secs(30),
            idle_timeout: Duration::from_secs(300),
            direct_tool_calls: true,
        }
    }
}

/// The 503 answer to a session `refusal`: what limit, and `Retry-After` when a place frees
/// by itself.
fn refusal_response(refusal: &places::Refusal) -> Response {
    let places::Refusal {
        setting,
        held,
        limit,
        ..
    } = refusal;
    tracing::warn!(
        held,
        limit,
        setting,
        "new MCP session refused: the limit is reached"
    );
    let whose = if *setting == "mcp.max_sessions" {
        "MCP sessions are open"
    } else {
        "MCP sessions are open for this client (its address and token)"
    };
    let when = match refusal.retry_after_s() {
        Some(s) => format!("the first of them ends by itself in {s} s (Retry-After)"),
        None => "none of them ends by itself: each ends when its client closes it".to_owned(),
    };
    let body = format!(
        "Service Unavailable: {held} {whose}, the limit is {limit} ({setting}); {when}. Close a \
         session (DELETE /mcp, or close the SSE stream) to free a place at once"
    );
    let mut response = (StatusCode::SERVICE_UNAVAILABLE, body).into_response();
    if let Some(s) = refusal.retry_after_s() {
        response
            .headers_mut()
            .insert(header::RETRY_AFTER, header::HeaderValue::from(s));
    }
    response
}

/// The MCP routes (`/sse`, `/messages/`, `/mcp`) with `options`. `shutdown` ends every
/// session. Serve them behind `robotd_http::guard` (the HTTP edge does).
pub fn router(service: McpService, options: RouterOptions, shutdown: CancellationToken) -> Router {
    // Host is checked by the port's guard, for every route; rmcp's own check would refuse a
    // client that reaches a non-loopback bind by its address.
    let config = StreamableHttpServerConfig::default()
        .with_allowed_hosts(Vec::<String>::new())
        .with_max_request_body_bytes(options.max_body_bytes)
        .with_cancellation_token(shutdown.child_token());
    let streamable_service = service.for_transport("streamable_http");
    let places = SessionPlaces::new(PlaceLimits {
        max_sessions: options.max_sessions,
        per_client: options.max_sessions_per_client,
        unused_timeout: options.unused_timeout,
        idle_timeout: options.idle_timeout,
    });
    let sessions = Arc::new(ClosingSessions::new(service.scopes(), places.clone()));
    let streamable = StreamableHttpService::new(
        move || Ok(streamable_service.clone()),
        sessions.clone(),
        config,
    );
    let direct = options.direct_tool_calls.then(|| direct_call::DirectCalls {
        service: service.for_transport("streamable_http"),
        sessions: sessions.clone(),
        scopes: service.scopes(),
    });
    let checks = streamable::StreamableChecks {
        scopes: service.scopes(),
        max_body_bytes: options.max_body_bytes,
        places: places.clone(),
        sessions: sessions.clone(),
        direct,
    };
    let state = sse::SseState {
        service,
        sessions: sse::SessionMap::default(),
        shutdown,
        places,
        direct: options.direct_tool_calls,
    };
    let streamable =
        Router::new()
            .fallback_service(streamable)
            .layer(middleware::from_fn_with_state(
                checks,
                streamable::streamable_checks,
            ));
    Router::new()
        .route("/sse", get(sse::open_sse))
        .route("/messages/", post(sse::post_message))
        .route("/messages", post(sse::post_message))
        .with_state(state)
        .nest_service("/mcp", streamable)
        .layer(DefaultBodyLimit::max(options.max_body_bytes))
}
