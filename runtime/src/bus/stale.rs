//! Shared-memory segments left half-created by a killed process, removed before they hang us.
//!
//! iceoryx2 creates a segment in `/dev/shm` in steps: the file appears write-only and empty,
//! then gets its size, is initialised, and only then becomes readable. A process killed between
//! the first two steps (`kill -9`, the OOM killer, a test harness's timeout) leaves an empty,
//! write-only `iox2_…` file behind. iceoryx2 0.10 opens such a file by waiting for it to grow,
//! and for an empty one it never checks its own timeout: listing services, cleaning up dead
//! nodes or opening that service then spins for good, in every process that tries. One such
//! file made every `robotd serve` and `robotd doctor` on a machine hang at start.
//!
//! A creator that is alive finishes those steps within microseconds, so an empty, write-only
//! segment older than [`HALF_CREATED_AFTER`] is a corpse: [`remove_half_created`] deletes it
//! (processes that already hold it keep their mapping; nobody can open it anyway). It runs
//! when a process joins the bus, in `robotd doctor`, and before every dead-node clean-up
//! (`Bus::cleanup_dead_nodes`: a supervisor restarting an actor, a request whose server went
//! quiet, a queue a dead subscriber keeps full). A supervisor that just saw a process die
//! also removes that process's younger corpses, after giving a living creator a moment
//! ([`remove_half_created_after`]). Any other dead-node clean-up that finds a younger one
//! waits for a later round ([`any_half_created`]) rather than risk iceoryx2's endless wait.

use std::path::{Path, PathBuf};
use std::time::{Duration, SystemTime};

/// Age after which an empty, write-only iceoryx2 segment counts as abandoned.
pub const HALF_CREATED_AFTER: Duration = Duration::from_secs(5);

/// How long a supervisor gives a living creator to finish its segments before taking an
/// empty, write-only one for a corpse ([`remove_half_created_after`]); creating one takes
/// microseconds.
pub const HALF_CREATED_SETTLE: Duration = Duration::from_secs(1);

/// Where iceoryx2 keeps its shared-memory segments on Linux.
pub const SHARED_MEMORY_DIR: &str = "/dev/shm";

/// Deletes the empty, write-only `iox2_*` files in `dir` last changed more than `older_than`
/// ago; returns the paths removed. Errors reading `dir` or a file are skipped (a directory we
/// cannot read holds nothing we could remove).
pub fn remove_half_created(dir: &Path, older_than: Duration) -> Vec<PathBuf> {
    let corpses = half_created(dir)
        .into_iter()
        .filter(|(_, age)| *age >= older_than)
        .map(|(path, _)| path)
        .collect();
    remove(corpses)
}

/// Deletes the half-created segments in `dir` whatever their age, once `settle` has given a
/// living creator its chance: a file still empty and write-only after `settle` returns is a
/// corpse. For a supervisor restarting a process it just saw die, whose segments are too young
/// for [`remove_half_created`]; `settle` is a short sleep there (a living creator needs
/// microseconds), and nothing waits when no such file exists.
pub fn remove_half_created_after(dir: &Path, settle: impl FnOnce()) -> Vec<PathBuf> {
    let candidates = half_created(dir);
    if candidates.is_empty() {
        return Vec::new();
    }
    settle();
    let still: Vec<PathBuf> = half_created(dir).into_iter().map(|(p, _)| p).collect();
    let corpses = candidates
        .into_iter()
        .map(|(path, _)| path)
        .filter(|path| still.contains(path))
        .collect();
    remove(corpses)
}

/// Whether `dir` holds a half-created segment of any age.
pub fn any_half_created(dir: &Path) -> bool {
    !half_created(dir).is_empty()
}

/// The empty, write-only `iox2_*` files in `dir`, with how long ago each last changed.
fn half_created(dir: &Path) -> Vec<(PathBuf, Duration)> {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return Vec::new();
    };
    let now = SystemTime::now();
    let mut found = Vec::new();
    for entry in entries.flatten() {
        if !entry.file_name().to_string_lossy().starts_with("iox2_") {
            continue;
        }
        let Ok(meta) = entry.metadata() else {
            continue;
        };
        let readable = std::os::unix::fs::PermissionsExt::mode(&meta.permissions()) & 0o444 != 0;
        if !meta.is_file() || meta.len() != 0 || readable {
            continue;
        }
        let age = meta
            .modified()
            .ok()
            .and_then(|m| now.duration_since(m).ok())
            .unwrap_or_default();
        found.push((entry.path(), age));
    }
    found
}

/// Deletes `corpses`; returns those removed, and warns once with their count.
fn remove(corpses: Vec<PathBuf>) -> Vec<PathBuf> {
    let mut removed = Vec::new();
    for path in corpses {
        match std::fs::remove_file(&path) {
            Ok(()) => {
                tracing::debug!(path = %path.display(), "removed a half-created bus segment");
                removed.push(path);
            }
            Err(error) if error.kind() == std::io::ErrorKind::NotFound => {}
            Err(error) => tracing::warn!(
                path = %path.display(),
                %error,
                "a half-created bus segment could not be removed; robotd may hang opening it (remove it by hand)"
            ),
        }
    }
    if let Some(first) = removed.first() {
        tracing::warn!(
            count = removed.len(),
            first = %first.display(),
            "removed bus segments killed processes left half-created (iceoryx2 would wait for them forever)"
        );
    }
    removed
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::os::unix::fs::PermissionsExt;

    fn file(dir: &Path, name: &str, bytes: usize, mode: u32, age: Duration) -> PathBuf {
        let path = dir.join(name);
        std::fs::write(&path, vec![0u8; bytes]).unwrap();
        std::fs::set_permissions(&path, std::fs::Permissions::from_mode(mode)).unwrap();
        // The owner may write a write-only file, so it can set its time.
        let times = std::fs::FileTimes::new().set_modified(SystemTime::now() - age);
        std::fs::File::options()
            .write(true)
            .open(&path)
            .and_then(|f| f.set_times(times))
            .unwrap();
        path
    }

    #[test]
    fn only_old_empty_write_only_iceoryx2_segments_are_removed() {
        let dir = tempfile::tempdir().unwrap();
        let old = Duration::from_secs(60);
        let corpse = file(dir.path(), "iox2_abc_1.dynamic", 0, 0o200, old);
        let young = file(dir.path(), "iox2_abc_2.dynamic", 0, 0o200, Duration::ZERO);
        let readable = file(dir.path(), "iox2_abc_3.dynamic", 0, 0o600, old);
        let sized = file(dir.path(), "iox2_abc_4.dynamic", 64, 0o200, old);
        let foreign = file(dir.path(), "other_5", 0, 0o200, old);
        let removed = remove_half_created(dir.path(), HALF_CREATED_AFTER);
        assert_eq!(removed, vec![corpse.clone()]);
        assert!(!corpse.exists());
        for kept in [young, readable, sized, foreign] {
            assert!(kept.exists(), "{} was removed", kept.display());
        }
    }

    /// iceoryx2's clean-up would wait forever on a young corpse it cannot yet be told from a
    /// segment being created, so the clean-up waits until the corpse is old enough to go.
    #[test]
    fn a_dead_node_clean_up_waits_while_a_young_half_created_segment_is_there() {
        use crate::bus::{Bus, BusOptions};
        let namespace = format!("test-stale-young-{}", std::process::id());
        let bus = Bus::open(BusOptions::new(&namespace, "sweeper")).unwrap();
        let dir = tempfile::tempdir().unwrap();
        let name = "iox2_abc_young.dynamic";
        let young = file(dir.path(), name, 0, 0o200, Duration::ZERO);
        let report = bus.cleanup_dead_nodes_in(dir.path(), true);
        assert!(report.deferred, "{report:?}");
        assert!(young.exists());
        // Old enough now: removed, and the clean-up goes on.
        file(dir.path(), name, 0, 0o200, Duration::from_secs(60));
        let report = bus.cleanup_dead_nodes_in(dir.path(), true);
        assert!(!report.deferred, "{report:?}");
        assert_eq!(report.half_created, 1);
        assert!(!young.exists());
        // A supervisor that swept the dead process's corpses itself does not wait.
        let young = file(dir.path(), name, 0, 0o200, Duration::ZERO);
        assert!(!bus.cleanup_dead_nodes_in(dir.path(), false).deferred);
        assert!(
            young.exists(),
            "a young one is left to its (living) creator"
        );
    }

    #[test]
    fn a_dead_node_clean_up_removes_a_corpse_that_appeared_after_the_start() {
        use crate::bus::{Bus, BusOptions};
        let namespace = format!("test-stale-{}", std::process::id());
        let bus = Bus::open(BusOptions::new(&namespace, "sweeper")).unwrap();
        // Made after the bus was joined, as by a process killed while the service ran.
        let name = format!("iox2_robotd_test_corpse_{}", std::process::id());
        let corpse = file(
            Path::new(SHARED_MEMORY_DIR),
            &name,
            0,
            0o200,
            Duration::from_secs(60),
        );
        let report = bus.cleanup_dead_nodes();
        assert!(!corpse.exists(), "the corpse is still there");
        assert!(report.half_created >= 1, "{report:?}");
    }

    #[test]
    fn after_settling_a_young_corpse_goes_and_a_segment_being_created_stays() {
        let dir = tempfile::tempdir().unwrap();
        let corpse = file(dir.path(), "iox2_abc_1.dynamic", 0, 0o200, Duration::ZERO);
        let growing = file(dir.path(), "iox2_abc_2.dynamic", 0, 0o200, Duration::ZERO);
        let removed = remove_half_created_after(dir.path(), || {
            // Its creator is alive: it sizes the segment and makes it readable meanwhile.
            std::fs::File::options()
                .write(true)
                .open(&growing)
                .and_then(|f| f.set_len(64))
                .unwrap();
            std::fs::set_permissions(&growing, std::fs::Permissions::from_mode(0o600)).unwrap();
        });
        assert_eq!(removed, vec![corpse.clone()]);
        assert!(!corpse.exists());
        assert!(growing.exists());
    }

    #[test]
    fn nothing_half_created_means_no_wait() {
        let dir = tempfile::tempdir().unwrap();
        file(dir.path(), "iox2_abc_3.dynamic", 64, 0o600, Duration::ZERO);
        let removed = remove_half_created_after(dir.path(), || panic!("waited for nothing"));
        assert!(removed.is_empty());
    }

    #[test]
    fn a_missing_directory_removes_nothing() {
        assert!(remove_half_created(Path::new("/nonexistent/robotd"), Duration::ZERO).is_empty());
    }
}
