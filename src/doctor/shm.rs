//! `shm`: the iceoryx2 bus keeps every message in shared memory under `/dev/shm`.
//!
//! If that directory is missing (some minimal containers), not writable, or nearly full (Docker
//! gives 64 MiB by default), the bus cannot create its segments and actors fail to start or
//! drop frames. The check creates and removes a probe file, then asks `statvfs` how much space
//! is left: below 256 MiB it warns, because a set of camera frame buffers alone needs about
//! 10 MiB per subscriber.

use super::Check;
use crate::disk::{fs_space, human_bytes};
use std::io::Write;
use std::path::Path;

/// Below this much free space in /dev/shm the shm row warns.
const SHM_MIN_FREE: u64 = 256 * 1024 * 1024;

pub(super) fn check_shm(dir: &Path) -> Check {
    const NAME: &str = "shm";
    let shown = dir.display();
    if !dir.is_dir() {
        return Check::problem(
            NAME,
            format!("{shown} does not exist; the iceoryx2 bus needs shared memory there"),
            format!("mount -t tmpfs -o size=1G tmpfs {shown} (in Docker: run with --shm-size=1g)"),
        );
    }
    let probe = dir.join(format!(
        ".robotd-doctor-{}-{}",
        std::process::id(),
        std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map(|d| d.as_nanos())
            .unwrap_or_default()
    ));
    let writable = std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(&probe)
        .and_then(|mut f| f.write_all(b"robotd"));
    let _ = std::fs::remove_file(&probe);
    if let Err(e) = writable {
        return Check::problem(
            NAME,
            format!("{shown} is not writable ({e})"),
            format!("chmod 1777 {shown}, or run robotd as a user that may write there"),
        );
    }
    let (total, free) = match fs_space(dir) {
        Ok(v) => v,
        Err(e) => {
            return Check::warn(
                NAME,
                format!("{shown} is writable, but its size is unknown (statvfs: {e})"),
                format!("check `df -h {shown}`; robotd needs at least 256 MiB free there"),
            )
        }
    };
    let found = format!(
        "{shown}: {} total, {} free, writable",
        human_bytes(total),
        human_bytes(free)
    );
    if free < SHM_MIN_FREE {
        Check::warn(
            NAME,
            format!(
                "{found}; less than 256 MiB free (a frame buffer set needs ~10 MiB per subscriber)"
            ),
            format!("mount -o remount,size=1G {shown} (in Docker: run with --shm-size=1g)"),
        )
    } else {
        Check::ok(NAME, found)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::doctor::Status;

    #[test]
    fn shm_check_real_and_missing() {
        let check = check_shm(Path::new("/dev/shm"));
        if Path::new("/dev/shm").is_dir() {
            assert_ne!(check.status, Status::Problem, "{check:?}");
            assert!(check.found.contains("free"), "{}", check.found);
        }
        let missing = check_shm(Path::new("/nonexistent/shm"));
        assert_eq!(missing.status, Status::Problem);
        assert!(missing.fix.is_some());
        assert_eq!(human_bytes(512), "512 B");
        assert_eq!(human_bytes(3 * 1024 * 1024 * 1024 / 2), "1.5 GiB");
    }
}
