//! Helpers of the speech-to-text tests: robotd with the STT actor supervised as a process,
//! spoken audio made with espeak-ng, and HTTP with room for a transcription's time.
#![allow(dead_code)]

use crate::common::{python, Running};
use std::io::{Read, Write};
use std::path::PathBuf;
use std::process::Command;
use std::time::Duration;

/// `python/robotd/tests/<name>`.
pub fn package_test(name: &str) -> String {
    format!("{}/python/robotd/tests/{name}", env!("CARGO_MANIFEST_DIR"))
}

/// A configuration file with `[actors.stt]` (the venv's python running `robotd.stt`) and
/// `more` appended.
pub fn config_with_stt(namespace: &str, more: &str) -> PathBuf {
    let path = std::env::temp_dir().join(format!("{namespace}-stt.toml"));
    std::fs::write(
        &path,
        format!(
            "[actors.stt]\nmode = \"process\"\ncommand = [{:?}, \"-m\", \"robotd.stt\"]\n\
             supervision = {{ backoff_initial_ms = 20 }}\n{more}",
            python()
        ),
    )
    .unwrap();
    path
}

/// Waits (event-driven, on the bus) until the STT actor serves `stt/transcribe`.
pub fn wait_for_stt(namespace: &str) {
    let runtime = crate::common::runtime();
    runtime.block_on(async {
        let bus = robotd_runtime::bus::Bus::open(robotd_runtime::bus::BusOptions::new(
            namespace, "stt-wait",
        ))
        .unwrap();
        let client = bus.client(&robotd_topics::STT_TRANSCRIBE).unwrap();
        assert!(
            client.wait_for_server(Duration::from_secs(120)).await,
            "the STT actor did not serve stt/transcribe within 120 s (is faster-whisper \
             installed in .venv? ./scripts/test.sh installs it)"
        );
    });
}

/// espeak-ng saying `text` as a `format` file (wav, webm, ogg, pcm) made by
/// `python/robotd/tests/speech_audio.py`; `extra` are its other flags.
pub fn spoken(text: &str, format: &str, extra: &[&str]) -> Vec<u8> {
    let out = tempfile::NamedTempFile::new().unwrap();
    let made = Command::new(python())
        .arg(package_test("speech_audio.py"))
        .arg(text)
        .args(["--format", format, "--out"])
        .arg(out.path())
        .args(extra)
        .output()
        .expect("run speech_audio.py");
    assert!(
        made.status.success(),
        "speech_audio.py: {}",
        String::from_utf8_lossy(&made.stderr)
    );
    std::fs::read(out.path()).unwrap()
}

/// `POST path` with `headers` and `body`; waits up to 60 s for the whole answer. Returns
/// (status, head, body).
pub fn post(port: u16, path: &str, headers: &[(&str, &str)], body: &[u8]) -> (u16, String, String) {
    let mut stream = std::net::TcpStream::connect(("127.0.0.1", port)).expect("connect");
    stream
        .set_read_timeout(Some(Duration::from_secs(60)))
        .unwrap();
    let mut head = format!(
        "POST {path} HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nConnection: close\r\n\
         Content-Length: {}\r\n",
        body.len()
    );
    for (k, v) in headers {
        head.push_str(&format!("{k}: {v}\r\n"));
    }
    head.push_str("\r\n");
    stream.write_all(head.as_bytes()).unwrap();
    let _ = stream.write_all(body);
    let mut response = Vec::new();
    let _ = stream.read_to_end(&mut response);
    let response = String::from_utf8_lossy(&response).to_string();
    let status = response
        .split_whitespace()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(0);
    let (head, body) = response
        .split_once("\r\n\r\n")
        .map(|(h, b)| (h.to_owned(), b.to_owned()))
        .unwrap_or_default();
    (status, head, body)
}

/// The `actor` row of `/health` (it answers 503 while an actor restarts).
pub fn actor_health(port: u16, actor: &str) -> serde_json::Value {
    let (status, body) = crate::common::http_get(port, "/health");
    assert!(status == 200 || status == 503, "{status}: {body}");
    let report: serde_json::Value = serde_json::from_str(&body).unwrap();
    report["actors"]
        .as_array()
        .and_then(|actors| actors.iter().find(|a| a["actor"] == actor))
        .cloned()
        .unwrap_or_else(|| panic!("no {actor} actor in {report}"))
}

/// Keeps the running robotd and removes its configuration file when dropped.
pub struct WithConfig {
    pub robotd: Running,
    pub config: PathBuf,
}

impl Drop for WithConfig {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.config);
    }
}

/// robotd on `port` in `namespace` with the STT actor (and `more` configuration), once the
/// actor serves.
pub fn robotd_with_stt(namespace: &str, port: u16, more: &str, extra: &[&str]) -> WithConfig {
    let config = config_with_stt(namespace, more);
    let mut args = vec!["--config", config.to_str().unwrap()];
    args.extend_from_slice(extra);
    let robotd = crate::common::start_robotd(namespace, port, &args);
    wait_for_stt(namespace);
    WithConfig { robotd, config }
}
