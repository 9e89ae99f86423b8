//! `[perception]`: the built-in detector's label table.

use robotd_runtime::config::{Checks, Section};
use serde::{Deserialize, Serialize};
use std::path::PathBuf;

/// `[perception]`
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PerceptionConfig {
    /// Label table of the built-in colour/shape detector (see `config/labels.toml`); `None`
    /// uses the built-in table.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub labels: Option<PathBuf>,
}

impl Section for PerceptionConfig {
    fn check(&self, checks: &mut Checks) {
        if let Some(path) = &self.labels {
            if path.as_os_str().is_empty() {
                checks.problem(
                    "labels",
                    "must name a label table file (or be left out for the built-in one)",
                );
            }
        }
    }
}
