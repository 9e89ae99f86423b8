//! MCP spoken by hand over real sockets, for the tests of the MCP edge under misuse: requests
//! from a chosen local address (127.0.0.0/8 are as many clients on one machine), streamable
//! HTTP sessions and legacy SSE streams read event by event.
#![allow(dead_code)]

use serde_json::Value;
use std::io::{BufRead, BufReader, Read, Write};
use std::net::{Ipv4Addr, TcpStream};
use std::time::Duration;

/// An `initialize` request (protocol 2025-06-18), id 1.
pub const INIT: &[u8] = br#"{"jsonrpc":"2.0","id":1,"method":"initialize","params":{"protocolVersion":"2025-06-18","capabilities":{},"clientInfo":{"name":"t","version":"1"}}}"#;

/// The `notifications/initialized` that completes a session's handshake.
pub const INITIALIZED: &[u8] = br#"{"jsonrpc":"2.0","method":"notifications/initialized"}"#;

/// How long any read waits before the test fails (a hang is a failure, not a wait).
pub const READ_TIMEOUT: Duration = Duration::from_secs(30);

/// A TCP connection to 127.0.0.1:`port` from the local address `source`.
pub fn connect_from(source: Ipv4Addr, port: u16) -> TcpStream {
    let connect = async {
        let socket = tokio::net::TcpSocket::new_v4()?;
        socket.bind((source, 0).into())?;
        socket
            .connect(([127, 0, 0, 1], port).into())
            .await?
            .into_std()
    };
    // On a thread of its own: the caller may itself be inside a tokio runtime.
    let stream = std::thread::scope(|s| {
        s.spawn(|| {
            tokio::runtime::Builder::new_current_thread()
                .enable_io()
                .build()
                .expect("runtime")
                .block_on(connect)
        })
        .join()
        .expect("connect thread")
    })
    .expect("connect");
    stream.set_nonblocking(false).expect("blocking");
    stream
        .set_read_timeout(Some(READ_TIMEOUT))
        .expect("timeout");
    stream
}

/// Writes `method path` with `headers` and `body` (and `Connection: close`) on `stream`.
pub fn send(
    stream: &mut TcpStream,
    method: &str,
    path: &str,
    headers: &[(&str, &str)],
    body: &[u8],
) {
    let mut head = format!(
        "{method} {path} HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\nContent-Length: {}\r\n",
        body.len()
    );
    for (k, v) in headers {
        head.push_str(&format!("{k}: {v}\r\n"));
    }
    head.push_str("\r\n");
    stream.write_all(head.as_bytes()).expect("send head");
    // A server may refuse before reading the body.
    let _ = stream.write_all(body);
}

/// An HTTP answer read to its end.
#[derive(Debug)]
pub struct Answer {
    pub status: u16,
    pub head: String,
    pub body: String,
}

impl Answer {
    /// The value of header `name`, if present.
    pub fn header(&self, name: &str) -> Option<&str> {
        self.head.lines().find_map(|l| {
            let (k, v) = l.split_once(':')?;
            k.eq_ignore_ascii_case(name).then(|| v.trim())
        })
    }

    /// The JSON-RPC messages in the body: one JSON body, or the `data:` lines of an event
    /// stream.
    pub fn messages(&self) -> Vec<Value> {
        if self.body.trim_start().starts_with('{') {
            return vec![serde_json::from_str(&self.body).unwrap_or(Value::Null)];
        }
        self.body
            .lines()
            .filter_map(|l| l.strip_prefix("data: "))
            .filter_map(|d| serde_json::from_str(d).ok())
            .collect()
    }

    /// The one JSON-RPC message of the answer.
    pub fn message(&self) -> Value {
        let messages = self.messages();
        assert_eq!(messages.len(), 1, "one message expected: {self:?}");
        messages.into_iter().next().unwrap_or_default()
    }
}

/// Reads the answer on `stream` until the server closes it (chunked bodies decoded).
pub fn read_answer(stream: &mut TcpStream) -> Answer {
    let mut raw = Vec::new();
    if let Err(error) = stream.read_to_end(&mut raw) {
        panic!(
            "the answer did not end ({error}); got {:?}",
            String::from_utf8_lossy(&raw)
        );
    }
    let text = String::from_utf8_lossy(&raw).into_owned();
    let (head, body) = text.split_once("\r\n\r\n").unwrap_or((&text, ""));
    let status = head
        .split_whitespace()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(0);
    let chunked = head
        .to_ascii_lowercase()
        .contains("transfer-encoding: chunked");
    let body = if chunked {
        dechunk(body)
    } else {
        body.to_owned()
    };
    Answer {
        status,
        head: head.to_owned(),
        body,
    }
}

fn dechunk(mut body: &str) -> String {
    let mut out = String::new();
    while let Some((size, rest)) = body.split_once("\r\n") {
        let Ok(size) = usize::from_str_radix(size.trim(), 16) else {
            break;
        };
        if size == 0 || rest.len() < size {
            break;
        }
        out.push_str(&rest[..size]);
        body = rest[size..].trim_start_matches("\r\n");
    }
    out
}

/// `method path` from `source` with `headers` and `body`, read to its end.
pub fn request(
    source: Ipv4Addr,
    port: u16,
    method: &str,
    path: &str,
    headers: &[(&str, &str)],
    body: &[u8],
) -> Answer {
    let mut stream = connect_from(source, port);
    send(&mut stream, method, path, headers, body);
    read_answer(&mut stream)
}

/// The headers of a streamable-HTTP request, in `session` when given.
pub fn mcp_headers(session: Option<&str>) -> Vec<(&str, &str)> {
    let mut headers = vec![
        ("Content-Type", "application/json"),
        ("Accept", "application/json, text/event-stream"),
        ("MCP-Protocol-Version", "2025-06-18"),
    ];
    if let Some(id) = session {
        headers.push(("Mcp-Session-Id", id));
    }
    headers
}

/// POSTs `body` to `/mcp` from `source`, in `session` when given.
pub fn post_mcp(source: Ipv4Addr, port: u16, session: Option<&str>, body: &[u8]) -> Answer {
    request(source, port, "POST", "/mcp", &mcp_headers(session), body)
}

/// Opens a streamable-HTTP session from `source` (only `initialize`: it made no call yet).
pub fn open_streamable(source: Ipv4Addr, port: u16) -> String {
    let answer = post_mcp(source, port, None, INIT);
    assert_eq!(answer.status, 200, "{answer:?}");
    answer
        .header("mcp-session-id")
        .expect("a session id")
        .to_owned()
}

/// Opens a streamable-HTTP session from `source` and makes a call in it (`tools/list`).
pub fn open_streamable_in_use(source: Ipv4Addr, port: u16) -> String {
    let session = open_streamable(source, port);
    let answer = post_mcp(source, port, Some(&session), INITIALIZED);
    assert_eq!(answer.status, 202, "{answer:?}");
    let list = br#"{"jsonrpc":"2.0","id":2,"method":"tools/list"}"#;
    let answer = post_mcp(source, port, Some(&session), list);
    assert_eq!(answer.status, 200, "{answer:?}");
    session
}

/// A legacy-SSE stream, read line by line.
pub struct SseStream {
    pub reader: BufReader<TcpStream>,
    /// `/messages/?session_id=…`
    pub path: String,
    pub source: Ipv4Addr,
    pub port: u16,
}

/// `GET /sse` from `source`: the status and, for a 200, the stream read up to its endpoint
/// event; otherwise the whole answer.
pub fn try_open_sse(source: Ipv4Addr, port: u16) -> Result<SseStream, Answer> {
    let mut stream = connect_from(source, port);
    send(
        &mut stream,
        "GET",
        "/sse",
        &[("Accept", "text/event-stream")],
        b"",
    );
    let mut reader = BufReader::new(stream);
    let mut status_line = String::new();
    reader.read_line(&mut status_line).expect("a status line");
    if !status_line.contains(" 200 ") {
        let mut rest = Vec::new();
        let _ = reader.read_to_end(&mut rest);
        let text = format!("{status_line}{}", String::from_utf8_lossy(&rest));
        let (head, body) = text.split_once("\r\n\r\n").unwrap_or((&text, ""));
        let status = status_line
            .split_whitespace()
            .nth(1)
            .and_then(|s| s.parse().ok())
            .unwrap_or(0);
        return Err(Answer {
            status,
            head: head.to_owned(),
            body: body.to_owned(),
        });
    }
    let mut sse = SseStream {
        reader,
        path: String::new(),
        source,
        port,
    };
    let endpoint = sse
        .line_with("data: /messages/")
        .expect("the endpoint event");
    sse.path = endpoint.trim().trim_start_matches("data: ").to_owned();
    Ok(sse)
}

/// `GET /sse` from `source`, which must open a session.
pub fn open_sse(source: Ipv4Addr, port: u16) -> SseStream {
    try_open_sse(source, port).unwrap_or_else(|answer| panic!("GET /sse refused: {answer:?}"))
}

impl SseStream {
    /// The session id.
    pub fn id(&self) -> &str {
        self.path.rsplit('=').next().unwrap_or_default()
    }

    /// The next line containing `wanted`; `None` when the stream ended first.
    pub fn line_with(&mut self, wanted: &str) -> Option<String> {
        loop {
            let mut line = String::new();
            let read = self.reader.read_line(&mut line).expect("the event stream");
            if read == 0 {
                return None;
            }
            if line.contains(wanted) {
                return Some(line);
            }
        }
    }

    /// The next JSON-RPC message on the stream; `None` when the stream ended.
    pub fn next_message(&mut self) -> Option<Value> {
        let line = self.line_with("data: {")?;
        serde_json::from_str(line.trim().trim_start_matches("data: ")).ok()
    }

    /// Reads until the server ends the stream; panics when it does not within
    /// [`READ_TIMEOUT`].
    pub fn until_closed(&mut self) {
        while self.line_with("\n").is_some() {}
    }

    /// POSTs `body` into the session; returns the answer to the POST.
    pub fn post(&self, body: &[u8]) -> Answer {
        request(
            self.source,
            self.port,
            "POST",
            &self.path,
            &[("Content-Type", "application/json")],
            body,
        )
    }

    /// `initialize`, then `notifications/initialized`; with `call`, a `ping` whose answer
    /// proves the session took both (and makes the session one in use).
    pub fn handshake(&mut self, call: bool) {
        assert_eq!(self.post(INIT).status, 202);
        self.line_with("\"id\":1").expect("the initialize answer");
        assert_eq!(self.post(INITIALIZED).status, 202);
        if call {
            let ping = br#"{"jsonrpc":"2.0","id":"ping-1","method":"ping"}"#;
            assert_eq!(self.post(ping).status, 202);
            self.line_with("\"ping-1\"").expect("the ping's answer");
        }
    }
}
