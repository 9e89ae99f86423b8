//! # robotd-dashboard: the robot in a browser
//!
//! `robotd serve` serves a page at `/` on its HTTP port: the live camera with the detections
//! drawn, a top-down map of the workspace (sheet, objects, the tool), the objects table, a chat
//! with the LLM agent showing its plan, each tool call as it happens and the pictures it
//! looked at ([`pictures`]), actor health and
//! restarts, recent speech, and an e-stop button that is always on screen. The page is one
//! HTML file with its script inline (no build step, nothing fetched from elsewhere), and it is
//! built only on the [`api`] that scripts can use as well.
//!
//! The page is fed by [`live`]: one thread that reads the bus and keeps the newest state, so a
//! browser never slows the robot — the camera is encoded at most `camera_fps` times a second
//! and a slow viewer skips frames.
//!
//! Security is the port's: the routes sit behind the same guard as MCP (loopback by default;
//! with a token, open the page as `/?access_token=<token>`; the page passes it on).

pub mod api;
pub mod config;
pub mod live;
mod page;
pub mod pictures;
pub mod voice;

pub use api::{AgentLink, DashboardApi};
pub use config::DashboardConfig;

/// The page and its API.
pub fn router(api: DashboardApi) -> axum::Router {
    page::routes().merge(api::routes(api))
}
