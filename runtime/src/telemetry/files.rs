//! robotd's log files: the service's daily rolling file, one file per chat session, and the
//! UTC stamps in their names.

use super::TelemetryError;
use crate::config::TelemetryConfig;
use std::path::PathBuf;
use tracing_appender::non_blocking::WorkerGuard;

/// Log lines queued for the writer thread before new ones are dropped (and counted as lost by
/// tracing-appender). tracing-appender's default of 128,000 reserves 4 MB at start; a disk
/// that takes more than 8,192 lines behind is a problem the dropped lines will not fix.
const QUEUED_LOG_LINES: usize = 8_192;

/// The daily rolling file, behind a non-blocking writer thread.
pub(super) fn log_file_writer(
    config: &TelemetryConfig,
) -> Result<(tracing_appender::non_blocking::NonBlocking, WorkerGuard), TelemetryError> {
    let dir = &config.log_dir;
    let fail = |source: Box<dyn std::error::Error + Send + Sync>| TelemetryError::LogFile {
        path: dir.clone(),
        source,
    };
    std::fs::create_dir_all(dir).map_err(|e| fail(Box::new(e)))?;
    let appender = tracing_appender::rolling::Builder::new()
        .rotation(tracing_appender::rolling::Rotation::DAILY)
        .max_log_files(config.keep_log_days.max(1))
        .filename_prefix(file_prefix(config.service_name()))
        .filename_suffix("log")
        .build(dir)
        .map_err(|e| fail(Box::new(e)))?;
    Ok(
        tracing_appender::non_blocking::NonBlockingBuilder::default()
            .thread_name("robotd-log-writer")
            .buffered_lines_limit(QUEUED_LOG_LINES)
            .finish(appender),
    )
}

/// A new file `<log_dir>/mcp_client_<UTC stamp>.log` for one session.
pub(super) fn session_file_writer(
    config: &TelemetryConfig,
) -> Result<
    (
        tracing_appender::non_blocking::NonBlocking,
        WorkerGuard,
        PathBuf,
    ),
    TelemetryError,
> {
    let dir = &config.log_dir;
    let fail = |source: Box<dyn std::error::Error + Send + Sync>| TelemetryError::LogFile {
        path: dir.clone(),
        source,
    };
    std::fs::create_dir_all(dir).map_err(|e| fail(Box::new(e)))?;
    let now = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_secs())
        .unwrap_or(0);
    // Each session writes a file of its own: those older than keep_log_days go.
    super::retention::remove_older_than(
        dir,
        |name| name.starts_with("mcp_client_") && name.ends_with(".log"),
        std::time::Duration::from_secs(86_400 * config.keep_log_days.max(1) as u64),
        std::time::SystemTime::now(),
    );
    let path = dir.join(format!("mcp_client_{}.log", file_stamp(now)));
    let file = std::fs::OpenOptions::new()
        .create(true)
        .append(true)
        .open(&path)
        .map_err(|e| fail(Box::new(e)))?;
    let (writer, guard) = tracing_appender::non_blocking::NonBlockingBuilder::default()
        .thread_name("robotd-log-writer")
        .buffered_lines_limit(QUEUED_LOG_LINES)
        .finish(file);
    Ok((writer, guard, path))
}

/// The service name with anything but `[A-Za-z0-9._-]` replaced, fit for a file name.
pub(super) fn file_prefix(service_name: &str) -> String {
    let prefix: String = service_name
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || matches!(c, '.' | '_' | '-') {
                c
            } else {
                '_'
            }
        })
        .collect();
    if prefix.is_empty() || prefix.starts_with('.') {
        format!("robotd{prefix}")
    } else {
        prefix
    }
}

/// `(year, month, day, hour, minute, second)` in UTC of a Unix time in seconds, for the names
/// and lines of robotd's log files (times past the year 9999 read as 9999-12-31 23:59:59).
pub fn utc_fields(unix_s: u64) -> (i32, u8, u8, u8, u8, u8) {
    let at = i64::try_from(unix_s)
        .ok()
        .and_then(|s| time::OffsetDateTime::from_unix_timestamp(s).ok())
        .unwrap_or_else(|| time::PrimitiveDateTime::MAX.assume_utc());
    (
        at.year(),
        u8::from(at.month()),
        at.day(),
        at.hour(),
        at.minute(),
        at.second(),
    )
}

/// `YYYYmmdd_HHMMSS` (UTC) of a Unix time: the stamp in log file names.
pub fn file_stamp(unix_s: u64) -> String {
    let (y, mo, d, h, mi, s) = utc_fields(unix_s);
    format!("{y:04}{mo:02}{d:02}_{h:02}{mi:02}{s:02}")
}
