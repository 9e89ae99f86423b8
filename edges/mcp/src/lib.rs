//! # robotd-mcp: the MCP edge
//!
//! Serves robotd's tool registry ([`robotd_tools`]) to MCP clients, so that anything that
//! drove the Python "robot-environment" FastMCP server drives robotd unchanged:
//!
//! | transport | where | module |
//! |---|---|---|
//! | legacy HTTP+SSE (2024-11-05) | `GET /sse`, `POST /messages/?session_id=…` | [`http`] (hand-written) |
//! | streamable HTTP | `/mcp` | [`http`] (rmcp's service) |
//! | stdio | `robotd mcp-stdio` | [`serve_stdio`] |
//!
//! Every transport serves the same [`McpService`]; every call is written to the call log
//! ([`call_log`]) and traced. [`client`] connects to any MCP server over SSE or streamable
//! HTTP (for `robotd call`, the benchmarks, the tests and the agent).
//!
//! ```no_run
//! # async fn demo(registry: robotd_tools::Registry) -> anyhow::Result<()> {
//! use robotd_mcp::{call_log::CallLog, http, McpService};
//! use std::sync::Arc;
//! let service = McpService::new(registry, false, Arc::new(CallLog::disabled()));
//! let app = http::router(service, Default::default(), Default::default());
//! let listener = tokio::net::TcpListener::bind("127.0.0.1:8000").await?;
//! axum::serve(listener, app).await?;
//! # Ok(()) }
//! ```

pub mod config;
pub use config::McpConfig;

pub mod agent_tools;
pub mod call_log;
pub mod client;
pub mod gate;
pub mod http;
pub mod owner;
pub mod resources;
mod service;
pub mod sessions;

pub use service::McpService;

use rmcp::ServiceExt;

/// Serves `service` on standard input and output until the client closes them. Nothing else
/// may write to stdout meanwhile (robotd's logs go to stderr and the log file).
pub async fn serve_stdio(service: McpService) -> anyhow::Result<()> {
    let running = service
        .for_transport("stdio")
        .serve(gate::gated(rmcp::transport::stdio()))
        .await
        .map_err(|e| anyhow::anyhow!("MCP over stdio did not initialise: {e}"))?;
    running
        .waiting()
        .await
        .map_err(|e| anyhow::anyhow!("MCP over stdio: {e}"))?;
    Ok(())
}
