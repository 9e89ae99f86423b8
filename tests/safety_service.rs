//! The motion policy of a served robotd, from outside its process: a bus client cannot move
//! the arm past the limits, the e-stop engages from every entry point and stays engaged until
//! a deliberate release, approvals hold motions until a human answers, closing an MCP session
//! stops the motion it started, a cancelled call that waits its turn never runs, and the
//! audit log's chain detects a deleted or edited line.

mod common;

use rmcp::model::{CallToolRequest, CallToolRequestParams, ClientRequest};
use rmcp::service::PeerRequestOptions;
use robotd_mcp::client::{connect, McpClient};
use robotd_protocol::arm::{ArmCommand, ArmError, ArmReply, ArmState};
use robotd_protocol::diagnostics::{SimObjectState, SimWorldRequest};
use robotd_protocol::geometry::Pose;
use robotd_protocol::health::{EStopRelease, EmergencyStop};
use robotd_runtime::bus::{Bus, BusOptions, Client, Subscriber};
use robotd_topics::{ARM_COMMAND, ARM_STATE, SAFETY_ESTOP, SAFETY_RELEASE, SIM_WORLD};
use serde_json::{json, Value};
use std::time::{Duration, Instant};

const TIMEOUT: Duration = Duration::from_secs(30);

fn runtime() -> tokio::runtime::Runtime {
    tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .unwrap()
}

fn down(x: f64, y: f64, z: f64) -> Pose {
    Pose::new(x, y, z, 0.0, std::f64::consts::FRAC_PI_2, 0.0)
}

async fn text(client: &McpClient, tool: &str, args: Value) -> String {
    let mut params = CallToolRequestParams::new(tool.to_owned());
    if let Value::Object(map) = args {
        params = params.with_arguments(map);
    }
    let result = client.call_tool(params).await.unwrap();
    result.content[0].as_text().unwrap().text.clone()
}

/// Waits for the next `arm/state` with `moving == want`.
async fn until_moving(states: &mut Subscriber<ArmState>, want: bool, within: Duration) -> ArmState {
    let deadline = Instant::now() + within;
    loop {
        let left = deadline.saturating_duration_since(Instant::now());
        let state = tokio::time::timeout(left, states.recv())
            .await
            .unwrap_or_else(|_| panic!("the arm never had moving = {want}"))
            .unwrap()
            .body;
        if state.moving == want {
            return state;
        }
    }
}

/// Waits until the arm has not moved for `quiet`; returns how long after the call that last
/// motion ended. Fails when it keeps moving for `within`.
async fn settled(states: &mut Subscriber<ArmState>, quiet: Duration, within: Duration) -> Duration {
    let started = Instant::now();
    let mut last_moving = started;
    loop {
        assert!(
            started.elapsed() < within,
            "the arm kept moving for {within:?}"
        );
        match tokio::time::timeout(Duration::from_millis(100), states.recv()).await {
            Ok(Ok(state)) if state.body.moving => last_moving = Instant::now(),
            Ok(Ok(_)) | Err(_) => {}
            Ok(Err(error)) => panic!("arm/state: {error}"),
        }
        if last_moving.elapsed() >= quiet {
            return last_moving - started;
        }
    }
}

async fn pose(arm: &Client<ArmCommand, ArmReply>) -> Pose {
    match arm.request(&ArmCommand::GetPose, TIMEOUT).await.unwrap() {
        ArmReply::Ok { pose } => pose,
        other => panic!("{other:?}"),
    }
}

async fn world(bus: &Bus) -> Vec<SimObjectState> {
    bus.client(&SIM_WORLD)
        .unwrap()
        .request(&SimWorldRequest {}, TIMEOUT)
        .await
        .unwrap()
        .objects
}

fn robotd_cli(namespace: &str, args: &[&str]) -> std::process::Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_robotd"))
        .args(["--namespace", namespace])
        .args(args)
        .output()
        .expect("run robotd")
}

#[test]
fn a_bus_client_elsewhere_cannot_pass_the_limits_and_the_estop_latches_from_every_entry_point() {
    let namespace = common::fresh_namespace("safety");
    let port = common::free_port();
    let dir = tempfile::tempdir().unwrap();
    let audit = dir.path().join("audit.jsonl");
    let _robotd = common::start_robotd(
        &namespace,
        port,
        &[
            "--set",
            "robot.time_scale=1.0",
            "--set",
            &format!("safety.audit.path={}", audit.display()),
        ],
    );
    runtime().block_on(async {
        let bus = Bus::open(BusOptions::new(&namespace, "safety-test")).unwrap();
        let arm = bus.client(&ARM_COMMAND).unwrap();
        let mut states = bus.subscriber(&ARM_STATE).unwrap();
        let estop = bus.publisher(&SAFETY_ESTOP).unwrap();
        let mcp = connect(&format!("http://127.0.0.1:{port}/mcp"), None)
            .await
            .unwrap();

        // Garbage to the safety routes gets a clear 400/404 and changes nothing (except
        // `POST /estop`, which engages whatever its body: tests/estop_doors.rs).
        for (path, body, status) in [
            ("/estop/release", &br#"{"confirm": "release", "extra": 1}"#[..], 400),
            ("/approvals/abc", &br#"{"approve": true}"#[..], 400),
            ("/approvals/7", &b"{}"[..], 400),
            ("/approvals/7", &br#"{"approve": true}"#[..], 404),
        ] {
            let (got, reply) = common::http_request(port, "POST", path, &[], body);
            assert_eq!(got, status, "{path}: {reply}");
            assert!(reply.contains("\"error\""), "{path}: {reply}");
        }
        let (_, health) = common::http_get(port, "/health");
        assert!(health.contains("\"engaged\":false"), "{health}");

        // This test process is a bus client of its own: the policy holds for it.
        let before = pose(&arm).await;
        let reply = arm
            .request(&ArmCommand::move_to(down(0.25, 0.0, -0.03)), TIMEOUT)
            .await
            .unwrap();
        assert_eq!(
            reply.into_result().unwrap_err().to_string(),
            "refused by the safety policy: the tool centre would go to z -0.030 m, below the table floor 0.000 m"
        );
        let reply = arm
            .request(&ArmCommand::move_to(down(0.20, 0.25, 0.10)), TIMEOUT)
            .await
            .unwrap();
        match reply.into_result().unwrap_err() {
            ArmError::Refused { limit, reason } => {
                assert_eq!(limit, "fence", "{reason}");
                assert!(reason.contains("outside the geofence"), "{reason}");
            }
            other => panic!("{other:?}"),
        }
        assert_eq!(pose(&arm).await, before, "a refused motion moved the arm");

        // Engage from each entry point during a motion; release from another.
        let entries = ["bus", "http", "mcp", "cli"];
        let targets = [down(0.33, 0.08, 0.05), down(0.18, -0.08, 0.05)];
        for (i, entry) in entries.iter().enumerate() {
            // Back and forth until something stops it: a slow entry point (the CLI starts a
            // process) on a loaded machine still lands during a motion.
            let motion = {
                let arm = bus.client(&ARM_COMMAND).unwrap();
                tokio::spawn(async move {
                    for k in 0..40 {
                        let reply = arm
                            .request(&ArmCommand::move_to(targets[(i + k) % 2]), TIMEOUT)
                            .await?;
                        if matches!(reply, ArmReply::Error { .. }) {
                            return Ok(reply);
                        }
                    }
                    arm.request(&ArmCommand::GetPose, TIMEOUT).await
                })
            };
            until_moving(&mut states, true, Duration::from_secs(10)).await;
            let engaged = Instant::now();
            match *entry {
                "bus" => {
                    estop
                        .publish(&EmergencyStop {
                            engaged: true,
                            reason: "test from the bus".into(),
                            source: "test".into(),
                        })
                        .unwrap();
                }
                "http" => {
                    let (status, body) = common::http_request(
                        port,
                        "POST",
                        "/estop",
                        &[("Content-Type", "application/json")],
                        br#"{"reason": "test over HTTP"}"#,
                    );
                    assert_eq!(status, 200, "{body}");
                }
                "mcp" => {
                    let t = text(&mcp, "emergency_stop", json!({"reason": "test over MCP"})).await;
                    assert!(t.starts_with("✓ Emergency stop engaged: test over MCP"), "{t}");
                }
                _ => {
                    let out = robotd_cli(&namespace, &["estop", "test from the CLI"]);
                    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
                }
            }
            let reply = motion.await.unwrap().unwrap();
            let stopped_after = engaged.elapsed();
            eprintln!("e-stop from {entry}: motion answered {stopped_after:?} after the entry point returned");
            assert!(
                matches!(reply, ArmReply::Error { error: ArmError::EStopped { .. } }),
                "{entry}: {reply:?}"
            );
            let held = pose(&arm).await;
            // Engaged: every motion is refused, and a new motion never releases it.
            for _ in 0..2 {
                let refused = arm
                    .request(&ArmCommand::move_to(down(0.25, 0.0, 0.10)), TIMEOUT)
                    .await
                    .unwrap();
                assert!(
                    matches!(refused, ArmReply::Error { error: ArmError::EStopped { .. } }),
                    "{refused:?}"
                );
            }
            assert_eq!(pose(&arm).await, held, "the arm moved while e-stopped");
            let (_, health) = common::http_get(port, "/health");
            let health: Value = serde_json::from_str(&health).unwrap();
            assert_eq!(health["safety"]["estop"]["engaged"], true, "{health}");
            let status = text(&mcp, "get_system_status", json!({})).await;
            assert!(status.contains("\"estop_engaged\": true"), "{status}");
            // A release must be deliberate.
            let (status, body) = common::http_request(port, "POST", "/estop/release", &[], b"{}");
            assert_eq!(status, 400, "{body}");
            let t = text(&mcp, "release_emergency_stop", json!({"confirm": "yes"})).await;
            assert!(t.starts_with("❌ Validation Error in release_emergency_stop"), "{t}");
            match (i + 1) % 4 {
                0 => {
                    // A bus client releases by asking the policy (an `engaged: false` on
                    // safety/estop releases nothing: tests/estop_doors.rs).
                    let state = bus
                        .client(&SAFETY_RELEASE)
                        .unwrap()
                        .request(
                            &EStopRelease {
                                confirm: "release".into(),
                                by: "test over".into(),
                                only_if_reason: None,
                            },
                            TIMEOUT,
                        )
                        .await
                        .unwrap();
                    assert!(!state.engaged, "{state:?}");
                }
                1 => {
                    let (status, body) = common::http_request(
                        port,
                        "POST",
                        "/estop/release",
                        &[],
                        br#"{"confirm": "release", "by": "the test"}"#,
                    );
                    assert_eq!(status, 200, "{body}");
                }
                2 => {
                    let t = text(&mcp, "release_emergency_stop", json!({"confirm": "release"})).await;
                    assert!(t.starts_with('✓'), "{t}");
                }
                _ => {
                    let out = robotd_cli(&namespace, &["estop", "--release"]);
                    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
                }
            }
            // Released: motions run again (the release reaches the arm through the bus). The
            // arm and the safety gate in front of it each latch the e-stop and each hear the
            // release on their own, so either may still refuse for a moment.
            let deadline = Instant::now() + Duration::from_secs(5);
            loop {
                let reply = arm
                    .request(&ArmCommand::move_to(down(0.25, 0.0, 0.12)), TIMEOUT)
                    .await
                    .unwrap();
                let still_latched = match &reply {
                    ArmReply::Error { error: ArmError::EStopped { .. } } => true,
                    ArmReply::Error { error: ArmError::Refused { limit, .. } } => limit == "estop",
                    _ => false,
                };
                match reply {
                    ArmReply::Ok { .. } => break,
                    _ if still_latched && Instant::now() < deadline => {
                        tokio::time::sleep(Duration::from_millis(20)).await;
                    }
                    other => panic!("after the release: {other:?}"),
                }
            }
        }
        mcp.cancel().await.unwrap();
    });

    // The audit log recorded all of it, in an unbroken chain; a deleted or edited line shows.
    let verify =
        |file: &std::path::Path| robotd_cli("unused", &["audit", "verify", file.to_str().unwrap()]);
    let mut ok = verify(&audit);
    for _ in 0..50 {
        if ok.status.success() {
            break;
        }
        std::thread::sleep(Duration::from_millis(100));
        ok = verify(&audit);
    }
    let report = String::from_utf8_lossy(&ok.stdout).to_string();
    assert!(ok.status.success(), "{report}");
    assert!(report.starts_with("ok: "), "{report}");
    // A file that is not there is not a broken chain: it is an error of its own.
    let missing = verify(&dir.path().join("missing.jsonl"));
    assert_eq!(missing.status.code(), Some(2));
    assert!(
        String::from_utf8_lossy(&missing.stderr).contains("cannot verify the audit log"),
        "{}",
        String::from_utf8_lossy(&missing.stderr)
    );
    let content = std::fs::read_to_string(&audit).unwrap();
    let lines: Vec<&str> = content.lines().collect();
    assert!(lines.len() >= 20, "{} audit lines", lines.len());
    assert!(
        content.contains("\"decision\":\"refused\""),
        "refusals are recorded"
    );
    assert!(content.contains("\"limit\":\"floor\""));
    let deleted = dir.path().join("deleted.jsonl");
    let mut kept = lines.clone();
    kept.remove(5);
    std::fs::write(&deleted, kept.join("\n") + "\n").unwrap();
    let out = verify(&deleted);
    let said = String::from_utf8_lossy(&out.stdout).to_string();
    assert_eq!(out.status.code(), Some(1), "{said}");
    assert!(said.contains("line 6"), "{said}");
    let edited = dir.path().join("edited.jsonl");
    // Turn a recorded refusal into an admission: the kind of edit the chain exists to catch.
    let at = lines
        .iter()
        .position(|l| l.contains("\"decision\":\"refused\""))
        .expect("a refusal was recorded");
    let mut changed: Vec<String> = lines.iter().map(|l| l.to_string()).collect();
    changed[at] = changed[at].replacen("\"decision\":\"refused\"", "\"decision\":\"admitted\"", 1);
    std::fs::write(&edited, changed.join("\n") + "\n").unwrap();
    let out = verify(&edited);
    let said = String::from_utf8_lossy(&out.stdout).to_string();
    assert_eq!(out.status.code(), Some(1), "{said}");
    assert!(
        said.contains(&format!("line {}", at + 1)) && said.contains("edited"),
        "{said}"
    );
}

fn pick_pencil() -> Value {
    json!({"object_name": "pencil", "pick_coordinate": [0.22, -0.05]})
}

fn pencil(world: &[SimObjectState]) -> SimObjectState {
    world.iter().find(|o| o.label == "pencil").unwrap().clone()
}

/// Asks for the pick on its own task; returns the task.
fn spawn_call(
    client: std::sync::Arc<McpClient>,
    tool: &'static str,
    args: Value,
) -> tokio::task::JoinHandle<String> {
    tokio::spawn(async move { text(&client, tool, args).await })
}

/// Answers approval `id` as "the operator".
fn answer(port: u16, id: u64, approve: bool) {
    let body = format!(r#"{{"approve": {approve}, "by": "the operator"}}"#);
    let (status, reply) = common::http_request(
        port,
        "POST",
        &format!("/approvals/{id}"),
        &[],
        body.as_bytes(),
    );
    assert_eq!(status, 200, "{reply}");
}

/// Waits until an approval is waiting; returns its id.
async fn waiting_approval(port: u16) -> u64 {
    let deadline = Instant::now() + Duration::from_secs(20);
    loop {
        let (status, body) = common::http_get(port, "/approvals");
        assert_eq!(status, 200, "{body}");
        let list: Value = serde_json::from_str(&body).unwrap();
        if let Some(first) = list.as_array().and_then(|l| l.first()) {
            assert_eq!(first["action"], "pick_object", "{first}");
            return first["id"].as_u64().unwrap();
        }
        assert!(Instant::now() < deadline, "no approval request appeared");
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
}

#[test]
fn an_approval_tool_moves_only_after_a_human_said_yes() {
    let namespace = common::fresh_namespace("approval");
    let port = common::free_port();
    let _robotd = common::start_robotd(
        &namespace,
        port,
        &[
            "--set",
            "safety.approval_tools=[\"pick_object\"]",
            "--set",
            "safety.approval_timeout_s=2",
        ],
    );
    runtime().block_on(async {
        let bus = Bus::open(BusOptions::new(&namespace, "approval-test")).unwrap();
        let arm = bus.client(&ARM_COMMAND).unwrap();
        let client = std::sync::Arc::new(
            connect(&format!("http://127.0.0.1:{port}/sse"), None)
                .await
                .unwrap(),
        );
        let start_world = world(&bus).await;
        let start_pose = pose(&arm).await;

        // Denied: refused, nothing moved.
        let call = spawn_call(client.clone(), "pick_object", pick_pencil());
        let id = waiting_approval(port).await;
        answer(port, id, false);
        let t = call.await.unwrap();
        assert_eq!(
            t,
            "❌ Failed to pick 'pencil': pick_object needs a human's approval: denied by the operator; nothing moved"
        );
        assert_eq!(world(&bus).await, start_world);
        assert_eq!(pose(&arm).await, start_pose);

        // Nobody answers: refused after the timeout, nothing moved.
        let t = text(&client, "pick_object", pick_pencil()).await;
        assert_eq!(
            t,
            "❌ Failed to pick 'pencil': pick_object needs a human's approval: nobody approved it within 2 s; nothing moved"
        );
        assert_eq!(world(&bus).await, start_world);
        assert_eq!(pose(&arm).await, start_pose);

        // Approved: it runs.
        let call = spawn_call(client.clone(), "pick_object", pick_pencil());
        let id = waiting_approval(port).await;
        answer(port, id, true);
        let t = call.await.unwrap();
        assert!(t.starts_with('✓'), "{t}");
        assert!(pencil(&world(&bus).await).held, "the approved pick did not pick");
        // An answered request cannot be answered again.
        let (status, _) = common::http_request(
            port,
            "POST",
            &format!("/approvals/{id}"),
            &[],
            br#"{"approve": true}"#,
        );
        assert_eq!(status, 404);
    });
}

#[test]
fn closing_the_session_stops_its_motion_and_a_cancelled_call_never_runs_later() {
    let namespace = common::fresh_namespace("deadman");
    let port = common::free_port();
    let _robotd = common::start_robotd(&namespace, port, &["--set", "robot.time_scale=1.0"]);
    runtime().block_on(async {
        let bus = Bus::open(BusOptions::new(&namespace, "deadman-test")).unwrap();
        let mut states = bus.subscriber(&ARM_STATE).unwrap();
        for url in ["sse", "mcp"] {
            let client = connect(&format!("http://127.0.0.1:{port}/{url}"), None)
                .await
                .unwrap();
            let request = ClientRequest::CallToolRequest(CallToolRequest::new(
                CallToolRequestParams::new("pick_object")
                    .with_arguments(pick_pencil().as_object().cloned().unwrap()),
            ));
            let _handle = client
                .peer()
                .send_cancellable_request(request, PeerRequestOptions::no_options())
                .await
                .unwrap();
            until_moving(&mut states, true, Duration::from_secs(20)).await;
            client.cancel().await.unwrap();
            // The call must be cancelled: the arm comes to rest for good, and the pick never
            // completes (a pick at this speed takes several seconds more).
            let rested_at =
                settled(&mut states, Duration::from_secs(2), Duration::from_secs(10)).await;
            eprintln!(
                "{url}: the arm came to rest for good {rested_at:?} after the session closed"
            );
            assert!(
                !pencil(&world(&bus).await).held,
                "{url}: the pick went on after the session closed"
            );
        }

        // Two clients: the second call waits behind the first, is cancelled while waiting,
        // and never runs.
        let first = std::sync::Arc::new(
            connect(&format!("http://127.0.0.1:{port}/sse"), None)
                .await
                .unwrap(),
        );
        let second = connect(&format!("http://127.0.0.1:{port}/sse"), None)
            .await
            .unwrap();
        let before = world(&bus).await;
        let running = spawn_call(
            first.clone(),
            "pick_object",
            json!({"object_name": "red cube", "pick_coordinate": [0.28, 0.04]}),
        );
        let request = ClientRequest::CallToolRequest(CallToolRequest::new(
            CallToolRequestParams::new("pick_object")
                .with_arguments(pick_pencil().as_object().cloned().unwrap()),
        ));
        let waiting = second
            .peer()
            .send_cancellable_request(request, PeerRequestOptions::no_options())
            .await
            .unwrap();
        tokio::time::sleep(Duration::from_millis(100)).await;
        waiting
            .cancel(Some("changed my mind".into()))
            .await
            .unwrap();
        let _ = running.await.unwrap();
        // Give the cancelled call every chance to run if it were going to.
        tokio::time::sleep(Duration::from_secs(3)).await;
        assert!(
            !pencil(&world(&bus).await).held,
            "the cancelled pick ran later"
        );
        assert_eq!(pencil(&world(&bus).await), pencil(&before));
    });
}
