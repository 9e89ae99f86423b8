//! The server's share of a streamable-HTTP MCP call, measured with the leanest client.
//!
//! `robotd bench mcp` times calls made with rmcp's client, so its figures are the server's
//! work plus the client's (request bookkeeping, SSE parsing, task hand-offs). This client is
//! a kept-alive HTTP connection that posts ready-made JSON-RPC bodies and reads each reply
//! whole: what it adds is little more than the loopback round trip, so the difference
//! between its latency and the direct registry call is mostly robotd's HTTP and MCP
//! handling. Every reply is still checked (the call's id and a `✓` answer), so a server that
//! answered nothing or an error is not timed as fast.

use super::Latency;
use anyhow::{bail, Context, Result};
use serde_json::{json, Map, Value};
use std::time::Instant;

/// The protocol version this client asks for: the newest one with sessions.
const PROTOCOL_VERSION: &str = "2025-06-18";

/// One streamable-HTTP MCP session driven with plain HTTP requests.
pub struct RawSession {
    http: reqwest::Client,
    url: String,
    session_id: String,
    protocol_version: String,
    next_id: u64,
}

impl RawSession {
    /// `initialize` and `notifications/initialized` on `url` (`http://host:port/mcp`).
    pub async fn open(url: &str) -> Result<Self> {
        let http = reqwest::Client::builder()
            .tcp_nodelay(true)
            .build()
            .context("building the HTTP client")?;
        let initialize = json!({
            "jsonrpc": "2.0", "id": 0, "method": "initialize",
            "params": {
                "protocolVersion": PROTOCOL_VERSION,
                "capabilities": {},
                "clientInfo": {"name": "robotd-bench-raw", "version": "0"}
            }
        });
        let response = http
            .post(url)
            .header("content-type", "application/json")
            .header("accept", "application/json, text/event-stream")
            .body(initialize.to_string())
            .send()
            .await
            .context("initialize")?;
        let session_id = response
            .headers()
            .get("mcp-session-id")
            .and_then(|v| v.to_str().ok())
            .context("the initialize answer named no Mcp-Session-Id")?
            .to_owned();
        let reply = json_rpc_reply(&response.text().await?, 0)?;
        let protocol_version = reply["result"]["protocolVersion"]
            .as_str()
            .context("the initialize answer named no protocol version")?
            .to_owned();
        let session = Self {
            http,
            url: url.to_owned(),
            session_id,
            protocol_version,
            next_id: 1,
        };
        let initialized = json!({"jsonrpc": "2.0", "method": "notifications/initialized"});
        let status = session.post(initialized.to_string()).await?.status();
        if !status.is_success() {
            bail!("notifications/initialized answered {status}");
        }
        Ok(session)
    }

    async fn post(&self, body: String) -> Result<reqwest::Response> {
        Ok(self
            .http
            .post(&self.url)
            .header("content-type", "application/json")
            .header("accept", "application/json, text/event-stream")
            .header("mcp-session-id", &self.session_id)
            .header("mcp-protocol-version", &self.protocol_version)
            .body(body)
            .send()
            .await?)
    }

    /// Calls `tool` and checks that it answered its id with a `✓` text.
    pub async fn call(&mut self, tool: &str, arguments: &Map<String, Value>) -> Result<()> {
        let id = self.next_id;
        self.next_id += 1;
        let body = json!({
            "jsonrpc": "2.0", "id": id, "method": "tools/call",
            "params": {"name": tool, "arguments": arguments}
        });
        let text = self.post(body.to_string()).await?.text().await?;
        let reply = json_rpc_reply(&text, id)?;
        let answer = reply["result"]["content"][0]["text"].as_str().unwrap_or("");
        if !answer.starts_with('✓') {
            bail!("{tool} answered {reply}");
        }
        Ok(())
    }

    /// A JSON-RPC `ping` through the session: the MCP layer's path without a tool.
    pub async fn ping(&mut self) -> Result<()> {
        let id = self.next_id;
        self.next_id += 1;
        let body = json!({"jsonrpc": "2.0", "id": id, "method": "ping"});
        let text = self.post(body.to_string()).await?.text().await?;
        let reply = json_rpc_reply(&text, id)?;
        if reply["result"] != json!({}) {
            bail!("ping answered {reply}");
        }
        Ok(())
    }

    /// `GET /health` on the same port and connection: the HTTP floor, no MCP at all.
    pub async fn health(&self) -> Result<()> {
        let url = self.url.trim_end_matches("/mcp").to_owned() + "/health";
        let response = self.http.get(&url).send().await?;
        let status = response.status();
        let body = response.bytes().await?;
        if !status.is_success() || body.is_empty() {
            bail!("GET /health answered {status}");
        }
        Ok(())
    }

    /// Ends the session (`DELETE`).
    pub async fn close(self) {
        let _ = self
            .http
            .delete(&self.url)
            .header("mcp-session-id", &self.session_id)
            .header("mcp-protocol-version", &self.protocol_version)
            .send()
            .await;
    }
}

/// The JSON-RPC message answering `id` in a reply body: plain JSON, or the `data:` lines of
/// an event stream.
fn json_rpc_reply(body: &str, id: u64) -> Result<Value> {
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
}

/// `calls` rounds of a `GET /health`, a `ping` and a call of `tool` on a fresh raw session on
/// `url`, interleaved so that all three see the same machine.
pub async fn layers(
    url: &str,
    tool: &str,
    arguments: &Map<String, Value>,
    calls: usize,
) -> Result<Layers> {
    let mut session = RawSession::open(url).await?;
    let mut http = Vec::with_capacity(calls);
    let mut ping = Vec::with_capacity(calls);
    let mut call = Vec::with_capacity(calls);
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
    }
    session.close().await;
    Ok(Layers {
        http: Latency::of(&mut http),
        ping: Latency::of(&mut ping),
        call: Latency::of(&mut call),
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
