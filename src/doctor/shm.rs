//! `shm`: the iceoryx2 bus keeps every message in shared memory under `/dev/shm`.
//!
//! If that directory is missing (some minimal containers), not writable, or nearly full (Docker
//! gives 64 MiB by default), the bus cannot create its segments and actors fail to start or
//! drop frames. The check creates and removes a probe file, then asks `statvfs` how much space
//! is left: below 256 MiB it warns, because a set of camera frame buffers alone needs about
//! 10 MiB per subscriber.

use super::Check;
use std::io::{ErrorKind, Write};
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

/// Total and available bytes of the file system holding `dir`.
fn fs_space(dir: &Path) -> std::io::Result<(u64, u64)> {
    use std::os::unix::ffi::OsStrExt;
    let c_path = std::ffi::CString::new(dir.as_os_str().as_bytes())
        .map_err(|e| std::io::Error::new(ErrorKind::InvalidInput, e))?;
    // SAFETY: `statvfs` is plain old data, so all-zero is a valid value; `c_path` is a valid
    // NUL-terminated string and `st` a valid, writable statvfs for the duration of the call.
    let mut st: libc::statvfs = unsafe { std::mem::zeroed() };
    let rc = unsafe { libc::statvfs(c_path.as_ptr(), &mut st) };
    if rc != 0 {
        return Err(std::io::Error::last_os_error());
    }
    #[allow(clippy::unnecessary_cast)] // the field types differ between platforms
    let (frsize, blocks, avail) = (st.f_frsize as u64, st.f_blocks as u64, st.f_bavail as u64);
    Ok((blocks.saturating_mul(frsize), avail.saturating_mul(frsize)))
}

fn human_bytes(bytes: u64) -> String {
    const UNITS: [&str; 5] = ["B", "KiB", "MiB", "GiB", "TiB"];
    let mut value = bytes as f64;
    let mut unit = 0;
    while value >= 1024.0 && unit + 1 < UNITS.len() {
        value /= 1024.0;
        unit += 1;
    }
    if unit == 0 {
        format!("{bytes} B")
    } else {
        format!("{value:.1} {}", UNITS[unit])
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
