//! The server's share of a legacy-SSE MCP call, measured with the leanest client.
//!
//! The legacy transport takes two connections: `GET /sse` opens the session's event stream,
//! whose first event (`endpoint`) names where to post; each JSON-RPC message is then a
//! `POST /messages/?session_id=…`, answered `202 Accepted`, and the request's answer comes
//! back on the event stream. robotd's MCP client adds its own work on both sides of that
//! (reqwest's pooled connection task, its transport tasks, rmcp's service loop, an event-stream
//! parser); this client is two kept-alive HTTP/1 connections driven by hyper's bare connection
//! API on the lean client's thread ([`super::mcp_raw`]), so the time from posting a call to reading its answer is the
//! loopback round trips plus robotd's own work. Every answer is still checked (the call's id
//! and a `✓` text), so a server that answered nothing or an error is not timed as fast.

use super::mcp_raw::{
    check_tool_answer, connect, exchange, initialize_request, json_rpc_reply, tool_call_request,
    INITIALIZED,
};
use anyhow::{bail, Context, Result};
use bytes::Bytes;
use http_body_util::{BodyExt, Full};
use hyper::body::Incoming;
use hyper::client::conn::http1::SendRequest;
use hyper::{Method, Request};
use serde_json::{Map, Value};
use std::net::SocketAddr;

/// The most bytes of one event this client keeps while waiting for its end: robotd's answers
/// to the benchmark's tools are a few hundred bytes, so more is a stream gone wrong.
const MAX_EVENT_BYTES: usize = 1 << 20;

/// One legacy-SSE MCP session: its event stream and the connection it posts on.
pub struct RawSseSession {
    events: EventStream,
    poster: Poster,
    next_id: u64,
}

/// The session's event stream (`GET /sse`), read event by event.
struct EventStream {
    body: Incoming,
    /// Bytes received and not yet split into events (an event may come in several frames,
    /// split anywhere, even inside a character).
    pending: Vec<u8>,
}

/// The connection that posts the session's messages.
struct Poster {
    sender: SendRequest<Full<Bytes>>,
    host: String,
    endpoint: String,
}

/// One server-sent event: its `event:` name (empty when none) and its `data:` lines joined.
struct Event {
    name: String,
    data: String,
}

impl RawSseSession {
    /// Opens a legacy-SSE session with robotd's HTTP port at `addr` (`GET /sse`, then
    /// `initialize` and `notifications/initialized` posted to the announced endpoint). Must run
    /// inside a tokio runtime: each connection is driven by a task of the current one.
    pub async fn open(addr: SocketAddr) -> Result<Self> {
        let mut stream_connection = connect(addr).await?;
        let host = addr.to_string();
        let request = Request::builder()
            .method(Method::GET)
            .uri("/sse")
            .header("host", &host)
            .header("accept", "text/event-stream")
            .body(Full::new(Bytes::new()))?;
        let response = stream_connection.send_request(request).await?;
        if !response.status().is_success() {
            bail!("GET /sse answered {}", response.status());
        }
        let mut events = EventStream {
            body: response.into_body(),
            pending: Vec::new(),
        };
        let endpoint = events.next().await?;
        if endpoint.name != "endpoint" || !endpoint.data.starts_with('/') {
            bail!(
                "the event stream began with {:?} {:?}, not the endpoint",
                endpoint.name,
                endpoint.data
            );
        }
        let poster = Poster {
            sender: connect(addr).await?,
            host,
            endpoint: endpoint.data,
        };
        let mut session = Self {
            events,
            poster,
            next_id: 1,
        };
        session
            .request(initialize_request("robotd-bench-raw-sse"), 0)
            .await
            .context("initialize")?;
        session.poster.post(INITIALIZED.to_owned()).await?;
        Ok(session)
    }

    /// Posts a request and waits both for its `202` and for its answer on the event stream
    /// (either may come first).
    async fn request(&mut self, body: String, id: u64) -> Result<Value> {
        let (posted, answer) = tokio::join!(self.poster.post(body), self.events.answer(id));
        posted?;
        answer
    }

    /// Calls `tool` and checks that it answered its id with a `✓` text.
    pub async fn call(&mut self, tool: &str, arguments: &Map<String, Value>) -> Result<()> {
        let id = self.next_id;
        self.next_id += 1;
        let reply = self
            .request(tool_call_request(id, tool, arguments), id)
            .await?;
        check_tool_answer(tool, &reply)
    }
}

impl Poster {
    /// Posts one message to the session's endpoint; robotd accepts it with `202`.
    async fn post(&mut self, body: String) -> Result<()> {
        let request = Request::builder()
            .method(Method::POST)
            .uri(&self.endpoint)
            .header("host", &self.host)
            .header("content-type", "application/json")
            .body(Full::new(Bytes::from(body)))?;
        let (head, text) = exchange(&mut self.sender, request).await?;
        if !head.status.is_success() {
            bail!(
                "POST {} answered {}: {}",
                self.endpoint,
                head.status,
                String::from_utf8_lossy(&text)
            );
        }
        Ok(())
    }
}

impl EventStream {
    /// Reads events until the JSON-RPC answer to `id`; notifications, keep-alives and other
    /// answers are skipped.
    async fn answer(&mut self, id: u64) -> Result<Value> {
        loop {
            let event = self.next().await?;
            if event.name == "message" {
                if let Ok(answer) = json_rpc_reply(&event.data, id) {
                    return Ok(answer);
                }
            }
        }
    }

    /// The next event with data (comments and empty events are skipped).
    async fn next(&mut self) -> Result<Event> {
        loop {
            while let Some(end) = self.pending.windows(2).position(|w| w == b"\n\n") {
                let block: Vec<u8> = self.pending.drain(..end + 2).collect();
                let block = std::str::from_utf8(&block).context("an event that is not UTF-8")?;
                if let Some(event) = parse_event(block) {
                    return Ok(event);
                }
            }
            if self.pending.len() > MAX_EVENT_BYTES {
                bail!("an event of more than {MAX_EVENT_BYTES} bytes on the session's stream");
            }
            let frame = self
                .body
                .frame()
                .await
                .context("the session's event stream ended")??;
            if let Ok(data) = frame.into_data() {
                self.pending.extend_from_slice(&data);
                // Line ends may be CRLF (a CR and its LF can come in two frames).
                if self.pending.contains(&b'\r') {
                    self.pending = without_cr_before_lf(&self.pending);
                }
            }
        }
    }
}

/// `bytes` with every CR that stands before an LF taken out.
fn without_cr_before_lf(bytes: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(bytes.len());
    for (i, &byte) in bytes.iter().enumerate() {
        if byte != b'\r' || bytes.get(i + 1) != Some(&b'\n') {
            out.push(byte);
        }
    }
    out
}

/// One event block (the lines before a blank line) as an [`Event`], or `None` when it holds no
/// data (a comment such as a keep-alive).
fn parse_event(block: &str) -> Option<Event> {
    let mut name = String::new();
    let mut data: Vec<&str> = Vec::new();
    for line in block.lines() {
        if let Some(value) = line.strip_prefix("event:") {
            name = value.trim().to_owned();
        } else if let Some(value) = line.strip_prefix("data:") {
            data.push(value.strip_prefix(' ').unwrap_or(value));
        }
    }
    (!data.is_empty()).then(|| Event {
        name,
        data: data.join("\n"),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_event_has_its_name_and_its_data_lines_joined() {
        let event = parse_event("event: message\ndata: {\"a\":\ndata: 1}\n\n").unwrap();
        assert_eq!(event.name, "message");
        assert_eq!(event.data, "{\"a\":\n1}");
    }

    #[test]
    fn crlf_line_ends_become_lf_and_a_lone_cr_stays() {
        assert_eq!(without_cr_before_lf(b"a\r\n\r\nb\r"), b"a\n\nb\r");
    }

    #[test]
    fn a_keep_alive_comment_is_no_event() {
        assert!(parse_event(":\n\n").is_none());
    }
}
