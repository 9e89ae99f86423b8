//! MCP over raw streamable HTTP, for tests that speak HTTP by hand: the handshake's bodies, a
//! response header, and the JSON-RPC message in an answer (one JSON body or an event stream).

use serde_json::Value;

/// An `initialize` request (protocol 2025-06-18), id 1.
pub const INIT: &[u8] = br#"{"jsonrpc":"2.0","id":1,"method":"initialize","params":{"protocolVersion":"2025-06-18","capabilities":{},"clientInfo":{"name":"t","version":"1"}}}"#;

/// The `notifications/initialized` that completes a session's handshake.
pub const INITIALIZED: &[u8] = br#"{"jsonrpc":"2.0","method":"notifications/initialized"}"#;

/// The value of header `name` in a response `head`, if present.
pub fn header<'a>(head: &'a str, name: &str) -> Option<&'a str> {
    head.lines().find_map(|l| {
        let (k, v) = l.split_once(':')?;
        k.eq_ignore_ascii_case(name).then(|| v.trim())
    })
}

/// The JSON-RPC message in a streamable-HTTP answer (plain JSON or the first SSE `data:` line
/// holding one).
pub fn json_rpc(body: &str) -> Value {
    let text = body
        .lines()
        .find_map(|l| l.strip_prefix("data: ").filter(|d| d.starts_with('{')))
        .unwrap_or(body);
    serde_json::from_str(text).unwrap_or_else(|e| panic!("not JSON-RPC ({e}): {body}"))
}
