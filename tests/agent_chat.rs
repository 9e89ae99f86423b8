//! `robotd chat` end to end on the simulator: the real binary, the real MCP edge (SSE and
//! streamable HTTP) or the in-process runtime, the real robot simulation — and a scripted mock
//! LLM speaking the OpenAI wire format, playing the calls a good model makes for "Pick up the
//! pencil and place it right next to the red cube". The world is checked afterwards. Also: a
//! missing key gives a clear error naming the variable to set.

mod common;

use robotd_agent::mock::{MockLlm, MockReply};
use robotd_protocol::diagnostics::SimWorldRequest;
use robotd_runtime::bus::{Bus, BusOptions};
use robotd_topics::SIM_WORLD;
use serde_json::{json, Value};
use std::path::PathBuf;
use std::process::Stdio;
use std::time::Duration;

const REQUEST: &str = "Pick up the pencil and place it right next to the red cube";

/// Variables that would let a developer's own keys leak into a test.
const KEY_VARIABLES: [&str; 11] = [
    "OPENAI_API_KEY",
    "GROQ_API_KEY",
    "GEMINI_API_KEY",
    "API_KEY",
    "LLM_API_KEY",
    "LLM_BASE_URL",
    "OLLAMA_HOST",
    "OPENAI_BASE_URL",
    "GROQ_BASE_URL",
    "GEMINI_BASE_URL",
    "ROBOTD_CONFIG",
];

fn runtime() -> tokio::runtime::Runtime {
    tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .unwrap()
}

/// A fresh empty directory (the chat's working directory: no stray secrets.env).
fn temp_dir(tag: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!(
        "robotd-agent-chat-{tag}-{}-{}",
        std::process::id(),
        common::free_port()
    ));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// label → [x, y] (centre of mass) from a `get_detected_objects` reply text.
fn objects_in(text: &str) -> Vec<(String, [f64; 2])> {
    let Some(start) = text.find('[') else {
        return Vec::new();
    };
    let Ok(Value::Array(objects)) = serde_json::from_str::<Value>(&text[start..]) else {
        return Vec::new();
    };
    objects
        .iter()
        .filter_map(|o| {
            let c = &o["position"]["center_of_mass"];
            Some((
                o["label"].as_str()?.to_owned(),
                [c["x"].as_f64()?, c["y"].as_f64()?],
            ))
        })
        .collect()
}

/// The text of the last tool message in an OpenAI request body.
fn last_tool_result(body: &Value) -> String {
    body["messages"]
        .as_array()
        .and_then(|m| m.iter().rev().find(|m| m["role"] == "tool"))
        .and_then(|m| m["content"].as_str())
        .unwrap_or("")
        .to_owned()
}

/// What a good model does: state the plan and look; pick the pencil where the camera saw it
/// and place it right next to the red cube; go back to the observation pose; answer.
fn good_model() -> Vec<MockReply> {
    vec![
        MockReply::plan_and_call(
            "I understand: move the pencil so it lies right next to the red cube. Plan: look at \
             the workspace, pick the pencil and place it 'right next to' the red cube, then return \
             to the observation pose.",
            "get_detected_objects",
            json!({}),
        ),
        MockReply::dynamic(|request| {
            let seen = objects_in(&last_tool_result(request));
            let find = |label: &str| seen.iter().find(|(l, _)| l == label).map(|(_, at)| *at);
            match (find("pencil"), find("red cube")) {
                (Some(pencil), Some(cube)) => MockReply::tool_call(
                    "pick_place_object",
                    json!({"object_name": "pencil", "pick_coordinate": pencil,
                           "place_coordinate": cube, "location": "right next to"}),
                ),
                _ => MockReply::text(&format!("I cannot see a pencil and a red cube: {seen:?}")),
            }
        }),
        MockReply::tool_call("move2observation_pose", json!({"workspace_id": "niryo_ws"})),
        MockReply::text("Done: the pencil now lies right next to the red cube."),
    ]
}

/// Runs `robotd chat` with the mock as the OpenAI endpoint; returns (exit code, stdout, stderr).
async fn chat(
    args: &[&str],
    mock: Option<&MockLlm>,
    dir: &std::path::Path,
) -> (i32, String, String) {
    let mut command = tokio::process::Command::new(env!("CARGO_BIN_EXE_robotd"));
    command
        .arg("chat")
        .args(args)
        .arg("--set")
        .arg(format!("telemetry.log_dir={}", dir.join("log").display()))
        .current_dir(dir)
        .stdin(Stdio::null())
        .kill_on_drop(true);
    for v in KEY_VARIABLES {
        command.env_remove(v);
    }
    if let Some(mock) = mock {
        command
            .env("OPENAI_API_KEY", "sk-test-key")
            .env("OPENAI_BASE_URL", mock.openai_base_url());
    }
    let output = tokio::time::timeout(Duration::from_secs(120), command.output())
        .await
        .expect("robotd chat finished within 120 s")
        .expect("robotd chat ran");
    let stdout = String::from_utf8_lossy(&output.stdout).into_owned();
    let stderr = String::from_utf8_lossy(&output.stderr).into_owned();
    eprintln!("--- robotd chat stdout ---\n{stdout}--- stderr ---\n{stderr}");
    (output.status.code().unwrap_or(-1), stdout, stderr)
}

/// `robotd call get_detected_objects --json`: label → [x, y].
fn detected(port: u16) -> Vec<(String, [f64; 2])> {
    let output = std::process::Command::new(env!("CARGO_BIN_EXE_robotd"))
        .args(["call", "get_detected_objects", "--json", "--url"])
        .arg(format!("http://127.0.0.1:{port}/mcp"))
        .output()
        .expect("robotd call");
    assert!(output.status.success(), "{output:?}");
    let structured: Value = serde_json::from_slice(&output.stdout).expect("JSON");
    structured["data"]
        .as_array()
        .expect("objects")
        .iter()
        .map(|o| {
            let c = &o["position"]["center_of_mass"];
            (
                o["label"].as_str().unwrap().to_owned(),
                [c["x"].as_f64().unwrap(), c["y"].as_f64().unwrap()],
            )
        })
        .collect()
}

fn the_pencil_lies_right_next_to_the_red_cube(objects: &[(String, [f64; 2])], what: &str) {
    let find = |label: &str| {
        objects
            .iter()
            .find(|(l, _)| l == label)
            .map(|(_, at)| *at)
            .unwrap_or_else(|| panic!("{what}: no {label} in {objects:?}"))
    };
    let pencil = find("pencil");
    let cube = find("red cube");
    assert!(
        pencil[1] < cube[1] - 0.02,
        "{what}: the pencil {pencil:?} is not right of (−y) the red cube {cube:?}"
    );
    assert!(
        (pencil[0] - cube[0]).abs() < 0.03 && cube[1] - pencil[1] < 0.10,
        "{what}: the pencil {pencil:?} is not next to the red cube {cube:?}"
    );
}

fn chat_over(path: &str) {
    let namespace = common::fresh_namespace("chat");
    let port = common::free_port();
    let _robotd = common::start_robotd(&namespace, port, &["--set", "robot.time_scale=0.05"]);
    let dir = temp_dir("mcp");
    runtime().block_on(async {
        let mock = MockLlm::start(good_model()).await.unwrap();
        let url = format!("http://127.0.0.1:{port}{path}");
        let (code, stdout, stderr) =
            chat(&["--mcp", &url, "--command", REQUEST], Some(&mock), &dir).await;
        assert_eq!(code, 0, "robotd chat failed:\n{stdout}\n{stderr}");
        // The user saw the plan, each call and result, and the answer, in order.
        let plan = stdout
            .find("Plan: I understand")
            .expect("the plan is shown");
        let look = stdout
            .find("→ get_detected_objects")
            .expect("the look is shown");
        let move_ = stdout
            .find("→ pick_place_object")
            .expect("the move is shown");
        let moved = stdout
            .find("← ✓ Successfully picked 'pencil'")
            .expect("the move's result");
        let answer = stdout.find("Answer: Done").expect("the answer is shown");
        assert!(
            plan < look && look < move_ && move_ < moved && moved < answer,
            "{stdout}"
        );
        // The model was sent the tools and the real tool results.
        let requests = mock.requests();
        assert_eq!(
            requests.len(),
            4,
            "one LLM call per step, no planning round"
        );
        assert_eq!(
            requests[0].authorization.as_deref(),
            Some("Bearer sk-test-key")
        );
        assert_eq!(requests[0].body["tools"].as_array().map(Vec::len), Some(24));
        assert!(last_tool_result(&requests[1].body).starts_with("✓ Found"));
        assert!(last_tool_result(&requests[2].body).starts_with("✓ Successfully picked 'pencil'"));
        // A session log named like the Python client's.
        let logs: Vec<String> = std::fs::read_dir(dir.join("log"))
            .expect("the log directory")
            .filter_map(|e| e.ok())
            .map(|e| e.file_name().to_string_lossy().into_owned())
            .collect();
        assert!(
            logs.iter().any(|n| n.starts_with("mcp_client_")
                && n.ends_with(".log")
                && n.len() == "mcp_client_20260101_000000.log".len()),
            "{logs:?}"
        );
        // The world afterwards: what the camera sees, and the simulator's ground truth.
        let port_copy = port;
        let seen = tokio::task::spawn_blocking(move || detected(port_copy))
            .await
            .unwrap();
        the_pencil_lies_right_next_to_the_red_cube(&seen, "robotd call get_detected_objects");
        let bus = Bus::open(BusOptions::new(&namespace, "chat-test")).unwrap();
        let truth = bus
            .client(&SIM_WORLD)
            .unwrap()
            .request(&SimWorldRequest {}, Duration::from_secs(5))
            .await
            .unwrap()
            .objects;
        let truth: Vec<(String, [f64; 2])> = truth
            .iter()
            .map(|o| (o.label.clone(), [o.x_m, o.y_m]))
            .collect();
        the_pencil_lies_right_next_to_the_red_cube(&truth, "the simulator");
    });
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn chat_over_sse_puts_the_pencil_right_next_to_the_red_cube() {
    chat_over("/sse");
}

#[test]
fn chat_over_streamable_http_puts_the_pencil_right_next_to_the_red_cube() {
    chat_over("/mcp");
}

#[test]
fn chat_in_process_puts_the_pencil_right_next_to_the_red_cube() {
    let namespace = common::fresh_namespace("chat-inproc");
    let dir = temp_dir("inproc");
    runtime().block_on(async {
        let mock = MockLlm::start(good_model()).await.unwrap();
        let (code, stdout, stderr) = chat(
            &[
                "--namespace",
                &namespace,
                "--set",
                "robot.time_scale=0.05",
                "--command",
                REQUEST,
            ],
            Some(&mock),
            &dir,
        )
        .await;
        assert_eq!(code, 0, "robotd chat failed:\n{stdout}\n{stderr}");
        assert!(stdout.contains("Answer: Done"), "{stdout}");
        // The registry's real replies reached the model.
        let requests = mock.requests();
        assert_eq!(requests.len(), 4);
        assert!(last_tool_result(&requests[2].body).starts_with("✓ Successfully picked 'pencil'"));
        // The system prompt names the simulated workspace's corners.
        let system = requests[0].body["messages"][0]["content"]
            .as_str()
            .unwrap_or("");
        assert!(
            system.contains("Workspace 'niryo_ws': upper left corner"),
            "{system}"
        );
    });
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_missing_key_names_the_variable_to_set() {
    let dir = temp_dir("nokey");
    runtime().block_on(async {
        // Nothing is started: the error comes first.
        let (code, stdout, stderr) = chat(
            &["--mcp", "http://127.0.0.1:9/sse", "--command", REQUEST],
            None,
            &dir,
        )
        .await;
        assert_ne!(code, 0);
        assert!(stdout.is_empty(), "{stdout}");
        assert!(stderr.contains("no LLM API key found"), "{stderr}");
        for variable in [
            "OPENAI_API_KEY",
            "GROQ_API_KEY",
            "GEMINI_API_KEY",
            "secrets.env",
        ] {
            assert!(
                stderr.contains(variable),
                "{variable} not named in: {stderr}"
            );
        }
        let (code, _, stderr) = chat(
            &[
                "--api",
                "groq",
                "--mcp",
                "http://127.0.0.1:9/sse",
                "--command",
                REQUEST,
            ],
            None,
            &dir,
        )
        .await;
        assert_ne!(code, 0);
        assert!(
            stderr.contains("no API key for groq: set GROQ_API_KEY"),
            "{stderr}"
        );
        // A key in secrets.env (next to the config file) is found; the rejected key is then
        // named (the mock refuses it).
        let mock = MockLlm::start(vec![MockReply::Status {
            status: 401,
            retry_after: None,
            body: r#"{"error":{"message":"Invalid API Key"}}"#.into(),
        }])
        .await
        .unwrap();
        std::fs::write(
            dir.join("secrets.env"),
            format!(
                "# keys\nGROQ_API_KEY=\"gsk_from_file\"\nGROQ_BASE_URL={}\n",
                mock.openai_base_url()
            ),
        )
        .unwrap();
        std::fs::write(dir.join("robotd.toml"), "").unwrap();
        let server = common::free_port();
        let namespace = common::fresh_namespace("chat-key");
        let _robotd = common::start_robotd(&namespace, server, &[]);
        let url = format!("http://127.0.0.1:{server}/mcp");
        let (code, _, stderr) = chat(
            &[
                "--config",
                "robotd.toml",
                "--api",
                "groq",
                "--mcp",
                &url,
                "--command",
                REQUEST,
            ],
            None,
            &dir,
        )
        .await;
        assert_ne!(code, 0);
        assert!(
            stderr.contains("groq rejected the API key (HTTP 401): check GROQ_API_KEY"),
            "{stderr}"
        );
        assert_eq!(
            mock.requests()[0].authorization.as_deref(),
            Some("Bearer gsk_from_file")
        );
    });
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn interactive_chat_lists_tools_switches_provider_and_keeps_the_conversation() {
    let namespace = common::fresh_namespace("chat-tty");
    let dir = temp_dir("tty");
    runtime().block_on(async {
        // One mock serves both wire formats: OpenAI first, then Ollama after `switch`.
        let mock = MockLlm::start(vec![
            MockReply::text("I can see a pencil and a red cube."),
            MockReply::text("You asked which objects I can see."),
            MockReply::text("Fresh start."),
        ])
        .await
        .unwrap();
        let mut command = tokio::process::Command::new(env!("CARGO_BIN_EXE_robotd"));
        command
            .args(["chat", "--namespace", &namespace, "--set"])
            .arg(format!("telemetry.log_dir={}", dir.join("log").display()))
            .current_dir(&dir)
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .kill_on_drop(true);
        for v in KEY_VARIABLES {
            command.env_remove(v);
        }
        command
            .env("OPENAI_API_KEY", "sk-test-key")
            .env("OPENAI_BASE_URL", mock.openai_base_url())
            .env("OLLAMA_HOST", mock.base_url());
        let mut child = command.spawn().unwrap();
        let mut stdin = child.stdin.take().unwrap();
        use tokio::io::AsyncWriteExt;
        stdin
            .write_all(
                b"tools\nWhich objects can you see?\nswitch ollama llama3.1:8b\n\
                  What did I ask you before?\nclear\nhello again\nswitch nonsense\nquit\n",
            )
            .await
            .unwrap();
        drop(stdin);
        let output = tokio::time::timeout(Duration::from_secs(120), child.wait_with_output())
            .await
            .expect("the chat ended")
            .unwrap();
        let stdout = String::from_utf8_lossy(&output.stdout).into_owned();
        let stderr = String::from_utf8_lossy(&output.stderr).into_owned();
        eprintln!("--- stdout ---\n{stdout}--- stderr ---\n{stderr}");
        assert!(output.status.success());
        assert!(
            stdout.contains("pick_place_object"),
            "the tools are listed: {stdout}"
        );
        assert!(
            stdout.contains("Answer: I can see a pencil and a red cube."),
            "{stdout}"
        );
        assert!(stdout.contains("Now using ollama llama3.1:8b"), "{stdout}");
        assert!(
            stdout.contains("Answer: You asked which objects I can see."),
            "{stdout}"
        );
        assert!(stdout.contains("Conversation cleared."), "{stdout}");
        assert!(
            stderr.contains("unknown LLM provider 'nonsense'"),
            "{stderr}"
        );
        let requests = mock.requests();
        assert_eq!(requests.len(), 3);
        assert_eq!(requests[0].path, "/v1/chat/completions");
        // After the switch: Ollama's wire format, the new model, and the earlier turn kept.
        assert_eq!(requests[1].path, "/api/chat");
        assert_eq!(requests[1].body["model"], "llama3.1:8b");
        let said = |i: usize| -> Vec<String> {
            requests[i].body["messages"]
                .as_array()
                .unwrap()
                .iter()
                .filter_map(|m| m["content"].as_str().map(str::to_owned))
                .collect()
        };
        assert!(said(1).contains(&"Which objects can you see?".to_owned()));
        assert!(said(1).contains(&"I can see a pencil and a red cube.".to_owned()));
        // After `clear`: only the system prompt and the new request.
        assert_eq!(said(2).len(), 2, "{:?}", said(2));
        assert_eq!(said(2)[1], "hello again");
    });
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn ctrl_c_during_a_motion_stops_the_arm_over_mcp() {
    use robotd_topics::ARM_STATE;
    use tokio::io::AsyncBufReadExt;
    let namespace = common::fresh_namespace("chat-cancel");
    let port = common::free_port();
    // Real-time motions, so the interrupt lands mid-motion.
    let _robotd = common::start_robotd(&namespace, port, &["--set", "robot.time_scale=1.0"]);
    let dir = temp_dir("cancel");
    runtime().block_on(async {
        let bus = Bus::open(BusOptions::new(&namespace, "chat-cancel-test")).unwrap();
        let mut states = bus.subscriber(&ARM_STATE).unwrap();
        let mock = MockLlm::start(vec![MockReply::plan_and_call(
            "Plan: pick up the red cube.",
            "pick_object",
            json!({"object_name": "red cube", "pick_coordinate": [0.28, 0.04]}),
        )])
        .await
        .unwrap();
        let mut command = tokio::process::Command::new(env!("CARGO_BIN_EXE_robotd"));
        command
            .args(["chat", "--mcp", &format!("http://127.0.0.1:{port}/sse")])
            .args(["--command", "Pick up the red cube", "--set"])
            .arg(format!("telemetry.log_dir={}", dir.join("log").display()))
            .current_dir(&dir)
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .kill_on_drop(true);
        for v in KEY_VARIABLES {
            command.env_remove(v);
        }
        command
            .env("OPENAI_API_KEY", "sk-test-key")
            .env("OPENAI_BASE_URL", mock.openai_base_url());
        let mut child = command.spawn().unwrap();
        let mut lines = tokio::io::BufReader::new(child.stdout.take().unwrap()).lines();
        loop {
            let line = tokio::time::timeout(Duration::from_secs(60), lines.next_line())
                .await
                .expect("the tool call is shown")
                .unwrap()
                .expect("robotd chat ended before calling the tool");
            if line.starts_with("→ pick_object") {
                break;
            }
        }
        // Wait until the arm really moves, then interrupt the chat.
        loop {
            let state = tokio::time::timeout(Duration::from_secs(10), states.recv())
                .await
                .expect("arm states")
                .unwrap()
                .body;
            if state.moving {
                break;
            }
        }
        let interrupted = std::time::Instant::now();
        let pid = child.id().unwrap().to_string();
        assert!(std::process::Command::new("kill")
            .args(["-INT", &pid])
            .status()
            .unwrap()
            .success());
        loop {
            let state = tokio::time::timeout(Duration::from_secs(5), states.recv())
                .await
                .expect("arm states")
                .unwrap()
                .body;
            if !state.moving {
                break;
            }
            assert!(
                interrupted.elapsed() < Duration::from_secs(3),
                "the arm kept moving after Ctrl-C"
            );
        }
        let output = tokio::time::timeout(Duration::from_secs(30), child.wait_with_output())
            .await
            .expect("the chat ended")
            .unwrap();
        let stderr = String::from_utf8_lossy(&output.stderr).into_owned();
        assert_eq!(output.status.code(), Some(1), "{stderr}");
        assert!(stderr.contains("robotd chat: cancelled"), "{stderr}");
        assert_eq!(mock.requests().len(), 1, "no LLM call after the cancel");
    });
    let _ = std::fs::remove_dir_all(&dir);
}

/// A local OTLP/HTTP collector stand-in: records the bodies POSTed to `/v1/traces`.
async fn trace_collector() -> (u16, std::sync::Arc<std::sync::Mutex<Vec<Vec<u8>>>>) {
    use axum::routing::post;
    let bodies = std::sync::Arc::new(std::sync::Mutex::new(Vec::<Vec<u8>>::new()));
    let seen = bodies.clone();
    let app = axum::Router::new().route(
        "/v1/traces",
        post(move |body: axum::body::Bytes| {
            let seen = seen.clone();
            async move {
                seen.lock().unwrap().push(body.to_vec());
                ""
            }
        }),
    );
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let port = listener.local_addr().unwrap().port();
    tokio::spawn(async move { axum::serve(listener, app).await });
    (port, bodies)
}

#[test]
fn chat_exports_its_llm_spans_over_otlp_and_keeps_the_session_log() {
    let namespace = common::fresh_namespace("chat-otlp");
    let dir = temp_dir("otlp");
    runtime().block_on(async {
        let (port, bodies) = trace_collector().await;
        let mock = MockLlm::start(vec![MockReply::text("Nothing to do.")])
            .await
            .unwrap();
        let endpoint = format!("telemetry.otlp_endpoint=http://127.0.0.1:{port}");
        let (code, stdout, stderr) = chat(
            &[
                "--namespace",
                &namespace,
                "--set",
                &endpoint,
                "--command",
                "Say hello",
            ],
            Some(&mock),
            &dir,
        )
        .await;
        assert_eq!(code, 0, "robotd chat failed:\n{stdout}\n{stderr}");
        // The exporter flushes on exit: the llm.call span of the one LLM call arrived.
        let bodies = bodies.lock().unwrap().clone();
        assert!(!bodies.is_empty(), "no OTLP export reached the collector");
        let names_llm_call = bodies
            .iter()
            .any(|b| b.windows(b"llm.call".len()).any(|w| w == b"llm.call"));
        assert!(
            names_llm_call,
            "no llm.call span in {} exports",
            bodies.len()
        );
    });
    let logs: Vec<String> = std::fs::read_dir(dir.join("log"))
        .map(|d| {
            d.flatten()
                .map(|e| e.file_name().to_string_lossy().into_owned())
                .collect()
        })
        .unwrap_or_default();
    assert!(
        logs.iter().any(|n| n.starts_with("mcp_client_")),
        "the session log is written: {logs:?}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}
