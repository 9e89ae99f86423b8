//! The MCP edge's HTTP side: legacy HTTP+SSE (`sse`) and streamable HTTP (rmcp's service
//! at `/mcp`, with `streamable` checks in front) on one port.
//!
//! Each session is bound to the client that opened it ([`crate::owner`]) and served through
//! [`crate::gate`] (no request before `notifications/initialized`). At most
//! [`RouterOptions::max_sessions`] sessions are open at once over both transports (503
//! beyond); a streamable-HTTP session idle for [`RouterOptions::idle_timeout`] is closed and
//! its calls cancelled. The port's guard (token, Host, Origin, body size) is the HTTP edge's:
//! `robotd_http::guard`, around every route.

mod call_run;
mod direct_call;
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
            idle_timeout: Duration::from_secs(300),
            direct_tool_calls: true,
        }
    }
}

/// The limit on open sessions, counted over both transports.
#[derive(Clone)]
struct SessionCap {
    max: usize,
    streamable: Arc<ClosingSessions>,
    sse: sse::SessionMap,
}

impl SessionCap {
    /// The 503 answer when no further session may open. Sessions opening at the same moment
    /// are counted as they appear, so a burst may pass the limit by the burst's size.
    async fn refusal(&self) -> Option<Response> {
        let sse = self.sse.lock().unwrap_or_else(|e| e.into_inner()).len();
        let open = self.streamable.open_sessions().await + sse;
        (open >= self.max).then(|| {
            tracing::warn!(
                open,
                max = self.max,
                "new MCP session refused: the limit is reached"
            );
            (
                StatusCode::SERVICE_UNAVAILABLE,
                [(header::RETRY_AFTER, "5")],
                format!(
                    "Service Unavailable: {open} MCP sessions are open, the limit is {} \
                     (mcp.max_sessions). Close a session (DELETE /mcp, or close the SSE \
                     stream) or wait for idle ones to expire (mcp.session_idle_timeout_s)",
                    self.max
                ),
            )
                .into_response()
        })
    }
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
    let sessions = Arc::new(ClosingSessions::new(service.scopes(), options.idle_timeout));
    let cap = SessionCap {
        max: options.max_sessions,
        streamable: sessions.clone(),
        sse: sse::SessionMap::default(),
    };
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
        cap: cap.clone(),
        direct,
    };
    let state = sse::SseState {
        service,
        sessions: cap.sse.clone(),
        shutdown,
        cap,
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
