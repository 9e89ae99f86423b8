//! `[workspace]`: the scene memory's free-space margin, forgetting, freshness waits and the
//! limits of the detectable-label list.

use robotd_runtime::config::{Checks, Section};
use serde::{Deserialize, Serialize};

/// `[workspace]`
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WorkspaceConfig {
    /// Margin kept free around every object when looking for free space, metres (0 … 0.1).
    #[serde(default = "WorkspaceConfig::free_space_margin_m")]
    pub free_space_margin_m: f64,
    /// An object not seen in this many steady frames of its workspace in a row is forgotten
    /// (1 … 1000).
    #[serde(default = "WorkspaceConfig::expire_after_frames")]
    pub expire_after_frames: u32,
    /// Longest a detection tool waits for a fresh view of the workspace, ms (1 … 60000).
    #[serde(default = "WorkspaceConfig::fresh_wait_ms")]
    pub fresh_wait_ms: u64,
    /// Most detectable labels held; `add_object_name2object_labels` beyond it is refused
    /// (1 … 10000).
    #[serde(default = "WorkspaceConfig::max_labels")]
    pub max_labels: u32,
    /// Longest detectable label, characters (1 … 1000).
    #[serde(default = "WorkspaceConfig::max_label_chars")]
    pub max_label_chars: u32,
}

impl Default for WorkspaceConfig {
    fn default() -> Self {
        Self {
            free_space_margin_m: Self::free_space_margin_m(),
            expire_after_frames: Self::expire_after_frames(),
            fresh_wait_ms: Self::fresh_wait_ms(),
            max_labels: Self::max_labels(),
            max_label_chars: Self::max_label_chars(),
        }
    }
}

impl WorkspaceConfig {
    fn free_space_margin_m() -> f64 {
        0.01
    }
    fn expire_after_frames() -> u32 {
        3
    }
    fn fresh_wait_ms() -> u64 {
        3000
    }
    fn max_labels() -> u32 {
        500
    }
    fn max_label_chars() -> u32 {
        100
    }
}

impl Section for WorkspaceConfig {
    fn check(&self, checks: &mut Checks) {
        checks.range_f64(
            "free_space_margin_m",
            self.free_space_margin_m,
            0.0..=0.1,
            " m",
        );
        checks.range_u64(
            "expire_after_frames",
            self.expire_after_frames.into(),
            1..=1000,
            "",
        );
        checks.range_u64("fresh_wait_ms", self.fresh_wait_ms, 1..=60_000, " ms");
        checks.range_u64("max_labels", self.max_labels.into(), 1..=10_000, "");
        checks.range_u64("max_label_chars", self.max_label_chars.into(), 1..=1000, "");
    }
}
