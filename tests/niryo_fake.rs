//! `robotd fake-niryo` against Niryo's own client: pyniryo 1.2.5 (in the test venv) connects,
//! calibrates, names the mounted tool, moves, grips, decodes an image, reads the intrinsics and
//! gets a collision set and cleared — so the fake, which the niryo driver's tests and the scenarios run against,
//! speaks what the robot speaks.

mod common;

#[test]
fn pyniryo_drives_the_fake_ned2() {
    let (_fake, port) = common::start_fake_niryo(
        &["--set", "robot.time_scale=0.05"],
        &["--needs-calibration"],
    );
    let seen = common::run_python_json("pyniryo_session.py", &[port.to_string()]);
    let numbers = |key: &str| -> Vec<f64> {
        seen[key]
            .as_array()
            .unwrap_or_else(|| panic!("{key}: {seen}"))
            .iter()
            .map(|v| v.as_f64().unwrap())
            .collect()
    };
    let near = |a: &[f64], b: &[f64], tolerance: f64| {
        a.len() == b.len() && a.iter().zip(b).all(|(x, y)| (x - y).abs() <= tolerance)
    };
    // pyniryo passes the robot's boolean strings through.
    assert_eq!(seen["need_calibration_before"], "True", "{seen}");
    assert_eq!(seen["need_calibration_after"], "False", "{seen}");
    assert_eq!(seen["hardware_version"], "ned2");
    // pyniryo turns the tool's name into its ToolID: the fake's standard gripper.
    assert_eq!(seen["tool"], "GRIPPER_1", "{seen}");
    assert!(
        near(
            &numbers("joints_after_move"),
            &[0.2, 0.3, -0.4, 0.0, -0.5, 0.1],
            1e-6
        ),
        "{seen}"
    );
    assert!(
        near(
            &numbers("joints_after_move_joints"),
            &[0.0, 0.3, -0.6, 0.0, -0.4, 0.0],
            1e-6
        ),
        "{seen}"
    );
    assert!(
        near(&numbers("pose_after_move")[..3], &[0.25, 0.05, 0.20], 0.002),
        "{seen}"
    );
    assert!(
        near(
            &numbers("pose_after_move_pose"),
            &[0.22, -0.03, 0.25],
            0.002
        ),
        "{seen}"
    );
    assert_eq!(seen["image_shape"], serde_json::json!([480, 640, 3]));
    assert!(
        seen["image_std"].as_f64().unwrap() > 10.0,
        "a real picture: {seen}"
    );
    assert_eq!(seen["camera_matrix"][0][0], 508.069);
    assert_eq!(seen["distortion"][0][0], -0.4146402);
    assert_eq!(seen["collision_before"], "False");
    let refused = seen["move_into_table"].as_str().unwrap();
    assert!(
        refused.starts_with("NiryoRobotException") && refused.contains("collision"),
        "{refused}"
    );
    assert_eq!(seen["collision_after"], "True");
    assert_eq!(seen["collision_cleared"], "False");
    assert!(
        near(&numbers("pose_after_recovery"), &[0.25, 0.0, 0.20], 0.002),
        "{seen}"
    );
}

#[test]
fn serve_starts_without_the_robot_says_why_and_picks_it_up_when_it_appears() {
    let robot_port = common::free_port();
    let namespace = common::fresh_namespace("niryo");
    let http = common::free_port();
    let config = concat!(env!("CARGO_MANIFEST_DIR"), "/config/niryo.toml");
    let robot_port_setting = format!("robot.port={robot_port}");
    let _robotd = common::start_robotd(
        &namespace,
        http,
        &[
            "--config",
            config,
            "--set",
            "robot.host=127.0.0.1",
            "--set",
            &robot_port_setting,
        ],
    );
    let health = || -> serde_json::Value {
        serde_json::from_str(&common::http_get(http, "/health").1).expect("health JSON")
    };
    let down = health();
    assert_eq!(down["status"], "degraded", "{down}");
    assert_eq!(down["robot"]["connected"], false, "{down}");
    assert_eq!(down["robot"]["available"], false, "{down}");
    let reason = down["robot"]["reason"].as_str().unwrap();
    assert!(
        reason.starts_with("robot not connected: cannot connect to 127.0.0.1:"),
        "{reason}"
    );

    // The robot appears on its port: robotd connects by itself (backoff ≤ 2 s).
    let (_fake, _) = common::start_fake_niryo(
        &["--set", "robot.time_scale=0.05"],
        &["--listen", &format!("127.0.0.1:{robot_port}")],
    );
    let started = std::time::Instant::now();
    loop {
        let up = health();
        if up["robot"]["connected"] == true {
            assert_eq!(up["robot"]["available"], true, "{up}");
            break;
        }
        assert!(
            started.elapsed() < std::time::Duration::from_secs(5),
            "not reconnected: {up}"
        );
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
}

#[test]
fn bench_niryo_json_reports_every_figure() {
    let output = std::process::Command::new(env!("CARGO_BIN_EXE_robotd"))
        .args([
            "bench",
            "niryo",
            "--json",
            "--round-trips",
            "50",
            "--images",
            "5",
            "--scenes",
            "3",
        ])
        .output()
        .expect("run robotd bench niryo");
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let figures: serde_json::Value = serde_json::from_slice(&output.stdout).expect("JSON");
    for key in [
        "ratio_p50",
        "camera_fps",
        "decode_ms_p50",
        "jpeg_recall",
        "jpeg_pos_err_p95_mm",
        "raw_recall",
        "jpeg_to_objects_ms_p50",
    ] {
        let value = figures[key].as_f64().unwrap_or(f64::NAN);
        assert!(value.is_finite() && value > 0.0, "{key}: {figures}");
    }
    assert!(figures["command"]["p50_us"].as_f64().unwrap() > 0.0);
    assert!(figures["objects"].as_u64().unwrap() >= 3);
}
