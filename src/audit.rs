//! `robotd audit verify FILE…`: checks the motion audit log's hash chain.
//!
//! Give the files oldest first (`log/audit.jsonl.2 log/audit.jsonl.1 log/audit.jsonl`). Every
//! line's hash is recomputed and the `seq` and `prev` links checked across the files; a
//! deleted, edited or reordered line is reported with its file and line number (exit 1); a file
//! that cannot be read is an error of its own (exit 2), not a broken chain.

use robotd_safety::audit::{verify, VerifyError};
use std::path::PathBuf;

/// What `robotd audit verify` found.
pub enum Verdict {
    /// The chain holds: the report.
    Intact(String),
    /// The chain is broken: where and how.
    Broken(String),
}

/// Verifies `files`; `Err` when they cannot be read at all.
pub fn run(files: &[PathBuf]) -> anyhow::Result<Verdict> {
    let report = match verify(files) {
        Ok(report) => report,
        Err(broken @ VerifyError::Broken { .. }) => return Ok(Verdict::Broken(broken.to_string())),
        Err(other) => anyhow::bail!("cannot verify the audit log: {other}"),
    };
    let origin = if report.starts_at_genesis {
        "from the first entry ever".to_owned()
    } else {
        format!(
            "from seq {} (older files were rotated away; what came before cannot be checked)",
            report.first_seq
        )
    };
    Ok(Verdict::Intact(format!(
        "ok: {} entries in {} file(s), seq {} … {}, {origin}; last hash {}",
        report.entries, report.files, report.first_seq, report.last_seq, report.last_hash
    )))
}
