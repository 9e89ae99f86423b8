//! `[record]`: `robotd serve` recording its bus all the time, into MCAP files of bounded size.
//!
//! One [`crate::bridge`] feeds a Foxglove context; the current file is that context's MCAP
//! sink. Four times a second a watcher looks at the file's size: past `max_file_bytes` it opens the
//! next file (a new sink on the same context, so no message falls between the two), closes the
//! full one, and deletes the oldest files beyond `keep_files`. Files are named
//! `robotd_<UTC YYYYmmdd_HHMMSS>.mcap` and sort by time. A file that cannot be opened stops
//! the recording with an error in the log; the robot goes on.

use crate::bridge::{self, Bridge, BridgeSettings};
use crate::config::RecordConfig;
use foxglove::{Context, McapWriter, McapWriterHandle};
use robotd_runtime::bus::Bus;
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, SystemTime, UNIX_EPOCH};

type Writer = McapWriterHandle<BufWriter<File>>;

/// The running recorder; dropping it closes the current file.
pub struct AlwaysOn {
    stop: Arc<AtomicBool>,
    watcher: Option<std::thread::JoinHandle<()>>,
    _bridge: Bridge,
}

impl Drop for AlwaysOn {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        if let Some(watcher) = self.watcher.take() {
            let _ = watcher.join();
        }
    }
}

/// A new file name in `dir`, not yet taken.
fn next_path(dir: &Path) -> PathBuf {
    let now = SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_secs());
    let stamp = robotd_runtime::telemetry::file_stamp(now);
    let mut path = dir.join(format!("robotd_{stamp}.mcap"));
    let mut n = 1;
    while path.exists() {
        path = dir.join(format!("robotd_{stamp}_{n}.mcap"));
        n += 1;
    }
    path
}

fn open(context: &Arc<Context>, dir: &Path) -> Result<(PathBuf, Writer), String> {
    let path = next_path(dir);
    let writer = McapWriter::new()
        .context(context)
        .create_new_buffered_file(&path)
        .map_err(|e| format!("cannot create {}: {e}", path.display()))?;
    tracing::info!(path = %path.display(), "recording the bus");
    Ok((path, writer))
}

/// The recordings in `dir`, oldest first.
fn recordings(dir: &Path) -> Vec<PathBuf> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
        .map(|entries| {
            entries
                .flatten()
                .map(|e| e.path())
                .filter(|p| {
                    p.file_name()
                        .and_then(|n| n.to_str())
                        .is_some_and(|n| n.starts_with("robotd_") && n.ends_with(".mcap"))
                })
                .collect()
        })
        .unwrap_or_default();
    files.sort();
    files
}

/// Starts recording `bus` per `config`; `None` when `config.dir` is empty.
pub fn start(
    bus: Bus,
    config: &RecordConfig,
    mut settings: BridgeSettings,
) -> Result<Option<AlwaysOn>, String> {
    if config.dir.as_os_str().is_empty() {
        return Ok(None);
    }
    std::fs::create_dir_all(&config.dir)
        .map_err(|e| format!("record.dir {} cannot be created: {e}", config.dir.display()))?;
    if !config.topics.is_empty() {
        settings.camera = config.topics.iter().any(|t| t == "camera/frames");
        settings.topics = Some(config.topics.clone());
    }
    let context = Context::new();
    let first = open(&context, &config.dir)?;
    let bridge = bridge::start(bus, context.clone(), settings).map_err(|e| e.to_string())?;
    let stop = Arc::new(AtomicBool::new(false));
    let watcher = {
        let (stop, config) = (stop.clone(), config.clone());
        std::thread::Builder::new()
            .name("record-rotate".into())
            .spawn(move || watch(&context, &config, first, &stop))
            .map_err(|e| e.to_string())?
    };
    Ok(Some(AlwaysOn {
        stop,
        watcher: Some(watcher),
        _bridge: bridge,
    }))
}

fn close(path: &Path, writer: Writer) {
    if let Err(error) = writer.close() {
        tracing::error!(path = %path.display(), %error, "closing a recording failed; it may be incomplete");
    }
}

fn watch(
    context: &Arc<Context>,
    config: &RecordConfig,
    first: (PathBuf, Writer),
    stop: &AtomicBool,
) {
    let (mut path, mut writer) = first;
    while !stop.load(Ordering::SeqCst) {
        std::thread::sleep(Duration::from_millis(250));
        let size = std::fs::metadata(&path).map_or(0, |m| m.len());
        if size < config.max_file_bytes {
            continue;
        }
        match open(context, &config.dir) {
            Ok((next_path, next_writer)) => {
                let full = std::mem::replace(&mut writer, next_writer);
                let full_path = std::mem::replace(&mut path, next_path);
                close(&full_path, full);
                let files = recordings(&config.dir);
                let excess = files.len().saturating_sub(config.keep_files);
                for old in files.into_iter().take(excess) {
                    if let Err(error) = std::fs::remove_file(&old) {
                        tracing::warn!(path = %old.display(), %error, "an old recording could not be deleted");
                    }
                }
            }
            Err(error) => {
                tracing::error!(%error, "recording stopped: the next file cannot be opened");
                break;
            }
        }
    }
    close(&path, writer);
}
