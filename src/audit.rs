//! `robotd audit verify FILE…`: checks the motion audit log's hash chain.
//!
//! Give the files oldest first (`log/audit.jsonl.2 log/audit.jsonl.1 log/audit.jsonl`). Every
//! line's hash is recomputed and the `seq` and `prev` links checked across the files; a
//! deleted, edited or reordered line is reported with its file and line number (exit 1).

use robotd_safety::audit::verify;
use std::path::PathBuf;

/// The verification report, or why the chain is broken.
pub fn run(files: &[PathBuf]) -> Result<String, String> {
    let report = verify(files).map_err(|e| e.to_string())?;
    let origin = if report.starts_at_genesis {
        "from the first entry ever".to_owned()
    } else {
        format!(
            "from seq {} (older files were rotated away; what came before cannot be checked)",
            report.first_seq
        )
    };
    Ok(format!(
        "ok: {} entries in {} file(s), seq {} … {}, {origin}; last hash {}",
        report.entries, report.files, report.first_seq, report.last_seq, report.last_hash
    ))
}
