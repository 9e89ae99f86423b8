//! The server's share of an MCP call, measured with the leanest client: streamable HTTP here,
//! legacy SSE in [`super::mcp_raw_sse`].
//!
//! `robotd bench mcp` times calls made with robotd's MCP client (rmcp's), so its figures are
//! the server's work plus the client's (request bookkeeping, SSE parsing, task hand-offs). This client is
//! one kept-alive HTTP/1 connection driven by hyper's bare connection API on a thread of its
//! own (a single-threaded runtime: no connection pool, no hand-off between threads on the
//! client's side), posting ready-made JSON-RPC bodies and reading each reply whole. What it
//! adds is little more than the loopback round trip, so the difference between its latency
//! and the direct registry call is robotd's HTTP and MCP handling. Every reply is still
//! checked (the call's id and a `✓` answer), so a server that answered nothing or an error is
//! not timed as fast.
//!
//! (Until the ninth session this client was reqwest's: its pooled connection runs on another
//! task, and on the 2-core VM that hand-off alone added ~150 µs to each request.)

use super::Latency;
use anyhow::{bail, Context, Result};
use bytes::Bytes;
use http_body_util::{BodyExt, Full};
use hyper::client::conn::http1::SendRequest;
use hyper::{Method, Request, StatusCode};
use hyper_util::rt::TokioIo;
use serde_json::{json, Map, Value};
use std::net::SocketAddr;
use std::time::Instant;

/// The protocol version this client asks for: the newest one with sessions.
pub(super) const PROTOCOL_VERSION: &str = "2025-06-18";

/// One streamable-HTTP MCP session driven with plain HTTP requests on one connection.
pub struct RawSession {
    sender: SendRequest<Full<Bytes>>,
    host: String,
    session_id: String,
    protocol_version: String,
    next_id: u64,
}

/// A whole HTTP reply.
struct Reply {
    status: StatusCode,
    session_id: Option<String>,
    body: String,
}

impl RawSession {
    /// Connects to robotd's HTTP port at `addr` and opens an MCP session on `/mcp`
    /// (`initialize`, then `notifications/initialized`). Must run inside a tokio runtime: the
    /// connection is driven by a task of the current one.
    pub async fn open(addr: SocketAddr) -> Result<Self> {
        let mut session = Self {
            sender: connect(addr).await?,
            host: addr.to_string(),
            session_id: String::new(),
            protocol_version: PROTOCOL_VERSION.to_owned(),
            next_id: 1,
        };
        let reply = session
            .post(initialize_request("robotd-bench-raw"))
            .await
            .context("initialize")?;
        session.session_id = reply
            .session_id
            .context("the initialize answer named no Mcp-Session-Id")?;
        let answer = json_rpc_reply(&reply.body, 0)?;
        session.protocol_version = answer["result"]["protocolVersion"]
            .as_str()
            .context("the initialize answer named no protocol version")?
            .to_owned();
        let status = session.post(INITIALIZED.to_owned()).await?.status;
        if !status.is_success() {
            bail!("notifications/initialized answered {status}");
        }
        Ok(session)
    }

    /// Sends one request on the connection and reads its reply whole.
    async fn send(&mut self, method: Method, path: &str, body: String) -> Result<Reply> {
        let mut request = Request::builder()
            .method(method)
            .uri(path)
            .header("host", &self.host)
            .header("content-type", "application/json")
            .header("accept", "application/json, text/event-stream");
        if !self.session_id.is_empty() {
            request = request
                .header("mcp-session-id", &self.session_id)
                .header("mcp-protocol-version", &self.protocol_version);
        }
        let request = request.body(Full::new(Bytes::from(body)))?;
        let (head, bytes) = exchange(&mut self.sender, request).await?;
        let session_id = head
            .headers
            .get("mcp-session-id")
            .and_then(|v| v.to_str().ok())
            .map(str::to_owned);
        let body = String::from_utf8(bytes.to_vec()).context("a reply that is not UTF-8")?;
        Ok(Reply {
            status: head.status,
            session_id,
            body,
        })
    }

    async fn post(&mut self, body: String) -> Result<Reply> {
        self.send(Method::POST, "/mcp", body).await
    }

    /// Calls `tool` and checks that it answered its id with a `✓` text.
    pub async fn call(&mut self, tool: &str, arguments: &Map<String, Value>) -> Result<()> {
        let id = self.next_id;
        self.next_id += 1;
        let reply = self.post(tool_call_request(id, tool, arguments)).await?;
        check_tool_answer(tool, &json_rpc_reply(&reply.body, id)?)
    }

    /// A JSON-RPC `ping` through the session: the MCP layer's path without a tool.
    pub async fn ping(&mut self) -> Result<()> {
        let id = self.next_id;
        self.next_id += 1;
        let body = json!({"jsonrpc": "2.0", "id": id, "method": "ping"});
        let reply = self.post(body.to_string()).await?;
        let reply = json_rpc_reply(&reply.body, id)?;
        if reply["result"] != json!({}) {
            bail!("ping answered {reply}");
        }
        Ok(())
    }

    /// `GET /health` on the same port and connection: the HTTP floor, no MCP at all.
    pub async fn health(&mut self) -> Result<()> {
        let reply = self.send(Method::GET, "/health", String::new()).await?;
        if !reply.status.is_success() || reply.body.is_empty() {
            bail!("GET /health answered {}", reply.status);
        }
        Ok(())
    }

    /// Ends the session (`DELETE`).
    pub async fn close(mut self) {
        let _ = self.send(Method::DELETE, "/mcp", String::new()).await;
    }
}

/// The `initialize` request (id 0) of a client named `client_name`.
pub(super) fn initialize_request(client_name: &str) -> String {
    json!({
        "jsonrpc": "2.0", "id": 0, "method": "initialize",
        "params": {
            "protocolVersion": PROTOCOL_VERSION,
            "capabilities": {},
            "clientInfo": {"name": client_name, "version": "0"}
        }
    })
    .to_string()
}

/// The notification that ends a session's initialization.
pub(super) const INITIALIZED: &str = r#"{"jsonrpc":"2.0","method":"notifications/initialized"}"#;

/// A `tools/call` request of `tool` with `arguments`.
pub(super) fn tool_call_request(id: u64, tool: &str, arguments: &Map<String, Value>) -> String {
    json!({
        "jsonrpc": "2.0", "id": id, "method": "tools/call",
        "params": {"name": tool, "arguments": arguments}
    })
    .to_string()
}

/// Fails unless `reply` is a tool's success (a text starting with `✓`): a server that
/// answered an error must not be timed as fast.
pub(super) fn check_tool_answer(tool: &str, reply: &Value) -> Result<()> {
    let answer = reply["result"]["content"][0]["text"].as_str().unwrap_or("");
    if !answer.starts_with('✓') {
        bail!("{tool} answered {reply}");
    }
    Ok(())
}

/// Sends `request` once the connection is free and reads its answer whole.
pub(super) async fn exchange(
    sender: &mut SendRequest<Full<Bytes>>,
    request: Request<Full<Bytes>>,
) -> Result<(hyper::http::response::Parts, Bytes)> {
    sender
        .ready()
        .await
        .context("the connection to robotd closed")?;
    let (head, body) = sender.send_request(request).await?.into_parts();
    Ok((head, body.collect().await?.to_bytes()))
}

/// One kept-alive HTTP/1 connection to `addr` (no Nagle delay), driven by a task of the
/// current runtime.
pub(super) async fn connect(addr: SocketAddr) -> Result<SendRequest<Full<Bytes>>> {
    let stream = tokio::net::TcpStream::connect(addr)
        .await
        .with_context(|| format!("connecting to {addr}"))?;
    stream.set_nodelay(true)?;
    let (sender, connection) = hyper::client::conn::http1::handshake(TokioIo::new(stream))
        .await
        .context("HTTP/1 handshake")?;
    tokio::spawn(async move {
        if let Err(error) = connection.await {
            tracing::debug!(%error, "the lean MCP client's connection ended");
        }
    });
    Ok(sender)
}

/// The JSON-RPC message answering `id` in a reply body: plain JSON, or the `data:` lines of
/// an event stream.
pub(super) fn json_rpc_reply(body: &str, id: u64) -> Result<Value> {
    let candidates = std::iter::once(body.trim()).chain(
        body.lines()
            .filter_map(|line| line.strip_prefix("data:"))
            .map(str::trim),
    );
    candidates
        .filter_map(|text| serde_json::from_str::<Value>(text).ok())
        .find(|message| message["id"] == json!(id))
        .with_context(|| format!("no answer to request {id} in the reply {body:?}"))
}

/// Where a streamable-HTTP call's time goes, layer by layer, on one kept-alive connection.
pub struct Layers {
    /// `GET /health`: TCP, HTTP and the port's guard.
    pub http: Latency,
    /// MCP `ping`: the above plus rmcp's session pipeline.
    pub ping: Latency,
    /// `tool`: the above plus the tool and its bus round trip.
    pub call: Latency,
    /// `tool` over legacy SSE ([`super::mcp_raw_sse`]): posted on one connection, answered on
    /// the session's event stream.
    pub sse_call: Latency,
}

/// `calls` rounds of a `GET /health`, a `ping` and a call of `tool` on a fresh raw session
/// with robotd's HTTP port at `addr`, and a call of `tool` on a fresh raw legacy-SSE session,
/// interleaved so that all four see the same machine.
/// The client runs on a thread of its own with a single-threaded runtime.
pub async fn layers(
    addr: SocketAddr,
    tool: &str,
    arguments: &Map<String, Value>,
    calls: usize,
) -> Result<Layers> {
    let tool = tool.to_owned();
    let arguments = arguments.clone();
    let (answer, answered) = tokio::sync::oneshot::channel();
    std::thread::Builder::new()
        .name("bench-mcp-lean".into())
        .spawn(move || {
            let result = tokio::runtime::Builder::new_current_thread()
                .enable_all()
                .build()
                .context("the lean client's runtime")
                .and_then(|runtime| runtime.block_on(measure(addr, &tool, &arguments, calls)));
            let _ = answer.send(result);
        })
        .context("starting the lean client's thread")?;
    answered
        .await
        .context("the lean client's thread ended without an answer")?
}

async fn measure(
    addr: SocketAddr,
    tool: &str,
    arguments: &Map<String, Value>,
    calls: usize,
) -> Result<Layers> {
    let mut session = RawSession::open(addr).await?;
    let mut sse = super::mcp_raw_sse::RawSseSession::open(addr)
        .await
        .context("the lean legacy-SSE session")?;
    let mut http = Vec::with_capacity(calls);
    let mut ping = Vec::with_capacity(calls);
    let mut call = Vec::with_capacity(calls);
    let mut sse_call = Vec::with_capacity(calls);
    for _ in 0..calls {
        let started = Instant::now();
        session.health().await?;
        http.push(started.elapsed());
        let started = Instant::now();
        session.ping().await?;
        ping.push(started.elapsed());
        let started = Instant::now();
        session.call(tool, arguments).await?;
        call.push(started.elapsed());
        let started = Instant::now();
        sse.call(tool, arguments).await?;
        sse_call.push(started.elapsed());
    }
    session.close().await;
    Ok(Layers {
        http: Latency::of(&mut http),
        ping: Latency::of(&mut ping),
        call: Latency::of(&mut call),
        sse_call: Latency::of(&mut sse_call),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_answer_is_found_in_an_event_stream_and_in_plain_json() {
        let stream = "id: 0\nretry: 3000\ndata: \n\nevent: message\ndata: {\"jsonrpc\":\"2.0\",\"id\":7,\"result\":{}}\n\n";
        assert_eq!(json_rpc_reply(stream, 7).unwrap()["id"], 7);
        assert_eq!(
            json_rpc_reply("{\"jsonrpc\":\"2.0\",\"id\":3,\"result\":{}}", 3).unwrap()["id"],
            3
        );
    }

    #[test]
    fn an_answer_to_another_request_is_not_taken() {
        let stream = "data: {\"jsonrpc\":\"2.0\",\"id\":6,\"result\":{}}\n\n";
        let error = json_rpc_reply(stream, 7).unwrap_err().to_string();
        assert!(error.contains("no answer to request 7"), "{error}");
    }
}
