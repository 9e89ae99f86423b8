//! The report of `robotd commission` for people (the file it writes: `config_file.rs`).

use super::Report;
use std::fmt::Write as _;

/// The report as lines for a terminal.
pub fn render(report: &Report) -> String {
    let mut out = format!("robotd commission: {} ({})", report.robot, report.driver);
    if report.attached {
        out.push_str(", through the robotd already running");
    }
    out.push('\n');
    for step in &report.steps {
        let mark = match step.status.as_str() {
            "ok" => "✓",
            "failed" => "❌",
            _ => "·",
        };
        let _ = write!(out, "{mark} {:<9} {}", step.step, step.status);
        if let Some(reason) = &step.reason {
            let _ = write!(out, ": {reason}");
        }
        out.push('\n');
        if let Some(measured) = &step.measured {
            if let Some(map) = measured.as_object() {
                for (key, value) in map {
                    let _ = writeln!(out, "    {key}: {value}");
                }
            }
        }
    }
    if let Some(path) = &report.written {
        let _ = writeln!(out, "measured values written to {}", path.display());
    }
    out
}
