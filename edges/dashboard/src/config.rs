//! `[dashboard]`: the web page at `/` and its API under `/api/`.

use robotd_runtime::config::{Checks, Section};
use serde::{Deserialize, Serialize};

/// `[dashboard]`
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct DashboardConfig {
    /// Serve the page and its API (behind the port's guard, like MCP).
    pub enabled: bool,
    /// Most camera frames per second encoded for the page (0.5 … 30).
    pub camera_fps: f64,
    /// JPEG quality of the page's camera view (10 … 100).
    pub jpeg_quality: u8,
}

impl Default for DashboardConfig {
    fn default() -> Self {
        Self {
            enabled: true,
            camera_fps: 10.0,
            jpeg_quality: 80,
        }
    }
}

impl Section for DashboardConfig {
    fn check(&self, checks: &mut Checks) {
        checks.camera_stream(self.camera_fps, self.jpeg_quality);
    }
}
