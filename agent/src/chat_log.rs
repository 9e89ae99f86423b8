//! The log of a chat session: `<dir>/mcp_client_YYYYmmdd_HHMMSS.log` (UTC), as the Python
//! client names it, with every LLM call, tool call and result at `info`; the terminal gets
//! warnings only, so the conversation itself stays readable.

use std::path::{Path, PathBuf};
use tracing_subscriber::layer::SubscriberExt;
use tracing_subscriber::util::SubscriberInitExt;
use tracing_subscriber::{EnvFilter, Layer};

/// Keeps the log file flushed; drop it when the session ends.
pub struct ChatLog {
    path: PathBuf,
    _guard: tracing_appender::non_blocking::WorkerGuard,
}

impl ChatLog {
    /// The log file.
    pub fn path(&self) -> &Path {
        &self.path
    }
}

/// `YYYYmmdd_HHMMSS` of a Unix time (UTC).
pub use robotd_runtime::telemetry::file_stamp as timestamp;

/// Why the log could not be set up.
#[derive(Debug, thiserror::Error)]
pub enum ChatLogError {
    /// The directory cannot be created or written.
    #[error("cannot write the chat log in {}: {source}; set telemetry.log_dir to a writable directory", dir.display())]
    Dir {
        /// The directory.
        dir: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// A subscriber is already installed.
    #[error("logging is already set up in this process")]
    AlreadySet,
}

/// Installs the process's tracing subscriber: `info` (or `RUST_LOG`) into the session's log
/// file in `dir`, warnings on stderr.
pub fn init(dir: &Path) -> Result<ChatLog, ChatLogError> {
    std::fs::create_dir_all(dir).map_err(|source| ChatLogError::Dir {
        dir: dir.to_owned(),
        source,
    })?;
    let now = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_secs())
        .unwrap_or(0);
    let name = format!("mcp_client_{}.log", timestamp(now));
    let path = dir.join(&name);
    let file = std::fs::OpenOptions::new()
        .create(true)
        .append(true)
        .open(&path)
        .map_err(|source| ChatLogError::Dir {
            dir: dir.to_owned(),
            source,
        })?;
    let (writer, guard) = tracing_appender::non_blocking(file);
    let file_filter = EnvFilter::try_from_default_env().unwrap_or_else(|_| EnvFilter::new("info"));
    tracing_subscriber::registry()
        .with(
            tracing_subscriber::fmt::layer()
                .with_writer(writer)
                .with_ansi(false)
                .with_filter(file_filter),
        )
        .with(
            tracing_subscriber::fmt::layer()
                .with_writer(std::io::stderr)
                .with_filter(EnvFilter::new("warn")),
        )
        .try_init()
        .map_err(|_| ChatLogError::AlreadySet)?;
    Ok(ChatLog {
        path,
        _guard: guard,
    })
}

#[cfg(test)]
mod tests {
    #[test]
    fn timestamps_are_civil_utc() {
        assert_eq!(super::timestamp(0), "19700101_000000");
        // 2026-11-24 05:21:28 UTC
        assert_eq!(super::timestamp(1_795_497_688), "20261124_052128");
        // A leap day.
        assert_eq!(super::timestamp(951_782_400 + 3661), "20000229_010101");
    }
}
