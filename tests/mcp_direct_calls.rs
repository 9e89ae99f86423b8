//! Streamable-HTTP tool calls answered without rmcp's session pipeline (the direct path of
//! `edges/mcp/src/http/direct_call.rs`), over raw HTTP against a served robotd: a plain call
//! is answered as one JSON body with the same result rmcp gives, anything else still goes to
//! rmcp, a motion streams its progress, a session used only by direct calls does not time
//! out, and a `notifications/cancelled` or a dropped connection stops a direct call's motion.

mod common;

use common::mcp_http::{header, json_rpc, INIT, INITIALIZED};

use robotd_protocol::arm::ArmState;
use robotd_runtime::bus::{Bus, BusOptions, Subscriber};
use robotd_topics::ARM_STATE;
use serde_json::{json, Value};
use std::io::{BufRead, BufReader, Read, Write};
use std::net::{Ipv4Addr, TcpStream};
use std::time::{Duration, Instant};

fn headers(session: Option<&str>) -> Vec<(&str, &str)> {
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

/// POSTs `body` to `/mcp`; returns (status, content type, JSON-RPC message or null).
fn post(port: u16, session: Option<&str>, body: &[u8]) -> (u16, String, Value) {
    let (status, head, body) = common::http_response_from(
        Ipv4Addr::LOCALHOST,
        port,
        "POST",
        "/mcp",
        &headers(session),
        body,
    );
    let content_type = header(&head, "content-type").unwrap_or("").to_owned();
    let message = if body.trim_start().starts_with('{') || body.contains("data: {") {
        json_rpc(&body)
    } else {
        Value::String(body)
    };
    (status, content_type, message)
}

/// Opens a session; with `initialized`, also sends `notifications/initialized`.
fn open_session(port: u16, initialized: bool) -> String {
    let (status, head, body) = common::http_response_from(
        Ipv4Addr::LOCALHOST,
        port,
        "POST",
        "/mcp",
        &headers(None),
        INIT,
    );
    assert_eq!(status, 200, "{body}");
    let id = header(&head, "mcp-session-id")
        .expect("a session id")
        .to_owned();
    if initialized {
        let (status, _, _) = post(port, Some(&id), INITIALIZED);
        assert_eq!(status, 202);
        // The session's gate reads `initialized` in order with the requests after it; once a
        // ping is answered, it has, and calls take the direct path (before, they go to rmcp).
        let ping = br#"{"jsonrpc":"2.0","id":0,"method":"ping"}"#;
        let (status, _, pong) = post(port, Some(&id), ping);
        assert_eq!((status, &pong["result"]), (200, &json!({})), "{pong}");
    }
    id
}

fn tool_call(id: u64, tool: &str, arguments: Value, meta: Option<Value>) -> Vec<u8> {
    let mut params = json!({"name": tool, "arguments": arguments});
    if let Some(meta) = meta {
        params["_meta"] = meta;
    }
    serde_json::to_vec(
        &json!({"jsonrpc": "2.0", "id": id, "method": "tools/call", "params": params}),
    )
    .unwrap()
}

fn center_point(id: u64, meta: Option<Value>) -> Vec<u8> {
    tool_call(
        id,
        "get_workspace_coordinate_from_point",
        json!({"workspace_id": "niryo_ws", "point": "center point"}),
        meta,
    )
}

#[test]
fn a_plain_call_is_answered_directly_with_what_rmcp_answers() {
    let namespace = common::fresh_namespace("direct");
    let port = common::free_port();
    let _robotd = common::start_robotd(&namespace, port, &[]);

    // Before notifications/initialized the call goes to rmcp's gate and is refused.
    let early = open_session(port, false);
    let (status, content_type, refused) = post(port, Some(&early), &center_point(2, None));
    assert_eq!(status, 200);
    assert!(
        content_type.starts_with("text/event-stream"),
        "{content_type}"
    );
    assert_eq!(refused["error"]["code"], -32600, "{refused}");

    let session = open_session(port, true);
    let (status, content_type, direct) = post(port, Some(&session), &center_point(3, None));
    assert_eq!(status, 200, "{direct}");
    assert_eq!(content_type, "application/json", "answered directly");
    assert_eq!(direct["id"], 3);
    let text = direct["result"]["content"][0]["text"].as_str().unwrap();
    assert!(text.starts_with('✓'), "{direct}");

    // A progress token alone keeps a call direct: a cheap tool reports no progress.
    let (_, content_type, with_token) = post(
        port,
        Some(&session),
        &center_point(4, Some(json!({"progressToken": "p4"}))),
    );
    assert_eq!(content_type, "application/json");
    assert_eq!(with_token["result"], direct["result"]);
    // Other `_meta` goes to rmcp, which answers on its event stream: the same result.
    let (status, content_type, through_rmcp) = post(
        port,
        Some(&session),
        &center_point(5, Some(json!({"robotd.test/route": "rmcp"}))),
    );
    assert_eq!(status, 200);
    assert!(
        content_type.starts_with("text/event-stream"),
        "{content_type}"
    );
    assert_eq!(through_rmcp["id"], 5);
    assert_eq!(
        through_rmcp["result"], direct["result"],
        "same result either way"
    );

    // A motion with a progress token: an event stream of the skill's steps, then the result.
    let (status, head, body) = common::http_response_from(
        Ipv4Addr::LOCALHOST,
        port,
        "POST",
        "/mcp",
        &headers(Some(&session)),
        &tool_call(
            8,
            "pick_object",
            json!({"object_name": "pencil", "pick_coordinate": [0.22, -0.05]}),
            Some(json!({"progressToken": "pick"})),
        ),
    );
    assert_eq!(status, 200, "{body}");
    assert!(
        header(&head, "content-type").is_some_and(|t| t.starts_with("text/event-stream")),
        "{head}"
    );
    let messages: Vec<Value> = body
        .lines()
        .filter_map(|l| l.strip_prefix("data: "))
        .map(|d| serde_json::from_str(d).unwrap())
        .collect();
    let (last, steps) = messages.split_last().expect("messages");
    assert!(!steps.is_empty(), "no progress: {body}");
    for step in steps {
        assert_eq!(step["method"], "notifications/progress", "{step}");
        assert_eq!(step["params"]["progressToken"], "pick");
    }
    assert_eq!(last["id"], 8);
    let text = last["result"]["content"][0]["text"].as_str().unwrap();
    assert!(text.starts_with('✓'), "{text}");

    // Errors: an unknown tool is -32602 on both paths.
    let unknown = tool_call(5, "no_such_tool", json!({}), None);
    let (_, content_type, direct_error) = post(port, Some(&session), &unknown);
    assert_eq!(content_type, "application/json");
    let unknown = tool_call(
        6,
        "no_such_tool",
        json!({}),
        Some(json!({"progressToken": 6})),
    );
    let (_, _, rmcp_error) = post(port, Some(&session), &unknown);
    assert_eq!(direct_error["error"]["code"], -32602, "{direct_error}");
    assert_eq!(direct_error["error"], rmcp_error["error"]);

    // A session that does not exist is 404, as rmcp answers it.
    let (status, _, _) = post(port, Some("no-such-session"), &center_point(7, None));
    assert_eq!(status, 404);
}

#[test]
fn with_direct_calls_off_every_call_goes_through_rmcp() {
    let namespace = common::fresh_namespace("nodirect");
    let port = common::free_port();
    let _robotd = common::start_robotd(&namespace, port, &["--set", "mcp.direct_tool_calls=false"]);
    let session = open_session(port, true);
    let (status, content_type, answer) = post(port, Some(&session), &center_point(2, None));
    assert_eq!(status, 200);
    assert!(
        content_type.starts_with("text/event-stream"),
        "{content_type}"
    );
    assert!(answer["result"]["content"][0]["text"]
        .as_str()
        .unwrap()
        .starts_with('✓'));
}

#[test]
fn a_session_used_only_by_direct_calls_does_not_time_out() {
    let namespace = common::fresh_namespace("directidle");
    let port = common::free_port();
    let _robotd = common::start_robotd(
        &namespace,
        port,
        &[
            "--set",
            "mcp.session_idle_timeout_s=2",
            "--set",
            "mcp.max_sessions=1",
        ],
    );
    let session = open_session(port, true);
    // Five seconds of direct calls, one every 400 ms: rmcp's 2 s idle timer must not fire.
    let until = Instant::now() + Duration::from_secs(5);
    let mut id = 10;
    while Instant::now() < until {
        let (status, content_type, answer) = post(port, Some(&session), &center_point(id, None));
        assert_eq!(status, 200, "session closed while in use: {answer}");
        assert_eq!(content_type, "application/json");
        id += 1;
        std::thread::sleep(Duration::from_millis(400));
    }
    // Left alone, it expires: watched without touching it, by the one session place
    // (mcp.max_sessions = 1) coming free.
    let deadline = Instant::now() + Duration::from_secs(15);
    loop {
        let (status, _, _) = post(port, None, INIT);
        if status == 200 {
            break;
        }
        assert_eq!(status, 503);
        assert!(Instant::now() < deadline, "the idle session never expired");
        std::thread::sleep(Duration::from_millis(200));
    }
    let (status, _, _) = post(port, Some(&session), &center_point(id, None));
    assert_eq!(status, 404, "an expired session still takes calls");
}

/// Starts a raw POST of `body` into `session` and returns the open connection.
fn start_post(port: u16, session: &str, body: &[u8]) -> TcpStream {
    let mut stream = TcpStream::connect((Ipv4Addr::LOCALHOST, port)).expect("connect");
    let mut head = format!(
        "POST /mcp HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nConnection: close\r\nContent-Length: {}\r\n",
        body.len()
    );
    for (k, v) in headers(Some(session)) {
        head.push_str(&format!("{k}: {v}\r\n"));
    }
    head.push_str("\r\n");
    stream.write_all(head.as_bytes()).expect("send head");
    stream.write_all(body).expect("send body");
    stream
}

/// Waits until the arm has not moved for 1.5 s; fails if it keeps moving for 4 s (a pick at
/// this speed takes several seconds more).
async fn comes_to_rest(states: &mut Subscriber<ArmState>, what: &str) {
    let started = Instant::now();
    let mut last_moving = started;
    loop {
        assert!(
            started.elapsed() < Duration::from_secs(4),
            "{what}: the arm kept moving"
        );
        match tokio::time::timeout(Duration::from_millis(100), states.recv()).await {
            Ok(Ok(state)) if state.body.moving => last_moving = Instant::now(),
            Ok(Ok(_)) | Err(_) => {}
            Ok(Err(error)) => panic!("arm/state: {error}"),
        }
        if last_moving.elapsed() >= Duration::from_millis(1500) {
            break;
        }
    }
    eprintln!(
        "{what}: the arm at rest for good {:?} after",
        last_moving - started
    );
}

/// Whether the simulated world has the pencil in the gripper.
async fn pencil_held(bus: &Bus) -> bool {
    common::sim_world(bus)
        .await
        .iter()
        .any(|o| o.label == "pencil" && o.held)
}

fn pick_pencil(id: u64) -> Vec<u8> {
    tool_call(
        id,
        "pick_object",
        json!({"object_name": "pencil", "pick_coordinate": [0.22, -0.05]}),
        None,
    )
}

#[test]
fn a_cancelled_or_abandoned_direct_call_stops_the_arm() {
    let namespace = common::fresh_namespace("directcancel");
    let port = common::free_port();
    // Real-time motions, so that the cancel lands mid-motion.
    let robotd = common::start_robotd(&namespace, port, &["--set", "robot.time_scale=1.0"]);
    common::runtime().block_on(async {
        let bus = Bus::open(BusOptions::new(&namespace, "direct-cancel-test")).unwrap();
        let mut states = bus.subscriber(&ARM_STATE).unwrap();
        let session = open_session(port, true);

        // notifications/cancelled naming the call: the arm stops and the call still answers.
        let mut call = start_post(port, &session, &pick_pencil(21));
        common::wait_until_the_arm_moves(&mut states).await;
        let cancel = br#"{"jsonrpc":"2.0","method":"notifications/cancelled","params":{"requestId":21,"reason":"test"}}"#;
        let (status, _, _) = post(port, Some(&session), cancel);
        assert_eq!(status, 202);
        comes_to_rest(&mut states, "cancelled").await;
        assert!(!pencil_held(&bus).await, "the cancelled pick went on");
        call.set_read_timeout(Some(Duration::from_secs(10)))
            .unwrap();
        let mut answer = String::new();
        call.read_to_string(&mut answer).expect("the call's answer");
        // One JSON body, or an event stream when the call ran past half a second.
        assert!(
            (answer.contains("application/json") || answer.contains("text/event-stream"))
                && answer.contains("\"id\":21")
                && answer.contains("cancelled; the arm was stopped"),
            "{answer}"
        );

        // A client that drops its connection mid-motion, once the answer became an event
        // stream: the arm stops as well.
        let mut call = start_post(port, &session, &pick_pencil(22));
        common::wait_until_the_arm_moves(&mut states).await;
        call.set_read_timeout(Some(Duration::from_secs(5))).unwrap();
        let mut head = Vec::new();
        let mut byte = [0u8; 1];
        while !head.ends_with(b"\r\n\r\n") {
            call.read_exact(&mut byte).expect("the answer's head");
            head.push(byte[0]);
        }
        let head = String::from_utf8_lossy(&head);
        assert!(head.contains("text/event-stream"), "{head}");
        drop(call);
        comes_to_rest(&mut states, "dropped").await;
        assert!(!pencil_held(&bus).await, "the abandoned pick went on");

        // A client that drops its connection while the call still runs on its request's task
        // (no progress token, usually within half a second; on a slow machine the call may
        // have moved to a task of its own already): the arm stops, and the call goes on to
        // its end, so it is in the call log.
        let call = start_post(port, &session, &pick_pencil(23));
        common::wait_until_the_arm_moves(&mut states).await;
        drop(call);
        comes_to_rest(&mut states, "dropped early").await;
        assert!(!pencil_held(&bus).await, "the abandoned pick went on");
        // All three picks ended cancelled, each in the call log.
        let logged = logged_calls(robotd.log_dir().expect("a log directory"), "pick_object", 3);
        for pick in &logged {
            assert!(
                pick["result"].as_str().is_some_and(|r| r.contains("cancelled")),
                "{pick}"
            );
        }

        // And the session still serves calls.
        let (status, _, answer) = post(port, Some(&session), &center_point(24, None));
        assert_eq!(status, 200, "{answer}");
    });
}

/// The MCP call log's lines in `dir` for `tool`, once there are `count`; fails after 5 s.
fn logged_calls(dir: &std::path::Path, tool: &str, count: usize) -> Vec<Value> {
    let deadline = Instant::now() + Duration::from_secs(5);
    loop {
        let calls: Vec<Value> = std::fs::read_dir(dir)
            .unwrap()
            .filter_map(Result::ok)
            .filter(|e| e.file_name().to_string_lossy().starts_with("mcp_server_"))
            .filter_map(|e| std::fs::read_to_string(e.path()).ok())
            .flat_map(|log| {
                log.lines()
                    .filter_map(|l| serde_json::from_str::<Value>(l).ok())
                    .collect::<Vec<_>>()
            })
            .filter(|l| l["tool"] == tool)
            .collect();
        if calls.len() >= count {
            return calls;
        }
        assert!(
            Instant::now() < deadline,
            "{} {tool} calls in the call log, {count} expected",
            calls.len()
        );
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// A legacy-SSE session opened by hand and initialized; returns its event stream's reader
/// (kept open, no longer read) and the session's message path.
fn open_sse_session(port: u16) -> (BufReader<TcpStream>, String) {
    // A small receive buffer: the unread answers fill it (and the service's send buffer) soon.
    let connect = async {
        let socket = tokio::net::TcpSocket::new_v4()?;
        socket.set_recv_buffer_size(4096)?;
        socket.connect((Ipv4Addr::LOCALHOST, port).into()).await
    };
    let mut stream = common::runtime()
        .block_on(connect)
        .and_then(|stream| stream.into_std())
        .expect("connect");
    stream.set_nonblocking(false).unwrap();
    let request =
        format!("GET /sse HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nAccept: text/event-stream\r\n\r\n");
    stream
        .write_all(request.as_bytes())
        .expect("open the stream");
    stream
        .set_read_timeout(Some(Duration::from_secs(10)))
        .unwrap();
    let mut events = BufReader::new(stream);
    let mut read_until = |wanted: &str| loop {
        let mut line = String::new();
        let read = events.read_line(&mut line).expect("the event stream");
        assert!(read > 0, "the event stream ended");
        if line.contains(wanted) {
            return line;
        }
    };
    let endpoint = read_until("data: /messages/");
    let path = endpoint.trim().trim_start_matches("data: ").to_owned();
    let post_message = |body: &[u8]| sse_post(port, &path, body);
    assert_eq!(post_message(INIT), 202);
    read_until("\"id\":1");
    assert_eq!(post_message(INITIALIZED), 202);
    // Once the ping is answered, the session's gate has read `initialized`.
    assert_eq!(
        post_message(br#"{"jsonrpc":"2.0","id":2,"method":"ping"}"#),
        202
    );
    read_until("\"id\":2");
    (events, path)
}

/// POSTs `body` to an SSE session's message `path`; returns the status. Waits up to 15 s
/// (a full session's queue holds a POST for 10 s before refusing it).
fn sse_post(port: u16, path: &str, body: &[u8]) -> u16 {
    let mut stream = TcpStream::connect((Ipv4Addr::LOCALHOST, port)).expect("connect");
    stream
        .set_read_timeout(Some(Duration::from_secs(15)))
        .unwrap();
    let head = format!(
        "POST {path} HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nConnection: close\r\n\
         Content-Type: application/json\r\nContent-Length: {}\r\n\r\n",
        body.len()
    );
    stream.write_all(head.as_bytes()).expect("send head");
    stream.write_all(body).expect("send body");
    let mut answer = String::new();
    stream.read_to_string(&mut answer).expect("the answer");
    answer
        .split(' ')
        .nth(1)
        .and_then(|code| code.parse().ok())
        .unwrap_or_else(|| panic!("not an HTTP answer: {answer:?}"))
}

#[test]
fn an_sse_client_that_stops_reading_is_refused_not_piled_up() {
    let namespace = common::fresh_namespace("directsse");
    let port = common::free_port();
    let _robotd = common::start_robotd(&namespace, port, &[]);
    let (_unread, path) = open_sse_session(port);
    // The answers fill the socket, then the session's queues and at most 64 direct calls
    // waiting to write theirs; from then on a call waits for room in rmcp's queue and is
    // refused with 503 after its 10 s wait. Without the bound every call would be taken (and
    // its task kept).
    // Each answer carries its request's id back: with ids of 32 KB the buffers (the service's
    // send buffer grows to megabytes) fill within a few hundred calls, not thousands.
    let padding = "x".repeat(32 * 1024);
    let call = |i: u64| {
        serde_json::to_vec(&json!({
            "jsonrpc": "2.0",
            "id": format!("{i}-{padding}"),
            "method": "tools/call",
            "params": {
                "name": "get_workspace_coordinate_from_point",
                "arguments": {"workspace_id": "niryo_ws", "point": "center point"},
            },
        }))
        .unwrap()
    };
    let mut accepted = 0;
    let refused = (0..40000u64).find_map(|i| match sse_post(port, &path, &call(10 + i)) {
        202 => {
            accepted += 1;
            None
        }
        status => Some(status),
    });
    assert_eq!(
        refused,
        Some(503),
        "{accepted} calls accepted from a client that reads none of its answers"
    );
    // The service still answers others.
    let other = open_session(port, true);
    let (status, _, answer) = post(port, Some(&other), &center_point(1, None));
    assert_eq!(status, 200, "{answer}");
}
