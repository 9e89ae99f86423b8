//! The Redis edge end to end: a real `redis-server` on a free port, robotd serving the simulator,
//! and the lab's side played by redis-py (tests/python/redis_client_check.py, in the test
//! venv) and by raw Redis commands.
//!
//! - the Python check decodes robotd's camera JPEG and publishes a vision-format detection
//!   that then appears in `get_detected_objects`, at the pixels' place on the table;
//! - Redis killed while frames stream: every tool call still succeeds, and publishing resumes
//!   within 2 s of Redis coming back;
//! - malformed entries are counted and skipped, and a good one after them still works;
//! - two robotd instances share one Redis: B's workspace model sees what A's camera saw.

mod common;

use common::{start_redis, start_redis_with};
use serde_json::Value;
use std::process::Command;
use std::time::{Duration, Instant};

fn redis_conn(port: u16) -> redis::Connection {
    redis::Client::open(format!("redis://127.0.0.1:{port}/0"))
        .and_then(|c| c.get_connection())
        .expect("connect to the test redis-server")
}

fn xlen(conn: &mut redis::Connection, stream: &str) -> u64 {
    redis::cmd("XLEN").arg(stream).query(conn).unwrap_or(0)
}

/// Calls a tool on robotd through `robotd call`; returns (succeeded, structuredContent or text).
fn call(port: u16, tool: &str, args: &[&str]) -> (bool, Value) {
    let mut command = Command::new(env!("CARGO_BIN_EXE_robotd"));
    command
        .args(["call", tool, "--json", "--url"])
        .arg(format!("http://127.0.0.1:{port}/mcp"));
    for arg in args {
        command.args(["--arg", arg]);
    }
    let output = command.output().expect("run robotd call");
    let stdout = String::from_utf8_lossy(&output.stdout);
    let value = serde_json::from_str(&stdout).unwrap_or(Value::String(stdout.to_string()));
    (output.status.success(), value)
}

fn health(port: u16) -> Value {
    let (status, body) = common::http_get(port, "/health");
    assert_eq!(status, 200, "{body}");
    serde_json::from_str(&body).unwrap_or_else(|e| panic!("{e}: {body}"))
}

fn wait_until(what: &str, timeout: Duration, mut done: impl FnMut() -> bool) -> Duration {
    let started = Instant::now();
    while !done() {
        assert!(
            started.elapsed() < timeout,
            "{what}: not within {timeout:?}"
        );
        std::thread::sleep(Duration::from_millis(25));
    }
    started.elapsed()
}

#[test]
fn python_tools_read_frames_and_their_detections_reach_the_tools() {
    let redis_port = common::free_port();
    let _redis = start_redis(redis_port);
    let port = common::free_port();
    let url = format!("redis://127.0.0.1:{redis_port}/0");
    // The Python detector answers one frame and then falls silent. The workspace model takes a
    // detector silent for 5 s (capture time) as gone and lets the built-in detector's views age
    // what only it saw: with the default 3 views the screwdriver could be forgotten before
    // a loaded machine gets to ask. Expiry has its own tests (workspace-model's tracker).
    let _robotd = common::start_robotd(
        &common::fresh_namespace("redis-py"),
        port,
        &[
            "--redis",
            &url,
            "--set",
            "robot.time_scale=0.05",
            "--set",
            "workspace.expire_after_frames=1000",
        ],
    );
    // Look once, so the arm stands at the observation pose and robotd's detections flow.
    let (ok, _) = call(port, "get_detected_objects", &[]);
    assert!(ok);

    let output = Command::new(common::python())
        .arg(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/tests/python/redis_client_check.py"
        ))
        .arg(redis_port.to_string())
        .output()
        .expect("run python (./scripts/test.sh installs the venv)");
    assert!(
        output.status.success(),
        "the redis-py check failed:\n{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let report: Value = serde_json::from_slice(&output.stdout).expect("the check's JSON");

    // The camera entry, as the spec lists its fields.
    let fields: Vec<&str> = report["camera_fields"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| f.as_str().unwrap())
        .collect();
    for field in [
        "timestamp",
        "image_data",
        "format",
        "width",
        "height",
        "channels",
        "dtype",
        "compressed_size",
        "original_size",
        "metadata",
    ] {
        assert!(
            fields.contains(&field),
            "robot_camera lacks {field}: {fields:?}"
        );
    }
    assert_eq!(report["camera"]["format"], "jpeg");
    assert_eq!(report["camera"]["width"], "640");
    assert_eq!(report["camera"]["height"], "480");
    assert_eq!(report["camera"]["channels"], "3");
    assert_eq!(report["camera"]["dtype"], "uint8");
    assert_eq!(report["camera"]["original_size"], "921600");
    assert_eq!(
        report["image"],
        serde_json::json!({"format": "JPEG", "size": [640, 480], "mode": "RGB"})
    );
    let metadata = &report["camera_metadata"];
    assert_eq!(metadata["workspace_id"], "niryo_ws");
    assert_eq!(metadata["image_source"], "robot_mounted_camera");
    assert!(metadata["frame_id"].is_u64());
    for key in ["x", "y", "z", "roll", "pitch", "yaw"] {
        assert!(metadata["robot_pose"][key].is_f64(), "robot_pose.{key}");
    }
    // robotd's own objects carry id and class_name for the newer Python validators.
    let keys = report["robotd_object_keys"].as_array().unwrap();
    assert!(keys.contains(&"id".into()) && keys.contains(&"class_name".into()));

    // The external detection is now a world object where the pencil's pixels lie.
    let pencil = &report["pencil"]["position"]["center_of_mass"];
    let (px, py) = (pencil["x"].as_f64().unwrap(), pencil["y"].as_f64().unwrap());
    // The answer travels through Redis and the edge's consumer: ask until it has arrived.
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(5);
    let found = loop {
        let (ok, found) = call(port, "get_detected_objects", &["label=screwdriver"]);
        assert!(ok, "{found}");
        if found["data"][0].is_object() || std::time::Instant::now() > deadline {
            break found;
        }
        std::thread::sleep(std::time::Duration::from_millis(100));
    };
    let screwdriver = &found["data"][0];
    assert_eq!(
        screwdriver["label"],
        "screwdriver",
        "{found}\nthe edge's counts: {}",
        health(port)["redis"]
    );
    let at = &screwdriver["position"]["center_of_mass"];
    let (x, y) = (at["x"].as_f64().unwrap(), at["y"].as_f64().unwrap());
    assert!(
        (x - px).abs() < 0.01 && (y - py).abs() < 0.01,
        "screwdriver at ({x:.3}, {y:.3}), its pixels are the pencil's at ({px:.3}, {py:.3})"
    );
    assert_eq!(screwdriver["confidence"], 0.87);
    // The label the detector announced is in the registry.
    let (ok, labels) = call(port, "get_object_labels_as_string", &[]);
    assert!(ok);
    assert!(labels.to_string().contains("screwdriver"), "{labels}");
    let redis = &health(port)["redis"];
    assert_eq!(redis["state"], "connected");
    assert!(
        redis["streams"]["detected_objects"]["consumed"].as_u64() >= Some(1),
        "{redis}"
    );
}

#[test]
fn redis_going_away_never_stops_the_robot_and_publishing_resumes() {
    let redis_port = common::free_port();
    let redis_server = start_redis(redis_port);
    let port = common::free_port();
    let url = format!("redis://127.0.0.1:{redis_port}/0");
    let _robotd = common::start_robotd(
        &common::fresh_namespace("redis-fault"),
        port,
        &["--redis", &url, "--set", "robot.time_scale=0.05"],
    );
    let mut conn = redis_conn(redis_port);
    wait_until("frames in robot_camera", Duration::from_secs(10), || {
        xlen(&mut conn, "robot_camera") > 0
    });
    drop(conn);
    drop(redis_server); // SIGTERM, then SIGKILL

    // The tools do not notice.
    let started = Instant::now();
    let mut calls = 0;
    while started.elapsed() < Duration::from_secs(3) {
        let (ok, out) = call(
            port,
            "get_workspace_coordinate_from_point",
            &["workspace_id=niryo_ws", "point=center point"],
        );
        assert!(ok, "{out}");
        let (ok, out) = call(port, "get_detected_objects", &[]);
        assert!(ok, "{out}");
        calls += 2;
    }
    assert!(calls >= 4);
    let redis = &health(port)["redis"];
    assert_eq!(redis["state"], "down", "{redis}");
    let (_, metrics) = common::http_get(port, "/metrics");
    assert_eq!(common::metric(&metrics, "robotd_redis_up "), Some(0.0));
    // `robotd doctor` names the problem of the running service's edge.
    let doctor = Command::new(env!("CARGO_BIN_EXE_robotd"))
        .args(["doctor", "--json", "--redis", &url, "--http"])
        .arg(format!("127.0.0.1:{port}"))
        .output()
        .expect("run robotd doctor");
    let report: Value = serde_json::from_slice(&doctor.stdout).expect("doctor's JSON");
    let edge = report["checks"]
        .as_array()
        .unwrap()
        .iter()
        .find(|c| c["name"] == "redis-edge")
        .expect("a redis-edge check")
        .clone();
    assert_eq!(edge["status"], "problem", "{edge}");
    assert!(
        edge["found"].as_str().unwrap().contains("cannot reach"),
        "{edge}"
    );

    // Back on the same port, empty (no persistence): new frames within 2 s.
    let _redis_again = start_redis(redis_port);
    let mut conn = redis_conn(redis_port);
    let resumed = wait_until("publishing resumed", Duration::from_secs(2), || {
        xlen(&mut conn, "robot_camera") > 0
    });
    eprintln!("publishing resumed {resumed:?} after redis-server listened again");
    wait_until("state connected", Duration::from_secs(2), || {
        health(port)["redis"]["state"] == "connected"
    });
    let redis = &health(port)["redis"];
    assert!(redis["reconnects"].as_u64() >= Some(1), "{redis}");
    assert!(
        redis["streams"]["robot_camera"]["dropped_disconnected"].as_u64() >= Some(1),
        "frames while Redis was away are counted as dropped: {redis}"
    );
}

#[test]
fn malformed_entries_are_counted_and_skipped() {
    let redis_port = common::free_port();
    let _redis = start_redis(redis_port);
    let port = common::free_port();
    let url = format!("redis://127.0.0.1:{redis_port}/0");
    let _robotd = common::start_robotd(
        &common::fresh_namespace("redis-fuzz"),
        port,
        &["--redis", &url, "--set", "robot.time_scale=0.05"],
    );
    let (ok, _) = call(port, "get_detected_objects", &[]);
    assert!(ok);
    let mut conn = redis_conn(redis_port);
    wait_until("the edge connected", Duration::from_secs(5), || {
        health(port)["redis"]["state"] == "connected"
    });
    let now = || {
        std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .unwrap()
            .as_secs_f64()
            .to_string()
    };
    let xadd = |conn: &mut redis::Connection, stream: &str, fields: &[(&str, Vec<u8>)]| {
        let mut cmd = redis::cmd("XADD");
        cmd.arg(stream).arg("*");
        for (k, v) in fields {
            cmd.arg(*k).arg(v.as_slice());
        }
        let _: String = cmd.query(conn).expect("XADD");
    };
    // A seeded stream of bad entries: broken JSON, wrong types, non-UTF-8, huge values,
    // impossible boxes and masks, missing fields.
    let mut seed = 0x2545_f491_4f6c_dd1du64;
    let mut next = || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        seed
    };
    let mut sent = 0;
    for i in 0..150 {
        let junk: Vec<u8> = (0..(next() % 64)).map(|_| next() as u8).collect();
        let objects: Vec<u8> = match i % 10 {
            0 => b"[{\"label\": \"x\", \"bbox\": {\"x_min\": 9, \"y_min\": 9, \"x_max\": 1}}]".to_vec(),
            1 => b"{\"not\": \"a list\"}".to_vec(),
            2 => b"[1, 2, 3]".to_vec(),
            3 => junk.clone(),
            4 => b"[{\"label\": \"x\", \"bbox\": {\"x_min\": 0, \"y_min\": 0, \"x_max\": 5, \"y_max\": 5}, \"has_mask\": true, \"mask_shape\": [99999, 99999], \"mask_data\": \"AAAA\"}]".to_vec(),
            5 => b"[{\"label\": \"x\", \"bbox\": {\"x_min\": 0, \"y_min\": 0, \"x_max\": 5, \"y_max\": 5}, \"has_mask\": true, \"mask_shape\": [2, 2], \"mask_data\": \"%%%\"}]".to_vec(),
            6 => vec![b'['; 10_000],
            7 => b"[{\"label\": \"ghost\", \"position\": {\"center_of_mass\": {\"x\": \"far\"}}}]".to_vec(),
            8 => b"[{\"label\": \"x\", \"confidence\": 7, \"bbox\": {\"x_min\": 0, \"y_min\": 0, \"x_max\": 5, \"y_max\": 5}}]".to_vec(),
            _ => vec![0xff, 0xfe, 0x00],
        };
        let timestamp = match i % 7 {
            0 => b"yesterday".to_vec(),
            1 => b"1.0".to_vec(),
            _ => now().into_bytes(),
        };
        xadd(
            &mut conn,
            "detected_objects",
            &[
                ("timestamp", timestamp),
                ("objects", objects),
                ("camera_pose", junk.clone()),
            ],
        );
        xadd(&mut conn, "detectable_labels", &[("labels", junk)]);
        sent += 2;
    }
    // Huge values: 20 MB of objects, and a label list of 5,000 labels.
    xadd(
        &mut conn,
        "detected_objects",
        &[
            ("timestamp", now().into_bytes()),
            ("objects", vec![b' '; 20 << 20]),
        ],
    );
    let many: Vec<String> = (0..5000).map(|i| format!("label{i}")).collect();
    xadd(
        &mut conn,
        "detectable_labels",
        &[("labels", serde_json::to_vec(&many).unwrap())],
    );
    sent += 2;

    // After all that, a good world-format entry from "another robotd" is still taken.
    let good = serde_json::json!([{
        "id": "x-1", "label": "blue marble", "class_name": "blue marble", "workspace_id": "niryo_ws",
        "timestamp": 0.0,
        "position": {"center_of_mass": {"x": 0.32, "y": 0.07, "z": 0.005},
                     "center": {"x": 0.32, "y": 0.07, "z": 0.005}},
        "image_coordinates": {"center_rel": {"u": 0.5, "v": 0.5}, "center_of_mass_rel": {"u": 0.5, "v": 0.5},
                              "bounding_box_rel": {"u_min": 0.4, "v_min": 0.4, "u_max": 0.6, "v_max": 0.6}},
        "dimensions": {"width_m": 0.01, "height_m": 0.01, "size_m2": 0.0001},
        "gripper_rotation": 0.0, "confidence": 0.9, "class_id": 1
    }]);
    let pose = serde_json::json!({"model_id": "robotd", "frame_id": 1, "workspace_id": "niryo_ws", "steady": true});
    let mut found = Value::Null;
    wait_until(
        "the good entry after the bad ones",
        Duration::from_secs(10),
        || {
            xadd(
                &mut conn,
                "detected_objects",
                &[
                    ("timestamp", now().into_bytes()),
                    ("objects", good.to_string().into_bytes()),
                    ("camera_pose", pose.to_string().into_bytes()),
                    ("robotd_instance", b"other-robotd".to_vec()),
                ],
            );
            let (ok, out) = call(port, "get_detected_objects", &["label=blue marble"]);
            found = out;
            ok && found["data"][0]["label"] == "blue marble"
        },
    );
    let redis = health(port)["redis"].clone();
    let skipped = |stream: &str| -> u64 {
        redis["streams"][stream]
            .as_object()
            .map(|m| {
                m.iter()
                    .filter(|(k, _)| k.starts_with("skipped_"))
                    .map(|(_, v)| v.as_u64().unwrap_or(0))
                    .sum()
            })
            .unwrap_or(0)
    };
    let (bad_objects, bad_labels) = (skipped("detected_objects"), skipped("detectable_labels"));
    eprintln!("sent {sent} bad entries; skipped {bad_objects} + {bad_labels}: {redis}");
    assert!(bad_objects >= 150, "{redis}");
    assert!(bad_labels >= 140, "{redis}");
    assert!(redis["streams"]["detected_objects"]["skipped_too_large"].as_u64() >= Some(1));
    assert_eq!(health(port)["status"], "ok");
    let (_, metrics) = common::http_get(port, "/metrics");
    assert!(
        metrics.contains(
            "robotd_redis_entries_total{stream=\"detected_objects\",outcome=\"skipped_malformed\"}"
        ),
        "metrics name the skipped entries"
    );
}

#[test]
fn two_robotd_instances_share_one_redis() {
    let redis_port = common::free_port();
    let _redis = start_redis(redis_port);
    let url = format!("redis://127.0.0.1:{redis_port}/0");
    // A: the default scene, its camera and built-in detector.
    let port_a = common::free_port();
    let _a = common::start_robotd(
        &common::fresh_namespace("redis-a"),
        port_a,
        &["--redis", &url, "--set", "robot.time_scale=0.05"],
    );
    // B: another scene, believing only what comes over Redis.
    let port_b = common::free_port();
    let _b = common::start_robotd(
        &common::fresh_namespace("redis-b"),
        port_b,
        &[
            "--redis",
            &url,
            "--set",
            "robot.time_scale=0.05",
            "--set",
            concat!(
                "robot.scene=",
                env!("CARGO_MANIFEST_DIR"),
                "/config/scenes/push.toml"
            ),
            "--set",
            "redis.trust=external",
        ],
    );
    let (ok, seen_by_a) = call(port_a, "get_detected_objects", &[]);
    assert!(ok, "{seen_by_a}");
    let labels_a: Vec<String> = seen_by_a["data"]
        .as_array()
        .unwrap()
        .iter()
        .map(|o| o["label"].as_str().unwrap().to_owned())
        .collect();
    assert!(labels_a.contains(&"pencil".to_owned()), "{labels_a:?}");
    let mut seen_by_b = Value::Null;
    wait_until("B sees A's objects", Duration::from_secs(10), || {
        let (ok, out) = call(port_b, "get_detected_objects", &["label=pencil"]);
        seen_by_b = out;
        ok && seen_by_b["data"][0]["label"] == "pencil"
    });
    let pencil_a = seen_by_a["data"]
        .as_array()
        .unwrap()
        .iter()
        .find(|o| o["label"] == "pencil")
        .unwrap();
    let (xa, xb) = (
        pencil_a["position"]["center_of_mass"]["x"]
            .as_f64()
            .unwrap(),
        seen_by_b["data"][0]["position"]["center_of_mass"]["x"]
            .as_f64()
            .unwrap(),
    );
    assert!((xa - xb).abs() < 0.005, "A: {xa}, B: {xb}");
    // B's own camera (the push scene's wide box) is not believed.
    let (ok, all_b) = call(port_b, "get_detected_objects", &[]);
    assert!(ok);
    let labels_b: Vec<&str> = all_b["data"]
        .as_array()
        .unwrap()
        .iter()
        .map(|o| o["label"].as_str().unwrap())
        .collect();
    assert!(
        labels_b.iter().all(|l| labels_a.iter().any(|a| a == l)),
        "B sees only A's objects: {labels_b:?} vs {labels_a:?}"
    );
    assert_eq!(health(port_b)["redis"]["trust"], "external");
}

#[test]
fn the_python_tools_variables_reach_a_password_protected_redis() {
    let redis_port = common::free_port();
    let _redis = start_redis_with(redis_port, &["--requirepass", "lab-secret"]);
    let port = common::free_port();
    let redis_port_text = redis_port.to_string();
    let _robotd = common::start_robotd_with_env(
        &common::fresh_namespace("redis-env"),
        port,
        &["--set", "robot.time_scale=0.05"],
        &[
            ("REDIS_HOST", "127.0.0.1"),
            ("REDIS_PORT", &redis_port_text),
            ("REDIS_DB", "2"),
            ("REDIS_PASSWORD", "lab-secret"),
        ],
    );
    let mut conn = redis::Client::open(format!("redis://:lab-secret@127.0.0.1:{redis_port}/2"))
        .and_then(|c| c.get_connection())
        .expect("connect with the password");
    wait_until("frames in db 2", Duration::from_secs(10), || {
        xlen(&mut conn, "robot_camera") > 0
    });
    let redis = &health(port)["redis"];
    assert_eq!(redis["state"], "connected", "{redis}");
    assert_eq!(redis["target"], format!("redis://127.0.0.1:{redis_port}/2"));
    assert!(
        !redis.to_string().contains("lab-secret"),
        "the password never shows: {redis}"
    );
}
