//! `robotd record`: the bus into an MCAP file that Foxglove and the `mcap` tools open.
//!
//! A recording is the [`crate::bridge`]'s channels written by the Foxglove SDK's MCAP writer:
//! the camera as JPEG (`foxglove.CompressedImage`) with each frame's header beside it, the arm
//! as transforms and a scene, the objects and workspace as scenes, logs, and every bus topic as
//! JSON under `/bus/<topic>` with its message type as the schema name and its JSON Schema
//! ([`crate::topics::JsonTopic::schema`]). Log times are the bus's, so [`crate::replay`]
//! reproduces the timing.

use crate::bridge::{self, BridgeSettings};
use foxglove::{Context, McapWriter};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// Why a recording failed.
#[derive(Debug, thiserror::Error)]
pub enum RecordError {
    /// The file cannot be created (exists, no directory, no permission).
    #[error("cannot create {path}: {reason} (recordings never overwrite a file)")]
    Create {
        /// The file asked for.
        path: PathBuf,
        /// The writer's reason.
        reason: String,
    },
    /// The bridge thread did not start.
    #[error("cannot start the recorder's bus thread: {0}")]
    Bridge(#[from] std::io::Error),
    /// Closing the file failed: it may be incomplete.
    #[error("closing {path} failed, the file may be incomplete: {reason}")]
    Close {
        /// The file.
        path: PathBuf,
        /// The writer's reason.
        reason: String,
    },
    /// The written file does not read back.
    #[error("{path} was written but does not read back as MCAP: {reason}")]
    ReadBack {
        /// The file.
        path: PathBuf,
        /// The reader's reason.
        reason: String,
    },
}

/// What a recording holds: messages per channel.
#[derive(Debug, Clone, Default, serde::Serialize)]
pub struct RecordSummary {
    /// The file written.
    pub path: PathBuf,
    /// Its size, bytes.
    pub bytes: u64,
    /// Messages per channel topic.
    pub messages: BTreeMap<String, u64>,
}

impl RecordSummary {
    /// All messages.
    pub fn total(&self) -> u64 {
        self.messages.values().sum()
    }
}

/// An open recording: the MCAP writer and the bridge feeding it. [`Recording::finish`] closes
/// the file; dropping it without finishing also closes it, without the summary.
pub struct Recording {
    path: PathBuf,
    bridge: Option<bridge::Bridge>,
    writer: Option<foxglove::McapWriterHandle<std::io::BufWriter<std::fs::File>>>,
    _context: Arc<Context>,
}

/// Starts recording `bus` into a new file at `path` with `settings`.
pub fn start(
    bus: robotd_runtime::bus::Bus,
    path: &Path,
    settings: BridgeSettings,
) -> Result<Recording, RecordError> {
    let context = Context::new();
    let writer = McapWriter::new()
        .context(&context)
        .create_new_buffered_file(path)
        .map_err(|e| RecordError::Create {
            path: path.to_path_buf(),
            reason: e.to_string(),
        })?;
    let bridge = bridge::start(bus, context.clone(), settings)?;
    Ok(Recording {
        path: path.to_path_buf(),
        bridge: Some(bridge),
        writer: Some(writer),
        _context: context,
    })
}

impl Recording {
    /// Stops, closes the file and reads it back for the summary.
    pub fn finish(mut self) -> Result<RecordSummary, RecordError> {
        drop(self.bridge.take());
        if let Some(writer) = self.writer.take() {
            writer.close().map_err(|e| RecordError::Close {
                path: self.path.clone(),
                reason: e.to_string(),
            })?;
        }
        summarize(&self.path)
    }
}

/// Messages per channel of the MCAP file at `path` (read a message at a time).
pub fn summarize(path: &Path) -> Result<RecordSummary, RecordError> {
    let fail = |reason: String| RecordError::ReadBack {
        path: path.to_path_buf(),
        reason,
    };
    let mut messages = BTreeMap::new();
    for message in
        robotd_recording::reader::Messages::open(path).map_err(|e| fail(e.to_string()))?
    {
        let message = message.map_err(|e| fail(e.to_string()))?;
        *messages.entry(message.topic.to_string()).or_insert(0) += 1;
    }
    Ok(RecordSummary {
        path: path.to_path_buf(),
        bytes: std::fs::metadata(path)
            .map_err(|e| fail(e.to_string()))?
            .len(),
        messages,
    })
}
