//! One trace across processes: a span started at an edge in one process continues in the
//! robotd process that serves its bus request, and the reply carries that continuation back.

mod common;

use robotd_config::Config;
use robotd_protocol::diagnostics::Ping;
use robotd_runtime::bus::{Bus, BusOptions};
use robotd_runtime::telemetry::{self, current_trace_context, Mode};
use robotd_topics::SYSTEM_PING;
use std::time::Duration;
use tracing::Instrument;

/// (trace id, span id) of a W3C traceparent `00-<trace>-<span>-<flags>`.
fn ids(traceparent: &str) -> (String, String) {
    let parts: Vec<&str> = traceparent.split('-').collect();
    assert_eq!(parts.len(), 4, "traceparent {traceparent}");
    (parts[1].to_owned(), parts[2].to_owned())
}

#[test]
fn robotd_continues_the_callers_trace_and_answers_from_its_own_span() {
    let namespace = common::fresh_namespace("trace");
    let port = common::free_port();
    let robotd = common::start_robotd(&namespace, port, &[]);

    let (dispatch, _guard) =
        telemetry::build(&Config::default().telemetry, Mode::Command).expect("telemetry");
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .unwrap();
    tracing::dispatcher::with_default(&dispatch, || {
        runtime.block_on(async {
            let bus = Bus::open(BusOptions::new(&namespace, "edge")).unwrap();
            let system = bus.client(&SYSTEM_PING).unwrap();
            assert!(system.wait_for_server(Duration::from_secs(10)).await);

            let span = tracing::info_span!("edge.call");
            let ours = span.in_scope(current_trace_context);
            let ours = ours.traceparent.expect("the edge span has a trace context");
            let reply = system
                .request_envelope(
                    &Ping {
                        seq: 1,
                        payload: Vec::new(),
                    },
                    Duration::from_secs(5),
                )
                .instrument(span)
                .await
                .unwrap();
            assert_eq!(reply.body.served_by_pid, robotd.pid());

            let theirs = reply
                .trace
                .traceparent
                .expect("robotd's reply carries its span's trace context");
            let (our_trace, our_span) = ids(&ours);
            let (their_trace, their_span) = ids(&theirs);
            assert_eq!(
                their_trace, our_trace,
                "robotd continued the caller's trace"
            );
            assert_ne!(their_span, our_span, "from a span of its own");
        })
    });
}

/// A tool argument with a line break and a terminal escape lands in robotd's log (a skill's
/// error names the object it could not find) as one escaped line: it cannot forge a line.
#[test]
fn tool_arguments_cannot_forge_log_lines() {
    let logs = tempfile::tempdir().unwrap();
    let log_setting = format!("telemetry.log_dir={}", logs.path().display());
    let port = common::free_port();
    let _robotd = common::start_robotd(
        &common::fresh_namespace("logs"),
        port,
        &["--set", &log_setting, "--set", "robot.time_scale=0.05"],
    );
    let tag = format!("t{}", std::process::id());
    let name = format!("ghost\nERROR robotd: forged {tag}\x1b[2J");
    let output = std::process::Command::new(env!("CARGO_BIN_EXE_robotd"))
        .args(["call", "pick_object", "--url"])
        .arg(format!("http://127.0.0.1:{port}/mcp"))
        .arg("--arg")
        .arg(format!("object_name={name}"))
        .args(["--arg", "pick_coordinate=[0.25,0.0]"])
        .output()
        .unwrap();
    assert_eq!(
        output.status.code(),
        Some(1),
        "the pick must fail: {output:?}"
    );
    let deadline = std::time::Instant::now() + Duration::from_secs(5);
    let text = loop {
        let mut text = String::new();
        for entry in std::fs::read_dir(logs.path()).unwrap().flatten() {
            if entry.file_name().to_string_lossy().starts_with("robotd") {
                text += &std::fs::read_to_string(entry.path()).unwrap_or_default();
            }
        }
        if text.contains(&tag) || std::time::Instant::now() > deadline {
            break text;
        }
        std::thread::sleep(Duration::from_millis(50));
    };
    assert!(
        text.contains(&format!("ghost\\nERROR robotd: forged {tag}\\x1b[2J")),
        "the name is logged, escaped: {text}"
    );
    assert!(
        !text.lines().any(|l| l.starts_with("ERROR robotd: forged")),
        "a forged line: {text}"
    );
    assert!(!text.contains('\x1b'), "a raw escape in the log");
}

/// A 60 KB tool argument leaves bounded lines: the service log cuts the event at
/// `telemetry.max_event_bytes`, the call log cuts the field at `mcp.call_log_max_field_bytes`.
#[test]
fn long_tool_arguments_make_bounded_log_lines() {
    let logs = tempfile::tempdir().unwrap();
    let log_setting = format!("telemetry.log_dir={}", logs.path().display());
    let port = common::free_port();
    let _robotd = common::start_robotd(
        &common::fresh_namespace("longlog"),
        port,
        &[
            "--set",
            &log_setting,
            "--set",
            "robot.time_scale=0.05",
            "--set",
            "telemetry.max_event_bytes=1024",
            "--set",
            "mcp.call_log_max_field_bytes=512",
            // Without a speech engine the text is logged instead of spoken: a long event.
            "--set",
            "tts.engine=none",
        ],
    );
    // The longest string a tool takes (its schema's maxLength: 2000 for `speak`); longer
    // ones are refused before anything logs them.
    let tag = format!("long{}", std::process::id());
    let text = format!("{tag}{}", "x".repeat(1_990 - tag.len()));
    let output = std::process::Command::new(env!("CARGO_BIN_EXE_robotd"))
        .args(["call", "speak", "--url"])
        .arg(format!("http://127.0.0.1:{port}/mcp"))
        .arg("--arg")
        .arg(format!("text={text}"))
        .output()
        .unwrap();
    assert_eq!(output.status.code(), Some(0), "{output:?}");
    let read = |prefix: &str| {
        let mut text = String::new();
        for entry in std::fs::read_dir(logs.path()).unwrap().flatten() {
            if entry.file_name().to_string_lossy().starts_with(prefix) {
                text += &std::fs::read_to_string(entry.path()).unwrap_or_default();
            }
        }
        text
    };
    let deadline = std::time::Instant::now() + Duration::from_secs(5);
    let (service, calls) = loop {
        let (service, calls) = (read("robotd"), read("mcp_server"));
        let done = service.contains("bytes cut]") && calls.contains(&tag);
        if done || std::time::Instant::now() > deadline {
            break (service, calls);
        }
        std::thread::sleep(Duration::from_millis(50));
    };
    assert!(service.contains(&tag), "the event is logged");
    assert!(service.contains("bytes cut]"), "the long event is cut");
    let longest = service.lines().map(str::len).max().unwrap_or(0);
    assert!(
        longest <= 1024 + 32,
        "a service log line of {longest} bytes"
    );
    let call: serde_json::Value = serde_json::from_str(
        calls
            .lines()
            .find(|l| l.contains(&tag))
            .expect("the call is logged"),
    )
    .unwrap();
    assert!(call["arguments"].as_str().unwrap().len() <= 512 + 3);
    assert!(call["cut"]["arguments"].as_u64().unwrap() > 1_990, "{call}");
}
