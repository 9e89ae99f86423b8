//! `[foxglove]`: the live view for the Foxglove app.

use robotd_runtime::config::{Checks, Section};
use serde::{Deserialize, Serialize};
use std::net::SocketAddr;

/// `[foxglove]`
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct FoxgloveConfig {
    /// Address of the Foxglove WebSocket server, e.g. "127.0.0.1:8765"; unset = off.
    pub bind: Option<SocketAddr>,
    /// Most camera frames per second sent (0.5 … 30).
    pub camera_fps: f64,
    /// JPEG quality of those frames (10 … 100).
    pub jpeg_quality: u8,
}

impl Default for FoxgloveConfig {
    fn default() -> Self {
        Self {
            bind: None,
            camera_fps: 10.0,
            jpeg_quality: 80,
        }
    }
}

impl Section for FoxgloveConfig {
    fn check(&self, checks: &mut Checks) {
        checks.camera_stream(self.camera_fps, self.jpeg_quality);
        if let Some(bind) = self.bind {
            if !bind.ip().is_loopback() {
                checks.problem(
                    "bind",
                    format!(
                        "{bind} is not a loopback address: the Foxglove protocol has no \
                         authentication, so the live view is served on this machine only \
                         (use an SSH tunnel to watch from elsewhere)"
                    ),
                );
            }
        }
    }
}

/// `[record]`: always-on recording of the bus by `robotd serve`, in size-limited MCAP files.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RecordConfig {
    /// Directory of the files (`robotd_<UTC stamp>.mcap`); empty = off.
    pub dir: std::path::PathBuf,
    /// Size at which a file is closed and the next one started, bytes (1 MiB … 64 GiB).
    pub max_file_bytes: u64,
    /// Files kept; the oldest beyond are deleted (1 … 10,000).
    pub keep_files: usize,
    /// Topics recorded (`camera/frames` and bus topics); empty = all.
    pub topics: Vec<String>,
}

impl Default for RecordConfig {
    fn default() -> Self {
        Self {
            dir: std::path::PathBuf::new(),
            max_file_bytes: 1024 * 1024 * 1024,
            keep_files: 10,
            topics: Vec::new(),
        }
    }
}

impl Section for RecordConfig {
    fn check(&self, checks: &mut Checks) {
        checks.range_u64(
            "max_file_bytes",
            self.max_file_bytes,
            1024 * 1024..=64 * 1024 * 1024 * 1024,
            "",
        );
        checks.range_u64("keep_files", self.keep_files as u64, 1..=10_000, "");
        for topic in &self.topics {
            if topic != "camera/frames" && crate::topics::find(topic).is_none() {
                checks.problem(
                    "topics",
                    format!(
                        "unknown topic '{topic}' (camera/frames or a bus topic such as arm/state)"
                    ),
                );
            }
        }
    }
}
