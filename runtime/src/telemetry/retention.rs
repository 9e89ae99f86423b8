//! Retention of files that a run of robotd starts anew: each run or session writes a file of
//! its own (`mcp_server_<stamp>.log`, `mcp_client_<stamp>.log`), so the files of earlier runs
//! pile up over months unless something deletes them. The writers call these two when they
//! open their new file:
//!
//! - [`keep_newest`]: of the files a predicate matches, keeps the `keep` last modified and
//!   deletes the rest (a count limit);
//! - [`remove_older_than`]: deletes the matching files last modified longer ago than an age
//!   (an age limit).
//!
//! Both report how many files they deleted. A file that cannot be deleted (or read) is left,
//! and the clean-up goes on: retention never stops a writer from opening its file.

use std::path::{Path, PathBuf};
use std::time::{Duration, SystemTime};

/// The regular files in `dir` whose names `matches`, with their modification times.
fn matching(dir: &Path, matches: &dyn Fn(&str) -> bool) -> Vec<(SystemTime, PathBuf)> {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return Vec::new();
    };
    entries
        .filter_map(Result::ok)
        .filter(|entry| entry.file_name().to_str().is_some_and(matches))
        .filter_map(|entry| {
            let meta = entry.metadata().ok()?;
            meta.is_file()
                .then(|| Some((meta.modified().ok()?, entry.path())))
                .flatten()
        })
        .collect()
}

/// Deletes all but the `keep` newest files of `dir` whose names `matches`; returns how many
/// were deleted.
pub fn keep_newest(dir: &Path, matches: impl Fn(&str) -> bool, keep: usize) -> usize {
    let mut files = matching(dir, &matches);
    // Newest first; equal times by name, newest stamp first.
    files.sort_by(|a, b| b.0.cmp(&a.0).then_with(|| b.1.cmp(&a.1)));
    files
        .into_iter()
        .skip(keep)
        .filter(|(_, path)| std::fs::remove_file(path).is_ok())
        .count()
}

/// Deletes the files of `dir` whose names `matches` and that were last modified more than
/// `age` before `now`; returns how many were deleted.
pub fn remove_older_than(
    dir: &Path,
    matches: impl Fn(&str) -> bool,
    age: Duration,
    now: SystemTime,
) -> usize {
    matching(dir, &matches)
        .into_iter()
        .filter(|(modified, _)| now.duration_since(*modified).is_ok_and(|old| old > age))
        .filter(|(_, path)| std::fs::remove_file(path).is_ok())
        .count()
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::fs::File;

    /// A file `name` in `dir` last modified `ago` before `now`.
    fn file(dir: &Path, name: &str, now: SystemTime, ago: Duration) {
        let file = File::create(dir.join(name)).unwrap();
        file.set_modified(now - ago).unwrap();
    }

    fn names(dir: &Path) -> Vec<String> {
        let mut names: Vec<String> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().into_string().unwrap())
            .collect();
        names.sort();
        names
    }

    #[test]
    fn keeps_the_newest_matching_files_and_nothing_else_is_touched() {
        let dir = tempfile::tempdir().unwrap();
        let now = SystemTime::now();
        for day in 0..6u64 {
            let name = format!("mcp_server_2026010{day}_000000.log");
            file(
                dir.path(),
                &name,
                now,
                Duration::from_secs(86_400 * (6 - day)),
            );
        }
        file(
            dir.path(),
            "robotd.2026-01-01.log",
            now,
            Duration::from_secs(1e6 as u64),
        );
        let deleted = keep_newest(dir.path(), |n| n.starts_with("mcp_server_"), 2);
        assert_eq!(deleted, 4);
        assert_eq!(
            names(dir.path()),
            [
                "mcp_server_20260104_000000.log",
                "mcp_server_20260105_000000.log",
                "robotd.2026-01-01.log"
            ]
        );
        assert_eq!(keep_newest(dir.path(), |n| n.starts_with("mcp_"), 2), 0);
    }

    #[test]
    fn removes_only_what_is_older_than_the_age() {
        let dir = tempfile::tempdir().unwrap();
        let now = SystemTime::now();
        let day = Duration::from_secs(86_400);
        file(dir.path(), "mcp_client_old.log", now, day * 31);
        file(dir.path(), "mcp_client_new.log", now, day * 29);
        file(dir.path(), "notes.txt", now, day * 400);
        let deleted = remove_older_than(
            dir.path(),
            |n| n.starts_with("mcp_client_") && n.ends_with(".log"),
            day * 30,
            now,
        );
        assert_eq!(deleted, 1);
        assert_eq!(names(dir.path()), ["mcp_client_new.log", "notes.txt"]);
    }

    #[test]
    fn a_missing_directory_deletes_nothing() {
        let dir = tempfile::tempdir().unwrap();
        let gone = dir.path().join("gone");
        assert_eq!(keep_newest(&gone, |_| true, 0), 0);
        assert_eq!(
            remove_older_than(&gone, |_| true, Duration::ZERO, SystemTime::now()),
            0
        );
    }
}
