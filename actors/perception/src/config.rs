//! `[perception]`: the built-in detector's label table and what it counts as an object.

use robotd_runtime::config::{Checks, Section};
use serde::{Deserialize, Serialize};
use std::path::PathBuf;

/// `[perception]`
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PerceptionConfig {
    /// Label table of the built-in colour/shape detector (see `config/labels.toml`); `None`
    /// uses the built-in table.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub labels: Option<PathBuf>,
    /// Nothing smaller than this along its longer side is reported as an object, millimetres
    /// (default 8).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub min_object_size_mm: Option<f64>,
    /// Nothing thinner than this is reported as an object, millimetres (default 2.5): pencil
    /// and pen lines, paper edges and printing on the sheet are thinner.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub min_object_thickness_mm: Option<f64>,
}

impl PerceptionConfig {
    /// The colour detector's settings: the defaults with this section's limits.
    pub fn detector_settings(&self) -> robotd_vision::detector::ColourDetectorSettings {
        let mut settings = robotd_vision::detector::ColourDetectorSettings::default();
        if let Some(mm) = self.min_object_size_mm {
            settings.min_size_m = mm / 1000.0;
        }
        if let Some(mm) = self.min_object_thickness_mm {
            settings.min_thickness_m = mm / 1000.0;
        }
        settings
    }
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
        for (key, value) in [
            ("min_object_size_mm", self.min_object_size_mm),
            ("min_object_thickness_mm", self.min_object_thickness_mm),
        ] {
            if let Some(mm) = value {
                if !(mm.is_finite() && (0.0..=100.0).contains(&mm)) {
                    checks.problem(
                        key,
                        format!("must be between 0 and 100 millimetres, not {mm}"),
                    );
                }
            }
        }
    }
}
