//! The replay driver end to end, with real processes: a session recorded by `robotd serve` on
//! the simulator is served as the robot of another `robotd serve` (`robot.driver =
//! "replay"`), in a namespace of its own, with no simulator or robot publishing there.
//!
//! - robotd's own perception and workspace model find the original run's objects on the
//!   replayed frames (same labels, positions within a few millimetres), through the MCP tool
//!   `get_detected_objects` and the dashboard's `/api/objects`;
//! - a motion tool (`pick_object`) is refused with the replay driver's reason, and the arm
//!   stays where the recording put it;
//! - `robotd replay` refuses to publish into the namespace of that running robotd;
//! - a missing recording, and one of another robot model, stop `robotd serve` at start with
//!   the file's name and what is wrong.

mod common;

use robotd_runtime::bus::{Bus, BusOptions};
use robotd_topics::{ARM_STATE, CAMERA_FRAMES};
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

/// `robotd call <tool> --json` against the robotd on `port`: (success, structured or text).
fn call(port: u16, tool: &str, args: &[&str]) -> (bool, String) {
    let mut command = Command::new(env!("CARGO_BIN_EXE_robotd"));
    command.args(["call", tool, "--json", "--url"]);
    command.arg(format!("http://127.0.0.1:{port}/mcp"));
    for arg in args {
        command.args(["--arg", arg]);
    }
    let output = command.output().expect("robotd call");
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&output.stdout),
        String::from_utf8_lossy(&output.stderr)
    );
    (output.status.success(), text)
}

/// Label and [x, y] of each object in a JSON list of detected objects.
fn objects_in(list: &Value) -> Vec<(String, [f64; 2])> {
    list.as_array()
        .map(|objects| {
            objects
                .iter()
                .map(|o| {
                    let c = &o["position"]["center_of_mass"];
                    (
                        o["label"].as_str().unwrap_or_default().to_owned(),
                        [
                            c["x"].as_f64().unwrap_or(f64::NAN),
                            c["y"].as_f64().unwrap_or(f64::NAN),
                        ],
                    )
                })
                .collect()
        })
        .unwrap_or_default()
}

/// The objects `get_detected_objects` lists, or why it failed.
fn detected(port: u16) -> Result<Vec<(String, [f64; 2])>, String> {
    let (ok, text) = call(port, "get_detected_objects", &[]);
    if !ok {
        return Err(text);
    }
    let structured: Value = serde_json::from_str(&text).map_err(|e| format!("{e}: {text}"))?;
    Ok(objects_in(&structured["data"]))
}

/// Whether every object of `expected` is in `found` with its label, within `tolerance_m`.
fn matches(
    expected: &[(String, [f64; 2])],
    found: &[(String, [f64; 2])],
    tolerance_m: f64,
) -> bool {
    found.len() == expected.len()
        && expected.iter().all(|(label, at)| {
            found
                .iter()
                .any(|(l, p)| l == label && (p[0] - at[0]).hypot(p[1] - at[1]) <= tolerance_m)
        })
}

/// `robotd serve` that must refuse to start: its stderr.
fn serve_refuses(extra: &[&str]) -> String {
    let namespace = common::fresh_namespace("replay-refused");
    let output = Command::new(env!("CARGO_BIN_EXE_robotd"))
        .args(["serve", "--namespace", &namespace, "--http", "127.0.0.1:0"])
        .args(extra)
        .output()
        .expect("robotd serve");
    let stderr = String::from_utf8_lossy(&output.stderr).into_owned();
    assert!(!output.status.success(), "robotd serve started: {stderr}");
    stderr
}

/// Records a session of `robotd serve` on the simulator: start, move to the observation pose,
/// detect. Returns the recording and the objects the original run found.
fn record_a_session(dir: &Path) -> (PathBuf, Vec<(String, [f64; 2])>) {
    let namespace = common::fresh_namespace("replay-source");
    let port = common::free_port();
    let record_dir = format!("record.dir=\"{}\"", dir.display());
    let robotd = common::start_robotd(
        &namespace,
        port,
        &[
            "--set",
            &record_dir,
            "--set",
            "robot.time_scale=0.05",
            "--set",
            "foxglove.camera_fps=15",
        ],
    );
    // The call moves the arm to the observation pose and answers from the first steady view
    // there.
    let original = detected(port).expect("the original run detects");
    assert_eq!(original.len(), 4, "the default scene: {original:?}");
    // Then a second and more of the resting arm's frames go into the recording.
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .unwrap();
    runtime.block_on(async {
        let bus = Bus::open(BusOptions::new(&namespace, "replay-test")).unwrap();
        let mut frames = bus.frame_subscriber(&CAMERA_FRAMES).unwrap();
        for _ in 0..20 {
            tokio::time::timeout(Duration::from_secs(10), frames.recv())
                .await
                .expect("the camera publishes")
                .unwrap();
        }
    });
    drop(robotd); // SIGTERM: the recording is closed
    let files: Vec<PathBuf> = std::fs::read_dir(dir)
        .unwrap()
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|e| e == "mcap"))
        .collect();
    assert_eq!(files.len(), 1, "{files:?}");
    (files[0].clone(), original)
}

#[test]
fn a_recorded_session_is_served_as_the_robot_and_never_moves() {
    let dir = tempfile::tempdir().unwrap();
    let (file, original) = record_a_session(dir.path());
    let file_setting = format!("robot.replay.file=\"{}\"", file.display());

    // The recording as the robot of a robotd in a namespace of its own.
    let namespace = common::fresh_namespace("replay");
    let port = common::free_port();
    let started = Instant::now();
    let _robotd = common::start_robotd(
        &namespace,
        port,
        &["--set", "robot.driver=replay", "--set", &file_setting],
    );
    let (status, health) = common::http_get(port, "/health");
    assert_eq!(status, 200, "{health}");
    let health: Value = serde_json::from_str(&health).unwrap();
    assert_eq!(health["robot"]["driver"], "replay", "{health}");
    assert_eq!(health["robot"]["scene"], "", "no simulator: {health}");

    // robotd's own perception and workspace model find the original run's objects. Until the
    // replay has reached the observation pose the tool cannot answer (it would have to move
    // the arm there); the recording plays at its recorded pace, so this takes seconds.
    let deadline = Instant::now() + Duration::from_secs(60);
    let replayed = loop {
        match detected(port) {
            Ok(found) if matches(&original, &found, 0.004) => break found,
            outcome => assert!(
                Instant::now() < deadline,
                "the replay did not find {original:?}; last answer: {outcome:?}"
            ),
        }
        std::thread::sleep(Duration::from_millis(250));
    };
    eprintln!(
        "replayed objects after {:.1} s: {replayed:?} (original {original:?})",
        started.elapsed().as_secs_f64()
    );
    // The dashboard follows the workspace model's published objects on its own loop, so it
    // may show them a moment after the tool answered.
    let answered = Instant::now();
    let deadline = answered + Duration::from_secs(10);
    loop {
        let (status, body) = common::http_get(port, "/api/objects");
        assert_eq!(status, 200, "{body}");
        let dashboard: Value = serde_json::from_str(&body).unwrap();
        let listed = objects_in(&dashboard["objects"]);
        if matches(&original, &listed, 0.004) {
            eprintln!(
                "the dashboard listed them {:.2} s after the tool",
                answered.elapsed().as_secs_f64()
            );
            break;
        }
        assert!(Instant::now() < deadline, "the dashboard lists {listed:?}");
        std::thread::sleep(Duration::from_millis(50));
    }

    // A motion is refused with the driver's reason; the arm does not move.
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .unwrap();
    let bus = runtime.block_on(async { Bus::open(BusOptions::new(&namespace, "replay-test")) });
    let mut states = runtime
        .block_on(async { bus.as_ref().unwrap().subscriber(&ARM_STATE) })
        .unwrap();
    // The newest state: one that arrives, then any queued behind it.
    let mut next_joints = || {
        runtime.block_on(async {
            let first = tokio::time::timeout(Duration::from_secs(10), states.recv())
                .await
                .expect("the arm publishes its state")
                .unwrap();
            let mut joints = first.body.joints.positions_rad;
            while let Ok(Some(newer)) = states.try_recv() {
                joints = newer.body.joints.positions_rad;
            }
            joints
        })
    };
    let before = next_joints();
    let (label, at) = &original[0];
    let name = format!("object_name={label}");
    let coordinate = format!("pick_coordinate=[{}, {}]", at[0], at[1]);
    let (ok, refusal) = call(port, "pick_object", &[&name, &coordinate]);
    assert!(!ok, "a pick on a replayed robot must fail: {refusal}");
    assert!(
        refusal.contains("recording being replayed") && refusal.contains("cannot move"),
        "{refusal}"
    );
    eprintln!("refused: {refusal}");
    let after = next_joints();
    assert_eq!(before, after, "the arm moved");

    // robotd replay does not add a second robot to this namespace.
    let output = Command::new(env!("CARGO_BIN_EXE_robotd"))
        .args(["replay", "--namespace", &namespace])
        .arg(&file)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(!output.status.success(), "{stderr}");
    assert!(
        stderr.contains("a robotd is running") && stderr.contains("robot.driver=replay"),
        "{stderr}"
    );

    // Recordings that cannot be played stop robotd at start, naming the file.
    let missing = dir.path().join("missing.mcap");
    let stderr = serve_refuses(&[
        "--set",
        "robot.driver=replay",
        "--set",
        &format!("robot.replay.file=\"{}\"", missing.display()),
    ]);
    assert!(
        stderr.contains(&missing.display().to_string()) && stderr.contains("no such file"),
        "{stderr}"
    );
    let stderr = serve_refuses(&[
        "--set",
        "robot.driver=replay",
        "--set",
        &file_setting,
        "--set",
        "robot.replay.model=widowx250",
    ]);
    assert!(
        stderr.contains(&file.display().to_string())
            && stderr.contains("recorded on a Niryo Ned2")
            && stderr.contains("robot.replay.model = \"ned2\""),
        "{stderr}"
    );
}
