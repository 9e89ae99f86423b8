//! The live view: a Foxglove WebSocket server on `[foxglove] bind`, fed by the [`bridge`].
//!
//! The server only encodes what a connected app subscribed to (the SDK drops messages of
//! channels without sinks), so an idle live view costs the bridge's bus reading and nothing
//! more. The protocol has no authentication: robotd serves it on loopback only (the config
//! check refuses other addresses); watch from elsewhere through an SSH tunnel.
//!
//! Limits: each connected app gets a queue of [`CLIENT_BACKLOG`] messages; a client that reads
//! slower than the bridge publishes loses its oldest messages instead of growing the queue
//! (at most ~6 MB of camera frames per client). The SDK (0.26) has no cap on the number of
//! clients and no Origin check: any local process, including a web page in a local browser,
//! can connect — do not enable the live view on a shared machine whose camera must stay private.

use crate::bridge::{self, Bridge, BridgeSettings};
use foxglove::{Context, WebSocketServer, WebSocketServerHandle};
use robotd_runtime::bus::Bus;
use std::net::SocketAddr;

/// Messages queued per connected app before the oldest are dropped (the SDK's default is
/// 1,024: about 50 MB of camera frames for one stalled client).
pub const CLIENT_BACKLOG: usize = 128;

/// Why the live view did not start.
#[derive(Debug, thiserror::Error)]
pub enum LiveError {
    /// The WebSocket server did not start (address in use, …).
    #[error("the Foxglove live view cannot listen on {bind}: {reason} (set [foxglove] bind)")]
    Listen {
        /// The address asked for.
        bind: SocketAddr,
        /// The server's reason.
        reason: String,
    },
    /// The bridge thread did not start.
    #[error("the Foxglove live view's bus thread did not start: {0}")]
    Bridge(#[from] std::io::Error),
}

/// The running live view; dropping it stops the bridge (the server stops with the process).
pub struct LiveView {
    server: WebSocketServerHandle,
    _bridge: Bridge,
}

impl LiveView {
    /// The port the server listens on (useful with port 0).
    pub fn port(&self) -> u16 {
        self.server.port()
    }
}

/// Starts the server on `bind` and the bridge from `bus`. Call inside a tokio runtime.
pub async fn start(
    bus: Bus,
    bind: SocketAddr,
    settings: BridgeSettings,
) -> Result<LiveView, LiveError> {
    let context = Context::new();
    let server = WebSocketServer::new()
        .name("robotd")
        .bind(bind.ip().to_string(), bind.port())
        .context(&context)
        .message_backlog_size(CLIENT_BACKLOG)
        .start()
        .await
        .map_err(|e| LiveError::Listen {
            bind,
            reason: e.to_string(),
        })?;
    let bridge = bridge::start(bus, context, settings)?;
    Ok(LiveView {
        server,
        _bridge: bridge,
    })
}
