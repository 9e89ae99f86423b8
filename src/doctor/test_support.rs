//! Helpers shared by the doctor's tests: a fake environment, free ports, temporary
//! directories, and a real `redis-server` on a free port.

use super::espeak::find_on_path;
use super::secrets::Secrets;
use std::collections::BTreeMap;
use std::net::{TcpListener, TcpStream};
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// An environment made of `pairs` only; blank values count as unset, as in `doctor::run`.
pub(super) fn env_from(pairs: &[(&str, &str)]) -> impl Fn(&str) -> Option<String> {
    let map: BTreeMap<String, String> = pairs
        .iter()
        .map(|(k, v)| (k.to_string(), v.to_string()))
        .collect();
    move |key: &str| map.get(key).cloned().filter(|v| !v.trim().is_empty())
}

/// No `secrets.env`.
pub(super) fn no_secrets() -> Secrets {
    Secrets {
        path: PathBuf::from("/nonexistent/secrets.env"),
        ..Default::default()
    }
}

/// A TCP port nothing listens on (bound, then released).
pub(super) fn free_port() -> u16 {
    TcpListener::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .map(|a| a.port())
        .expect("bind an ephemeral port")
}

/// A fresh directory under the system's temporary directory.
pub(super) fn temp_dir(tag: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!(
        "robotd-doctor-{tag}-{}-{:?}",
        std::process::id(),
        std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .unwrap_or_default()
            .as_nanos()
    ));
    std::fs::create_dir_all(&dir).expect("create temp dir");
    dir
}

/// Fails the test, naming what to install, when `program` (of the Debian package `package`)
/// is not on `PATH`: a test never passes without running.
pub(super) fn require_program(program: &str, package: &str) {
    let path = std::env::var("PATH").ok();
    assert!(
        find_on_path(program, path.as_deref()).is_some(),
        "{program} is not installed: `apt-get install {package}` (./scripts/test.sh installs \
         what the tests need)"
    );
}

/// A redis-server on a free port with `extra` arguments, killed on drop. The test fails,
/// naming the package, when redis-server is not installed.
pub(super) struct RedisServer {
    child: Child,
    pub(super) port: u16,
}

impl RedisServer {
    pub(super) fn start(extra: &[&str]) -> Self {
        Self::start_on(free_port(), false, extra)
    }

    /// Starts it listening on `port`: plain Redis, or with `tls` TLS only (`--tls-port`, the
    /// plain port off; `extra` then names the certificate files).
    pub(super) fn start_on(port: u16, tls: bool, extra: &[&str]) -> Self {
        require_program("redis-server", "redis-server");
        let port_text = port.to_string();
        let mut args = vec![
            if tls { "--tls-port" } else { "--port" },
            &port_text,
            "--bind",
            "127.0.0.1",
            "--save",
            "",
            "--appendonly",
            "no",
        ];
        if tls {
            args.extend_from_slice(&["--port", "0"]);
        }
        args.extend_from_slice(extra);
        let child = Command::new("redis-server")
            .args(&args)
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .expect("start redis-server");
        let server = RedisServer { child, port };
        let deadline = Instant::now() + Duration::from_secs(10);
        while TcpStream::connect(("127.0.0.1", port)).is_err() {
            assert!(
                Instant::now() < deadline,
                "redis-server did not start on {port}"
            );
            std::thread::sleep(Duration::from_millis(20));
        }
        server
    }
}

impl Drop for RedisServer {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}
