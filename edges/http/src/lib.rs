//! robotd's HTTP edge: the service's one HTTP port, with `GET /health` (JSON) and
//! `GET /metrics` (Prometheus text) for dashboards and monitoring; the MCP edge mounts its
//! routes on the same port ([`HttpEdge::with_routes`]). Every route sits behind one
//! [`guard`] (Host, Origin, bearer token, body size), and the port holds a bounded number of
//! connections, closing idle ones ([`connections`]). It holds no robot logic.
//!
//! ```no_run
//! # async fn demo() -> std::io::Result<()> {
//! use robotd_http::{HealthSource, HttpEdge};
//! let health: HealthSource = std::sync::Arc::new(|| serde_json::json!({"status": "ok"}));
//! let edge = HttpEdge::bind("127.0.0.1:8000".parse().unwrap(), health).await?
//!     .with_guard(robotd_http::guard::HttpGuard::default());
//! println!("serving on {}", edge.local_addr()?);
//! edge.serve(std::future::pending()).await
//! # }
//! ```

pub use robotd_web::body_deadline;
pub mod config;
pub mod connections;
mod event_streams;
pub mod guard;
pub mod safety;
pub use config::HttpConfig;
pub use connections::ConnectionLimits;

use axum::extract::State;
use axum::http::{header, StatusCode};
use axum::response::IntoResponse;
use axum::routing::get;
use axum::Router;
use robotd_runtime::metrics::{Metrics, CONTENT_TYPE};
use std::future::Future;
use std::net::SocketAddr;
use std::sync::Arc;

/// Produces the current health report (actors, restarts, e-stop) as JSON.
pub type HealthSource = Arc<dyn Fn() -> serde_json::Value + Send + Sync>;

/// A bound, not yet serving, HTTP edge.
pub struct HttpEdge {
    listener: tokio::net::TcpListener,
    router: Router,
    guard: guard::HttpGuard,
    limits: ConnectionLimits,
}

impl HttpEdge {
    /// Binds `addr` (port 0 picks a free port).
    pub async fn bind(addr: SocketAddr, health: HealthSource) -> std::io::Result<Self> {
        let listener = tokio::net::TcpListener::bind(addr).await.map_err(|e| {
            std::io::Error::new(
                e.kind(),
                format!("cannot listen on {addr}: {e} (is another robotd running? set http.bind)"),
            )
        })?;
        let loopback = addr.ip().is_loopback();
        Ok(Self {
            listener,
            router: router(health),
            guard: guard::HttpGuard {
                loopback,
                ..Default::default()
            },
            limits: ConnectionLimits::default(),
        })
    }

    /// Adds `routes` (e.g. the MCP edge's) beside `/health` and `/metrics`.
    pub fn with_routes(mut self, routes: Router) -> Self {
        self.router = self.router.merge(routes);
        self
    }

    /// Puts every route behind `guard` (its `loopback` is set from the bound address).
    pub fn with_guard(mut self, guard: guard::HttpGuard) -> Self {
        self.guard = guard::HttpGuard {
            loopback: self.guard.loopback,
            ..guard
        };
        self
    }

    /// Sets the connection cap and idle timeout (defaults: [`ConnectionLimits::default`]).
    pub fn with_limits(mut self, limits: ConnectionLimits) -> Self {
        self.limits = limits;
        self
    }

    /// The address actually bound.
    pub fn local_addr(&self) -> std::io::Result<SocketAddr> {
        self.listener.local_addr()
    }

    /// Serves until `shutdown` completes. Handlers can read the client's address as
    /// `ConnectInfo<SocketAddr>`.
    pub async fn serve(
        self,
        shutdown: impl Future<Output = ()> + Send + 'static,
    ) -> std::io::Result<()> {
        let app = guard::guarded(self.router, self.guard);
        connections::serve(self.listener, app, self.limits, shutdown).await
    }
}

/// The routes of the HTTP edge.
pub fn router(health: HealthSource) -> Router {
    Router::new()
        .route("/health", get(health_handler))
        .route("/metrics", get(metrics_handler))
        .with_state(health)
}

async fn health_handler(State(health): State<HealthSource>) -> impl IntoResponse {
    let report = health();
    let healthy = report.get("status").and_then(|s| s.as_str()) == Some("ok");
    let status = if healthy {
        StatusCode::OK
    } else {
        StatusCode::SERVICE_UNAVAILABLE
    };
    (status, axum::Json(report))
}

async fn metrics_handler() -> impl IntoResponse {
    (
        [(header::CONTENT_TYPE, CONTENT_TYPE)],
        Metrics::global().render(),
    )
}
