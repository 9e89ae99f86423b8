//! # robotd-web: what the HTTP-facing edges share
//!
//! The HTTP edge (`edges/http`: dashboard, health, e-stop) and the MCP edge (`edges/mcp`:
//! the tools over SSE and streamable HTTP) serve on the same listener behind the same guard,
//! and need two things in common that belong to neither:
//!
//! - [`bearer::bearer_token`]: the token a request presents (the `Authorization` header, or
//!   `?access_token=` where a browser cannot set headers). The HTTP guard checks it; the MCP
//!   edge binds sessions to it.
//! - [`body_deadline`]: a request body that must arrive within a deadline after its head, and
//!   [`body_deadline::is_too_slow`] to answer such a body `408 Request Timeout`.
//!
//! Living here, below the edges, they keep one edge from depending on another.

pub mod bearer;
pub mod body_deadline;
