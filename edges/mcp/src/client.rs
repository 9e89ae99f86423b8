//! MCP clients of any MCP server: legacy HTTP+SSE (hand-written, as rmcp 3 has no SSE client)
//! and streamable HTTP (rmcp's), behind one [`connect`].
//!
//! Used by `robotd call`, `robotd bench mcp`, the tests, and `robotd chat --mcp` — so robotd
//! can drive its own edge and any other MCP robot server. A URL whose path ends in `/sse` is
//! spoken to with the legacy transport, anything else with streamable HTTP.
//!
//! The SSE transport: `GET <url>` opens the event stream; its `endpoint` event names the URL
//! to POST JSON-RPC messages to; replies arrive as `message` events. Both halves run as
//! tasks joined to rmcp by a pair of channels.

use futures::channel::mpsc;
use futures::{SinkExt, StreamExt};
use rmcp::model::{ClientJsonRpcMessage, ServerJsonRpcMessage};
use rmcp::service::RunningService;
use rmcp::transport::streamable_http_client::StreamableHttpClientTransportConfig;
use rmcp::transport::StreamableHttpClientTransport;
use rmcp::{RoleClient, ServiceExt};
use std::time::Duration;

/// A connected MCP client session.
pub type McpClient = RunningService<RoleClient, ()>;

/// Why a client could not connect.
#[derive(Debug, thiserror::Error)]
pub enum ConnectError {
    /// The URL is not an `http://` or `https://` URL.
    #[error("'{url}' is not an MCP URL: expected http(s)://host:port/sse or …/mcp")]
    BadUrl {
        /// The URL given.
        url: String,
    },
    /// The HTTP exchange failed.
    #[error("{url}: {reason}")]
    Http {
        /// The URL.
        url: String,
        /// What went wrong.
        reason: String,
    },
    /// The MCP handshake failed.
    #[error("{url}: MCP initialisation failed: {reason}")]
    Handshake {
        /// The URL.
        url: String,
        /// What went wrong.
        reason: String,
    },
}

fn http_error(url: &str, reason: impl std::fmt::Display) -> ConnectError {
    ConnectError::Http {
        url: url.to_owned(),
        reason: reason.to_string(),
    }
}

/// Connects to the MCP server at `url` (`…/sse` = legacy SSE, otherwise streamable HTTP),
/// sending `token` as a bearer token when given, and completes the MCP handshake.
pub async fn connect(url: &str, token: Option<&str>) -> Result<McpClient, ConnectError> {
    robotd_runtime::telemetry::install_tls_provider();
    if !(url.starts_with("http://") || url.starts_with("https://")) {
        return Err(ConnectError::BadUrl {
            url: url.to_owned(),
        });
    }
    let path = url.split('?').next().unwrap_or(url).trim_end_matches('/');
    let handshake = |e: &dyn std::fmt::Display| ConnectError::Handshake {
        url: url.to_owned(),
        reason: e.to_string(),
    };
    if path.ends_with("/sse") {
        let (sink, stream) = sse_transport(url, token).await?;
        ().serve((sink, stream)).await.map_err(|e| handshake(&e))
    } else {
        let mut config = StreamableHttpClientTransportConfig::with_uri(url.to_owned());
        if let Some(token) = token {
            config = config.auth_header(token.to_owned());
        }
        let transport =
            StreamableHttpClientTransport::with_client(pooled_http_client(url)?, config);
        ().serve(transport).await.map_err(|e| handshake(&e))
    }
}

/// The HTTP client of a streamable-HTTP session: one that keeps its connections.
///
/// rmcp's default client keeps none (`pool_max_idle_per_host(0)`), so every request opens a
/// new TCP connection: on the 2-vCPU test VM that was most of a cheap call's time with this
/// client (BENCHMARKS.md, fourteenth session). rmcp gave up pooling after stalls of ~40 ms
/// (Nagle's algorithm against delayed ACKs) on connections whose event-stream answer had not
/// been read to its end. Here requests go out with `TCP_NODELAY`, robotd answers with
/// `TCP_NODELAY` and ends each request's event stream after its answer, and rmcp reads a
/// stream to its end after the answer (up to 50 ms) before the connection is reused; a
/// connection whose answer was not read to its end is closed by hyper, never reused.
fn pooled_http_client(url: &str) -> Result<reqwest::Client, ConnectError> {
    robotd_runtime::telemetry::install_tls_provider();
    reqwest::Client::builder()
        .connect_timeout(Duration::from_secs(10))
        .tcp_nodelay(true)
        // Shorter than servers keep an idle connection (uvicorn: 5 s, robotd: 60 s), so a
        // request is not sent down a connection the server is closing.
        .pool_idle_timeout(Duration::from_secs(4))
        .redirect(same_origin_redirects())
        .build()
        .map_err(|e| http_error(url, e))
}

/// Follows only the redirects that keep a POST's body (307, 308) to the same origin, at most
/// [`MAX_REDIRECTS`] (as rmcp's default client does): a 301–303 would turn the POSTed message
/// into a GET without it, and another origin must not see the session id or the token.
fn same_origin_redirects() -> reqwest::redirect::Policy {
    reqwest::redirect::Policy::custom(|attempt| {
        let keeps_body = matches!(
            attempt.status(),
            reqwest::StatusCode::TEMPORARY_REDIRECT | reqwest::StatusCode::PERMANENT_REDIRECT
        );
        let same_origin = attempt
            .previous()
            .first()
            .is_some_and(|first| first.origin() == attempt.url().origin());
        if !keeps_body || !same_origin {
            attempt.stop()
        } else if attempt.previous().len() > MAX_REDIRECTS {
            attempt.error(format!("more than {MAX_REDIRECTS} redirects"))
        } else {
            attempt.follow()
        }
    })
}

/// Most redirects one request follows.
const MAX_REDIRECTS: usize = 10;

/// The events of a `text/event-stream` body (the `sse-stream` crate: lines split across
/// chunks, and UTF-8 characters split across chunks, are put back together before decoding).
fn event_stream<S, E>(
    bytes: S,
) -> sse_stream::SseStream<sse_stream::ByteStreamBody<S, bytes::Bytes>>
where
    S: futures::Stream<Item = Result<bytes::Bytes, E>>,
    E: std::error::Error,
{
    sse_stream::SseStream::from_bytes_stream(bytes)
}

/// Resolves the `endpoint` event's (usually relative) URL against the SSE URL.
fn resolve(base: &str, endpoint: &str) -> String {
    if endpoint.starts_with("http://") || endpoint.starts_with("https://") {
        return endpoint.to_owned();
    }
    let scheme_end = base.find("://").map(|i| i + 3).unwrap_or(0);
    let origin_end = base[scheme_end..]
        .find('/')
        .map(|i| scheme_end + i)
        .unwrap_or(base.len());
    let origin = &base[..origin_end];
    if endpoint.starts_with('/') {
        format!("{origin}{endpoint}")
    } else {
        format!("{origin}/{endpoint}")
    }
}

async fn sse_transport(
    url: &str,
    token: Option<&str>,
) -> Result<
    (
        mpsc::Sender<ClientJsonRpcMessage>,
        mpsc::Receiver<ServerJsonRpcMessage>,
    ),
    ConnectError,
> {
    let http = reqwest::Client::builder()
        .connect_timeout(Duration::from_secs(10))
        .build()
        .map_err(|e| http_error(url, e))?;
    let mut request = http.get(url).header("Accept", "text/event-stream");
    if let Some(token) = token {
        request = request.bearer_auth(token);
    }
    let response = request.send().await.map_err(|e| http_error(url, e))?;
    if !response.status().is_success() {
        let status = response.status();
        let body = response.text().await.unwrap_or_default();
        return Err(http_error(url, format!("{status}: {body}")));
    }
    let mut events = Box::pin(event_stream(response.bytes_stream()));
    let mut pending = Vec::new();
    let endpoint = loop {
        let event = tokio::time::timeout(Duration::from_secs(10), events.next())
            .await
            .map_err(|_| http_error(url, "no endpoint event within 10 s"))?
            .ok_or_else(|| http_error(url, "the event stream ended before the endpoint event"))?
            .map_err(|e| http_error(url, e))?;
        if event.event.as_deref() == Some("endpoint") {
            break resolve(url, event.data.as_deref().unwrap_or("").trim());
        }
        pending.push(event);
    };
    let (to_client, from_server) = mpsc::channel::<ServerJsonRpcMessage>(64);
    let (to_server, mut outgoing) = mpsc::channel::<ClientJsonRpcMessage>(64);
    // Reader: events → rmcp.
    let mut inbound = to_client;
    tokio::spawn(async move {
        let deliver = |event: sse_stream::Sse| -> Option<ServerJsonRpcMessage> {
            if !matches!(event.event.as_deref(), None | Some("message")) {
                return None;
            }
            match serde_json::from_str(event.data.as_deref()?) {
                Ok(message) => Some(message),
                Err(error) => {
                    tracing::warn!(%error, "unreadable SSE message from the server skipped");
                    None
                }
            }
        };
        for event in pending {
            if let Some(m) = deliver(event) {
                if inbound.send(m).await.is_err() {
                    return;
                }
            }
        }
        // Until the stream ends or the client is gone: a client that closed (or was dropped)
        // closes the event stream within half a second, so the server ends the session at once (waiting for
        // the next message to find out kept the connection open for as long as the server
        // had nothing to say).
        let mut check = tokio::time::interval(Duration::from_millis(500));
        loop {
            let event = tokio::select! {
                _ = check.tick() => {
                    if inbound.is_closed() {
                        return;
                    }
                    continue;
                }
                event = events.next() => event,
            };
            let Some(Ok(event)) = event else {
                return;
            };
            if let Some(m) = deliver(event) {
                if inbound.send(m).await.is_err() {
                    return;
                }
            }
        }
    });
    // Writer: rmcp → POSTs.
    let token = token.map(str::to_owned);
    tokio::spawn(async move {
        while let Some(message) = outgoing.next().await {
            let mut post = http.post(&endpoint).json(&message);
            if let Some(token) = &token {
                post = post.bearer_auth(token);
            }
            match post.send().await {
                Ok(r) if r.status().is_success() => {}
                Ok(r) => {
                    tracing::warn!(status = %r.status(), "the MCP server refused a message");
                }
                Err(error) => {
                    tracing::warn!(%error, "posting an MCP message failed");
                    return;
                }
            }
        }
    });
    Ok((to_server, from_server))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The events of `chunks` fed to [`event_stream`] one by one.
    fn events_of(chunks: Vec<Vec<u8>>) -> Vec<(Option<String>, Option<String>)> {
        let bytes = futures::stream::iter(
            chunks
                .into_iter()
                .map(|c| Ok::<_, std::io::Error>(bytes::Bytes::from(c))),
        );
        futures::executor::block_on(
            event_stream(bytes)
                .map(|e| e.expect("a well-formed event"))
                .map(|e| (e.event, e.data))
                .collect(),
        )
    }

    #[test]
    fn events_are_parsed_across_chunks() {
        let events = events_of(vec![
            b"event: endpoint\r\nda".to_vec(),
            b"ta: /messages/?session_id=ab\r\n\r\n: ping\n\nevent: message\ndata: {\"a\":\ndata: 1}\n\n"
                .to_vec(),
        ]);
        assert_eq!(
            events,
            vec![
                (
                    Some("endpoint".into()),
                    Some("/messages/?session_id=ab".into())
                ),
                (Some("message".into()), Some("{\"a\":\n1}".into())),
            ]
        );
    }

    #[test]
    fn a_character_split_across_chunks_arrives_whole() {
        // "✓ done" with the three bytes of ✓ split over three chunks.
        let text = "data: ✓ done\n\n".as_bytes();
        let at = "data: ".len();
        let chunks = vec![
            text[..at + 1].to_vec(),
            text[at + 1..at + 2].to_vec(),
            text[at + 2..].to_vec(),
        ];
        assert_eq!(events_of(chunks), vec![(None, Some("✓ done".into()))]);
    }

    /// A server on loopback answering `POST /a` 307 → `/b`, `/c` 302 → `/b`, `/d` 307 → the
    /// same port under another host name (another origin), `/b` 200.
    async fn redirecting_server() -> u16 {
        use axum::http::{header::LOCATION, StatusCode};
        let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
        let port = listener.local_addr().unwrap().port();
        let to = |status: StatusCode, location: String| {
            move || async move { (status, [(LOCATION, location)]) }
        };
        let app = axum::Router::new()
            .route(
                "/a",
                axum::routing::post(to(StatusCode::TEMPORARY_REDIRECT, "/b".into())),
            )
            .route(
                "/c",
                axum::routing::post(to(StatusCode::FOUND, "/b".into())),
            )
            .route(
                "/d",
                axum::routing::post(to(
                    StatusCode::TEMPORARY_REDIRECT,
                    format!("http://localhost:{port}/b"),
                )),
            )
            .route(
                "/b",
                axum::routing::post(|body: String| async move { body }),
            );
        tokio::spawn(async move { axum::serve(listener, app).await });
        port
    }

    #[tokio::test]
    async fn only_same_origin_redirects_that_keep_the_body_are_followed() {
        let port = redirecting_server().await;
        let client = pooled_http_client("test").unwrap();
        let post = |path: &str| {
            client
                .post(format!("http://127.0.0.1:{port}{path}"))
                .body("the message")
                .send()
        };
        let followed = post("/a").await.unwrap();
        assert_eq!(followed.status(), 200);
        assert_eq!(followed.text().await.unwrap(), "the message");
        assert_eq!(post("/c").await.unwrap().status(), 302);
        assert_eq!(post("/d").await.unwrap().status(), 307);
    }

    #[test]
    fn endpoints_resolve_against_the_server() {
        assert_eq!(
            resolve("http://127.0.0.1:8000/sse", "/messages/?session_id=1"),
            "http://127.0.0.1:8000/messages/?session_id=1"
        );
        assert_eq!(
            resolve("http://h:1/a/sse", "http://other/x"),
            "http://other/x"
        );
    }
}
