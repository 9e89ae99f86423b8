//! `robotd commission` without `--yes`: before a step that moves the arm it says what will move
//! and waits for the operator at the terminal. A "no" (or anything but yes) moves nothing and
//! the step is reported as declined; a "yes" runs it; with no terminal at all it refuses
//! rather than move unattended. The terminal is a real pseudo-terminal (Python's `pty.spawn`,
//! which gives the child a terminal and relays what the test writes to it).

mod common;

use serde_json::Value;
use std::io::Write;
use std::process::{Command, Stdio};

/// Runs `robotd commission --only stopping --json` on the simulator inside a pseudo-terminal,
/// typing `answer`; the exit code, everything the terminal showed, and the JSON report.
fn commission_at_a_terminal(answer: &str) -> (Option<i32>, String, Value) {
    let logs = tempfile::tempdir().unwrap();
    let log_dir = format!("telemetry.log_dir={}", logs.path().display());
    let namespace = common::fresh_namespace("commission-pty");
    let mut child = Command::new(common::python())
        .arg("-c")
        .arg("import os, pty, sys; sys.exit(os.waitstatus_to_exitcode(pty.spawn(sys.argv[1:])))")
        .arg(env!("CARGO_BIN_EXE_robotd"))
        .args(["--namespace", &namespace, "--set", &log_dir])
        .args(["commission", "--only", "stopping", "--json"])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("python3 with its pty module");
    child
        .stdin
        .take()
        .unwrap()
        .write_all(answer.as_bytes())
        .unwrap();
    let output = child.wait_with_output().unwrap();
    let shown = String::from_utf8_lossy(&output.stdout).replace('\r', "");
    let json_at = shown
        .find("{\n")
        .unwrap_or_else(|| panic!("no report on the terminal: {shown}"));
    let report: Value = serde_json::from_str(&shown[json_at..])
        .unwrap_or_else(|e| panic!("not a JSON report ({e}): {shown}"));
    (output.status.code(), shown, report)
}

fn the_step(report: &Value) -> &Value {
    let steps = report["steps"].as_array().expect("steps");
    assert_eq!(steps.len(), 1, "{report:#}");
    assert_eq!(steps[0]["step"], "stopping", "{report:#}");
    &steps[0]
}

#[test]
fn a_no_at_the_prompt_moves_nothing() {
    let (code, shown, report) = commission_at_a_terminal("n\n");
    assert!(
        shown.contains("the arm swings the tool") && shown.contains("Go ahead? [y/N]"),
        "the step is explained and asked for: {shown}"
    );
    let step = the_step(&report);
    assert_eq!(step["status"], "failed", "{report:#}");
    assert_eq!(step["reason"], "the operator declined; nothing moved");
    assert!(step.get("measured").is_none(), "{report:#}");
    assert_eq!(code, Some(1), "a declined step is not a commissioned robot");
}

#[test]
fn a_yes_at_the_prompt_runs_the_step() {
    let (code, shown, report) = commission_at_a_terminal("y\n");
    let step = the_step(&report);
    assert_eq!(step["status"], "ok", "{shown}");
    assert_eq!(step["measured"]["trials"], 3, "{report:#}");
    assert_eq!(code, Some(0), "{shown}");
}

#[test]
fn without_a_terminal_and_without_yes_nothing_moves() {
    let logs = tempfile::tempdir().unwrap();
    let output = Command::new(env!("CARGO_BIN_EXE_robotd"))
        .args(["--namespace", &common::fresh_namespace("commission-nopty")])
        .arg("--set")
        .arg(format!("telemetry.log_dir={}", logs.path().display()))
        .args(["commission", "--only", "stopping", "--json"])
        .stdin(Stdio::null())
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_ne!(output.status.code(), Some(0), "{stderr}");
    assert!(
        stderr.contains("nobody is at the terminal to agree: run with --yes"),
        "{stderr}"
    );
}
