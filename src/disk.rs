//! Free space where robotd writes: the log directory, the audit log, the speech spool and the
//! recordings.
//!
//! Every file robotd writes has a size or age limit (docs/install.md, "Disk"), but the disk
//! is shared: another program can still fill it. When it is nearly full robotd must say so
//! before something fails: `/health` carries a `disk` part (each place, its free space, and
//! `low` when any has less than [`LOW_FREE_BYTES`]) and reports `degraded`, systemd's status
//! line names the place, and `robotd doctor` checks the same places. What happens when a disk
//! is really full: the audit log's writer fails and every motion is refused with that reason
//! (a motion that cannot be audited does not happen; `libs/safety/src/audit.rs`); the log
//! files and the MCP call log lose lines; everything else serves on.

use robotd_config::Config;
use std::io::ErrorKind;
use std::path::{Path, PathBuf};

/// Less free space than this where robotd writes is "low".
pub const LOW_FREE_BYTES: u64 = 512 * 1024 * 1024;

/// The places robotd writes to under `config`: (what, directory).
pub fn places(config: &Config) -> Vec<(&'static str, PathBuf)> {
    let log_dir = config.telemetry.log_dir.clone();
    let mut places = vec![("log", log_dir.clone())];
    if config.safety.audit.enabled {
        let audit = match config.safety.audit.path.trim() {
            "" => log_dir.clone(),
            path => Path::new(path)
                .parent()
                .map(Path::to_path_buf)
                .unwrap_or_default(),
        };
        places.push(("audit", audit));
    }
    places.push(("speech spool", config.tts.spool_dir.clone()));
    if !config.record.dir.as_os_str().is_empty() {
        places.push(("recordings", config.record.dir.clone()));
    }
    places
}

/// Total and available bytes of the file system holding `dir` (or its nearest existing
/// ancestor: a directory robotd has not created yet will be on that one).
pub fn fs_space(dir: &Path) -> std::io::Result<(u64, u64)> {
    use std::os::unix::ffi::OsStrExt;
    let absolute = std::path::absolute(dir)?;
    let existing = absolute
        .ancestors()
        .find(|p| p.exists())
        .unwrap_or(Path::new("/"));
    let c_path = std::ffi::CString::new(existing.as_os_str().as_bytes())
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

/// `bytes` for a person: `1.5 GiB`.
pub fn human_bytes(bytes: u64) -> String {
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

/// One place robotd writes to, measured: (what, directory, total and free bytes).
type Measured<'a> = (&'a str, &'a Path, std::io::Result<(u64, u64)>);

/// `/health`'s `disk`: each place with its free space, and `low` when any place is low.
pub fn report(places: &[(&'static str, PathBuf)]) -> serde_json::Value {
    let measured: Vec<Measured<'_>> = places
        .iter()
        .map(|(what, dir)| (*what, dir.as_path(), fs_space(dir)))
        .collect();
    report_of(&measured)
}

fn report_of(measured: &[Measured<'_>]) -> serde_json::Value {
    let mut low = Vec::new();
    let places: Vec<serde_json::Value> = measured
        .iter()
        .map(|(what, dir, space)| match space {
            Ok((total, free)) => {
                let is_low = *free < LOW_FREE_BYTES;
                if is_low {
                    low.push(format!(
                        "{what} {} has {} free",
                        dir.display(),
                        human_bytes(*free)
                    ));
                }
                serde_json::json!({
                    "what": what, "path": dir, "free_bytes": free, "total_bytes": total,
                    "low": is_low,
                })
            }
            Err(error) => serde_json::json!({
                "what": what, "path": dir, "error": error.to_string(),
            }),
        })
        .collect();
    serde_json::json!({
        "low": !low.is_empty(),
        "reason": if low.is_empty() { serde_json::Value::Null } else { low.join("; ").into() },
        "places": places,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_place_with_little_space_makes_the_disk_low() {
        let measured = [
            ("log", Path::new("/var/log/robotd"), Ok((10 << 30, 4 << 30))),
            (
                "audit",
                Path::new("/var/lib/robotd/audit"),
                Ok((10 << 30, 100 << 20)),
            ),
            (
                "recordings",
                Path::new("/mnt/gone"),
                Err(std::io::Error::other("no such device")),
            ),
        ];
        let report = report_of(&measured);
        assert_eq!(report["low"], true);
        assert_eq!(
            report["reason"],
            "audit /var/lib/robotd/audit has 100.0 MiB free"
        );
        assert_eq!(report["places"][0]["low"], false);
        assert_eq!(report["places"][2]["error"], "no such device");
        let fine = report_of(&measured[..1]);
        assert_eq!(fine["low"], false);
        assert!(fine["reason"].is_null());
    }

    #[test]
    fn the_places_follow_the_configuration() {
        let mut config = Config::default();
        config.telemetry.log_dir = "/var/log/robotd".into();
        config.safety.audit.path = "/var/lib/robotd/audit/audit.jsonl".into();
        config.tts.spool_dir = "/var/lib/robotd/speech".into();
        let places = places(&config);
        let whats: Vec<&str> = places.iter().map(|p| p.0).collect();
        assert_eq!(whats, ["log", "audit", "speech spool"], "recording is off");
        assert_eq!(places[1].1, Path::new("/var/lib/robotd/audit"));
    }

    #[test]
    fn a_directory_not_yet_made_is_measured_on_its_parent() {
        let dir = tempfile::tempdir().unwrap();
        let (total, free) = fs_space(&dir.path().join("not/yet")).unwrap();
        assert!(total > 0 && free <= total);
        assert_eq!(human_bytes(512), "512 B");
        assert_eq!(human_bytes(3 * 1024 * 1024 * 1024 / 2), "1.5 GiB");
    }
}
