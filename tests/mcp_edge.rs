//! The MCP edge of a served robotd, driven by a real MCP client (rmcp) over legacy SSE,
//! streamable HTTP and stdio: the tool list, the contract's texts for successes, validation
//! errors and failures, structuredContent, cancellation of a motion, and the HTTP guard
//! (bearer token, Origin, body limit, non-loopback binds), and robotd's client keeping its
//! connection.

mod common;

use rmcp::model::{CallToolRequest, CallToolRequestParams, CallToolResult, ClientRequest};
use rmcp::service::PeerRequestOptions;
use robotd_mcp::client::{connect, McpClient};
use robotd_protocol::arm::ArmState;
use robotd_runtime::bus::{Bus, BusOptions};
use robotd_topics::ARM_STATE;
use serde_json::{json, Value};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

const TOOLS: [&str; 24] = [
    "pick_place_object",
    "pick_object",
    "place_object",
    "push_object",
    "move2by",
    "move2observation_pose",
    "clear_collision_detected",
    "calibrate",
    "get_detected_objects",
    "get_detected_object",
    "get_largest_detected_object",
    "get_smallest_detected_object",
    "get_detected_objects_sorted",
    "get_largest_free_space_with_center",
    "get_workspace_coordinate_from_point",
    "get_object_labels_as_string",
    "add_object_name2object_labels",
    "get_system_status",
    "speak",
    "set_user_task",
    "emergency_stop",
    "release_emergency_stop",
    "get_camera_image",
    "label_object",
];

fn runtime() -> tokio::runtime::Runtime {
    tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .unwrap()
}

async fn call_raw(client: &McpClient, tool: &str, args: Value) -> CallToolResult {
    let mut params = CallToolRequestParams::new(tool.to_owned());
    if let Value::Object(map) = args {
        params = params.with_arguments(map);
    }
    client
        .call_tool(params)
        .await
        .unwrap_or_else(|e| panic!("{tool}: {e}"))
}

/// Calls `tool`; returns its one text, after checking structuredContent mirrors it.
async fn call(client: &McpClient, tool: &str, args: Value) -> (String, Value) {
    let result = call_raw(client, tool, args).await;
    assert_eq!(result.content.len(), 1, "{tool}: one content item");
    let text = result.content[0]
        .as_text()
        .unwrap_or_else(|| panic!("{tool}: a text item"))
        .text
        .clone();
    let structured = result
        .structured_content
        .clone()
        .unwrap_or_else(|| panic!("{tool}: structuredContent"));
    assert_eq!(structured["result"], Value::String(text.clone()), "{tool}");
    assert_eq!(result.is_error, Some(false), "{tool}: failures are results");
    if text.starts_with('❌') {
        assert!(structured["data"].is_null(), "{tool}: no data on failure");
    }
    (text, structured["data"].clone())
}

async fn text(client: &McpClient, tool: &str, args: Value) -> String {
    call(client, tool, args).await.0
}

/// The contract, tool by tool, for everything that does not pick or place.
async fn check_contract(client: &McpClient, tag: &str) {
    let tools = client.list_all_tools().await.unwrap();
    let names: Vec<&str> = tools.iter().map(|t| t.name.as_ref()).collect();
    assert_eq!(names, TOOLS);
    for tool in &tools {
        assert!(
            tool.output_schema.is_some(),
            "{} has an outputSchema",
            tool.name
        );
    }
    let ppo = &tools[0].input_schema;
    assert_eq!(ppo["properties"]["pick_coordinate"]["maxItems"], 2);

    // Workspace.
    assert_eq!(
        text(
            client,
            "get_workspace_coordinate_from_point",
            json!({"workspace_id": "niryo_ws", "point": " Upper Left Corner"})
        )
        .await,
        "✓ Coordinate of 'upper left corner' in workspace 'niryo_ws': [0.337, 0.087]"
    );
    let (t, data) = call(
        client,
        "get_workspace_coordinate_from_point",
        json!({"workspace_id": "niryo_ws", "point": "center point"}),
    )
    .await;
    assert_eq!(
        t,
        "✓ Coordinate of 'center point' in workspace 'niryo_ws': [0.250, 0.000]"
    );
    assert_eq!(data["coordinate"], json!([0.25, 0.0]));
    assert_eq!(
        text(
            client,
            "get_workspace_coordinate_from_point",
            json!({"workspace_id": "lab", "point": "center point"})
        )
        .await,
        "❌ Error getting workspace coordinate: unknown workspace 'lab'; known: niryo_ws, gazebo_1"
    );
    assert_eq!(
        text(
            client,
            "get_workspace_coordinate_from_point",
            json!({"workspace_id": "niryo_ws", "point": "middle"})
        )
        .await,
        "❌ Validation Error in get_workspace_coordinate_from_point:\n  • point: Value error, Point must be one of: upper left corner, upper right corner, lower left corner, lower right corner, center point"
    );

    // Labels.
    let labels = text(client, "get_object_labels_as_string", json!({})).await;
    assert!(
        labels.starts_with("✓ Detectable objects: I can recognize these objects: pencil, red cube"),
        "{labels}"
    );
    let label = format!("Screwdriver {tag}");
    assert_eq!(
        text(
            client,
            "add_object_name2object_labels",
            json!({"object_name": label})
        )
        .await,
        format!("✓ Added {label} to the list of recognizable objects.")
    );
    assert_eq!(
        text(
            client,
            "add_object_name2object_labels",
            json!({"object_name": label.to_lowercase()})
        )
        .await,
        format!(
            "✓ {} is already in the list of recognizable objects.",
            label.to_lowercase()
        )
    );
    assert_eq!(
        text(
            client,
            "add_object_name2object_labels",
            json!({"object_name": "  "})
        )
        .await,
        "❌ Validation Error: object_name must be a non-empty string"
    );
    // A huge label is refused with the limit, twice, and the list still answers.
    for _ in 0..2 {
        let refused = text(
            client,
            "add_object_name2object_labels",
            json!({"object_name": "x".repeat(600_000)}),
        )
        .await;
        assert!(
            refused.starts_with("❌") && refused.contains("at most 100"),
            "{}",
            &refused[..refused.len().min(300)]
        );
    }
    let labels = text(client, "get_object_labels_as_string", json!({})).await;
    assert!(
        labels.starts_with("✓ Detectable objects:") && labels.len() < 10_000,
        "{}",
        &labels[..labels.len().min(300)]
    );

    // Feedback.
    assert_eq!(
        text(client, "speak", json!({"text": "hello"})).await,
        "✓ Speaking: 'hello'"
    );
    assert_eq!(
        text(client, "speak", json!({"text": ""})).await,
        "❌ Validation Error: text must be a non-empty string"
    );
    assert_eq!(
        text(client, "set_user_task", json!({"task": "sort the objects"})).await,
        "✓ User task set: sort the objects"
    );

    // Detection (the first call moves the arm to the observation pose).
    let (found, data) = call(client, "get_detected_objects", json!({})).await;
    assert!(
        found.starts_with("✓ Found 4 object(s):\n[\n  {\n"),
        "{found}"
    );
    let mut seen: Vec<String> = data
        .as_array()
        .unwrap()
        .iter()
        .map(|o| o["label"].as_str().unwrap().to_owned())
        .collect();
    seen.sort();
    assert_eq!(
        seen,
        ["blue square", "green cylinder", "pencil", "red cube"]
    );
    let (cubes, data) = call(client, "get_detected_objects", json!({"label": "CUBE"})).await;
    assert!(cubes.starts_with("✓ Found 1 object(s):"), "{cubes}");
    assert_eq!(data[0]["label"], "red cube");
    assert_eq!(
        text(client, "get_detected_objects", json!({"location": "left next to"})).await,
        "❌ Error getting detected objects: Coordinate must be provided for location filter: left next to"
    );
    let left = text(
        client,
        "get_detected_objects",
        json!({"location": "Left Next To", "coordinate": [0.25, 0.0]}),
    )
    .await;
    assert!(left.starts_with("✓ Found 2 object(s):"), "{left}");
    assert_eq!(
        text(client, "get_detected_objects", json!({"label": "unicorn"})).await,
        "✓ No objects detected matching the criteria"
    );
    let near = text(
        client,
        "get_detected_object",
        json!({"coordinate": [0.28, 0.04]}),
    )
    .await;
    assert!(
        near.starts_with("✓ Found object near [0.280, 0.040]:\n{"),
        "{near}"
    );
    assert!(near.contains("\"label\": \"red cube\""), "{near}");
    assert_eq!(
        text(
            client,
            "get_detected_object",
            json!({"coordinate": [0.17, 0.08]})
        )
        .await,
        "✓ No object found near [0.170, 0.080]"
    );
    let largest = text(client, "get_largest_detected_object", json!({})).await;
    assert!(largest.starts_with("✓ Largest object (0.00"), "{largest}");
    assert!(largest.contains("\"label\": \"blue square\""), "{largest}");
    let smallest = text(client, "get_smallest_detected_object", json!({})).await;
    assert!(
        smallest.starts_with("✓ Smallest object (0.000"),
        "{smallest}"
    );
    let (sorted, data) = call(
        client,
        "get_detected_objects_sorted",
        json!({"ascending": false}),
    )
    .await;
    assert!(
        sorted.starts_with("✓ Found 4 object(s) sorted largest to smallest:"),
        "{sorted}"
    );
    let sizes: Vec<f64> = data
        .as_array()
        .unwrap()
        .iter()
        .map(|o| o["dimensions"]["size_m2"].as_f64().unwrap())
        .collect();
    assert!(sizes.windows(2).all(|w| w[0] >= w[1]), "{sizes:?}");
    let (free, data) = call(client, "get_largest_free_space_with_center", json!({})).await;
    assert!(free.starts_with("✓ Largest free space: 0.0"), "{free}");
    assert!(free.contains(" m² at center coordinates ["), "{free}");
    // A free square of at least 45 mm: the default scene's cube and cylinder fit it.
    assert!(data["area_m2"].as_f64().unwrap() > 0.002, "{free}");

    // Status.
    let status = text(client, "get_system_status", json!({})).await;
    let status: Value = serde_json::from_str(&status).unwrap();
    assert_eq!(status["workspace_id"], "niryo_ws");
    // The robot type, as the Python server answers.
    assert_eq!(status["robot_id"], "niryo");
    assert_eq!(status["estop_engaged"], false);
    for key in ["x", "y", "z", "roll", "pitch", "yaw"] {
        assert!(status["pose"][key].is_number(), "{status}");
    }
    assert!(status["actors"].as_array().unwrap().len() >= 4, "{status}");

    // Robot control: the failures and validation texts of the contract.
    assert_eq!(
        text(
            client,
            "move2observation_pose",
            json!({"workspace_id": "lab"})
        )
        .await,
        "❌ Error moving to observation pose: unknown workspace 'lab'; known: niryo_ws, gazebo_1"
    );
    assert_eq!(
        text(
            client,
            "pick_place_object",
            json!({
                "object_name": "", "pick_coordinate": [0.1], "z_offset": 0.5, "location": "beside"
            })
        )
        .await,
        "❌ Validation Error in pick_place_object:\n  \
         • object_name: String should have at least 1 character\n  \
         • pick_coordinate: List should have at least 2 items after validation, not 1\n  \
         • place_coordinate: Field required\n  \
         • location: Value error, Invalid location 'beside'. Must be one of: left next to, \
         right next to, above, below, on top of, inside. Note: 'close to' is not allowed for \
         pick_place_object.\n  \
         • z_offset: Input should be less than or equal to 0.1"
    );
    assert_eq!(
        text(
            client,
            "pick_place_object",
            json!({
                "object_name": "pencil", "pick_coordinate": [0.2, -0.05],
                "place_coordinate": [0.28, 0.04], "location": "close to"
            })
        )
        .await,
        "❌ Validation Error in pick_place_object:\n  • location: Value error, Invalid location \
         'close to'. Must be one of: left next to, right next to, above, below, on top of, \
         inside. Note: 'close to' is not allowed for pick_place_object."
    );
    assert_eq!(
        text(
            client,
            "push_object",
            json!({
                "object_name": "large box", "push_coordinate": [0.25, "x"], "direction": "sideways",
                "distance": -5
            })
        )
        .await,
        "❌ Validation Error in push_object:\n  \
         • push_coordinate.1: Input should be a valid number, unable to parse string as a \
         number\n  \
         • direction: Value error, Direction must be one of: up, down, left, right\n  \
         • distance: Input should be greater than 0"
    );
    assert_eq!(
        text(
            client,
            "get_detected_objects_sorted",
            json!({"ascending": "yes", "extra": 1})
        )
        .await,
        "❌ Validation Error in get_detected_objects_sorted:\n  \
         • ascending: Input should be a valid boolean, unable to interpret input\n  \
         • extra: Extra inputs are not permitted"
    );
    assert_eq!(
        text(
            client,
            "move2by",
            json!({
                "object_name": "pencil", "pick_coordinate": [0.22, -0.05], "direction": "diagonal",
                "distance": 0.05
            })
        )
        .await,
        "❌ Error during move2by: Invalid direction 'diagonal'"
    );
    assert_eq!(
        text(client, "pick_object",
            json!({"object_name": "unicorn", "pick_coordinate": [0.22, -0.05]})).await,
        "❌ Failed to pick 'unicorn': no 'unicorn' within 5 cm of [0.220, -0.050]; seen there: pencil"
    );
    assert_eq!(
        text(client, "pick_place_object", json!({
            "object_name": "pencil", "pick_coordinate": [0.22, -0.05],
            "place_coordinate": [99.9, 99.9]
        })).await,
        "❌ Failed to pick and place 'pencil': place coordinate [99.900, 99.900] is outside workspace 'niryo_ws'"
    );
    assert_eq!(
        text(client, "clear_collision_detected", json!({})).await,
        "✓ Collision detection flag cleared"
    );

    // An unknown tool stays a protocol error.
    let unknown = client.call_tool(CallToolRequestParams::new("fly")).await;
    assert!(unknown.is_err(), "{unknown:?}");
}

#[test]
fn the_contract_holds_over_sse_and_streamable_http() {
    let namespace = common::fresh_namespace("mcp");
    let port = common::free_port();
    let _robotd = common::start_robotd(&namespace, port, &["--set", "robot.time_scale=0.05"]);
    runtime().block_on(async {
        for (tag, path) in [("sse", "/sse"), ("http", "/mcp")] {
            let url = format!("http://127.0.0.1:{port}{path}");
            let client = connect(&url, None)
                .await
                .unwrap_or_else(|e| panic!("{url}: {e}"));
            check_contract(&client, tag).await;
            client.cancel().await.unwrap();
        }
    });
}

#[test]
fn the_contract_holds_over_stdio() {
    let namespace = common::fresh_namespace("stdio");
    let log_dir = std::env::temp_dir().join(format!("robotd-stdio-logs-{}", std::process::id()));
    runtime().block_on(async {
        use rmcp::ServiceExt;
        let mut child = tokio::process::Command::new(env!("CARGO_BIN_EXE_robotd"))
            .args(["mcp-stdio", "--namespace", &namespace])
            .args(["--set", "robot.time_scale=0.05"])
            .arg("--set")
            .arg(format!("telemetry.log_dir={}", log_dir.display()))
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .kill_on_drop(true)
            .spawn()
            .expect("start robotd mcp-stdio");

        let stdout = child.stdout.take().unwrap();
        let stdin = child.stdin.take().unwrap();
        let client = ().serve((stdout, stdin)).await.expect("MCP over stdio");
        check_contract(&client, "stdio").await;
        client.cancel().await.unwrap();
        // The client closed stdin: robotd ends on its own.
        let status = tokio::time::timeout(Duration::from_secs(10), child.wait())
            .await
            .expect("robotd mcp-stdio ends when stdin closes")
            .unwrap();
        assert!(status.success(), "{status}");
    });
    // Every call went to the call log.
    let logs: Vec<_> = std::fs::read_dir(&log_dir)
        .unwrap()
        .filter_map(Result::ok)
        .filter(|e| e.file_name().to_string_lossy().starts_with("mcp_server_"))
        .collect();
    assert_eq!(logs.len(), 1, "one call log");
    let log = std::fs::read_to_string(logs[0].path()).unwrap();
    let lines: Vec<Value> = log
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert!(lines.len() > 30, "{} calls logged", lines.len());
    assert!(lines.iter().any(|l| l["tool"] == "speak"
        && l["status"] == "ok"
        && l["transport"] == "stdio"
        && l["duration_ms"].is_number()));
    std::fs::remove_dir_all(&log_dir).ok();
}

#[test]
fn a_cancelled_pick_stops_the_arm() {
    let namespace = common::fresh_namespace("cancel");
    let port = common::free_port();
    // Slow motions (real time) so that the cancel lands mid-motion.
    let _robotd = common::start_robotd(&namespace, port, &["--set", "robot.time_scale=1.0"]);
    runtime().block_on(async {
        let bus = Bus::open(BusOptions::new(&namespace, "cancel-test")).unwrap();
        let mut states = bus.subscriber(&ARM_STATE).unwrap();
        let client = connect(&format!("http://127.0.0.1:{port}/sse"), None)
            .await
            .unwrap();
        let args = json!({"object_name": "red cube", "pick_coordinate": [0.28, 0.04]});
        let request = ClientRequest::CallToolRequest(CallToolRequest::new(
            CallToolRequestParams::new("pick_object")
                .with_arguments(args.as_object().cloned().unwrap()),
        ));
        let handle = client
            .peer()
            .send_cancellable_request(request, PeerRequestOptions::no_options())
            .await
            .unwrap();
        // Wait until the arm moves, then cancel.
        common::wait_until_the_arm_moves(&mut states).await;
        let cancelled_at = Instant::now();
        handle.cancel(Some("test".into())).await.unwrap();
        // The arm comes to rest promptly and stays there.
        loop {
            let state: ArmState = tokio::time::timeout(Duration::from_secs(5), states.recv())
                .await
                .expect("arm states")
                .unwrap()
                .body;
            if !state.moving {
                break;
            }
            assert!(
                cancelled_at.elapsed() < Duration::from_secs(2),
                "the arm kept moving"
            );
        }
        let stopped_after = cancelled_at.elapsed();
        tokio::time::sleep(Duration::from_millis(500)).await;
        while let Ok(Some(state)) = states.try_recv() {
            assert!(!state.body.moving, "the arm moved again after the cancel");
        }
        eprintln!("arm at rest {stopped_after:?} after the cancel");
        // The next call works.
        let (t, _) = call(
            &client,
            "get_workspace_coordinate_from_point",
            json!({"workspace_id": "niryo_ws", "point": "center point"}),
        )
        .await;
        assert!(t.starts_with('✓'), "{t}");
        client.cancel().await.unwrap();
    });
}

#[test]
fn the_http_guard_refuses_strangers() {
    let namespace = common::fresh_namespace("guard");
    let port = common::free_port();
    let token = "test-token-0123456789";
    let _robotd = common::start_robotd(
        &namespace,
        port,
        &[
            "--set",
            &format!("mcp.token={token}"),
            "--set",
            "mcp.max_body_bytes=4096",
        ],
    );
    let init = br#"{"jsonrpc":"2.0","id":1,"method":"initialize","params":{"protocolVersion":"2025-06-18","capabilities":{},"clientInfo":{"name":"t","version":"1"}}}"#;
    let json_headers = [
        ("Content-Type", "application/json"),
        ("Accept", "application/json, text/event-stream"),
    ];
    // No token: 401, on every MCP route.
    for (method, path) in [
        ("GET", "/sse"),
        ("POST", "/mcp"),
        ("POST", "/messages/?session_id=x"),
    ] {
        let (status, body) = common::http_request(port, method, path, &json_headers, init);
        assert_eq!(status, 401, "{method} {path}: {body}");
    }
    let auth = format!("Bearer {token}");
    let wrong = "Bearer not-the-token";
    let (status, _) = common::http_request(
        port,
        "POST",
        "/mcp",
        &[json_headers[0], json_headers[1], ("Authorization", wrong)],
        init,
    );
    assert_eq!(status, 401);
    // Foreign Origin: 403 even with the token.
    let (status, body) = common::http_request(
        port,
        "POST",
        "/mcp",
        &[
            json_headers[0],
            json_headers[1],
            ("Authorization", &auth),
            ("Origin", "http://evil.example.com"),
        ],
        init,
    );
    assert_eq!(status, 403, "{body}");
    // Too large: 413.
    let big = vec![b' '; 10_000];
    let (status, _) = common::http_request(
        port,
        "POST",
        "/mcp",
        &[json_headers[0], json_headers[1], ("Authorization", &auth)],
        &big,
    );
    assert_eq!(status, 413);
    // Local origin with the token: served.
    let (status, body) = common::http_request(
        port,
        "POST",
        "/mcp",
        &[
            json_headers[0],
            json_headers[1],
            ("Authorization", &auth),
            ("Origin", "http://localhost:6274"),
        ],
        init,
    );
    assert_eq!(status, 200, "{body}");
    // /health stays open for monitoring.
    assert_eq!(common::http_get(port, "/health").0, 200);
    // A real client with the token works over both transports.
    runtime().block_on(async {
        for path in ["/sse", "/mcp"] {
            let url = format!("http://127.0.0.1:{port}{path}");
            assert!(connect(&url, None).await.is_err(), "{path} without a token");
            let client = connect(&url, Some(token)).await.unwrap();
            let (t, _) = call(&client, "speak", json!({"text": "authorised"})).await;
            assert_eq!(t, "✓ Speaking: 'authorised'");
            client.cancel().await.unwrap();
        }
    });

    // A non-loopback bind without a token refuses to start, saying why.
    let output = Command::new(env!("CARGO_BIN_EXE_robotd"))
        .args([
            "serve",
            "--namespace",
            &common::fresh_namespace("open"),
            "--http",
            "0.0.0.0:0",
        ])
        .stdout(Stdio::null())
        .output()
        .unwrap();
    assert!(!output.status.success());
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(
        stderr.contains(
            "mcp.token: is required because http.bind 0.0.0.0:0 is not a loopback address"
        ),
        "{stderr}"
    );
}

/// A streamable-HTTP client connecting while a legacy-SSE client's pick is under way leaves
/// that pick alone (the streamable session manager once swept every session it did not know,
/// SSE ones included, and so cancelled their motions).
#[test]
fn a_new_client_does_not_cancel_another_transports_motion() {
    let namespace = common::fresh_namespace("sweep");
    let port = common::free_port();
    let _robotd = common::start_robotd(&namespace, port, &["--set", "robot.time_scale=1.0"]);
    runtime().block_on(async {
        let bus = Bus::open(BusOptions::new(&namespace, "sweep-test")).unwrap();
        let mut states = bus.subscriber(&ARM_STATE).unwrap();
        let sse = connect(&format!("http://127.0.0.1:{port}/sse"), None)
            .await
            .unwrap();
        let pick = tokio::spawn(async move {
            let args = json!({"object_name": "red cube", "pick_coordinate": [0.28, 0.04]});
            let text = text(&sse, "pick_object", args).await;
            sse.cancel().await.unwrap();
            text
        });
        common::wait_until_the_arm_moves(&mut states).await;
        let streamable = connect(&format!("http://127.0.0.1:{port}/mcp"), None)
            .await
            .unwrap();
        let picked = pick.await.unwrap();
        assert!(picked.starts_with('✓'), "{picked}");
        streamable.cancel().await.unwrap();
    });
}

/// The TCP connections of this machine to `port` on loopback, in any state (closed ones stay
/// listed in TIME_WAIT for a minute on the side that closed first).
fn connections_to(port: u16) -> usize {
    let table = std::fs::read_to_string("/proc/net/tcp").expect("/proc/net/tcp");
    let remote = format!("0100007F:{port:04X}");
    table
        .lines()
        .skip(1)
        .filter(|line| line.split_whitespace().nth(2) == Some(remote.as_str()))
        .count()
}

/// robotd's streamable-HTTP client keeps its connection from call to call (rmcp's default
/// client opens a new one for every request: a TCP handshake and a new server connection per
/// call).
#[test]
fn the_streamable_http_client_keeps_its_connection() {
    let namespace = common::fresh_namespace("pool");
    let port = common::free_port();
    let _robotd = common::start_robotd(&namespace, port, &[]);
    runtime().block_on(async {
        let client = connect(&format!("http://127.0.0.1:{port}/mcp"), None)
            .await
            .unwrap();
        let args = json!({"workspace_id": "niryo_ws", "point": "center point"});
        text(&client, "get_workspace_coordinate_from_point", args.clone()).await;
        let before = connections_to(port);
        for _ in 0..20 {
            let answer = text(&client, "get_workspace_coordinate_from_point", args.clone()).await;
            assert!(answer.starts_with('✓'), "{answer}");
        }
        let opened = connections_to(port).saturating_sub(before);
        assert!(opened <= 1, "20 calls opened {opened} new connections");
        client.cancel().await.unwrap();
    });
}
