//! The MCP call log: one JSON line per tool call in `log/mcp_server_YYYYmmdd_HHMMSS.log`.
//!
//! The Python server wrote such a file per run, and labs read it to see what an LLM did to
//! their robot; robotd keeps the file name and writes one JSON object per line: time (UTC),
//! transport, tool, arguments, result text, status (`ok`, `failed`, `protocol_error`),
//! duration and the call's trace id (the actors' spans of the call carry the same trace, so a
//! log line leads to its trace on a dashboard). A log that cannot be written is reported once and the calls go on.
//!
//! The log is bounded ([`CallLogLimits`], from `[mcp]`): an `arguments` or `result` longer
//! than `max_field_bytes` is cut there (the line says which fields were cut and their full
//! sizes), and the file rotates at `max_file_bytes`, keeping `keep_files` old ones
//! (`….log.1` is the newest). Each run starts a file of its own; when it does, the files of
//! earlier runs (rotated ones included) beyond the newest `keep_files` are deleted, so the
//! directory holds at most `2 × keep_files + 1` call-log files of `max_file_bytes` each.

use robotd_runtime::telemetry::rotating::RotatingFile;
use serde_json::{json, Map, Value};
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::time::{Duration, SystemTime, UNIX_EPOCH};

/// One tool call, as the call log writes it.
#[derive(Debug, Clone, Copy)]
pub struct CallRecord<'a> {
    /// `sse`, `streamable_http` or `stdio`.
    pub transport: &'a str,
    /// The tool's name.
    pub tool: &'a str,
    /// The arguments as sent.
    pub arguments: Option<&'a Map<String, Value>>,
    /// The reply text.
    pub result: &'a str,
    /// `ok`, `failed` or `protocol_error`.
    pub status: &'a str,
    /// How long the call took.
    pub duration: Duration,
    /// The call's trace id (32 hex digits), when tracing is on.
    pub trace_id: Option<&'a str>,
}

/// How large the call log may grow.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CallLogLimits {
    /// Longest `arguments` (as JSON) or `result` written, bytes; longer ones are cut.
    pub max_field_bytes: usize,
    /// Size at which the file rotates, bytes.
    pub max_file_bytes: u64,
    /// Rotated files kept.
    pub keep_files: u32,
}

impl Default for CallLogLimits {
    fn default() -> Self {
        Self {
            max_field_bytes: 16 * 1024,
            max_file_bytes: 64 * 1024 * 1024,
            keep_files: 5,
        }
    }
}

/// The call log of one robotd run.
#[derive(Debug)]
pub struct CallLog {
    path: Option<PathBuf>,
    file: Mutex<Option<RotatingFile>>,
    max_field_bytes: usize,
}

/// `text` cut to at most `max` bytes (at a character boundary), and whether it was cut.
fn cut(text: &str, max: usize) -> (&str, bool) {
    if text.len() <= max {
        return (text, false);
    }
    let mut end = max;
    while !text.is_char_boundary(end) {
        end -= 1;
    }
    (&text[..end], true)
}

fn now_s() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map(|d| d.as_secs())
        .unwrap_or(0)
}

pub use robotd_runtime::telemetry::{file_stamp, utc_fields};

fn iso_time(unix: Duration) -> String {
    let (y, mo, d, h, mi, s) = utc_fields(unix.as_secs());
    format!(
        "{y:04}-{mo:02}-{d:02}T{h:02}:{mi:02}:{s:02}.{:03}Z",
        unix.subsec_millis()
    )
}

impl CallLog {
    /// Opens `<dir>/mcp_server_<YYYYmmdd_HHMMSS>.log`, creating `dir`. On failure the log is
    /// off and the error is returned alongside, for the caller to report.
    pub fn open(dir: &Path, limits: CallLogLimits) -> (Self, Option<std::io::Error>) {
        let path = dir.join(format!("mcp_server_{}.log", file_stamp(now_s())));
        robotd_runtime::telemetry::retention::keep_newest(
            dir,
            |name| name.starts_with("mcp_server_") && name.contains(".log"),
            limits.keep_files as usize,
        );
        let opened = std::fs::create_dir_all(dir)
            .and_then(|_| RotatingFile::open(&path, limits.max_file_bytes, limits.keep_files));
        match opened {
            Ok(file) => (
                Self {
                    path: Some(path),
                    file: Mutex::new(Some(file)),
                    max_field_bytes: limits.max_field_bytes,
                },
                None,
            ),
            Err(error) => (Self::disabled(), Some(error)),
        }
    }

    /// A log that writes nothing.
    pub fn disabled() -> Self {
        Self {
            path: None,
            file: Mutex::new(None),
            max_field_bytes: 0,
        }
    }

    /// Where the log is written, if anywhere.
    pub fn path(&self) -> Option<&Path> {
        self.path.as_deref()
    }

    /// Records one call.
    pub fn record(&self, call: &CallRecord<'_>) {
        let CallRecord {
            transport,
            tool,
            arguments,
            result,
            status,
            duration,
            trace_id,
        } = *call;
        robotd_runtime::metrics::Metrics::global().tool_call(transport, status);
        // Debug, not info: this file is the record of every call. An info line per call in
        // the service log repeated it and woke the log writer's thread on every call.
        tracing::debug!(
            target: "robotd::mcp::calls",
            transport,
            tool,
            status,
            duration_ms = duration.as_secs_f64() * 1000.0,
            "tool call"
        );
        let mut guard = self.file.lock().unwrap_or_else(|e| e.into_inner());
        let Some(file) = guard.as_mut() else {
            return;
        };
        let now = SystemTime::now()
            .duration_since(UNIX_EPOCH)
            .unwrap_or_default();
        let mut line = json!({
            "time": iso_time(now),
            "transport": transport,
            "tool": tool,
            "arguments": arguments,
            "result": result,
            "status": status,
            "duration_ms": (duration.as_secs_f64() * 1e6).round() / 1e3,
            "trace_id": trace_id,
        });
        let max = self.max_field_bytes;
        let mut cut_fields = Map::new();
        let arguments_json = arguments.map(|a| Value::Object(a.clone()).to_string());
        if let Some(text) = arguments_json.as_deref().filter(|t| t.len() > max) {
            line["arguments"] = Value::String(format!("{}…", cut(text, max).0));
            cut_fields.insert("arguments".into(), json!(text.len()));
        }
        if let (head, true) = cut(result, max) {
            line["result"] = Value::String(format!("{head}…"));
            cut_fields.insert("result".into(), json!(result.len()));
        }
        if !cut_fields.is_empty() {
            // Which fields were cut, with their full sizes in bytes.
            line["cut"] = Value::Object(cut_fields);
        }
        let mut text = line.to_string();
        text.push('\n');
        let written = file.write(text.as_bytes()).and_then(|()| file.flush());
        if let Err(error) = written {
            tracing::warn!(%error, "the MCP call log cannot be written; it is off from now on");
            *guard = None;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dates_are_utc_civil_dates() {
        assert_eq!(file_stamp(0), "19700101_000000");
        // 2026-11-23 04:10:05 UTC
        assert_eq!(file_stamp(1_795_407_005), "20261123_041005");
        // A leap day.
        assert_eq!(file_stamp(1_709_164_800), "20240229_000000");
    }

    #[test]
    fn calls_are_json_lines() {
        let dir = std::env::temp_dir().join(format!("robotd-calllog-{}", std::process::id()));
        let (log, error) = CallLog::open(&dir, CallLogLimits::default());
        assert!(error.is_none());
        let args = serde_json::json!({"text": "hi"});
        log.record(&CallRecord {
            transport: "sse",
            tool: "speak",
            arguments: args.as_object(),
            result: "✓ Speaking: 'hi'",
            status: "ok",
            duration: Duration::from_micros(1500),
            trace_id: Some("4bf92f3577b34da6a3ce929d0e0e4736"),
        });
        let text = std::fs::read_to_string(log.path().unwrap()).unwrap();
        let line: Value = serde_json::from_str(text.trim()).unwrap();
        assert_eq!(line["tool"], "speak");
        assert_eq!(line["arguments"]["text"], "hi");
        assert_eq!(line["duration_ms"], 1.5);
        assert_eq!(line["trace_id"], "4bf92f3577b34da6a3ce929d0e0e4736");
        let name = log
            .path()
            .unwrap()
            .file_name()
            .unwrap()
            .to_string_lossy()
            .to_string();
        assert!(
            name.starts_with("mcp_server_") && name.ends_with(".log"),
            "{name}"
        );
        std::fs::remove_dir_all(dir).ok();
    }

    #[test]
    fn long_fields_are_cut_and_the_file_rotates() {
        let dir = tempfile::tempdir().unwrap();
        let limits = CallLogLimits {
            max_field_bytes: 100,
            max_file_bytes: 2_000,
            keep_files: 2,
        };
        let (log, error) = CallLog::open(dir.path(), limits);
        assert!(error.is_none());
        let args = serde_json::json!({"object_name": "é".repeat(300)});
        let result = "x".repeat(5_000);
        for _ in 0..10 {
            log.record(&CallRecord {
                transport: "sse",
                tool: "add_object_name2object_labels",
                arguments: args.as_object(),
                result: &result,
                status: "ok",
                duration: Duration::from_millis(1),
                trace_id: None,
            });
        }
        let path = log.path().unwrap();
        let text = std::fs::read_to_string(path).unwrap();
        let line: Value = serde_json::from_str(text.lines().next().unwrap()).unwrap();
        assert!(line["result"].as_str().unwrap().len() <= 100 + "…".len());
        assert!(line["arguments"].as_str().unwrap().len() <= 100 + "…".len());
        assert_eq!(line["cut"]["result"], 5_000);
        assert_eq!(line["cut"]["arguments"], 618);
        let names: Vec<String> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        assert_eq!(names.len(), 3, "the file and two rotated ones: {names:?}");
        for file in std::fs::read_dir(dir.path()).unwrap() {
            let size = file.unwrap().metadata().unwrap().len();
            assert!(size <= 2_000, "{size}");
        }
    }

    #[test]
    fn a_new_run_deletes_earlier_runs_files_beyond_keep_files() {
        let dir = tempfile::tempdir().unwrap();
        let now = SystemTime::now();
        // Forty earlier runs, some rotated, and a file that is not the call log's.
        for run in 0..40u64 {
            let stamp = 20_260_101_000_000 + run;
            for name in [
                format!("mcp_server_{stamp}.log"),
                format!("mcp_server_{stamp}.log.1"),
            ] {
                let file = std::fs::File::create(dir.path().join(name)).unwrap();
                file.set_modified(now - Duration::from_secs(3_600 * (41 - run)))
                    .unwrap();
            }
        }
        std::fs::write(dir.path().join("robotd.2026-01-01.log"), "kept").unwrap();
        let limits = CallLogLimits {
            keep_files: 3,
            ..CallLogLimits::default()
        };
        let (log, error) = CallLog::open(dir.path(), limits);
        assert!(error.is_none());
        let mut names: Vec<String> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        let current = log.path().unwrap().file_name().unwrap().to_string_lossy();
        assert!(names.contains(&current.to_string()));
        assert!(names.contains(&"robotd.2026-01-01.log".to_owned()));
        let earlier: Vec<&String> = names
            .iter()
            .filter(|n| n.starts_with("mcp_server_") && **n != current)
            .collect();
        assert_eq!(earlier.len(), 3, "the newest three: {names:?}");
        assert!(
            earlier
                .iter()
                .all(|n| n.contains("000039.log") || n.contains("000038.log")),
            "{earlier:?}"
        );
    }
}
