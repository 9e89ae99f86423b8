//! The origin of the work a task does, carried with every bus request it makes.
//!
//! An edge runs each piece of work (an MCP tool call, an agent request) inside
//! [`with_origin`]; every [`Client`](crate::bus::Client) request made inside it, however deep
//! (the tool, the skills actor's own requests to the arm while serving it), carries that
//! [`Origin`], and the serving side reads it from [`Incoming::origin`](crate::bus::Incoming).
//! A server that does work on behalf of a request runs it inside `with_origin` too, so the
//! origin follows the work across actors and processes. Outside any scope the origin is an
//! unnamed bus client.
//!
//! ```
//! use robotd_protocol::safety::{Origin, OriginKind};
//! use robotd_runtime::origin::{current_origin, with_origin};
//!
//! # tokio::runtime::Builder::new_current_thread().build().unwrap().block_on(async {
//! assert_eq!(current_origin().kind, OriginKind::Bus);
//! let seen = with_origin(Origin::new(OriginKind::Cli), async { current_origin() }).await;
//! assert_eq!(seen.kind, OriginKind::Cli);
//! # });
//! ```

use robotd_protocol::safety::Origin;
use std::future::Future;

tokio::task_local! {
    static ORIGIN: Origin;
}

/// Runs `work` with `origin` as the origin of every bus request it makes.
pub async fn with_origin<F: Future>(origin: Origin, work: F) -> F::Output {
    ORIGIN.scope(origin, work).await
}

/// The origin of the current task's work (an unnamed bus client outside any scope).
pub fn current_origin() -> Origin {
    ORIGIN.try_with(Origin::clone).unwrap_or_default()
}
