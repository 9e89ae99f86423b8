//! `robotd audit verify [--key FILE] FILE…`: checks the motion audit log's keyed chain.
//!
//! Give the files oldest first (`log/audit.jsonl.2 log/audit.jsonl.1 log/audit.jsonl`). Every
//! line's HMAC is recomputed with the key (`--key`, by default `audit.key` beside the last
//! file) and the `seq` and `prev` links checked across the files; a deleted, edited or
//! reordered line, or a tail re-hashed without the key, is reported with its file and line
//! number (exit 1); a file or key that cannot be read is an error of its own (exit 2), not a
//! broken chain. Lines of the older, unkeyed format verify by their plain hash and are counted
//! apart: "unkeyed (older format)".

use robotd_safety::audit::{default_key_file, verify, Break, VerifyError};
use robotd_safety::AuditKey;
use std::path::{Path, PathBuf};

/// What `robotd audit verify` found.
pub enum Verdict {
    /// The chain holds: the report.
    Intact(String),
    /// The chain is broken: where and how.
    Broken(String),
}

/// Verifies `files` with the key in `key` (or `audit.key` beside the last file, when it
/// exists); `Err` when they cannot be read at all.
pub fn run(files: &[PathBuf], key: Option<&Path>) -> anyhow::Result<Verdict> {
    let key_file = match (key, files.last()) {
        (Some(file), _) => Some(file.to_path_buf()),
        (None, Some(last)) => Some(default_key_file(last)).filter(|f| f.exists()),
        (None, None) => None,
    };
    let key = match &key_file {
        Some(file) => Some(
            AuditKey::load(file)
                .map_err(|e| anyhow::anyhow!("cannot verify the audit log: {e}"))?,
        ),
        None => None,
    };
    let report = match verify(files, key.as_ref()) {
        Ok(report) => report,
        Err(VerifyError::Broken {
            path,
            line,
            problem: Break::NoKey,
        }) => anyhow::bail!(
            "cannot verify the audit log: {}: line {line}: the line is keyed (hmac) and no key \
             was found: give the key file with --key FILE",
            path.display()
        ),
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
    let keyed = match (report.keyed, report.unkeyed) {
        (_, 0) => format!("keyed (HMAC-SHA256, key {})", shown(key_file.as_deref())),
        (0, unkeyed) => format!(
            "unkeyed (older format): {unkeyed} entries with a plain hash, which anyone can \
             rewrite together with their tail"
        ),
        (keyed, unkeyed) => format!(
            "{keyed} keyed (HMAC-SHA256, key {}) after {unkeyed} unkeyed (older format, which \
             anyone can rewrite together with their tail)",
            shown(key_file.as_deref())
        ),
    };
    Ok(Verdict::Intact(format!(
        "ok: {} entries in {} file(s), seq {} … {}, {origin}; {keyed}; last hash {}",
        report.entries, report.files, report.first_seq, report.last_seq, report.last_hash
    )))
}

fn shown(file: Option<&Path>) -> String {
    file.map_or_else(|| "none".to_owned(), |f| f.display().to_string())
}
