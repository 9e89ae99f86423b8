//! `disk`: free space where robotd writes (its log directory, the audit log, the speech
//! spool, the recordings; `crate::disk`).
//!
//! Each of them has a size limit of its own, but the disk is shared. Below 512 MiB free on any
//! of them the row warns (robotd's `/health` then says `degraded`); with no space at all the
//! audit log cannot be written and every motion is refused, so that is a problem.

use super::Check;
use crate::disk::{fs_space, human_bytes, LOW_FREE_BYTES};
use std::path::PathBuf;

/// Less than this is no space at all: the next audit line may not fit.
const NO_SPACE: u64 = 1024 * 1024;

pub(super) fn check_disk(places: &[(&'static str, PathBuf)]) -> Check {
    const NAME: &str = "disk";
    let mut found = Vec::new();
    let mut low = Vec::new();
    let mut full = Vec::new();
    for (what, dir) in places {
        match fs_space(dir) {
            Ok((_, free)) => {
                let line = format!("{what} {} {} free", dir.display(), human_bytes(free));
                if free < NO_SPACE {
                    full.push(line.clone());
                } else if free < LOW_FREE_BYTES {
                    low.push(line.clone());
                }
                found.push(line);
            }
            Err(e) => low.push(format!(
                "{what} {}: free space unknown ({e})",
                dir.display()
            )),
        }
    }
    let fix = "free space on that file system (`df -h`, `du -sh` on the directory), or move \
               the directory elsewhere in the configuration ([telemetry] log_dir, \
               [safety.audit] path, [tts] spool_dir, [record] dir)";
    if !full.is_empty() {
        Check::problem(
            NAME,
            format!(
                "no space left: {}; motions are refused (nothing can be audited)",
                full.join("; ")
            ),
            fix,
        )
    } else if !low.is_empty() {
        Check::warn(
            NAME,
            format!("less than 512 MiB free: {}", low.join("; ")),
            fix,
        )
    } else {
        Check::ok(NAME, found.join("; "))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::doctor::Status;

    #[test]
    fn the_places_with_room_pass() {
        let dir = tempfile::tempdir().unwrap();
        let check = check_disk(&[("log", dir.path().to_path_buf())]);
        // The test machine's disk may itself be low; then the row says so.
        assert_ne!(check.status, Status::Problem, "{check:?}");
        assert!(check.found.contains("log "), "{}", check.found);
    }
}
