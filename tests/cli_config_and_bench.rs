//! The command line as a user meets it: bad configuration is refused with the place and the
//! reason, logs land in date-stamped files, and `robotd bench bus|mcp|jpeg --json` report
//! every figure.

mod common;

use std::process::Command;

#[test]
fn an_unknown_key_in_a_config_file_stops_the_start_with_file_key_and_reason() {
    let file = std::env::temp_dir().join(format!("robotd-bad-{}.toml", std::process::id()));
    std::fs::write(&file, "[http]\nbind = \"127.0.0.1:0\"\nbnid = \"oops\"\n").unwrap();
    let output = Command::new(env!("CARGO_BIN_EXE_robotd"))
        .args(["serve", "--config"])
        .arg(&file)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("bnid"), "names the key: {stderr}");
    assert!(
        stderr.contains(&file.display().to_string()),
        "names the file: {stderr}"
    );
    let _ = std::fs::remove_file(&file);
}

#[test]
fn an_invalid_value_from_the_environment_is_refused_naming_the_variable() {
    let output = Command::new(env!("CARGO_BIN_EXE_robotd"))
        .arg("serve")
        .env("ROBOTD_HTTP__BIND", "not-an-address")
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("ROBOTD_HTTP__BIND"), "{stderr}");
    assert!(stderr.contains("http.bind"), "{stderr}");
}

#[test]
fn the_service_writes_a_date_stamped_log_file() {
    let namespace = common::fresh_namespace("log");
    let port = common::free_port();
    let log_dir = std::env::temp_dir().join(format!("robotd-logs-{namespace}"));
    let robotd = common::start_robotd(
        &namespace,
        port,
        &["--set", &format!("telemetry.log_dir={}", log_dir.display())],
    );
    drop(robotd);
    let names: Vec<String> = std::fs::read_dir(&log_dir)
        .unwrap()
        .filter_map(|e| e.ok()?.file_name().into_string().ok())
        .collect();
    let stamped = names.iter().any(|n| {
        let date = n.trim_start_matches("robotd.").trim_end_matches(".log");
        n.starts_with("robotd.")
            && date.len() == 10
            && date.chars().filter(|c| *c == '-').count() == 2
    });
    assert!(stamped, "log files: {names:?}");
    let _ = std::fs::remove_dir_all(&log_dir);
}

/// Runs `robotd <args>` (a `bench … --json`) and returns its figures.
fn bench_figures(args: &[&str]) -> serde_json::Value {
    let output = Command::new(env!("CARGO_BIN_EXE_robotd"))
        .args(args)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(output.status.success(), "{stderr}");
    serde_json::from_slice(&output.stdout).unwrap()
}

/// Every figure named in `keys` is a positive, finite number.
fn assert_all_positive(figures: &serde_json::Value, keys: &[&str]) {
    for key in keys {
        let value = figures[key].as_f64().unwrap_or(f64::NAN);
        assert!(value.is_finite() && value > 0.0, "{key} = {}", figures[key]);
    }
}

#[test]
fn bench_bus_json_reports_every_figure() {
    let figures = bench_figures(&[
        "bench",
        "bus",
        "--json",
        "--round-trips",
        "200",
        "--frames",
        "200",
        "--restarts",
        "20",
    ]);
    assert_all_positive(
        &figures,
        &[
            "raw_rtt_p50_us",
            "raw_rtt_p99_us",
            "bus_rtt_p50_us",
            "bus_rtt_p99_us",
            "bus_inproc_rtt_p50_us",
            "raw_frames_per_s",
            "bus_frames_per_s",
            "restart_p50_us",
            "restart_p99_us",
        ],
    );
    assert_eq!(figures["bus_frames_lost"], 0);
    assert_eq!(figures["raw_frames_lost"], 0);
}

/// A short `robotd bench mcp` run (about 15 s).
const BENCH_MCP_QUICK: [&str; 7] = [
    "bench",
    "mcp",
    "--json",
    "--calls",
    "20",
    "--seconds",
    "0.5",
];

#[test]
fn bench_mcp_json_reports_every_figure() {
    let figures = bench_figures(&BENCH_MCP_QUICK);
    assert_eq!(figures["one_core"], false);
    assert_all_positive(
        &figures,
        &[
            "coordinate_sse_us_p50",
            "coordinate_http_us_p50",
            "coordinate_http_raw_us_p50",
            "coordinate_sse_raw_us_p50",
            "ping_http_raw_us_p50",
            "http_floor_us_p50",
            "tcp_echo_us_p50",
            "coordinate_direct_us_p50",
            "objects_http_us_p50",
            "calls_per_s_8_clients",
            "calls_per_s_64_clients",
            "service_rss_mb",
            "service_rss_after_clients_left_mb",
        ],
    );
}

#[test]
fn bench_mcp_one_core_pins_the_service_and_says_so() {
    let figures = bench_figures(&[&BENCH_MCP_QUICK[..], &["--one-core"]].concat());
    // The benchmark itself refuses to report when the service was not pinned.
    assert_eq!(figures["one_core"], true);
    assert_all_positive(
        &figures,
        &[
            "coordinate_sse_us_p50",
            "coordinate_http_raw_us_p50",
            "coordinate_direct_us_p50",
        ],
    );
}

#[test]
fn bench_jpeg_json_reports_every_figure() {
    let figures = bench_figures(&["bench", "jpeg", "--json", "--frames", "20"]);
    assert_all_positive(
        &figures,
        &[
            "encode_q85_ms_p50",
            "encode_q85_ms_p99",
            "image_crate_q85_ms_p50",
            "encode_q80_ms_p50",
            "copy_ms_p50",
            "q85_bytes",
            "image_crate_q85_bytes",
        ],
    );
    // The encoder robotd uses is the faster one (≈ 3× here; the margin allows a noisy run).
    let ours = figures["encode_q85_ms_p50"].as_f64().unwrap();
    let old = figures["image_crate_q85_ms_p50"].as_f64().unwrap();
    assert!(ours < old, "jpeg-encoder {ours} ms, image {old} ms");
}

#[test]
fn bench_safety_json_reports_stopping_per_driver() {
    let figures = bench_figures(&[
        "bench",
        "safety",
        "--json",
        "--commands",
        "20",
        "--stops",
        "1",
    ]);
    assert_all_positive(&figures, &["commands", "estop_trials"]);
    let stops = figures["stopping"].as_array().expect("stopping figures");
    let drivers: Vec<&str> = stops.iter().filter_map(|s| s["driver"].as_str()).collect();
    assert_eq!(
        drivers,
        [
            "sim",
            "fake Ned2 (TCP)",
            "fake Ned2 (TCP)",
            "fake Ned2 (TCP)",
            "fake WidowX (DYNAMIXEL)"
        ],
        "{figures}"
    );
    for stop in stops {
        // The arm was moving when the e-stop came, and stood still within the 5 s the
        // benchmark allows; a swing took time.
        assert!(stop["speed_at_stop_m_s"].as_f64().unwrap() > 0.05, "{stop}");
        assert!(stop["time_ms_max"].as_f64().unwrap() < 5000.0, "{stop}");
        assert!(stop["swing_s"].as_f64().unwrap() > 0.05, "{stop}");
        assert_eq!(stop["joint_rad_max"].as_array().unwrap().len(), 6, "{stop}");
    }
    // The Ned2 stops only between segments: it travels after the e-stop.
    assert!(
        stops[2]["distance_mm_max"].as_f64().unwrap() > 0.5,
        "{}",
        stops[2]
    );
}
