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
        if !(0.5..=30.0).contains(&self.camera_fps) {
            checks.problem(
                "camera_fps",
                format!(
                    "must be 0.5 … 30 frames per second, got {}",
                    self.camera_fps
                ),
            );
        }
        checks.range_u64("jpeg_quality", u64::from(self.jpeg_quality), 10..=100, "");
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
