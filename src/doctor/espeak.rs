//! `espeak-ng`: the speech actor speaks through the `espeak-ng` program.
//!
//! Without it robotd cannot say anything (the `say` tool fails), so a missing program is a
//! problem. The check looks it up on `PATH` like a shell would and runs `espeak-ng --version`,
//! killing it if it does not answer within a few seconds — a broken install can hang on its
//! data files, and the doctor must never hang with it.

use super::Check;
use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// How long an external program (`espeak-ng --version`) may take.
const PROGRAM_TIMEOUT: Duration = Duration::from_secs(3);

pub(super) fn find_on_path(program: &str, path_var: Option<&str>) -> Option<PathBuf> {
    use std::os::unix::fs::PermissionsExt;
    let path_var = path_var?;
    std::env::split_paths(path_var)
        .map(|dir| dir.join(program))
        .find(|candidate| {
            std::fs::metadata(candidate)
                .map(|m| m.is_file() && m.permissions().mode() & 0o111 != 0)
                .unwrap_or(false)
        })
}

/// Runs `program args`, killing it if it takes longer than `timeout`; returns its stdout.
fn run_bounded(
    program: &Path,
    args: &[&str],
    timeout: Duration,
) -> std::result::Result<String, String> {
    let mut child = Command::new(program)
        .args(args)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .map_err(|e| format!("could not start: {e}"))?;
    let deadline = Instant::now() + timeout;
    let status = loop {
        match child.try_wait() {
            Ok(Some(status)) => break status,
            Ok(None) if Instant::now() < deadline => std::thread::sleep(Duration::from_millis(10)),
            Ok(None) => {
                let _ = child.kill();
                let _ = child.wait();
                return Err(format!("no answer within {} s", timeout.as_secs()));
            }
            Err(e) => return Err(format!("could not wait for it: {e}")),
        }
    };
    let mut out = String::new();
    if let Some(mut stdout) = child.stdout.take() {
        let _ = stdout.read_to_string(&mut out);
    }
    if status.success() {
        Ok(out)
    } else {
        Err(format!("exited with {status}"))
    }
}

pub(super) fn check_espeak(path_var: Option<&str>) -> Check {
    const NAME: &str = "espeak-ng";
    const FIX: &str = "apt-get install espeak-ng";
    let Some(path) = find_on_path("espeak-ng", path_var) else {
        return Check::problem(
            NAME,
            "espeak-ng not found on PATH; robotd cannot speak",
            FIX,
        );
    };
    match run_bounded(&path, &["--version"], PROGRAM_TIMEOUT) {
        Ok(out) => {
            // "eSpeak NG text-to-speech: 1.51  Data at: /usr/lib/..."
            let version = out
                .split_once(':')
                .and_then(|(_, rest)| rest.split_whitespace().next())
                .unwrap_or("(unknown version)");
            Check::ok(NAME, format!("espeak-ng {version} at {}", path.display()))
        }
        Err(e) => Check::problem(
            NAME,
            format!("{} --version failed: {e}", path.display()),
            format!("reinstall it: apt-get install --reinstall espeak-ng ({FIX})"),
        ),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::doctor::Status;

    #[test]
    fn espeak_missing_is_a_problem() {
        let check = check_espeak(Some("/nonexistent"));
        assert_eq!(check.status, Status::Problem);
        assert_eq!(check.fix.as_deref(), Some("apt-get install espeak-ng"));
    }

    #[test]
    fn espeak_installed_is_ok_with_its_version() {
        crate::doctor::test_support::require_program("espeak-ng", "espeak-ng");
        let path = std::env::var("PATH").ok();
        let check = check_espeak(path.as_deref());
        assert_eq!(check.status, Status::Ok, "{check:?}");
        assert!(!check.found.contains("unknown version"), "{check:?}");
    }
}
