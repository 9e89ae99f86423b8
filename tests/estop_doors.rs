//! The e-stop's side doors (issue 39), against a served robotd from outside its process:
//!
//! - a malformed e-stop still stops: any MCP `emergency_stop` call, any `POST /estop` and any
//!   `robotd estop` engages, whatever its arguments, body or command line, and the reply says
//!   what was wrong;
//! - only a deliberate release releases: a bare `engaged: false` on `safety/estop` (from
//!   anyone, a replayed recording) is ignored and audited; `release_emergency_stop` with
//!   `confirm` (schema `const: "release"`), `POST /estop/release` and `robotd estop --release`
//!   release at once, after any e-stop sent before them, and are recorded with their origin;
//! - `robotd replay` never publishes a safety topic, even when asked to.

mod common;

use common::mcp_http::{header, json_rpc, INIT, INITIALIZED};
use rmcp::model::CallToolRequestParams;
use robotd_mcp::client::{connect, McpClient};
use robotd_protocol::arm::{ArmCommand, ArmError, ArmReply, ArmState};
use robotd_protocol::geometry::Pose;
use robotd_protocol::health::EmergencyStop;
use robotd_runtime::bus::{Bus, BusOptions, Subscriber};
use robotd_topics::{ARM_COMMAND, ARM_STATE, SAFETY_ESTOP};
use serde_json::{json, Value};
use std::io::{BufRead, BufReader};
use std::net::Ipv4Addr;
use std::process::{Command, Stdio};
use std::time::Duration;

const TIMEOUT: Duration = Duration::from_secs(30);

fn down(x: f64, y: f64, z: f64) -> Pose {
    Pose::new(x, y, z, 0.0, std::f64::consts::FRAC_PI_2, 0.0)
}

fn robotd_cli(namespace: &str, args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_robotd"))
        .args(["--namespace", namespace])
        .args(args)
        .output()
        .expect("run robotd")
}

/// The text of a tool call's reply, and whether it is an error.
async fn call(client: &McpClient, tool: &str, args: Value) -> (String, bool) {
    let mut params = CallToolRequestParams::new(tool.to_owned());
    if let Value::Object(map) = args {
        params = params.with_arguments(map);
    }
    let result = client.call_tool(params).await.unwrap();
    (
        result.content[0].as_text().unwrap().text.clone(),
        result.is_error.unwrap_or(false),
    )
}

/// Waits for the arm to report `estop_engaged == want` on `arm/state`.
async fn until_estop(states: &mut Subscriber<ArmState>, want: bool, what: &str) {
    let deadline = tokio::time::Instant::now() + Duration::from_secs(10);
    loop {
        match tokio::time::timeout_at(deadline, states.recv()).await {
            Ok(Ok(state)) if state.body.estop_engaged == want => return,
            Ok(Ok(_)) => {}
            Ok(Err(error)) => panic!("arm/state: {error}"),
            Err(_) => panic!("{what}: the arm never reported estop_engaged = {want}"),
        }
    }
}

/// Waits for the next `arm/state` that says the arm moves.
async fn until_moving(states: &mut Subscriber<ArmState>) {
    let deadline = tokio::time::Instant::now() + Duration::from_secs(10);
    loop {
        match tokio::time::timeout_at(deadline, states.recv()).await {
            Ok(Ok(state)) if state.body.moving => return,
            Ok(Ok(_)) => {}
            Ok(Err(error)) => panic!("arm/state: {error}"),
            Err(_) => panic!("the arm never moved"),
        }
    }
}

/// Releases the e-stop over HTTP, the deliberate way, and waits until the arm says so.
async fn release(port: u16, states: &mut Subscriber<ArmState>) {
    let (status, body) = common::http_request(
        port,
        "POST",
        "/estop/release",
        &[],
        br#"{"confirm": "release", "by": "the test"}"#,
    );
    assert_eq!(status, 200, "{body}");
    until_estop(states, false, "release").await;
}

/// Opens a streamable-HTTP MCP session by hand (initialized); returns its id.
fn raw_session(port: u16) -> String {
    let headers = [
        ("Content-Type", "application/json"),
        ("Accept", "application/json, text/event-stream"),
    ];
    let (status, head, body) =
        common::http_response_from(Ipv4Addr::LOCALHOST, port, "POST", "/mcp", &headers, INIT);
    assert_eq!(status, 200, "{body}");
    let id = header(&head, "mcp-session-id")
        .expect("a session id")
        .to_owned();
    let (status, _) = raw_post(port, &id, INITIALIZED);
    assert_eq!(status, 202);
    id
}

fn raw_post(port: u16, session: &str, body: &[u8]) -> (u16, String) {
    let headers = [
        ("Content-Type", "application/json"),
        ("Accept", "application/json, text/event-stream"),
        ("Mcp-Session-Id", session),
    ];
    let (status, _, body) =
        common::http_response_from(Ipv4Addr::LOCALHOST, port, "POST", "/mcp", &headers, body);
    (status, body)
}

#[test]
fn a_malformed_estop_still_stops_and_says_what_was_wrong() {
    let namespace = common::fresh_namespace("estop-malformed");
    let port = common::free_port();
    let _robotd = common::start_robotd(&namespace, port, &["--set", "robot.time_scale=1.0"]);
    common::runtime().block_on(async {
        let bus = Bus::open(BusOptions::new(&namespace, "estop-test")).unwrap();
        let arm = bus.client(&ARM_COMMAND).unwrap();
        let mut states = bus.subscriber(&ARM_STATE).unwrap();
        let mcp = connect(&format!("http://127.0.0.1:{port}/mcp"), None)
            .await
            .unwrap();

        // During a motion: a reason that is not a string stops the arm all the same.
        let motion = {
            let arm = bus.client(&ARM_COMMAND).unwrap();
            tokio::spawn(async move {
                let targets = [down(0.33, 0.08, 0.05), down(0.18, -0.08, 0.05)];
                for k in 0..40 {
                    let reply = arm
                        .request(&ArmCommand::move_to(targets[k % 2]), TIMEOUT)
                        .await?;
                    if matches!(reply, ArmReply::Error { .. }) {
                        return Ok(reply);
                    }
                }
                arm.request(&ArmCommand::GetPose, TIMEOUT).await
            })
        };
        until_moving(&mut states).await;
        let (text, failed) = call(&mcp, "emergency_stop", json!({"reason": 5})).await;
        assert!(
            !failed && text.starts_with("✓ Emergency stop engaged"),
            "{text}"
        );
        assert!(
            text.contains("argument 'reason': Input should be a valid string (got 5)"),
            "{text}"
        );
        let reply = motion.await.unwrap().unwrap();
        assert!(
            matches!(
                reply,
                ArmReply::Error {
                    error: ArmError::EStopped { .. }
                }
            ),
            "{reply:?}"
        );
        until_estop(&mut states, true, "MCP reason 5").await;
        let refused = arm
            .request(&ArmCommand::move_to(down(0.25, 0.0, 0.10)), TIMEOUT)
            .await
            .unwrap();
        assert!(
            matches!(
                refused,
                ArmReply::Error {
                    error: ArmError::EStopped { .. }
                }
            ),
            "{refused:?}"
        );
        release(port, &mut states).await;

        // MCP: an unknown argument, and no arguments at all.
        for (args, says) in [
            (
                json!({"reason": "smoke", "colour": "red"}),
                Some("argument 'colour': Extra inputs are not permitted"),
            ),
            (Value::Null, None),
        ] {
            let (text, failed) = call(&mcp, "emergency_stop", args.clone()).await;
            assert!(
                !failed && text.starts_with("✓ Emergency stop engaged"),
                "{args}: {text}"
            );
            match says {
                Some(says) => assert!(text.contains(says), "{args}: {text}"),
                None => assert!(!text.contains("Note"), "{args}: {text}"),
            }
            until_estop(&mut states, true, &args.to_string()).await;
            release(port, &mut states).await;
        }

        // MCP by hand: arguments that are not an object (no SDK client can send them).
        let session = raw_session(port);
        for (i, arguments) in [json!(5), json!("stop now"), json!([1, 2])]
            .iter()
            .enumerate()
        {
            let body = json!({"jsonrpc": "2.0", "id": 10 + i, "method": "tools/call",
                "params": {"name": "emergency_stop", "arguments": arguments}});
            let (status, answer) = raw_post(port, &session, body.to_string().as_bytes());
            assert_eq!(status, 200, "{answer}");
            let answer = json_rpc(&answer);
            let text = answer["result"]["content"][0]["text"]
                .as_str()
                .unwrap_or_default();
            assert!(
                text.starts_with("✓ Emergency stop engaged")
                    && text.contains("the arguments must be an object")
                    && text.contains(&arguments.to_string()),
                "{arguments}: {answer}"
            );
            until_estop(&mut states, true, &format!("arguments {arguments}")).await;
            release(port, &mut states).await;
        }

        // HTTP: whatever the body.
        let big = vec![b'x'; 2 * 1024 * 1024];
        for (body, says) in [
            (&b"{not json"[..], "the body is not JSON"),
            (
                &br#"{"reason": 5}"#[..],
                "field 'reason' must be a string, got 5",
            ),
            (
                &br#"{"reason": "smoke", "extra": 1}"#[..],
                "unknown field 'extra'",
            ),
            (&br#"[1, 2]"#[..], "the body must be a JSON object"),
            (&br#""stop""#[..], "the body must be a JSON object"),
            (&big[..], "the body could not be read"),
            (&b""[..], ""),
        ] {
            let shown = String::from_utf8_lossy(&body[..body.len().min(20)]).to_string();
            let (status, reply) = common::http_request(
                port,
                "POST",
                "/estop",
                &[("Content-Type", "application/json")],
                body,
            );
            assert_eq!(status, 200, "{shown}: {reply}");
            let reply: Value =
                serde_json::from_str(&reply).unwrap_or_else(|e| panic!("{e}: {reply}"));
            assert_eq!(reply["engaged"], true, "{shown}: {reply}");
            if says.is_empty() {
                assert!(reply.get("note").is_none(), "{reply}");
                assert_eq!(reply["reason"], "engaged over HTTP", "{reply}");
            } else {
                let note = reply["note"].as_str().unwrap_or_default();
                assert!(note.contains(says), "{shown}: {reply}");
            }
            until_estop(&mut states, true, &format!("POST /estop {shown}")).await;
            release(port, &mut states).await;
        }
        // The reason of a body with problems is still used when it is one.
        let (_, reply) = common::http_request(
            port,
            "POST",
            "/estop",
            &[],
            br#"{"reason": "smoke", "extra": 1}"#,
        );
        assert!(reply.contains(r#""reason":"smoke""#), "{reply}");
        until_estop(&mut states, true, "reason kept").await;
        release(port, &mut states).await;

        // The command line: an unknown option, a stray value.
        for args in [
            &["estop", "--reason", "smoke in the cell"][..],
            &["estop", "--now", "smoke"][..],
            &["estop", "--release=yes"][..],
        ] {
            let out = robotd_cli(&namespace, args);
            let said = String::from_utf8_lossy(&out.stderr).to_string();
            assert!(out.status.success(), "{args:?}: {said}");
            assert!(
                said.contains("emergency stop engaged") && said.contains("note:"),
                "{args:?}: {said}"
            );
            until_estop(&mut states, true, &format!("{args:?}")).await;
            release(port, &mut states).await;
        }
        let out = robotd_cli(&namespace, &["estop", "--reason", "smoke in the cell"]);
        let said = String::from_utf8_lossy(&out.stderr).to_string();
        assert!(
            said.contains("smoke in the cell") && said.contains("'--reason' ignored"),
            "{said}"
        );
        until_estop(&mut states, true, "CLI reason").await;
        // A release with a malformed command line releases nothing.
        let out = robotd_cli(&namespace, &["estop", "--release", "--force"]);
        let said = String::from_utf8_lossy(&out.stderr).to_string();
        assert!(!out.status.success(), "{said}");
        assert!(said.contains("nothing was released"), "{said}");
        let (_, state) = common::http_get(port, "/estop");
        assert!(state.contains(r#""engaged":true"#), "{state}");
        release(port, &mut states).await;
        mcp.cancel().await.unwrap();
    });
}

#[test]
fn replay_never_publishes_a_safety_topic_even_when_asked() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("estop.mcap");
    // A real recording of safety/estop: an engage and a release, as a bus carried them.
    let recorded_ns = common::fresh_namespace("estop-record");
    let mut recorder = Command::new(env!("CARGO_BIN_EXE_robotd"))
        .args(["record", "--namespace", &recorded_ns, "--duration", "3s"])
        .args(["--topics", "safety/estop"])
        .arg(&file)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut stderr = BufReader::new(recorder.stderr.take().unwrap());
    let mut line = String::new();
    while !line.contains("robotd: recording bus") {
        line.clear();
        assert!(
            stderr.read_line(&mut line).unwrap() > 0,
            "the recorder ended before recording"
        );
    }
    common::runtime().block_on(async {
        let bus = Bus::open(BusOptions::new(&recorded_ns, "estop-record-test")).unwrap();
        let estop = bus.publisher(&SAFETY_ESTOP).unwrap();
        // The recorder subscribes from a reader thread of its own, a moment after it says it
        // records: a message nobody took is not sent, so the first is offered until taken.
        let deadline = std::time::Instant::now() + Duration::from_secs(20);
        for (engaged, reason) in [(true, "recorded engage"), (false, "recorded release")] {
            let message = EmergencyStop {
                engaged,
                reason: reason.into(),
                source: "test".into(),
            };
            while estop.publish(&message).unwrap() == 0 {
                assert!(
                    std::time::Instant::now() < deadline,
                    "the recorder never subscribed to safety/estop"
                );
                tokio::time::sleep(Duration::from_millis(20)).await;
            }
        }
    });
    let mut rest = String::new();
    std::io::Read::read_to_string(&mut stderr, &mut rest).unwrap();
    assert!(recorder.wait().unwrap().success(), "{rest}");
    assert!(rest.contains("safety/estop 2"), "{rest}");
    let bytes = std::fs::read(&file).unwrap();
    let has = |needle: &str| bytes.windows(needle.len()).any(|w| w == needle.as_bytes());
    assert!(
        has("recorded release"),
        "the release is not in the recording"
    );

    // Replayed onto a bus where someone listens on safety/estop: refused, and nothing sent.
    let replay_ns = common::fresh_namespace("estop-replay");
    common::runtime().block_on(async {
        let bus = Bus::open(BusOptions::new(&replay_ns, "estop-replay-test")).unwrap();
        let mut listener = bus.subscriber(&SAFETY_ESTOP).unwrap();
        for topics in ["safety/estop", "arm/state,safety/estop"] {
            let out = Command::new(env!("CARGO_BIN_EXE_robotd"))
                .args(["replay", "--namespace", &replay_ns, "--speed", "0"])
                .args(["--topics", topics])
                .arg(&file)
                .output()
                .unwrap();
            let said = String::from_utf8_lossy(&out.stderr).to_string();
            assert!(!out.status.success(), "{topics}: {said}");
            assert!(
                said.contains("safety/estop") && said.contains("never replayed"),
                "{topics}: {said}"
            );
            // The replay process has ended: whatever it published is in the queue now.
            let got = listener.try_recv().unwrap();
            assert!(got.is_none(), "{topics}: replay published {got:?}");
        }
    });
}

/// The events recorded in the audit log at `path` (none while it does not exist).
fn audit_records(path: &std::path::Path) -> Vec<Value> {
    std::fs::read_to_string(path)
        .unwrap_or_default()
        .lines()
        .filter_map(|line| serde_json::from_str::<Value>(line).ok())
        .map(|line| line["event"].clone())
        .collect()
}

/// The first record of the audit log at `path` that `matches`, waiting up to 10 s for it (the
/// log is written by a thread of its own, behind a queue).
fn until_audited(path: &std::path::Path, matches: impl Fn(&Value) -> bool) -> Option<Value> {
    let deadline = std::time::Instant::now() + Duration::from_secs(10);
    loop {
        if let Some(found) = audit_records(path).into_iter().find(&matches) {
            return Some(found);
        }
        if std::time::Instant::now() > deadline {
            return None;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

fn estop_message(engaged: bool, reason: &str, source: &str) -> EmergencyStop {
    EmergencyStop {
        engaged,
        reason: reason.into(),
        source: source.into(),
    }
}

fn engaged_now(port: u16) -> bool {
    let (status, state) = common::http_get(port, "/estop");
    assert_eq!(status, 200, "{state}");
    let state: Value = serde_json::from_str(&state).unwrap();
    state["engaged"].as_bool().unwrap()
}

#[test]
fn a_bare_release_on_the_bus_releases_nothing_and_is_audited() {
    let namespace = common::fresh_namespace("estop-bare");
    let port = common::free_port();
    let dir = tempfile::tempdir().unwrap();
    let audit = dir.path().join("audit.jsonl");
    let audit_path = format!("safety.audit.path={}", audit.display());
    let _robotd = common::start_robotd(&namespace, port, &["--set", &audit_path]);
    common::runtime().block_on(async {
        let bus = Bus::open(BusOptions::new(&namespace, "estop-bare-test")).unwrap();
        let arm = bus.client(&ARM_COMMAND).unwrap();
        let mut states = bus.subscriber(&ARM_STATE).unwrap();
        let estop = bus.publisher(&SAFETY_ESTOP).unwrap();
        estop
            .publish(&estop_message(true, "smoke", "test"))
            .unwrap();
        until_estop(&mut states, true, "engage on the bus").await;

        // Anyone's engaged=false (a client mirroring the state, a replayed recording).
        estop
            .publish(&estop_message(false, "replayed release", "someone"))
            .unwrap();
        let ignored = until_audited(&audit, |r| r["event"] == "estop_release_ignored");
        assert!(
            engaged_now(port),
            "a bare engaged=false on safety/estop released the e-stop"
        );
        let ignored = ignored.expect("the ignored release is not in the audit log");
        assert_eq!(ignored["source"], "someone", "{ignored}");
        assert_eq!(ignored["reason"], "replayed release", "{ignored}");
        let refused = arm
            .request(&ArmCommand::move_to(down(0.25, 0.0, 0.10)), TIMEOUT)
            .await
            .unwrap();
        assert!(
            matches!(
                refused,
                ArmReply::Error {
                    error: ArmError::EStopped { .. }
                }
            ),
            "{refused:?}"
        );

        // The MCP tool's schema pins the word, and nothing else releases.
        let mcp = connect(&format!("http://127.0.0.1:{port}/mcp"), None)
            .await
            .unwrap();
        let tools = mcp.list_all_tools().await.unwrap();
        let release = tools
            .iter()
            .find(|t| t.name == "release_emergency_stop")
            .expect("release_emergency_stop is listed");
        let confirm = &release.input_schema["properties"]["confirm"];
        assert_eq!(confirm["const"], "release", "{confirm}");
        let (text, _) = call(&mcp, "release_emergency_stop", json!({"confirm": "yes"})).await;
        assert!(
            text.starts_with('❌') && text.contains("Input should be 'release'"),
            "{text}"
        );
        let (status, body) = common::http_request(
            port,
            "POST",
            "/estop/release",
            &[],
            br#"{"confirm": "yes"}"#,
        );
        assert_eq!(status, 400, "{body}");
        assert!(engaged_now(port));
        let (text, failed) = call(
            &mcp,
            "release_emergency_stop",
            json!({"confirm": "release", "note": "smoke cleared"}),
        )
        .await;
        assert!(
            !failed && text.starts_with("✓ Emergency stop released"),
            "{text}"
        );
        assert!(
            !engaged_now(port),
            "the release was answered before it was made"
        );
        mcp.cancel().await.unwrap();
    });
}

#[test]
fn each_deliberate_release_releases_at_once_and_is_recorded_with_its_origin() {
    let namespace = common::fresh_namespace("estop-release");
    let port = common::free_port();
    let dir = tempfile::tempdir().unwrap();
    let audit = dir.path().join("audit.jsonl");
    let audit_path = format!("safety.audit.path={}", audit.display());
    let _robotd = common::start_robotd(&namespace, port, &["--set", &audit_path]);
    common::runtime().block_on(async {
        let bus = Bus::open(BusOptions::new(&namespace, "estop-release-test")).unwrap();
        let arm = bus.client(&ARM_COMMAND).unwrap();
        let estop = bus.publisher(&SAFETY_ESTOP).unwrap();
        let mcp = connect(&format!("http://127.0.0.1:{port}/mcp"), None)
            .await
            .unwrap();
        let targets = [down(0.25, 0.0, 0.12), down(0.22, 0.03, 0.12)];
        for (i, entry) in ["mcp", "http", "cli"].into_iter().enumerate() {
            // An e-stop, and at once a release: the release is not overtaken by it.
            estop
                .publish(&estop_message(
                    true,
                    &format!("before the {entry} release"),
                    "test",
                ))
                .unwrap();
            match entry {
                "mcp" => {
                    let (text, failed) = call(
                        &mcp,
                        "release_emergency_stop",
                        json!({"confirm": "release"}),
                    )
                    .await;
                    assert!(!failed, "{text}");
                }
                "http" => {
                    let (status, body) = common::http_request(
                        port,
                        "POST",
                        "/estop/release",
                        &[],
                        br#"{"confirm": "release", "by": "ana"}"#,
                    );
                    assert_eq!(status, 200, "{body}");
                    assert!(body.contains(r#""engaged":false"#), "{body}");
                }
                _ => {
                    let out = robotd_cli(&namespace, &["estop", "--release"]);
                    let said = String::from_utf8_lossy(&out.stderr).to_string();
                    assert!(out.status.success(), "{said}");
                    assert!(said.contains("emergency stop released"), "{said}");
                }
            }
            // Released when the entry point answered: a motion runs at once.
            assert!(
                !engaged_now(port),
                "{entry}: still engaged after its release"
            );
            let reply = arm
                .request(&ArmCommand::move_to(targets[i % 2]), TIMEOUT)
                .await
                .unwrap();
            assert!(matches!(reply, ArmReply::Ok { .. }), "{entry}: {reply:?}");
        }
        mcp.cancel().await.unwrap();
    });
    // Each release is in the audit log with who asked.
    for (kind, by) in [
        ("mcp", "an MCP client"),
        ("http", "ana"),
        ("cli", "robotd estop --release"),
    ] {
        let released = until_audited(&audit, |r| {
            r["event"] == "estop_released" && r["origin"]["kind"] == kind
        })
        .unwrap_or_else(|| panic!("no release by {kind} in {:#?}", audit_records(&audit)));
        assert!(
            released["by"].as_str().unwrap_or_default().contains(by),
            "{released}"
        );
        assert_eq!(released["was_engaged"], true, "{released}");
    }
    let engaged = audit_records(&audit)
        .into_iter()
        .filter(|r| r["event"] == "estop_engaged")
        .count();
    assert_eq!(engaged, 3, "{:#?}", audit_records(&audit));
}
