//! robotd in Foxglove, against a served robotd on the simulator:
//!
//! - the live view: a WebSocket client speaking the Foxglove protocol subscribes to the
//!   camera, transforms, objects, workspace, URDF, joint states and a bus topic, and decodes
//!   what arrives;
//! - a recording: `robotd record` writes an MCAP file that the reference Python reader opens,
//!   with the channels, schemas and messages expected;
//! - a replay: `robotd replay` publishes the recording on another bus namespace, and
//!   perception on the replayed frames finds what the original run's perception found.

mod common;

use foxglove::messages::{CompressedImage, FrameTransforms, SceneUpdate};
use foxglove::Decode;
use futures::{SinkExt, StreamExt};
use robotd_perception::eval::Lab;
use robotd_runtime::bus::{Bus, BusOptions};
use robotd_topics::CAMERA_FRAMES;
use serde_json::{json, Value};
use std::collections::HashMap;
use std::process::Command;
use std::time::{Duration, Instant};
use tokio_tungstenite::tungstenite::client::IntoClientRequest;
use tokio_tungstenite::tungstenite::Message;

#[test]
fn the_live_view_serves_camera_transforms_objects_and_topics() {
    let namespace = common::fresh_namespace("foxglove");
    let port = common::free_port();
    let fox = common::free_port();
    let _robotd = common::start_robotd(
        &namespace,
        port,
        &[
            "--set",
            &format!("foxglove.bind=\"127.0.0.1:{fox}\""),
            "--set",
            "robot.time_scale=0.05",
        ],
    );
    common::look_at_the_workspace(port);
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .unwrap();
    runtime.block_on(async {
        let mut request = format!("ws://127.0.0.1:{fox}")
            .into_client_request()
            .unwrap();
        request
            .headers_mut()
            .insert("sec-websocket-protocol", "foxglove.sdk.v1".parse().unwrap());
        let (mut socket, _) = tokio_tungstenite::connect_async(request).await.unwrap();
        let wanted = [
            "/camera",
            "/tf",
            "/scene/objects",
            "/scene/workspace",
            "/robot_description",
            "/joint_states",
            "/bus/arm/state",
        ];
        // Channels are advertised (possibly over several messages); subscribe to ours.
        let mut channels: HashMap<String, (u64, Value)> = HashMap::new();
        let deadline = Instant::now() + Duration::from_secs(10);
        while !wanted.iter().all(|w| channels.contains_key(*w)) {
            assert!(
                Instant::now() < deadline,
                "advertised: {:?}",
                channels.keys()
            );
            let message = tokio::time::timeout(Duration::from_secs(5), socket.next())
                .await
                .expect("a message from the server")
                .unwrap()
                .unwrap();
            if let Message::Text(text) = message {
                let value: Value = serde_json::from_str(&text).unwrap();
                if value["op"] == "advertise" {
                    for channel in value["channels"].as_array().unwrap() {
                        let topic = channel["topic"].as_str().unwrap().to_owned();
                        channels.insert(topic, (channel["id"].as_u64().unwrap(), channel.clone()));
                    }
                }
            }
        }
        assert_eq!(
            channels["/camera"].1["schemaName"],
            "foxglove.CompressedImage"
        );
        assert_eq!(channels["/bus/arm/state"].1["encoding"], "json");
        // Bus topics carry the JSON Schema generated from their Rust type, not a placeholder.
        let arm_channel = &channels["/bus/arm/state"].1;
        assert_eq!(arm_channel["schemaEncoding"], "jsonschema");
        let arm_schema: Value =
            serde_json::from_str(arm_channel["schema"].as_str().unwrap()).unwrap();
        assert_eq!(
            arm_schema["properties"]["tool_pose"]["properties"]["x"]["type"], "number",
            "{arm_schema}"
        );
        let subscriptions: Vec<Value> = wanted
            .iter()
            .enumerate()
            .map(|(i, topic)| json!({"id": i, "channelId": channels[*topic].0}))
            .collect();
        let subscribe = json!({"op": "subscribe", "subscriptions": subscriptions});
        socket
            .send(Message::Text(subscribe.to_string().into()))
            .await
            .unwrap();
        // Message data: opcode 1, subscription id (u32 LE), log time (u64 LE), payload.
        let mut seen: HashMap<&str, Vec<u8>> = HashMap::new();
        let deadline = Instant::now() + Duration::from_secs(15);
        while seen.len() < wanted.len() {
            assert!(Instant::now() < deadline, "received only {:?}", seen.keys());
            let message = tokio::time::timeout(Duration::from_secs(5), socket.next())
                .await
                .expect("data from the server")
                .unwrap()
                .unwrap();
            let Message::Binary(data) = message else {
                continue;
            };
            if data.first() != Some(&1) || data.len() < 13 {
                continue;
            }
            let subscription = u32::from_le_bytes(data[1..5].try_into().unwrap()) as usize;
            seen.insert(wanted[subscription], data[13..].to_vec());
        }
        let image = CompressedImage::decode(seen["/camera"].as_slice()).unwrap();
        assert_eq!(image.format, "jpeg");
        let decoded = image::load_from_memory(&image.data).unwrap();
        assert_eq!((decoded.width(), decoded.height()), (640, 480));
        let urdf: Value = serde_json::from_slice(&seen["/robot_description"]).unwrap();
        let urdf = urdf["data"].as_str().unwrap();
        assert!(urdf.contains("<robot"));
        let model = robotd_foxglove::urdf::parse(urdf);
        // The model is drawable (every link has a visual) ...
        assert!(
            model.links.iter().all(|l| l.visuals > 0),
            "{:?}",
            model.links
        );
        // ... and /tf is its tree: each transform is one of its joints, parent to child.
        let transforms = FrameTransforms::decode(seen["/tf"].as_slice()).unwrap();
        let children: Vec<&str> = transforms
            .transforms
            .iter()
            .map(|t| t.child_frame_id.as_str())
            .collect();
        assert!(children.contains(&"tcp_link"), "{children:?}");
        for t in &transforms.transforms {
            assert!(
                model
                    .joints
                    .iter()
                    .any(|j| j.parent == t.parent_frame_id && j.child == t.child_frame_id),
                "{} -> {} is not a joint of the URDF",
                t.parent_frame_id,
                t.child_frame_id
            );
        }
        // /joint_states names the URDF's movable joints, one per position.
        let joints: Value = serde_json::from_slice(&seen["/joint_states"]).unwrap();
        let movable: Vec<&str> = model
            .joints
            .iter()
            .filter(|j| j.is_movable())
            .map(|j| j.name.as_str())
            .collect();
        let names: Vec<&str> = joints["name"]
            .as_array()
            .unwrap()
            .iter()
            .map(|n| n.as_str().unwrap())
            .collect();
        assert_eq!(names, movable, "{joints}");
        assert_eq!(joints["position"].as_array().unwrap().len(), 6, "{joints}");
        // /scene/workspace: the workspaces' sheets and the motion policy's geofence.
        let workspace = SceneUpdate::decode(seen["/scene/workspace"].as_slice()).unwrap();
        let ids: Vec<&str> = workspace.entities.iter().map(|e| e.id.as_str()).collect();
        assert!(ids.contains(&"geofence"), "{ids:?}");
        assert!(
            ids.iter().any(|id| id.starts_with("workspaces/")),
            "{ids:?}"
        );
        let fence = workspace
            .entities
            .iter()
            .find(|e| e.id == "geofence")
            .unwrap();
        assert_eq!(fence.lines[0].points.len(), 24, "the fence's twelve edges");
        let scene = SceneUpdate::decode(seen["/scene/objects"].as_slice()).unwrap();
        let labels: Vec<&str> = scene
            .entities
            .iter()
            .flat_map(|e| e.texts.iter().map(|t| t.text.as_str()))
            .collect();
        assert!(labels.iter().any(|l| l.starts_with("pencil")), "{labels:?}");
        let arm: Value = serde_json::from_slice(&seen["/bus/arm/state"]).unwrap();
        assert_eq!(
            arm["joints"]["positions_rad"].as_array().unwrap().len(),
            6,
            "{arm}"
        );
    });
}

#[test]
fn a_recording_opens_in_the_mcap_reader_and_replays_into_perception() {
    let namespace = common::fresh_namespace("record");
    let port = common::free_port();
    let _robotd = common::start_robotd(&namespace, port, &["--set", "robot.time_scale=0.05"]);
    common::look_at_the_workspace(port);
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("session.mcap");
    let recorded = Command::new(env!("CARGO_BIN_EXE_robotd"))
        .args(["record", "--namespace", &namespace, "--duration", "2s"])
        .arg(&file)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&recorded.stderr);
    assert!(recorded.status.success(), "{stderr}");
    assert!(stderr.contains("robotd: wrote"), "{stderr}");
    assert!(!stderr.contains("no robotd is running"), "{stderr}");
    // A namespace without a robotd (a mistyped --namespace) is said so.
    let elsewhere = Command::new(env!("CARGO_BIN_EXE_robotd"))
        .args(["record", "--namespace", &common::fresh_namespace("nobody")])
        .args(["--duration", "1s"])
        .arg(dir.path().join("nobody.mcap"))
        .output()
        .unwrap();
    let warned = String::from_utf8_lossy(&elsewhere.stderr);
    assert!(warned.contains("no robotd is running on bus"), "{warned}");
    // It never overwrites.
    let again = Command::new(env!("CARGO_BIN_EXE_robotd"))
        .args(["record", "--namespace", &namespace, "--duration", "1s"])
        .arg(&file)
        .output()
        .unwrap();
    assert!(!again.status.success());
    assert!(String::from_utf8_lossy(&again.stderr).contains("never overwrite"));

    // The reference reader.
    let read = common::run_python_json("mcap_read.py", &[file.display().to_string()]);
    let channels = &read["channels"];
    for topic in [
        "/camera",
        "/camera/meta",
        "/tf",
        "/joint_states",
        "/scene/arm",
        "/scene/workspace",
        "/robot_description",
        "/bus/arm/state",
        "/bus/perception/detections",
    ] {
        assert!(
            channels[topic]["count"].as_u64().unwrap_or(0) > 0,
            "{topic} missing: {read}"
        );
    }
    assert_eq!(
        channels["/camera"]["schema_name"],
        "foxglove.CompressedImage"
    );
    assert_eq!(channels["/camera"]["message_encoding"], "protobuf");
    assert_eq!(channels["/bus/arm/state"]["schema_name"], "arm.state");
    assert_eq!(channels["/bus/arm/state"]["schema_encoding"], "jsonschema");
    // The schema's JSON Schema is in the file (the reader script prints no schema data; MCAP
    // keeps schema records uncompressed, and repeats them in the summary).
    let bytes = std::fs::read(&file).unwrap();
    let has = |needle: &str| bytes.windows(needle.len()).any(|w| w == needle.as_bytes());
    assert!(
        has(r#""title":"ArmState""#) && has(r#""properties":{"joints""#),
        "no JSON Schema of arm.state in the recording"
    );
    assert_eq!(read["last"]["/camera"]["has_jpeg"], true, "{read}");
    let recorded_objects = read["last"]["/bus/perception/detections"]["objects"]
        .as_array()
        .unwrap()
        .clone();
    assert_eq!(recorded_objects.len(), 4, "{read}");

    // Replay into an empty namespace, and run perception on what arrives there.
    let replay_ns = common::fresh_namespace("replay");
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .unwrap();
    let _inside = runtime.enter();
    let bus = Bus::open(BusOptions::new(&replay_ns, "replay-test")).unwrap();
    let mut frames = bus.frame_subscriber(&CAMERA_FRAMES).unwrap();
    let replayer = std::thread::spawn({
        let file = file.clone();
        let replay_ns = replay_ns.clone();
        move || {
            Command::new(env!("CARGO_BIN_EXE_robotd"))
                .args(["replay", "--namespace", &replay_ns, "--speed", "1"])
                .arg(&file)
                .output()
                .unwrap()
        }
    });
    let mut lab = Lab::new(0.0, false).unwrap();
    let (mut received, mut detected) = (0, None);
    runtime.block_on(async {
        while let Ok(Ok(frame)) = tokio::time::timeout(Duration::from_secs(5), frames.recv()).await
        {
            received += 1;
            let (w, h) = (
                frame.header().width as usize,
                frame.header().height as usize,
            );
            lab.frame_mut()
                .copy_from_slice(&frame.pixels()[..w * h * 3]);
            let id = frame.header().frame_id;
            drop(frame);
            detected = Some(lab.detect(id, 0).unwrap());
        }
    });
    let output = replayer.join().unwrap();
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(output.status.success(), "{stderr}");
    assert!(stderr.contains("camera/frames"), "{stderr}");
    assert!(received > 3, "{received} frames replayed: {stderr}");
    let detected = detected.unwrap();
    for object in &recorded_objects {
        let label = object["label"].as_str().unwrap();
        let at = &object["position"]["center_of_mass"];
        let (x, y) = (at["x"].as_f64().unwrap(), at["y"].as_f64().unwrap());
        let found = detected
            .objects
            .iter()
            .find(|o| o.label == label)
            .unwrap_or_else(|| panic!("{label} not found on the replayed frames"));
        let c = &found.position.center_of_mass;
        let off = (c.x_m - x).hypot(c.y_m - y);
        assert!(
            off < 0.005,
            "{label}: {off:.4} m from the original run's position"
        );
    }
}

/// `[record]`: files are closed at `max_file_bytes`, the oldest beyond `keep_files` deleted,
/// and every closed file reads back as MCAP.
#[test]
fn always_on_recording_rotates_and_keeps_the_newest_files() {
    let namespace = common::fresh_namespace("always");
    let port = common::free_port();
    let dir = tempfile::tempdir().unwrap();
    let record_dir = format!("record.dir=\"{}\"", dir.path().display());
    let robotd = common::start_robotd(
        &namespace,
        port,
        &[
            "--set",
            &record_dir,
            "--set",
            "record.max_file_bytes=1048576",
            "--set",
            "record.keep_files=2",
            "--set",
            "robot.camera.fps=30",
            "--set",
            "foxglove.camera_fps=30",
        ],
    );
    let names = || {
        let mut names: Vec<String> = std::fs::read_dir(dir.path())
            .unwrap()
            .flatten()
            .map(|e| e.file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        names
    };
    // Wait until a file has been started and rotated away at least twice.
    let mut seen: Vec<String> = Vec::new();
    let deadline = Instant::now() + Duration::from_secs(60);
    while seen.len() < 4 {
        assert!(
            Instant::now() < deadline,
            "files seen: {seen:?}, now {:?}",
            names()
        );
        let now = names();
        assert!(
            now.len() <= 3,
            "more files than keep_files (+ the open one): {now:?}"
        );
        for name in now {
            if !seen.contains(&name) {
                seen.push(name);
            }
        }
        std::thread::sleep(Duration::from_millis(100));
    }
    drop(robotd);
    let left = names();
    assert!(left.len() <= 2, "{left:?}");
    assert!(
        !left.contains(&seen[0]),
        "the oldest file was deleted: {left:?}"
    );
    for name in left {
        let summary = robotd_foxglove::record::summarize(&dir.path().join(&name))
            .unwrap_or_else(|e| panic!("{name}: {e}"));
        assert!(
            summary.messages.get("/camera").copied().unwrap_or(0) > 0,
            "{summary:?}"
        );
    }
}

/// `robotd record` and `robotd replay` refuse what they cannot do before touching the bus or a
/// file: an unknown topic, a bad speed or duration, a file that is not a recording.
#[test]
fn record_and_replay_refuse_bad_arguments_with_a_reason() {
    let dir = tempfile::tempdir().unwrap();
    let not_mcap = dir.path().join("notes.mcap");
    std::fs::write(&not_mcap, b"these are not MCAP bytes").unwrap();
    let namespace = common::fresh_namespace("badargs");
    let run = |args: &[&str]| {
        let output = Command::new(env!("CARGO_BIN_EXE_robotd"))
            .args(["--namespace", &namespace])
            .args(args)
            .output()
            .unwrap();
        assert!(!output.status.success(), "{args:?} succeeded");
        String::from_utf8_lossy(&output.stderr).into_owned()
    };
    let file = dir.path().join("out.mcap");
    let file = file.to_str().unwrap();
    let said = run(&["record", "--topics", "arm/state,bogus/topic", file]);
    assert!(said.contains("unknown topic 'bogus/topic'"), "{said}");
    assert!(said.contains("arm/state"), "lists the known topics: {said}");
    let said = run(&["record", "--duration", "ten", file]);
    assert!(said.to_lowercase().contains("duration"), "{said}");
    let notes = not_mcap.to_str().unwrap();
    let said = run(&["replay", "--speed=-1", notes]);
    assert!(said.contains("--speed"), "{said}");
    let said = run(&["replay", notes]);
    assert!(said.contains("notes.mcap"), "names the file: {said}");
    assert!(!std::path::Path::new(file).exists(), "nothing written");
}
