//! What the `robotd commission` tests share: running it, reading its JSON report.

#![allow(dead_code)] // each test file uses a part

use robotd_kinematics::CameraMount;
use serde_json::Value;
use std::process::Command;

/// Runs `robotd commission --yes --json` with the global `settings` and `args`.
pub fn run(settings: &[&str], args: &[&str]) -> std::process::Output {
    let logs = tempfile::tempdir().unwrap();
    Command::new(env!("CARGO_BIN_EXE_robotd"))
        .arg("--set")
        .arg(format!("telemetry.log_dir={}", logs.path().display()))
        .args(settings)
        .args(["commission", "--yes", "--json"])
        .args(args)
        .output()
        .unwrap()
}

/// Runs `robotd commission` with `settings` and `args`: its exit code, JSON report and
/// stderr.
pub fn commission(settings: &[&str], args: &[&str]) -> (Option<i32>, Value, String) {
    let output = run(settings, args);
    let stdout = String::from_utf8_lossy(&output.stdout);
    let stderr = String::from_utf8_lossy(&output.stderr).into_owned();
    let report = serde_json::from_str(&stdout)
        .unwrap_or_else(|e| panic!("not a JSON report ({e}): {stdout}\nstderr: {stderr}"));
    (output.status.code(), report, stderr)
}

/// The step `name` of a report.
pub fn step<'a>(report: &'a Value, name: &str) -> &'a Value {
    report["steps"]
        .as_array()
        .and_then(|steps| steps.iter().find(|s| s["step"] == name))
        .unwrap_or_else(|| panic!("no {name} step in {report:#}"))
}

/// The camera step's measured mount's distance (mm) and angle (°) from `truth`.
pub fn error_of(camera: &Value, truth: &CameraMount) -> (f64, f64) {
    let values: Vec<f64> = camera["measured"]["mount"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    let measured = CameraMount::from_xyz_rpy_deg(values.try_into().unwrap()).unwrap();
    let (m, deg) = truth.difference(&measured);
    (m * 1000.0, deg)
}

/// The settings that commission a fake Ned2 listening on `port` with `config/niryo.toml` on
/// bus `namespace`, then `extra` (`--set` pairs and the like).
pub fn ned2_settings(namespace: &str, port: u16, extra: &[&str]) -> Vec<String> {
    let mut settings: Vec<String> = [
        "--namespace",
        namespace,
        "--config",
        concat!(env!("CARGO_MANIFEST_DIR"), "/config/niryo.toml"),
        "--set",
        "robot.host=127.0.0.1",
        "--set",
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    settings.push(format!("robot.port={port}"));
    settings.extend(extra.iter().map(|s| s.to_string()));
    settings
}

/// `strings` as the `&str`s the functions above take.
pub fn strs(strings: &[String]) -> Vec<&str> {
    strings.iter().map(String::as_str).collect()
}
