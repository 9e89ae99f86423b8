//! Accepting the HTTP port's connections, with two limits a long-running service needs:
//!
//! - **a cap** ([`ConnectionLimits::max_connections`]): past it, a new connection gets one
//!   `503 Service Unavailable` naming the setting and is closed, so a client that opens
//!   connections without end cannot use up the process's file descriptors (the same port
//!   serves the e-stop). So that one remote client cannot fill it, a remote address holds at
//!   most a quarter of the places, and the last [`LOOPBACK_RESERVE`] are kept for clients on
//!   this machine (the dashboard's e-stop, local tools). The guard closes the connection of
//!   every request it refuses, so requests without the token hold no place either;
//! - **an idle timeout** ([`ConnectionLimits::idle_timeout`]): a connection that does not
//!   send a complete request head within it — a kept-alive connection left unused, or a
//!   client that trickles its headers — is closed. A response in progress (a long tool call,
//!   an SSE stream) is not cut: the timeout runs only while the server waits for a request.
//!   A request's body must arrive within the same time after its head
//!   ([`crate::body_deadline`]).
//!
//! Each connection is served by hyper's HTTP/1 server with TCP_NODELAY (without it a response
//! written in two pieces waits for the client's delayed ACK: a ~40 ms floor per call), on a
//! task of its own, and handlers read the client's address as `ConnectInfo<SocketAddr>`, as
//! with `axum::serve`.

use crate::body_deadline::DeadlineBody;
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

/// Places under the cap only clients on this machine may take.
pub const LOOPBACK_RESERVE: usize = 16;

/// Turned-away connections answered at once; past this, more are closed without a word.
const MAX_REFUSALS_IN_FLIGHT: usize = 64;

/// How long open connections get to finish their responses after shutdown is asked.
pub(crate) const SHUTDOWN_GRACE: Duration = Duration::from_secs(2);

/// How long a refused connection is given to read its 503 before it is closed.
const REFUSAL_LINGER: Duration = Duration::from_secs(1);

/// Serves `app` on `listener` within `limits` until `shutdown` completes; then event streams
/// end ([`crate::event_streams`]), open connections get [`SHUTDOWN_GRACE`] to finish their
/// responses and the rest are closed.
pub(crate) async fn serve(
    listener: TcpListener,
    app: Router,
    limits: ConnectionLimits,
    shutdown: impl Future<Output = ()> + Send + 'static,
) -> std::io::Result<()> {
    let places = Places::new(limits.max_connections);
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
        let Some(place) = places.take(peer.ip()) else {
            tracing::warn!(%peer, max = limits.max_connections, "HTTP connection refused: too many open");
            if refusals.len() < MAX_REFUSALS_IN_FLIGHT {
                refusals.spawn(refuse(stream, limits.max_connections));
            }
            continue;
        };
        let app = app.clone();
        let stopping = stopping.clone();
        connections.spawn(async move {
            serve_connection(stream, peer, app, limits.idle_timeout, stopping).await;
            drop(place);
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

/// Who holds the port's places: all of them, the remote share, and each remote address's.
#[derive(Clone)]
struct Places {
    all: Arc<Semaphore>,
    remote: Arc<Semaphore>,
    per_address: Arc<std::sync::Mutex<std::collections::HashMap<std::net::IpAddr, usize>>>,
    max_per_address: usize,
}

/// A connection's place; given back when dropped.
struct Place {
    _all: tokio::sync::OwnedSemaphorePermit,
    _remote: Option<tokio::sync::OwnedSemaphorePermit>,
    address: Option<(std::net::IpAddr, Places)>,
}

impl Places {
    fn new(max_connections: usize) -> Self {
        let reserve = LOOPBACK_RESERVE.min(max_connections / 2);
        Self {
            all: Arc::new(Semaphore::new(max_connections)),
            remote: Arc::new(Semaphore::new(max_connections - reserve)),
            per_address: Arc::default(),
            max_per_address: (max_connections / 4).max(1),
        }
    }

    /// A place for a connection from `ip`, if the limits leave one.
    fn take(&self, ip: std::net::IpAddr) -> Option<Place> {
        let all = self.all.clone().try_acquire_owned().ok()?;
        if is_this_machine(ip) {
            return Some(Place {
                _all: all,
                _remote: None,
                address: None,
            });
        }
        let remote = self.remote.clone().try_acquire_owned().ok()?;
        let mut counts = self.per_address.lock().unwrap_or_else(|e| e.into_inner());
        let held = counts.entry(ip).or_default();
        if *held >= self.max_per_address {
            return None;
        }
        *held += 1;
        Some(Place {
            _all: all,
            _remote: Some(remote),
            address: Some((ip, self.clone())),
        })
    }
}

impl Drop for Place {
    fn drop(&mut self) {
        if let Some((ip, places)) = self.address.take() {
            let mut counts = places.per_address.lock().unwrap_or_else(|e| e.into_inner());
            if let Some(held) = counts.get_mut(&ip) {
                *held -= 1;
                if *held == 0 {
                    counts.remove(&ip);
                }
            }
        }
    }
}

/// Loopback addresses, IPv4-mapped ones included.
fn is_this_machine(ip: std::net::IpAddr) -> bool {
    match ip {
        std::net::IpAddr::V4(v4) => v4.is_loopback(),
        std::net::IpAddr::V6(v6) => {
            v6.is_loopback() || v6.to_ipv4_mapped().is_some_and(|v4| v4.is_loopback())
        }
    }
}

/// One connection: HTTP/1 with keep-alive, the idle timeout, and a graceful close on shutdown.
async fn serve_connection(
    stream: TcpStream,
    peer: SocketAddr,
    app: Router,
    idle_timeout: Duration,
    mut stopping: watch::Receiver<bool>,
) {
    let stopping_for_streams = stopping.clone();
    let service = hyper::service::service_fn(move |request: hyper::Request<_>| {
        let mut request = request.map(|body| {
            axum::body::Body::new(DeadlineBody::new(axum::body::Body::new(body), idle_timeout))
        });
        request.extensions_mut().insert(ConnectInfo(peer));
        let response = tower_service::Service::call(&mut app.clone(), request);
        let stopping = stopping_for_streams.clone();
        async move {
            response
                .await
                .map(|response| crate::event_streams::ends_at_shutdown(response, stopping))
        }
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

/// [`stopped`], owning its receiver.
pub(crate) async fn stopped_owned(mut stopping: watch::Receiver<bool>) {
    stopped(&mut stopping).await
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_remote_address_holds_a_quarter_and_this_machine_keeps_a_reserve() {
        let places = Places::new(64);
        let remote: std::net::IpAddr = "10.0.0.5".parse().unwrap();
        let held: Vec<Place> = (0..16).map_while(|_| places.take(remote)).collect();
        assert_eq!(held.len(), 16, "a quarter of 64");
        assert!(places.take(remote).is_none());
        // Other remote addresses fill the rest but the reserve.
        let mut others = Vec::new();
        for i in 0.. {
            let ip: std::net::IpAddr = format!("10.0.1.{i}").parse().unwrap();
            match places.take(ip) {
                Some(place) => others.push(place),
                None => break,
            }
        }
        assert_eq!(held.len() + others.len(), 64 - LOOPBACK_RESERVE);
        let local: Vec<Place> = (0..16)
            .map_while(|_| places.take("127.0.0.1".parse().unwrap()))
            .collect();
        assert_eq!(local.len(), LOOPBACK_RESERVE, "this machine still gets in");
        assert!(
            places.take("::1".parse().unwrap()).is_none(),
            "the cap holds"
        );
        drop(held);
        assert!(places.take(remote).is_some(), "places are given back");
    }
}
