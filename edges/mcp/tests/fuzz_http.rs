//! Fuzzing the MCP edge's HTTP side with real sockets: random bodies, JSON-RPC messages of
//! every shape and tool calls with random arguments, into streamable HTTP (`/mcp`, with and
//! without a session) and legacy SSE (`/messages/`). Every answer is a 2xx or 4xx with a clear
//! body — never a 5xx, never a dropped connection — and the edge still serves a good client
//! afterwards. A 4xx names what was wrong: a non-empty message, in a JSON-RPC error object
//! when the body is JSON. Every request has a timeout, so a hang fails a case (and is shrunk)
//! instead of waiting for the test runner's kill.
//!
//! Bounded cases (`PROPTEST_CASES` for a longer run). Failures are saved to, and replayed
//! first from, `fuzz_http.proptest-regressions` next to this file (proptest's runner only does
//! that when it knows the source file: see [`config`]).

use proptest::prelude::*;
use robotd_fuzzing::{cases, fuzz, runner_config};
use robotd_mcp::call_log::CallLog;
use robotd_mcp::http::{router, RouterOptions};
use robotd_mcp::McpService;
use robotd_protocol::workspace::{builtin_workspaces, WorkspaceInfo};
use robotd_protocol::RobotModel;
use robotd_runtime::bus::{Bus, BusOptions};
use robotd_tools::{Registry, ToolSettings};
use serde_json::{json, Value};
use std::sync::{Arc, OnceLock};
use std::time::Duration;

/// How long one request may take, answer included (the edge answers in milliseconds).
const REQUEST_TIMEOUT: Duration = Duration::from_secs(10);

/// One served MCP edge for all cases, with an open streamable session and an SSE session.
struct Edge {
    runtime: tokio::runtime::Runtime,
    base: String,
    session: String,
    sse_path: String,
    http: reqwest::Client,
}

fn edge() -> &'static Edge {
    static EDGE: OnceLock<Edge> = OnceLock::new();
    EDGE.get_or_init(|| {
        let runtime = tokio::runtime::Builder::new_multi_thread()
            .worker_threads(2)
            .enable_all()
            .build()
            .unwrap();
        let (base, session, sse_path, http) = runtime.block_on(async {
            let namespace = format!("mcpfuzz{}", std::process::id());
            let bus = Bus::open(BusOptions::new(&namespace, "fuzz")).unwrap();
            let workspaces: Vec<WorkspaceInfo> = builtin_workspaces(RobotModel::Ned2)
                .iter()
                .map(|w| w.to_info(RobotModel::Ned2))
                .collect();
            let registry = Registry::connect(&bus, ToolSettings::new("fuzz", workspaces)).unwrap();
            std::mem::forget(bus);
            let service = McpService::new(registry, false, Arc::new(CallLog::disabled()));
            let app = router(service, RouterOptions::default(), Default::default());
            let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
            let base = format!("http://{}", listener.local_addr().unwrap());
            tokio::spawn(async move { axum::serve(listener, app).await });
            robotd_runtime::telemetry::install_tls_provider();
            // Every fuzzing request (and its answer) within REQUEST_TIMEOUT.
            let http = reqwest::Client::builder()
                .timeout(REQUEST_TIMEOUT)
                .build()
                .unwrap();
            let init = json!({"jsonrpc": "2.0", "id": 1, "method": "initialize", "params": {
                "protocolVersion": "2025-06-18", "capabilities": {},
                "clientInfo": {"name": "fuzz", "version": "1"}}});
            let reply = post(&http, &base, None, init.to_string().into_bytes())
                .await
                .unwrap();
            let session = reply.session.expect("a session id");
            let initialized = json!({"jsonrpc": "2.0", "method": "notifications/initialized"});
            post(
                &http,
                &base,
                Some(&session),
                initialized.to_string().into_bytes(),
            )
            .await
            .unwrap();
            // An SSE session: read the stream until its endpoint event. The stream stays open
            // for the whole run, so its client has no overall timeout (only its steps do).
            let stream_client = reqwest::Client::builder()
                .connect_timeout(REQUEST_TIMEOUT)
                .build()
                .unwrap();
            let mut sse = tokio::time::timeout(
                REQUEST_TIMEOUT,
                stream_client.get(format!("{base}/sse")).send(),
            )
            .await
            .expect("the SSE stream opens in time")
            .unwrap();
            let mut text = String::new();
            let sse_path = loop {
                let chunk = tokio::time::timeout(REQUEST_TIMEOUT, sse.chunk())
                    .await
                    .expect("the endpoint event in time")
                    .unwrap()
                    .expect("the endpoint event");
                text.push_str(&String::from_utf8_lossy(&chunk));
                if let Some(line) = text.lines().find(|l| l.starts_with("data: /messages/")) {
                    break line.trim_start_matches("data: ").to_owned();
                }
            };
            // Keep the stream open for the whole run, and initialise the session.
            tokio::spawn(async move { while let Ok(Some(_)) = sse.chunk().await {} });
            for message in [init.clone(), initialized.clone()] {
                let status = http
                    .post(format!("{base}{sse_path}"))
                    .header("Content-Type", "application/json")
                    .body(message.to_string())
                    .send()
                    .await
                    .unwrap()
                    .status();
                assert_eq!(status, 202);
            }
            (base, session, sse_path, http)
        });
        Edge {
            runtime,
            base,
            session,
            sse_path,
            http,
        }
    })
}

/// An answer of `/mcp`.
struct Answer {
    status: u16,
    content_type: String,
    body: String,
    session: Option<String>,
}

/// POSTs `body` to `/mcp`; `Err` = no answer within [`REQUEST_TIMEOUT`] or a dropped
/// connection.
async fn post(
    http: &reqwest::Client,
    base: &str,
    session: Option<&str>,
    body: Vec<u8>,
) -> Result<Answer, String> {
    let mut request = http
        .post(format!("{base}/mcp"))
        .header("Content-Type", "application/json")
        .header("Accept", "application/json, text/event-stream")
        .body(body);
    if let Some(id) = session {
        request = request.header("Mcp-Session-Id", id);
    }
    let response = request
        .send()
        .await
        .map_err(|e| format!("no answer (hang or dropped connection): {e}"))?;
    let header = |name: &str| {
        response
            .headers()
            .get(name)
            .and_then(|v| v.to_str().ok())
            .map(str::to_owned)
    };
    let (session, content_type) = (header("mcp-session-id"), header("content-type"));
    let status = response.status().as_u16();
    let body = response
        .text()
        .await
        .map_err(|e| format!("status {status}, but the body did not end: {e}"))?;
    Ok(Answer {
        status,
        content_type: content_type.unwrap_or_default(),
        body,
        session,
    })
}

fn any_json() -> impl Strategy<Value = Value> {
    let leaf = prop_oneof![
        Just(Value::Null),
        any::<bool>().prop_map(Value::Bool),
        any::<i64>().prop_map(|n| json!(n)),
        ".{0,16}".prop_map(Value::String),
    ];
    leaf.prop_recursive(3, 24, 5, |inner| {
        prop_oneof![
            proptest::collection::vec(inner.clone(), 0..5).prop_map(Value::Array),
            proptest::collection::btree_map(".{0,8}", inner, 0..5)
                .prop_map(|m| Value::Object(m.into_iter().collect())),
        ]
    })
}

/// JSON-RPC-shaped messages: real and made-up methods, ids and params of every type.
fn message() -> impl Strategy<Value = Value> {
    let method = prop_oneof![
        Just("tools/call".to_owned()),
        Just("tools/list".to_owned()),
        Just("initialize".to_owned()),
        Just("ping".to_owned()),
        Just("notifications/initialized".to_owned()),
        Just("notifications/cancelled".to_owned()),
        "[a-z/]{0,16}",
    ];
    let id = prop_oneof![
        Just(Value::Null),
        any::<i64>().prop_map(|n| json!(n)),
        ".{0,8}".prop_map(Value::String),
        any_json()
    ];
    let tool = prop_oneof![
        Just("pick_object"),
        Just("speak"),
        Just("push_object"),
        Just("nope")
    ];
    let params = prop_oneof![
        any_json(),
        (tool, any_json())
            .prop_map(|(name, arguments)| json!({"name": name, "arguments": arguments})),
    ];
    (
        method,
        proptest::option::of(id),
        proptest::option::of(params),
        any::<bool>(),
    )
        .prop_map(|(method, id, params, jsonrpc)| {
            let mut m = json!({"method": method});
            if jsonrpc {
                m["jsonrpc"] = json!("2.0");
            }
            if let Some(id) = id {
                m["id"] = id;
            }
            if let Some(params) = params {
                m["params"] = params;
            }
            m
        })
}

/// A 2xx, a 4xx, or the session limit's 503 (a random `initialize` can open sessions); a
/// refusal (4xx, 503) says why in its body.
fn check(answer: Result<Answer, String>) -> Result<(), TestCaseError> {
    let Answer {
        status,
        content_type,
        body,
        ..
    } = answer.map_err(TestCaseError::fail)?;
    let full = status == 503 && body.contains("mcp.max_sessions");
    prop_assert!(
        (200..300).contains(&status) || (400..500).contains(&status) || full,
        "status {status}: {body}"
    );
    if status >= 400 {
        check_refusal(status, &content_type, &body)?;
    }
    Ok(())
}

/// A refusal's body is a human-readable message: a JSON-RPC error object with a message when
/// the body is JSON, else the text itself.
fn check_refusal(status: u16, content_type: &str, body: &str) -> Result<(), TestCaseError> {
    let readable = |text: &str| text.chars().filter(|c| c.is_alphabetic()).count() >= 3;
    let json = serde_json::from_str::<Value>(body).ok();
    if content_type.starts_with("application/json") || json.as_ref().is_some_and(Value::is_object) {
        let message = json
            .as_ref()
            .and_then(|v| v.pointer("/error/message"))
            .and_then(Value::as_str)
            .unwrap_or_default();
        prop_assert!(
            readable(message),
            "status {status}: a JSON body without a JSON-RPC error message: {body}"
        );
    } else {
        prop_assert!(
            readable(body),
            "status {status} ({content_type}) without a message: {body:?}"
        );
    }
    Ok(())
}

/// Cases of the CI run: random bodies, and JSON-RPC messages (each sent on both transports).
const BYTES_CASES: u32 = 300;
const MESSAGE_CASES: u32 = 300;

/// Random bytes, then JSON-RPC of every shape over both transports, then a good client: all in
/// one test, so that "after the fuzzing" holds under a runner that starts each test alone.
#[test]
fn fuzzed_requests_get_clear_answers_and_a_good_client_is_served_after() {
    let edge = edge();
    fuzz(
        runner_config!(cases(BYTES_CASES)),
        proptest::collection::vec(any::<u8>(), 0..300),
        |body| {
            check(
                edge.runtime
                    .block_on(post(&edge.http, &edge.base, Some(&edge.session), body)),
            )
        },
    );
    fuzz(
        runner_config!(cases(MESSAGE_CASES)),
        (message(), any::<bool>()),
        |(message, in_session)| {
            let session = in_session.then_some(edge.session.as_str());
            let body = message.to_string().into_bytes();
            check(
                edge.runtime
                    .block_on(post(&edge.http, &edge.base, session, body.clone())),
            )?;
            // The same over legacy SSE: accepted (202) or refused (400) with a message.
            let (status, text) = edge
                .runtime
                .block_on(async {
                    let response = edge
                        .http
                        .post(format!("{}{}", edge.base, edge.sse_path))
                        .header("Content-Type", "application/json")
                        .body(body)
                        .send()
                        .await?;
                    let status = response.status().as_u16();
                    Ok::<_, reqwest::Error>((status, response.text().await?))
                })
                .map_err(|e| TestCaseError::fail(format!("SSE post: no answer: {e}")))?;
            prop_assert!(status == 202 || status == 400, "SSE post: {status}: {text}");
            if status == 400 {
                check_refusal(status, "", &text)?;
            }
            Ok(())
        },
    );
    let list = json!({"jsonrpc": "2.0", "id": 99, "method": "tools/list"});
    let answer = edge
        .runtime
        .block_on(post(
            &edge.http,
            &edge.base,
            Some(&edge.session),
            list.to_string().into_bytes(),
        ))
        .unwrap();
    assert_eq!(answer.status, 200, "{}", answer.body);
    assert!(answer.body.contains("pick_object"), "{}", answer.body);
}
