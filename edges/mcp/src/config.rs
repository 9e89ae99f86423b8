//! `[mcp]`: the MCP edge on the HTTP port — on or off, bearer token, body limit, allowed
//! browser origins, error style, motion time limit, session limits.

use robotd_runtime::config::{check_url, Checks, Section};
use serde::{Deserialize, Serialize};

/// `[mcp]`: the MCP edge, served on the `[http]` port (`/sse`, `/messages/`, `/mcp`).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct McpConfig {
    /// Serve the MCP routes at all.
    pub enabled: bool,
    /// Bearer token of the whole HTTP port (`Authorization: Bearer …`): MCP, e-stop and
    /// approvals always, `/health` and `/metrics` unless `http.bind` is loopback. Required
    /// when `http.bind` is not a loopback address, with MCP on or off. Prefer the `ROBOTD_MCP__TOKEN` environment
    /// variable to writing it in a file.
    pub token: Option<String>,
    /// Largest request body, bytes (1 KiB … 64 MiB).
    pub max_body_bytes: usize,
    /// Browser origins allowed besides local ones, e.g. `https://lab.example.org`.
    pub allowed_origins: Vec<String>,
    /// Set `isError: true` on failure replies (the Python server never did).
    pub strict_errors: bool,
    /// Longest a motion tool (pick, place, push …) may take, seconds.
    pub skill_timeout_s: u64,
    /// Most MCP sessions open at once, SSE and streamable HTTP together (1 … 10,000); a
    /// client opening one more gets 503.
    pub max_sessions: usize,
    /// Most sessions one client (its address and token) holds at once (1 … 10,000; at most
    /// `max_sessions` count). A client at its share that opens another closes its oldest
    /// session that never made a call, or gets 503 when it has none.
    pub max_sessions_per_client: usize,
    /// A session that made no call (no request after `initialize`) for this long after it
    /// opened is closed, seconds (1 … 86,400): an abandoned handshake gives its place back.
    pub unused_session_timeout_s: u64,
    /// A streamable-HTTP session without a request for this long is closed, seconds
    /// (1 … 86,400). SSE sessions end when their stream closes.
    pub session_idle_timeout_s: u64,
    /// Longest `arguments` or `result` written to the call log, bytes (256 … 16 MiB); longer
    /// ones are cut and the line says so.
    pub call_log_max_field_bytes: usize,
    /// Size at which the call log rotates, bytes (64 KiB … 16 GiB).
    pub call_log_max_file_bytes: u64,
    /// Rotated call logs kept (0 … 1,000).
    pub call_log_keep_files: u32,
    /// Run streamable-HTTP `tools/call` requests of initialized sessions without rmcp's
    /// session pipeline (`crate::http::direct_call`): ~100 µs less per call on a small PC.
    /// `false` sends every call through rmcp.
    pub direct_tool_calls: bool,
}

impl Default for McpConfig {
    fn default() -> Self {
        Self {
            enabled: true,
            token: None,
            max_body_bytes: 1024 * 1024,
            allowed_origins: Vec::new(),
            strict_errors: false,
            skill_timeout_s: 180,
            max_sessions: 100,
            max_sessions_per_client: 80,
            unused_session_timeout_s: 30,
            session_idle_timeout_s: 300,
            call_log_max_field_bytes: 16 * 1024,
            call_log_max_file_bytes: 64 * 1024 * 1024,
            call_log_keep_files: 5,
            direct_tool_calls: true,
        }
    }
}

impl Section for McpConfig {
    fn check(&self, checks: &mut Checks) {
        checks.range_u64(
            "max_body_bytes",
            self.max_body_bytes as u64,
            1024..=64 * 1024 * 1024,
            "",
        );
        checks.range_u64("skill_timeout_s", self.skill_timeout_s, 1..=3600, " s");
        checks.range_u64("max_sessions", self.max_sessions as u64, 1..=10_000, "");
        checks.range_u64(
            "max_sessions_per_client",
            self.max_sessions_per_client as u64,
            1..=10_000,
            "",
        );
        checks.range_u64(
            "unused_session_timeout_s",
            self.unused_session_timeout_s,
            1..=86_400,
            " s",
        );
        checks.range_u64(
            "session_idle_timeout_s",
            self.session_idle_timeout_s,
            1..=86_400,
            " s",
        );
        checks.range_u64(
            "call_log_max_field_bytes",
            self.call_log_max_field_bytes as u64,
            256..=16 * 1024 * 1024,
            "",
        );
        checks.range_u64(
            "call_log_max_file_bytes",
            self.call_log_max_file_bytes,
            64 * 1024..=16 * 1024 * 1024 * 1024,
            "",
        );
        checks.range_u64(
            "call_log_keep_files",
            u64::from(self.call_log_keep_files),
            0..=1_000,
            "",
        );
        if let Some(token) = &self.token {
            if token.trim().len() < 8 {
                checks.problem(
                    "token",
                    "must be at least 8 characters (a random string; leave it out for no token)",
                );
            }
        }
        for origin in &self.allowed_origins {
            if let Err(reason) = check_url(origin, &["http", "https"]) {
                checks.problem(
                    "allowed_origins",
                    format!("{reason}; expected an origin such as \"https://lab.example.org\""),
                );
            }
        }
    }
}

impl McpConfig {
    /// The problem of serving the HTTP port on `bind` without a token: anyone on the network
    /// could move the robot (MCP) or stop it (e-stop). `None` when `bind` is loopback or a
    /// token is set; MCP being off does not matter, the port serves more than MCP.
    pub fn bind_problem(&self, bind: std::net::SocketAddr) -> Option<(String, String)> {
        let no_token = self.token.as_deref().is_none_or(|t| t.trim().is_empty());
        (!bind.ip().is_loopback() && no_token).then(|| {
            (
                "mcp.token".to_owned(),
                format!(
                    "is required because http.bind {bind} is not a loopback address: without it \
                     anyone on the network could move or stop the robot and read its state (set \
                     ROBOTD_MCP__TOKEN, or bind 127.0.0.1)"
                ),
            )
        })
    }
}

impl McpConfig {
    /// The call log's limits.
    pub fn call_log_limits(&self) -> crate::call_log::CallLogLimits {
        crate::call_log::CallLogLimits {
            max_field_bytes: self.call_log_max_field_bytes,
            max_file_bytes: self.call_log_max_file_bytes,
            keep_files: self.call_log_keep_files,
        }
    }

    /// The MCP routes' limits.
    pub fn router_options(&self) -> crate::http::RouterOptions {
        crate::http::RouterOptions {
            max_body_bytes: self.max_body_bytes,
            max_sessions: self.max_sessions,
            max_sessions_per_client: self.max_sessions_per_client,
            unused_timeout: std::time::Duration::from_secs(self.unused_session_timeout_s),
            idle_timeout: std::time::Duration::from_secs(self.session_idle_timeout_s),
            direct_tool_calls: self.direct_tool_calls,
        }
    }
}
