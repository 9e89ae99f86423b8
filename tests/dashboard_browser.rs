//! The dashboard in a real browser: Debian's `chromium`, driven over WebDriver by
//! `chromedriver`, against a served robotd on the simulator with the scripted mock LLM as its
//! agent. The page loads; the camera image arrives and its frame changes; the objects table
//! lists the scene; a chat request moves the pencil (checked against the simulator's ground
//! truth); the e-stop button stops a motion under way. Screenshots of the key states are
//! kept in `target/test-artifacts/`.

#[path = "common/browser.rs"]
mod browser;
mod common;

use browser::Browser;

use robotd_agent::mock::{MockLlm, MockReply};
use robotd_protocol::diagnostics::SimWorldRequest;
use robotd_runtime::bus::{Bus, BusOptions};
use robotd_topics::{ARM_STATE, SIM_WORLD};
use serde_json::{json, Value};
use std::io::{BufRead, BufReader};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

fn start_robotd(
    namespace: &str,
    port: u16,
    mock: &MockLlm,
    dir: &std::path::Path,
) -> common::Running {
    let mut command = Command::new(env!("CARGO_BIN_EXE_robotd"));
    command
        .args(["serve", "--namespace", namespace, "--http"])
        .arg(format!("127.0.0.1:{port}"))
        .args(["--set", "robot.time_scale=1.0", "--set"])
        .arg(format!("telemetry.log_dir={}", dir.display()))
        .current_dir(dir)
        .env("OPENAI_API_KEY", "sk-test-dashboard")
        .env("OPENAI_BASE_URL", mock.openai_base_url())
        .stdout(Stdio::null())
        .stderr(Stdio::piped());
    for v in [
        "GROQ_API_KEY",
        "GEMINI_API_KEY",
        "API_KEY",
        "LLM_BASE_URL",
        "ROBOTD_CONFIG",
    ] {
        command.env_remove(v);
    }
    let mut robotd = common::Running::new(command.spawn().expect("start robotd serve"), "robotd");
    let stderr = robotd.child.stderr.take().unwrap();
    let mut lines = BufReader::new(stderr).lines();
    assert!(
        lines.any(|l| l.is_ok_and(|l| l.contains("robotd: serving on"))),
        "robotd did not start"
    );
    std::thread::spawn(move || for _ in lines {});
    robotd
}

async fn pencil_in_the_world(bus: &Bus) -> [f64; 2] {
    let world = bus
        .client(&SIM_WORLD)
        .unwrap()
        .request(&SimWorldRequest {}, Duration::from_secs(5))
        .await
        .unwrap();
    let pencil = world
        .objects
        .iter()
        .find(|o| o.label == "pencil")
        .expect("a pencil in the scene");
    [pencil.x_m, pencil.y_m]
}

#[test]
fn the_dashboard_shows_the_robot_chats_and_stops_it() {
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .unwrap();
    runtime.block_on(async {
        let mock = MockLlm::start(vec![
            MockReply::plan_and_call(
                "Plan: pick the pencil and place it right next to the red cube.",
                "pick_place_object",
                json!({"object_name": "pencil", "pick_coordinate": [0.22, -0.05],
                       "place_coordinate": [0.28, 0.04], "location": "right next to"}),
            ),
            MockReply::text("Done: the pencil lies right next to the red cube."),
        ])
        .await
        .unwrap();
        let namespace = common::fresh_namespace("dashboard");
        let port = common::free_port();
        let dir = tempfile::tempdir().unwrap();
        let _robotd = start_robotd(&namespace, port, &mock, dir.path());
        let bus = Bus::open(BusOptions::new(&namespace, "dashboard-test")).unwrap();
        let pencil_before = pencil_in_the_world(&bus).await;
        // The detection tools look from the observation pose; the table fills from then on.
        common::look_at_the_workspace(port);
        let url = format!("http://127.0.0.1:{port}/mcp");

        let browser = Browser::start().await;
        browser.open(&format!("http://127.0.0.1:{port}/")).await;
        // The camera: frames arrive and change.
        let first = browser
            .wait_for(
                "a camera frame",
                "return Number(document.getElementById('camera-info').dataset.frameId || 0)",
                Duration::from_secs(20),
            )
            .await;
        browser
            .wait_for(
                "a newer camera frame",
                &format!(
                    "return Number(document.getElementById('camera-info').dataset.frameId) > {first}"
                ),
                Duration::from_secs(10),
            )
            .await;
        let width = browser
            .eval("return document.getElementById('camera').naturalWidth")
            .await;
        assert_eq!(width, 640, "the camera image is shown");
        // Capture → in the page: read the MJPEG stream in the page itself and compare each
        // part's capture time with the page's clock (same machine, same clock).
        browser
            .eval(
                "window.frameAges = []; (async () => { \
                   const r = await fetch('/api/camera.mjpg'); const reader = r.body.getReader(); \
                   const dec = new TextDecoder('latin1'); let buf = ''; \
                   while (window.frameAges.length < 30) { \
                     const { value, done } = await reader.read(); if (done) break; \
                     buf += dec.decode(value, { stream: true }); let m; \
                     while ((m = buf.match(/X-Frame-Timestamp-Ns: (\\d+)/))) { \
                       window.frameAges.push(Date.now() - Number(m[1]) / 1e6); \
                       buf = buf.slice(m.index + m[0].length); } } \
                   reader.cancel(); })(); return true",
            )
            .await;
        let ages = browser
            .wait_for(
                "30 frames read in the page",
                "return window.frameAges.length >= 30 ? window.frameAges : null",
                Duration::from_secs(20),
            )
            .await;
        let mut ages: Vec<f64> = ages
            .as_array()
            .unwrap()
            .iter()
            .filter_map(Value::as_f64)
            .collect();
        ages.sort_by(f64::total_cmp);
        eprintln!(
            "camera frame capture -> received in the page: p50 {:.1} ms, max {:.1} ms ({} frames)",
            ages[ages.len() / 2],
            ages[ages.len() - 1],
            ages.len()
        );
        assert!(ages[ages.len() / 2] < 500.0, "frames reach the page late: {ages:?}");
        // The objects table lists the scene.
        let labels = browser
            .wait_for(
                "the objects",
                "const rows = [...document.querySelectorAll('#objects tr')].map(r => r.dataset.label); \
                 return rows.length >= 4 ? rows.sort().join(',') : ''",
                Duration::from_secs(10),
            )
            .await;
        assert_eq!(labels, "blue square,green cylinder,pencil,red cube");
        browser.screenshot("dashboard-loaded").await;

        // Chat: the mock LLM moves the pencil; the page shows the plan, the call, the answer.
        browser
            .type_into("#chat-input", "put the pencil right next to the red cube")
            .await;
        browser.click("#chat-send").await;
        let log = browser
            .wait_for(
                "the agent's answer",
                "const t = document.getElementById('chat-log').innerText; \
                 return t.includes('Done: the pencil') ? t : ''",
                Duration::from_secs(60),
            )
            .await;
        let log = log.as_str().unwrap();
        for expected in [
            "plan: Plan: pick the pencil",
            "→ pick_place_object",
            "← ✓",
        ] {
            assert!(log.contains(expected), "{expected:?} in {log}");
        }
        // The tool latency plot counts the calls (the chat's pick_place_object at least).
        browser
            .wait_for(
                "tool calls in the latency plot",
                "return /[1-9][0-9]* calls, p50/.test(document.getElementById('latency-p50').textContent)",
                Duration::from_secs(5),
            )
            .await;
        browser.screenshot("dashboard-after-chat").await;
        let pencil_after = pencil_in_the_world(&bus).await;
        let moved = (pencil_after[0] - pencil_before[0]).hypot(pencil_after[1] - pencil_before[1]);
        assert!(
            moved > 0.03,
            "the pencil moved {moved:.3} m: {pencil_before:?} -> {pencil_after:?}"
        );

        // The e-stop button stops a motion under way (a pick: several seconds of motion).
        let mut states = bus.subscriber(&ARM_STATE).unwrap();
        let motion = std::thread::spawn({
            let url = url.clone();
            move || {
                Command::new(env!("CARGO_BIN_EXE_robotd"))
                    .args(["call", "pick_object", "--url", &url])
                    .args(["--arg", "object_name=blue square"])
                    .args(["--arg", "pick_coordinate=[0.22,0.05]"])
                    .output()
                    .unwrap()
            }
        });
        // The arm moves, or the call ended first: then its answer says why.
        let deadline = Instant::now() + Duration::from_secs(30);
        loop {
            let state = tokio::time::timeout(Duration::from_millis(200), states.recv()).await;
            if let Ok(Ok(state)) = state {
                if state.body.moving {
                    break;
                }
            }
            if motion.is_finished() {
                let answer = motion.join().unwrap();
                panic!(
                    "pick_object ended before the arm moved: {}{}",
                    String::from_utf8_lossy(&answer.stdout),
                    String::from_utf8_lossy(&answer.stderr)
                );
            }
            assert!(Instant::now() < deadline, "the arm never moved within 30 s");
        }
        browser.click("#estop").await;
        let engaged_at = Instant::now();
        browser
            .wait_for(
                "the e-stop engaged and the arm at rest",
                "const s = window.lastStatus; return s && s.health.safety.estop.engaged && !s.arm.moving",
                Duration::from_secs(5),
            )
            .await;
        eprintln!("e-stop shown with the arm at rest {:?} after the click", engaged_at.elapsed());
        let answer = motion.join().unwrap();
        let text = String::from_utf8_lossy(&answer.stdout);
        assert!(text.contains("❌"), "the motion was stopped: {text}");
        browser.screenshot("dashboard-estop").await;
        // A phone-sized screen: one column, nothing wider than the screen.
        browser
            .command("/window/rect", json!({"width": 390, "height": 844}))
            .await;
        let overflow = browser
            .wait_for(
                "the page laid out for a phone",
                "return window.innerWidth <= 400 ? String(Math.max(0, document.documentElement.scrollWidth - window.innerWidth)) : ''",
                Duration::from_secs(5),
            )
            .await;
        assert_eq!(overflow, "0", "the page is wider than a phone's screen");
        browser.screenshot("dashboard-phone").await;
        browser
            .command("/window/rect", json!({"width": 1280, "height": 1000}))
            .await;
        // Release, confirming the dialog.
        browser.click("#release").await;
        browser.accept_dialog().await;
        browser
            .wait_for(
                "the e-stop released",
                "const s = window.lastStatus; return s && !s.health.safety.estop.engaged",
                Duration::from_secs(5),
            )
            .await;
        browser.close().await;
    });
}
