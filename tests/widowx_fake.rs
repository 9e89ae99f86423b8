//! `robotd fake-widowx` against ROBOTIS's own client: dynamixel-sdk 4.1.0 (in the test venv)
//! pings the nine servos, reads and writes the control-table items robotd uses, sync-reads and
//! sync-writes and moves a joint — so the fake, which the widowx driver's tests and the
//! scenarios run against, speaks what the servos speak. And `robotd serve` with the widowx
//! driver starts without the arm, says why, and finds it when it appears.

mod common;

use std::time::{Duration, Instant};

#[test]
fn dynamixel_sdk_drives_the_fake_servo_bus() {
    let dir = tempfile::tempdir().unwrap();
    let device = dir.path().join("ttyDXL");
    let (_fake, camera_url) = common::start_fake_widowx(&[], &device, &[]);
    assert!(camera_url.ends_with("/stream.mjpg"), "{camera_url}");
    let seen = common::run_python_json("dynamixel_sdk_session.py", &[device.display().to_string()]);
    for id in 1..=9 {
        let model = seen["models"][id.to_string()].as_u64().unwrap();
        assert!(model == 1020 || model == 1060, "servo {id}: {seen}");
    }
    assert!(
        seen["ping_42"]
            .as_str()
            .unwrap()
            .contains("no status packet"),
        "{seen}"
    );
    assert_eq!(seen["gripper_mode"], 3, "factory position mode: {seen}");
    assert_eq!(seen["shadow_secondary_id"], 255, "{seen}");
    assert!(
        seen["eeprom_with_torque_on"]
            .as_str()
            .unwrap()
            .contains("not available"),
        "{seen}"
    );
    assert_eq!(seen["eeprom_with_torque_off"], 0, "{seen}");
    assert!(
        seen["goal_out_of_limits"]
            .as_str()
            .unwrap()
            .contains("exceeds the limit"),
        "{seen}"
    );
    // The session waits until the waist is within one tick of its goal (it settles there).
    let start = seen["waist_start"].as_i64().unwrap();
    let reached = seen["waist_after_goal"].as_i64().unwrap();
    assert!((reached - (start + 200)).abs() <= 1, "{seen}");
    let sync = &seen["sync_read"];
    assert_eq!(sync["6"], 2148, "{seen}");
    assert_eq!(sync["8"], 1948, "{seen}");
    assert_eq!(
        sync["3"], sync["2"],
        "the shadow reports its master's position: {seen}"
    );
    assert_eq!(sync.as_object().unwrap().len(), 9, "{seen}");
    assert_eq!(seen["hardware_error_status"], 0, "{seen}");
    assert!(
        seen["reboot"].as_str().unwrap().contains("success"),
        "{seen}"
    );
}

#[test]
fn serve_without_the_arm_says_why_and_picks_it_up_when_it_appears() {
    let dir = tempfile::tempdir().unwrap();
    let device = dir.path().join("ttyDXL");
    let namespace = common::fresh_namespace("wxs");
    let port = common::free_port();
    let config = concat!(env!("CARGO_MANIFEST_DIR"), "/config/widowx.toml");
    let device_setting = format!("robot.widowx.device={}", device.display());
    let _robotd = common::start_robotd(
        &namespace,
        port,
        &["--config", config, "--set", &device_setting],
    );
    let (_, health) = common::http_get(port, "/health");
    let health: serde_json::Value = serde_json::from_str(&health).unwrap();
    assert_eq!(health["robot"]["connected"], false, "{health}");
    let reason = health["robot"]["reason"].as_str().unwrap_or_default();
    assert!(
        reason.contains("not found") && reason.contains("U2D2"),
        "{health}"
    );
    let (_fake, _) = common::start_fake_widowx(&[], &device, &[]);
    let deadline = Instant::now() + Duration::from_secs(10);
    loop {
        let (_, health) = common::http_get(port, "/health");
        let health: serde_json::Value = serde_json::from_str(&health).unwrap();
        if health["robot"]["connected"] == true {
            break;
        }
        assert!(Instant::now() < deadline, "never connected: {health}");
        std::thread::sleep(Duration::from_millis(50));
    }
}

#[test]
fn bench_widowx_json_reports_every_figure() {
    let output = std::process::Command::new(env!("CARGO_BIN_EXE_robotd"))
        .args(["bench", "widowx", "--json", "--round-trips", "50"])
        .output()
        .unwrap();
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let figures: serde_json::Value = serde_json::from_slice(&output.stdout).unwrap();
    for key in ["ratio_p50", "control_rate_hz", "fault_recovery_ms"] {
        assert!(figures[key].as_f64().unwrap() > 0.0, "{key}: {figures}");
    }
    assert!(
        figures["sync_read"]["p50_us"].as_f64().unwrap() > 0.0,
        "{figures}"
    );
    assert!(figures["ticks"].as_u64().unwrap() > 50, "{figures}");
    assert!(
        figures["fault_recovery_ms"].as_f64().unwrap() < 1000.0,
        "{figures}"
    );
}

/// The `widowx` row of `robotd doctor --json` for the servo bus at `device`.
fn doctor_widowx_row(device: &std::path::Path) -> serde_json::Value {
    let output = std::process::Command::new(env!("CARGO_BIN_EXE_robotd"))
        .args([
            "--config",
            concat!(env!("CARGO_MANIFEST_DIR"), "/config/widowx.toml"),
        ])
        .arg("--set")
        .arg(format!("robot.widowx.device={}", device.display()))
        .args(["doctor", "--json"])
        .output()
        .unwrap();
    let report: serde_json::Value = serde_json::from_slice(&output.stdout).unwrap();
    report["checks"]
        .as_array()
        .unwrap()
        .iter()
        .find(|c| c["name"] == "widowx")
        .cloned()
        .unwrap_or_else(|| panic!("no widowx row: {report}"))
}

#[test]
fn doctor_checks_the_servo_bus() {
    let dir = tempfile::tempdir().unwrap();
    let device = dir.path().join("ttyDXL");
    let missing = doctor_widowx_row(&device);
    assert_eq!(missing["status"], "problem", "{missing}");
    assert!(
        missing["found"]
            .as_str()
            .unwrap()
            .contains("does not exist"),
        "{missing}"
    );
    assert!(
        missing["fix"].as_str().unwrap().contains("udev rule"),
        "{missing}"
    );
    let (_fake, _) = common::start_fake_widowx(&[], &device, &[]);
    let present = doctor_widowx_row(&device);
    assert_eq!(present["status"], "ok", "{present}");
    assert!(
        present["found"]
            .as_str()
            .unwrap()
            .starts_with("9 servos answer"),
        "{present}"
    );
}
