//! The MCP edge at the edges of the protocol (issue 43, items 6–8), over real sockets against
//! a served robotd, on both transports (streamable HTTP `/mcp`, legacy SSE `/messages/`):
//!
//! - a JSON-RPC envelope that is wrong is HTTP 400 with `-32600` saying what is wrong, and
//!   ids come back exactly as sent (2^70 as its integer text);
//! - every string argument of every tool has a `maxLength`, and a longer string is a
//!   validation error in the contract's form (a 100 kB `set_user_task` included);
//! - a request cancelled while it waited behind another client's motion never runs and gets
//!   no answer.

mod common;
mod mcp_raw;

use mcp_raw::{open_sse, open_streamable_in_use, post_mcp, SseStream};
use serde_json::{json, Value};
use std::net::Ipv4Addr;

const LOCAL: Ipv4Addr = Ipv4Addr::LOCALHOST;

/// Bodies with a wrong envelope, what the answer must say, and the id it must carry (as
/// JSON text).
const BAD_ENVELOPES: &[(&str, &str, &str)] = &[
    (
        r#"{"jsonrpc":"1.0","id":2,"method":"tools/call","params":{"name":"speak","arguments":{"text":"x"}}}"#,
        r#""jsonrpc" must be "2.0", not "1.0""#,
        "2",
    ),
    (
        r#"{"id":3,"method":"tools/list"}"#,
        r#""jsonrpc" is missing"#,
        "3",
    ),
    (
        r#"{"jsonrpc":"2.0","id":{"a":1},"method":"tools/list"}"#,
        r#""id" must be a string or an integer, not an object"#,
        "null",
    ),
    (
        r#"{"jsonrpc":"2.0","id":[4],"method":"ping"}"#,
        "not an array",
        "null",
    ),
    (
        r#"{"jsonrpc":"2.0","id":true,"method":"ping"}"#,
        "not a boolean",
        "null",
    ),
    (
        r#"{"jsonrpc":"2.0","id":1180591620717411303424,"method":"ping"}"#,
        "does not fit in 64 bits",
        "1180591620717411303424",
    ),
];

/// The id of a JSON-RPC answer `body` as its JSON text.
fn raw_id(body: &str) -> String {
    let at = body
        .find("\"id\":")
        .unwrap_or_else(|| panic!("no id: {body}"))
        + 5;
    let rest = &body[at..];
    let end = rest.find([',', '}']).unwrap_or(rest.len());
    rest[..end].to_owned()
}

#[test]
fn a_bad_envelope_is_400_invalid_request_and_ids_come_back_as_sent() {
    let namespace = common::fresh_namespace("envelope");
    let port = common::free_port();
    let _robotd = common::start_robotd(&namespace, port, &[]);
    let session = open_streamable_in_use(LOCAL, port);
    let mut sse = open_sse(LOCAL, port);
    sse.handshake(true);
    for (body, says, id) in BAD_ENVELOPES {
        for (transport, answer) in [
            (
                "/mcp",
                post_mcp(LOCAL, port, Some(&session), body.as_bytes()),
            ),
            (
                "/mcp without a session",
                post_mcp(LOCAL, port, None, body.as_bytes()),
            ),
            ("/messages/", sse.post(body.as_bytes())),
        ] {
            assert_eq!(answer.status, 400, "{transport} {body}: {answer:?}");
            let error: Value = serde_json::from_str(&answer.body)
                .unwrap_or_else(|e| panic!("{transport} {body}: {e}: {}", answer.body));
            assert_eq!(
                error["error"]["code"], -32600,
                "{transport} {body}: {error}"
            );
            let message = error["error"]["message"].as_str().unwrap_or_default();
            assert!(message.contains(says), "{transport} {body}: {message}");
            assert_eq!(
                raw_id(&answer.body),
                *id,
                "{transport} {body}: {}",
                answer.body
            );
        }
    }
    // Ids MCP takes come back exactly as sent, in answers of either transport.
    for id in [
        "9223372036854775807",
        "-9223372036854775808",
        "\"007\"",
        "\"1e3\"",
    ] {
        let ping = format!(r#"{{"jsonrpc":"2.0","id":{id},"method":"ping"}}"#);
        let answer = post_mcp(LOCAL, port, Some(&session), ping.as_bytes());
        assert_eq!(answer.status, 200, "{answer:?}");
        assert_eq!(raw_id(&answer.body), id, "{}", answer.body);
        assert_eq!(sse.post(ping.as_bytes()).status, 202);
        let line = sse.line_with("\"result\"").expect("the ping's answer");
        assert_eq!(raw_id(&line), id, "{line}");
    }
    // A good envelope with params that do not fit the method stays a params error.
    let bad_params = br#"{"jsonrpc":"2.0","id":"p","method":"tools/call","params":[1,2]}"#;
    let answer = post_mcp(LOCAL, port, Some(&session), bad_params);
    assert_eq!(answer.message()["error"]["code"], -32602, "{answer:?}");
    let answer = sse.post(bad_params);
    assert_eq!(answer.status, 400, "{answer:?}");
    assert_eq!(answer.message()["error"]["code"], -32602, "{answer:?}");
}

fn tool_call(id: &str, tool: &str, arguments: Value) -> Vec<u8> {
    serde_json::to_vec(&json!({"jsonrpc": "2.0", "id": id, "method": "tools/call",
        "params": {"name": tool, "arguments": arguments}}))
    .unwrap()
}

/// The reply text of a `tools/call` answer.
fn text_of(answer: &Value) -> String {
    answer["result"]["content"][0]["text"]
        .as_str()
        .unwrap_or_else(|| panic!("no text: {answer}"))
        .to_owned()
}

/// The answer to request `id` on an SSE stream.
fn sse_answer(sse: &mut SseStream, id: &str) -> Value {
    loop {
        let message = sse.next_message().expect("the stream ended");
        if message["id"] == id {
            return message;
        }
    }
}

/// The string schemas of a property: itself, or its `anyOf` branches.
fn strings(property: &Value) -> Vec<&Value> {
    let is_string = |s: &Value| {
        s["type"] == "string"
            || s["type"]
                .as_array()
                .is_some_and(|t| t.contains(&json!("string")))
    };
    match property["anyOf"].as_array() {
        Some(any) => any.iter().filter(|s| is_string(s)).collect(),
        None => [property].into_iter().filter(|s| is_string(s)).collect(),
    }
}

#[test]
fn every_string_argument_says_its_limit_and_a_longer_one_is_refused_as_invalid() {
    let namespace = common::fresh_namespace("maxlength");
    let port = common::free_port();
    let _robotd = common::start_robotd(&namespace, port, &[]);
    let session = open_streamable_in_use(LOCAL, port);
    let mut sse = open_sse(LOCAL, port);
    sse.handshake(true);

    let list = br#"{"jsonrpc":"2.0","id":"list","method":"tools/list"}"#;
    let tools = post_mcp(LOCAL, port, Some(&session), list).message();
    assert_eq!(sse.post(list).status, 202);
    assert_eq!(
        sse_answer(&mut sse, "list"),
        tools,
        "the same tools on both transports"
    );
    let tools = tools["result"]["tools"].as_array().expect("tools").clone();
    let mut checked = 0;
    for tool in &tools {
        let properties = tool["inputSchema"]["properties"]
            .as_object()
            .expect("properties");
        for (name, property) in properties {
            for string in strings(property) {
                assert!(
                    string["maxLength"].as_u64().is_some(),
                    "{}.{name} has no maxLength: {property}",
                    tool["name"]
                );
                checked += 1;
            }
        }
    }
    assert!(checked >= 20, "{checked} string arguments");
    let max_length = |tool: &str, argument: &str| {
        let tool = tools.iter().find(|t| t["name"] == tool).expect(tool);
        tool["inputSchema"]["properties"][argument]["maxLength"].clone()
    };
    assert_eq!(
        max_length("add_object_name2object_labels", "object_name"),
        100
    );
    assert_eq!(max_length("set_user_task", "task"), 2000);

    let cases = [
        (
            tool_call("t1", "set_user_task", json!({"task": "x".repeat(100_000)})),
            "❌ Validation Error in set_user_task:\n  • task: String should have at most 2000 characters",
        ),
        (
            tool_call("t2", "add_object_name2object_labels", json!({"object_name": "y".repeat(101)})),
            "❌ Validation Error in add_object_name2object_labels:\n  • object_name: String should have at most 100 characters",
        ),
        (
            tool_call("t3", "speak", json!({"text": "z".repeat(2001)})),
            "❌ Validation Error in speak:\n  • text: String should have at most 2000 characters",
        ),
        // Listed with the call's other problems, in the order of the tool's arguments.
        (
            tool_call("t4", "pick_object", json!({"object_name": "p".repeat(101), "pick_coordinate": [0.2],
                                                    "colour": "red"})),
            "❌ Validation Error in pick_object:\n  • object_name: String should have at most 100 characters\
             \n  • pick_coordinate: List should have at least 2 items after validation, not 1\
             \n  • colour: Extra inputs are not permitted",
        ),
        (
            tool_call("t5", "push_object", json!({"object_name": "pencil", "push_coordinate": [0.22, -0.05],
                                                    "direction": "l".repeat(33), "distance": 20})),
            "❌ Validation Error in push_object:\n  • direction: String should have at most 32 characters",
        ),
    ];
    for (call, expected) in &cases {
        let answer = post_mcp(LOCAL, port, Some(&session), call);
        assert_eq!(answer.status, 200, "{answer:?}");
        assert_eq!(text_of(&answer.message()), *expected);
        assert_eq!(sse.post(call).status, 202);
        let id = serde_json::from_slice::<Value>(call).unwrap()["id"].clone();
        let answer = sse_answer(&mut sse, id.as_str().unwrap());
        assert_eq!(text_of(&answer), *expected, "over SSE");
    }
    // Within the limits, the tools work.
    let fine = tool_call("ok", "set_user_task", json!({"task": "t".repeat(2000)}));
    let text = text_of(&post_mcp(LOCAL, port, Some(&session), &fine).message());
    assert!(text.starts_with("✓ User task set: ttt"), "{text}");
}

/// `notifications/cancelled` for request `id` (JSON text).
fn cancel(id: &str) -> Vec<u8> {
    format!(
        r#"{{"jsonrpc":"2.0","method":"notifications/cancelled","params":{{"requestId":{id},"reason":"test"}}}}"#
    )
    .into_bytes()
}

fn pick_pencil(id: u64, meta: Option<Value>) -> Vec<u8> {
    let mut params = json!({"name": "pick_object",
        "arguments": {"object_name": "pencil", "pick_coordinate": [0.22, -0.05]}});
    if let Some(meta) = meta {
        params["_meta"] = meta;
    }
    serde_json::to_vec(
        &json!({"jsonrpc": "2.0", "id": id, "method": "tools/call", "params": params}),
    )
    .unwrap()
}

/// Starts a POST of `body` into streamable-HTTP `session`; returns the connection, whose
/// answer is read later.
fn start_post(port: u16, session: &str, body: &[u8]) -> std::net::TcpStream {
    let mut stream = mcp_raw::connect_from(LOCAL, port);
    mcp_raw::send(
        &mut stream,
        "POST",
        "/mcp",
        &mcp_raw::mcp_headers(Some(session)),
        body,
    );
    stream
}

#[test]
fn a_request_cancelled_before_it_started_gets_no_answer_on_either_transport() {
    let namespace = common::fresh_namespace("queuedcancel");
    let port = common::free_port();
    // Real-time motions: the first client's move lasts seconds, the others wait behind it.
    let _robotd = common::start_robotd(&namespace, port, &["--set", "robot.time_scale=1.0"]);
    let mover = open_streamable_in_use(LOCAL, port);
    let waiter = open_streamable_in_use(LOCAL, port);
    let mut sse = open_sse(LOCAL, port);
    sse.handshake(true);

    // The first client picks the pencil; its first progress event says the skill runs.
    let pick = pick_pencil(11, Some(json!({"progressToken": "move"})));
    let mut moving = std::io::BufReader::new(start_post(port, &mover, &pick));
    let mut line = String::new();
    while !line.contains("notifications/progress") {
        line.clear();
        let read = std::io::BufRead::read_line(&mut moving, &mut line).expect("the answer");
        assert!(read > 0, "the motion ended without progress");
    }

    // Behind it, three picks, each cancelled at once: on legacy SSE, on streamable HTTP's
    // direct path, and through rmcp (a `_meta` it must see itself).
    assert_eq!(sse.post(&pick_pencil(31, None)).status, 202);
    assert_eq!(sse.post(&cancel("31")).status, 202);
    let mut direct = start_post(port, &waiter, &pick_pencil(41, None));
    let mut through_rmcp = start_post(
        port,
        &waiter,
        &pick_pencil(51, Some(json!({"progressToken": 5, "note": "rmcp"}))),
    );
    for id in ["41", "51"] {
        let answer = post_mcp(LOCAL, port, Some(&waiter), &cancel(id));
        assert_eq!(answer.status, 202, "{answer:?}");
    }
    // A call behind the cancelled one on the SSE session: its answer comes after the
    // cancelled call's would have.
    let after = serde_json::to_vec(&json!({"jsonrpc": "2.0", "id": 32, "method": "tools/call",
        "params": {"name": "move2observation_pose", "arguments": {"workspace_id": "niryo_ws"}}}))
    .unwrap();
    assert_eq!(sse.post(&after).status, 202);

    // The streamable-HTTP answers end without a JSON-RPC answer.
    for (id, stream) in [(41, &mut direct), (51, &mut through_rmcp)] {
        let answer = mcp_raw::read_answer(stream);
        assert_eq!(answer.status, 200, "{answer:?}");
        assert!(
            answer.messages().iter().all(|m| m["id"] != id),
            "request {id} was cancelled before it started, and answered: {answer:?}"
        );
    }
    // The mover's call ended as it should.
    let mut rest = String::new();
    std::io::Read::read_to_string(&mut moving, &mut rest).expect("the mover's answer");
    assert!(rest.contains("✓ Successfully picked 'pencil'"), "{rest}");
    // On SSE, nothing for 31 before 32's answer.
    loop {
        let message = sse.next_message().expect("the stream ended");
        assert_ne!(message["id"], 31, "request 31 was answered: {message}");
        if message["id"] == 32 {
            assert!(text_of(&message).starts_with('✓'), "{message}");
            break;
        }
    }
}
