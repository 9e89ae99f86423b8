//! Fuzzing the MCP edge's HTTP side with real sockets: random bodies, JSON-RPC messages of
//! every shape and tool calls with random arguments, into streamable HTTP (`/mcp`, with and
//! without a session) and legacy SSE (`/messages/`). Every answer is a 2xx or 4xx with a clear
//! body — never a 5xx, never a dropped connection — and the edge still serves a good client
//! afterwards. Bounded cases; regressions in `proptest-regressions/`.

use proptest::prelude::*;
use robotd_mcp::call_log::CallLog;
use robotd_mcp::http::{router, RouterOptions};
use robotd_mcp::McpService;
use robotd_protocol::workspace::{builtin_workspaces, WorkspaceInfo};
use robotd_protocol::RobotModel;
use robotd_runtime::bus::{Bus, BusOptions};
use robotd_tools::{Registry, ToolSettings};
use serde_json::{json, Value};
use std::sync::{Arc, OnceLock};

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
            let http = reqwest::Client::new();
            let init = json!({"jsonrpc": "2.0", "id": 1, "method": "initialize", "params": {
                "protocolVersion": "2025-06-18", "capabilities": {},
                "clientInfo": {"name": "fuzz", "version": "1"}}});
            let reply = post(&http, &base, None, init.to_string().into_bytes()).await;
            let session = reply.2.expect("a session id");
            let initialized = json!({"jsonrpc": "2.0", "method": "notifications/initialized"});
            post(
                &http,
                &base,
                Some(&session),
                initialized.to_string().into_bytes(),
            )
            .await;
            // An SSE session: read the stream until its endpoint event.
            let mut sse = http.get(format!("{base}/sse")).send().await.unwrap();
            let mut text = String::new();
            let sse_path = loop {
                let chunk = sse.chunk().await.unwrap().expect("the endpoint event");
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

/// POSTs `body` to `/mcp`: (status, body, session id header).
async fn post(
    http: &reqwest::Client,
    base: &str,
    session: Option<&str>,
    body: Vec<u8>,
) -> (u16, String, Option<String>) {
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
        .expect("the edge answers (no dropped connection)");
    let status = response.status().as_u16();
    let id = response
        .headers()
        .get("mcp-session-id")
        .and_then(|v| v.to_str().ok())
        .map(str::to_owned);
    let text = tokio::time::timeout(std::time::Duration::from_secs(10), response.text())
        .await
        .expect("the answer ends")
        .unwrap_or_default();
    (status, text, id)
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

/// A 2xx, a 4xx, or the session limit's 503 (a random `initialize` can open sessions).
fn check(status: u16, body: &str) -> Result<(), TestCaseError> {
    let full = status == 503 && body.contains("mcp.max_sessions");
    prop_assert!(
        (200..300).contains(&status) || (400..500).contains(&status) || full,
        "status {status}: {body}"
    );
    Ok(())
}

/// `PROPTEST_CASES` when set (a longer run), else `default` (the bounded CI run).
fn cases(default: u32) -> u32 {
    std::env::var("PROPTEST_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

/// Random bytes, then JSON-RPC of every shape over both transports, then a good client: all in
/// one test, so that "after the fuzzing" holds under a runner that starts each test alone.
#[test]
fn fuzzed_requests_get_clear_answers_and_a_good_client_is_served_after() {
    let edge = edge();
    let mut runner = proptest::test_runner::TestRunner::new(ProptestConfig::with_cases(cases(300)));
    runner
        .run(&proptest::collection::vec(any::<u8>(), 0..300), |body| {
            let (status, text, _) =
                edge.runtime
                    .block_on(post(&edge.http, &edge.base, Some(&edge.session), body));
            check(status, &text)
        })
        .unwrap();
    runner
        .run(&(message(), any::<bool>()), |(message, in_session)| {
            let session = in_session.then_some(edge.session.as_str());
            let body = message.to_string().into_bytes();
            let (status, text, _) =
                edge.runtime
                    .block_on(post(&edge.http, &edge.base, session, body.clone()));
            check(status, &text)?;
            // The same over legacy SSE: accepted (202) or refused (400), never more.
            let status = edge.runtime.block_on(async {
                edge.http
                    .post(format!("{}{}", edge.base, edge.sse_path))
                    .header("Content-Type", "application/json")
                    .body(body)
                    .send()
                    .await
                    .expect("the edge answers")
                    .status()
                    .as_u16()
            });
            prop_assert!(status == 202 || status == 400, "SSE post: {status}");
            Ok(())
        })
        .unwrap();
    let list = json!({"jsonrpc": "2.0", "id": 99, "method": "tools/list"});
    let (status, text, _) = edge.runtime.block_on(post(
        &edge.http,
        &edge.base,
        Some(&edge.session),
        list.to_string().into_bytes(),
    ));
    assert_eq!(status, 200, "{text}");
    assert!(text.contains("pick_object"), "{text}");
}
