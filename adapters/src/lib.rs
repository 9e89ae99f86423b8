//! robotd adapters: the edges that translate the outside world into bus messages.
//!
//! Edges hold no robot logic. This crate has the HTTP edge (health and Prometheus metrics);
//! the MCP and Redis edges join it in later work.
pub mod http;
