//! Accepting the HTTP port's connections, with two limits a long-running service needs:
//!
//! - **a cap** ([`ConnectionLimits::max_connections`]): past it, a new connection gets one
//!   `503 Service Unavailable` naming the setting and is closed, so a client that opens
//!   connections without end cannot use up the process's file descriptors (the same port
//!   serves the e-stop);
//! - **an idle timeout** ([`ConnectionLimits::idle_timeout`]): a connection that does not
//!   send a complete request head within it — a kept-alive connection left unused, or a
//!   client that trickles its headers — is closed. A response in progress (a long tool call,
//!   an SSE stream) is not cut: the timeout runs only while the server waits for a request.
//!
//! Each connection is served by hyper's HTTP/1 server with TCP_NODELAY (without it a response
//! written in two pieces waits for the client's delayed ACK: a ~40 ms floor per call), and
//! handlers read the client's address as `ConnectInfo<SocketAddr>`, as with `axum::serve`.

use axum::extract::ConnectInfo;
use axum::Router;
use hyper_util::rt::{TokioIo, TokioTimer};
use std::future::Future;
use std::net::SocketAddr;
use std::sync::Arc;
use std::time::Duration;
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::{TcpListener, TcpStream};
use tokio::sync::{watch, Semaphore};
use tokio::task::JoinSet;

/// How many connections the port holds open and how long one may wait idle.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ConnectionLimits {
    /// Connections open at once; the next one gets a 503 and is closed.
    pub max_connections: usize,
    /// Longest wait for a request head on an open connection before it is closed.
    pub idle_timeout: Duration,
}

impl Default for ConnectionLimits {
    fn default() -> Self {
        Self {
            max_connections: 256,
            idle_timeout: Duration::from_secs(60),
        }
    }
}

/// How long open connections get to finish their responses after shutdown is asked.
const SHUTDOWN_GRACE: Duration = Duration::from_secs(2);

/// How long a refused connection is given to read its 503 before it is closed.
const REFUSAL_LINGER: Duration = Duration::from_secs(1);

/// Serves `app` on `listener` within `limits` until `shutdown` completes; then open
/// connections get [`SHUTDOWN_GRACE`] to finish and the rest are closed.
pub(crate) async fn serve(
    listener: TcpListener,
    app: Router,
    limits: ConnectionLimits,
    shutdown: impl Future<Output = ()> + Send + 'static,
) -> std::io::Result<()> {
    let permits = Arc::new(Semaphore::new(limits.max_connections));
    let (stop, stopping) = watch::channel(false);
    let mut connections = JoinSet::new();
    let mut refusals = JoinSet::new();
    tokio::pin!(shutdown);
    loop {
        while connections.try_join_next().is_some() {}
        while refusals.try_join_next().is_some() {}
        let (stream, peer) = tokio::select! {
            accepted = listener.accept() => match accepted {
                Ok(accepted) => accepted,
                Err(error) => {
                    // Out of descriptors or a connection reset before accept: keep serving
                    // the connections already open, try again shortly.
                    tracing::warn!(%error, "accepting an HTTP connection failed");
                    tokio::time::sleep(Duration::from_millis(100)).await;
                    continue;
                }
            },
            () = &mut shutdown => break,
        };
        if let Err(error) = stream.set_nodelay(true) {
            tracing::debug!(%error, "TCP_NODELAY not set");
        }
        let Ok(permit) = permits.clone().try_acquire_owned() else {
            tracing::warn!(%peer, max = limits.max_connections, "HTTP connection refused: too many open");
            refusals.spawn(refuse(stream, limits.max_connections));
            continue;
        };
        let app = app.clone();
        let stopping = stopping.clone();
        connections.spawn(async move {
            serve_connection(stream, peer, app, limits.idle_timeout, stopping).await;
            drop(permit);
        });
    }
    let _ = stop.send(true);
    refusals.abort_all();
    let _ = tokio::time::timeout(SHUTDOWN_GRACE, async {
        while connections.join_next().await.is_some() {}
    })
    .await;
    connections.abort_all();
    Ok(())
}

/// One connection: HTTP/1 with keep-alive, the idle timeout, and a graceful close on shutdown.
async fn serve_connection(
    stream: TcpStream,
    peer: SocketAddr,
    app: Router,
    idle_timeout: Duration,
    mut stopping: watch::Receiver<bool>,
) {
    let service = hyper::service::service_fn(move |mut request| {
        request.extensions_mut().insert(ConnectInfo(peer));
        tower_service::Service::call(&mut app.clone(), request)
    });
    let mut builder = hyper::server::conn::http1::Builder::new();
    builder
        .timer(TokioTimer::new())
        .header_read_timeout(idle_timeout)
        .keep_alive(true);
    let connection = builder.serve_connection(TokioIo::new(stream), service);
    tokio::pin!(connection);
    tokio::select! {
        result = connection.as_mut() => {
            if let Err(error) = result {
                tracing::debug!(%peer, %error, "HTTP connection ended");
            }
        }
        () = stopped(&mut stopping) => {
            connection.as_mut().graceful_shutdown();
            let _ = connection.await;
        }
    }
}

/// Completes when shutdown is asked (or the server is gone).
async fn stopped(stopping: &mut watch::Receiver<bool>) {
    while !*stopping.borrow_and_update() {
        if stopping.changed().await.is_err() {
            return;
        }
    }
}

/// Answers a connection over the cap with a 503 that says why, then closes it.
async fn refuse(mut stream: TcpStream, max_connections: usize) {
    let body = format!(
        "robotd: too many open HTTP connections ({max_connections}, http.max_connections); \
         close idle ones or raise the limit\n"
    );
    let response = format!(
        "HTTP/1.1 503 Service Unavailable\r\ncontent-type: text/plain; charset=utf-8\r\n\
         content-length: {}\r\nretry-after: 1\r\nconnection: close\r\n\r\n{body}",
        body.len()
    );
    if stream.write_all(response.as_bytes()).await.is_err() {
        return;
    }
    let _ = stream.shutdown().await;
    // Read what the client sent until it closes (or a moment passes): closing with unread
    // bytes would reset the connection and the client could lose the 503.
    let _ = tokio::time::timeout(REFUSAL_LINGER, async {
        let mut sink = [0u8; 1024];
        while matches!(stream.read(&mut sink).await, Ok(n) if n > 0) {}
    })
    .await;
}
