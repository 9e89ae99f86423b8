//! `robotd serve` with no arguments runs the simulated Ned2 in the default scene: another
//! process drives the arm over the bus and reads camera frames; bad scenes are refused at
//! start-up with the file and the reason; `robotd bench sim --json` reports its figures.

mod common;

use robotd_protocol::arm::{ArmCommand, ArmReply};
use robotd_runtime::bus::{Bus, BusOptions};
use robotd_topics::{ARM_COMMAND, CAMERA_FRAMES};
use std::process::{Command, Stdio};
use std::time::Duration;

#[test]
fn the_default_service_runs_the_simulated_ned2_that_another_process_can_drive() {
    let namespace = common::fresh_namespace("sim");
    let port = common::free_port();
    let robotd = common::start_robotd(&namespace, port, &["--set", "robot.time_scale=0.05"]);

    let (status, body) = common::http_get(port, "/health");
    assert_eq!(status, 200, "{body}");
    let health: serde_json::Value = serde_json::from_str(&body).unwrap();
    assert_eq!(health["robot"]["available"], true, "{body}");
    assert_eq!(health["robot"]["model"], "Niryo Ned2", "{body}");
    let actors: Vec<&str> = health["actors"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(|a| a["actor"].as_str())
        .collect();
    for actor in ["arm", "gripper", "camera"] {
        assert!(actors.contains(&actor), "{actor} missing from {body}");
    }

    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .unwrap();
    runtime.block_on(async {
        let bus = Bus::open(BusOptions::new(&namespace, "sim-test-client")).unwrap();
        let arm = bus.client(&ARM_COMMAND).unwrap();
        assert!(arm.wait_for_server(Duration::from_secs(5)).await);
        let reply = arm
            .request(
                &ArmCommand::GoToObservationPose {
                    workspace_id: "niryo_ws".into(),
                },
                Duration::from_secs(20),
            )
            .await
            .unwrap();
        let ArmReply::Ok { pose } = reply else {
            panic!("expected the arm at the observation pose, got {reply:?}");
        };
        assert!((pose.x_m - 0.173).abs() < 0.002, "{pose}");

        let mut frames = bus.frame_subscriber(&CAMERA_FRAMES).unwrap();
        let frame = tokio::time::timeout(Duration::from_secs(5), frames.recv())
            .await
            .expect("a camera frame within 5 s")
            .unwrap();
        assert_eq!(frame.header().width, 640);
        // A real image: not one flat colour.
        let pixels = frame.pixels();
        let distinct: std::collections::BTreeSet<u8> =
            pixels.iter().step_by(997).copied().collect();
        assert!(
            distinct.len() > 20,
            "only {} distinct values",
            distinct.len()
        );
    });

    let (_, metrics) = common::http_get(port, "/metrics");
    assert!(
        metrics.contains("robotd_actor_up{actor=\"arm\"} 1"),
        "{metrics}"
    );
    drop(robotd);
}

#[test]
fn a_scene_with_overlapping_objects_is_refused_at_start_up() {
    let file = std::env::temp_dir().join(format!("robotd-overlap-{}.toml", std::process::id()));
    let default_scene = include_str!("../config/scenes/default.toml");
    // The default scene plus a second cube right on top of the first one's footprint.
    let overlapping = format!(
        "{default_scene}\n[[objects]]\nlabel = \"second red cube\"\nshape = \"box\"\nlength_x_m = 0.03\nwidth_y_m = 0.03\nheight_z_m = 0.03\ncolor = \"red\"\nx_m = 0.28\ny_m = 0.04\n"
    );
    std::fs::write(&file, overlapping).unwrap();
    let output = Command::new(env!("CARGO_BIN_EXE_robotd"))
        .args(["serve", "--namespace", &common::fresh_namespace("overlap")])
        .args(["--http", "127.0.0.1:0", "--set"])
        .arg(format!("robot.scene={}", file.display()))
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("second red cube"), "{stderr}");
    assert!(stderr.contains("overlap"), "{stderr}");
    let _ = std::fs::remove_file(&file);
}

#[test]
fn bench_sim_json_reports_every_figure() {
    let output = Command::new(env!("CARGO_BIN_EXE_robotd"))
        .args(["bench", "sim", "--json", "--frames", "5"])
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&output.stdout);
    assert!(
        output.status.success(),
        "{stdout}{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let figures: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    for key in [
        "render_ms_p50",
        "ik_solve_rate",
        "ik_us_p50",
        "frame_to_bus_us_p50",
    ] {
        let value = figures[key].as_f64();
        assert!(value.is_some_and(|v| v > 0.0), "{key} in {stdout}");
    }
    assert!(
        figures["ik_solve_rate"].as_f64().unwrap() >= 0.99,
        "{stdout}"
    );
}

/// `robotd serve` started with a low soft open-files limit lifts it to the hard limit (each
/// iceoryx2 port and client connection needs descriptors).
#[test]
fn serve_raises_the_soft_open_files_limit() {
    let port = common::free_port();
    let robotd = env!("CARGO_BIN_EXE_robotd");
    let mut child = Command::new("bash")
        .arg("-c")
        .arg(format!(
            "ulimit -Sn 512 && exec {robotd} serve --namespace {} --http 127.0.0.1:{port}",
            common::fresh_namespace("nofile")
        ))
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let stderr = child.stderr.take().unwrap();
    let served = std::io::BufRead::lines(std::io::BufReader::new(stderr))
        .any(|l| l.is_ok_and(|l| l.contains("robotd: serving on")));
    let robotd = common::Running::new(child, "robotd");
    assert!(served, "robotd did not start");
    let limits = std::fs::read_to_string(format!("/proc/{}/limits", robotd.pid())).unwrap();
    let line = limits
        .lines()
        .find(|l| l.starts_with("Max open files"))
        .unwrap();
    let numbers: Vec<&str> = line.split_whitespace().skip(3).take(2).collect();
    assert_eq!(numbers[0], numbers[1], "soft limit not raised: {line}");
}
