//! The report: one [`Check`] per row, rendered as a table for a terminal or as JSON for scripts.
//!
//! Every check returns a `Check` with a stable `name`, a [`Status`], what it found in words and,
//! for every row that is not `ok`, a `fix` a user can act on. The rendering lives here and only
//! here, so the checks never print and the format stays one thing:
//!
//! ```text
//! STATUS   CHECK      FOUND
//! ok       shm        /dev/shm: 1.0 GiB total, 1020.0 MiB free, writable
//! PROBLEM  redis      ...
//!                     fix: ...
//!
//! 2 checks: 1 ok, 0 warnings, 1 problem
//! ```

use serde_json::{json, Value};

/// Outcome of one check.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Status {
    /// Works.
    Ok,
    /// Works, but degraded or worth a look; does not fail `robotd doctor`.
    Warn,
    /// Something robotd needs or was configured to use does not work.
    Problem,
}

impl Status {
    /// Lower-case name, as printed in the table and the JSON.
    pub fn as_str(self) -> &'static str {
        match self {
            Status::Ok => "ok",
            Status::Warn => "warn",
            Status::Problem => "problem",
        }
    }
}

/// One row of the report.

#[derive(Debug, Clone)]
pub struct Check {
    /// Short, stable identifier: `shm`, `iceoryx2`, `redis`, `espeak-ng`, `audio`, `llm-keys`.
    pub name: &'static str,
    /// How it went.
    pub status: Status,
    /// What the doctor found, in words (never a secret).
    pub found: String,
    /// What to do about it; set for every row that is not `ok`.
    pub fix: Option<String>,
}

impl Check {
    pub(super) fn ok(name: &'static str, found: impl Into<String>) -> Self {
        Self {
            name,
            status: Status::Ok,
            found: found.into(),
            fix: None,
        }
    }

    pub(super) fn warn(
        name: &'static str,
        found: impl Into<String>,
        fix: impl Into<String>,
    ) -> Self {
        Self {
            name,
            status: Status::Warn,
            found: found.into(),
            fix: Some(fix.into()),
        }
    }

    pub(super) fn problem(
        name: &'static str,
        found: impl Into<String>,
        fix: impl Into<String>,
    ) -> Self {
        Self {
            name,
            status: Status::Problem,
            found: found.into(),
            fix: Some(fix.into()),
        }
    }
}

/// The result of `robotd doctor`: one [`Check`] per row.

#[derive(Debug, Clone)]
pub struct DoctorReport {
    /// The rows, in the order they were checked.
    pub checks: Vec<Check>,
}

impl DoctorReport {
    /// True when at least one row is a problem (warnings do not count).
    pub fn has_problems(&self) -> bool {
        self.checks.iter().any(|c| c.status == Status::Problem)
    }

    fn count(&self, status: Status) -> usize {
        self.checks.iter().filter(|c| c.status == status).count()
    }

    /// The report as a plain-text table for a terminal, fixes under their rows, and a summary
    /// line at the end.
    pub fn render_table(&self) -> String {
        let name_width = self
            .checks
            .iter()
            .map(|c| c.name.len())
            .chain(std::iter::once("CHECK".len()))
            .max()
            .unwrap_or(5);
        let status_width = "PROBLEM".len();
        let indent = " ".repeat(status_width + 2 + name_width + 2);
        let mut out = format!(
            "{:<status_width$}  {:<name_width$}  FOUND\n",
            "STATUS", "CHECK"
        );
        for check in &self.checks {
            let status = match check.status {
                Status::Ok => "ok",
                Status::Warn => "warn",
                Status::Problem => "PROBLEM",
            };
            out.push_str(&format!(
                "{status:<status_width$}  {:<name_width$}  {}\n",
                check.name, check.found
            ));
            if let Some(fix) = &check.fix {
                out.push_str(&format!("{indent}fix: {fix}\n"));
            }
        }
        let problems = self.count(Status::Problem);
        let warnings = self.count(Status::Warn);
        out.push('\n');
        out.push_str(&format!(
            "{} checks: {} ok, {} {}, {} {}\n",
            self.checks.len(),
            self.count(Status::Ok),
            warnings,
            if warnings == 1 { "warning" } else { "warnings" },
            problems,
            if problems == 1 { "problem" } else { "problems" },
        ));
        out
    }

    /// The report as JSON:
    /// `{"ok": bool, "summary": {"ok": n, "warn": n, "problem": n},
    ///   "checks": [{"name", "status", "found", "fix"}]}`; `ok` is false when there are problems.
    pub fn to_json(&self) -> Value {
        let checks: Vec<Value> = self
            .checks
            .iter()
            .map(|c| {
                json!({
                    "name": c.name,
                    "status": c.status.as_str(),
                    "found": c.found,
                    "fix": c.fix,
                })
            })
            .collect();
        json!({
            "ok": !self.has_problems(),
            "summary": {
                "ok": self.count(Status::Ok),
                "warn": self.count(Status::Warn),
                "problem": self.count(Status::Problem),
            },
            "checks": checks,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn report_json_table_and_problems() {
        let report = DoctorReport {
            checks: vec![
                Check::ok("shm", "fine"),
                Check::warn("audio", "no device", "attach one"),
            ],
        };
        assert!(!report.has_problems());
        let json = report.to_json();
        assert_eq!(json["ok"], true);
        assert_eq!(json["summary"]["warn"], 1);
        assert_eq!(json["checks"][1]["status"], "warn");
        assert_eq!(json["checks"][1]["fix"], "attach one");
        assert!(json["checks"][0]["fix"].is_null());

        let mut report = report;
        report
            .checks
            .push(Check::problem("redis", "down", "start it"));
        assert!(report.has_problems());
        assert_eq!(report.to_json()["ok"], false);
        let table = report.render_table();
        assert!(table.contains("PROBLEM  redis"), "{table}");
        assert!(table.contains("fix: start it"), "{table}");
        assert!(
            table.contains("3 checks: 1 ok, 1 warning, 1 problem"),
            "{table}"
        );
    }
}
