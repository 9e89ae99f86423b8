//! Helpers for the end-to-end tests: start robotd and the example actor as real processes.
#![allow(dead_code)]

pub mod mcp_http;

use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpListener;
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::sync::atomic::{AtomicU32, Ordering};
use std::time::Duration;

/// A bus namespace no other test uses.
pub fn fresh_namespace(tag: &str) -> String {
    static COUNTER: AtomicU32 = AtomicU32::new(0);
    format!(
        "e2e-{tag}-{}-{}",
        std::process::id(),
        COUNTER.fetch_add(1, Ordering::Relaxed)
    )
}

/// A loopback port nothing listens on right now.
pub fn free_port() -> u16 {
    TcpListener::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .map(|a| a.port())
        .expect("a free port")
}

/// The example external actor's binary, built if needed.
pub fn external_actor_binary() -> PathBuf {
    let robotd = PathBuf::from(env!("CARGO_BIN_EXE_robotd"));
    let path = robotd
        .parent()
        .expect("target dir")
        .join("examples")
        .join("external_actor");
    if !path.exists() {
        let status = Command::new(env!("CARGO"))
            .args(["build", "--example", "external_actor"])
            .status()
            .expect("cargo build --example external_actor");
        assert!(status.success(), "building the example failed");
    }
    path
}

/// A child process killed when dropped, with the temporary directory of its logs (removed
/// after the process is gone, so test runs leave nothing behind).
pub struct Running {
    pub child: Child,
    pub name: &'static str,
    logs: Option<tempfile::TempDir>,
}

impl Running {
    /// A running `child`, called `name` in failure messages.
    pub fn new(child: Child, name: &'static str) -> Self {
        Self {
            child,
            name,
            logs: None,
        }
    }

    pub fn pid(&self) -> u32 {
        self.child.id()
    }

    /// The directory the child writes its logs to (`telemetry.log_dir`), when it has one.
    pub fn log_dir(&self) -> Option<&std::path::Path> {
        self.logs.as_ref().map(|dir| dir.path())
    }
}

/// A fresh temporary directory for a child's logs; kept after the test (its path printed) when
/// `KEEP_TEST_LOGS` is set, to read what robotd logged and answered (`mcp_server_*.log`).
fn log_dir() -> tempfile::TempDir {
    let mut dir = tempfile::Builder::new()
        .prefix("robotd-test-logs-")
        .tempdir()
        .expect("a temporary log directory");
    if std::env::var_os("KEEP_TEST_LOGS").is_some() {
        dir.disable_cleanup(true);
        eprintln!("robotd logs in {}", dir.path().display());
    }
    dir
}

impl Drop for Running {
    fn drop(&mut self) {
        // Ask politely first (robotd then stops its actor processes), then insist.
        let _ = Command::new("kill")
            .args(["-TERM", &self.child.id().to_string()])
            .status();
        let deadline = std::time::Instant::now() + Duration::from_secs(3);
        while std::time::Instant::now() < deadline {
            if let Ok(Some(_)) = self.child.try_wait() {
                return;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// Reads lines from `stream` until one contains `marker` (or the stream ends: panic).
fn wait_for_line(stream: impl Read + Send + 'static, marker: &'static str, what: &str) {
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let mut seen = Vec::new();
        for line in BufReader::new(stream).lines().map_while(Result::ok) {
            if line.contains(marker) {
                let _ = tx.send(Ok(()));
                // Keep draining so the child never blocks on a full pipe.
                seen.clear();
                continue;
            }
            seen.push(line);
        }
        let _ = tx.send(Err(seen.join("\n")));
    });
    match rx.recv_timeout(Duration::from_secs(30)) {
        Ok(Ok(())) => {}
        Ok(Err(output)) => panic!("{what} exited before '{marker}':\n{output}"),
        Err(_) => panic!("{what} did not print '{marker}' within 30 s"),
    }
}

/// Starts `robotd serve` and waits until it serves HTTP.
pub fn start_robotd(namespace: &str, port: u16, extra: &[&str]) -> Running {
    start_robotd_with_env(namespace, port, extra, &[])
}

/// [`start_robotd`] with extra environment variables.
pub fn start_robotd_with_env(
    namespace: &str,
    port: u16,
    extra: &[&str],
    env: &[(&str, &str)],
) -> Running {
    let logs = log_dir();
    let mut child = Command::new(env!("CARGO_BIN_EXE_robotd"))
        .envs(env.iter().copied())
        .args(["serve", "--namespace", namespace, "--http"])
        .arg(format!("127.0.0.1:{port}"))
        .arg("--set")
        .arg(format!("telemetry.log_dir={}", logs.path().display()))
        .args(extra)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("start robotd");
    let stderr = child.stderr.take().expect("stderr");
    let running = Running {
        child,
        name: "robotd",
        logs: Some(logs),
    };
    wait_for_line(stderr, "robotd: serving on", "robotd serve");
    running
}

/// Starts `robotd fake-niryo` (the simulator behind the Ned2's TCP protocol) on a free
/// loopback port (unless `args` has its own `--listen`) with the global `settings` (e.g. `--set robot.scene=…`) and `args`; returns
/// it and its port.
pub fn start_fake_niryo(settings: &[&str], args: &[&str]) -> (Running, u16) {
    let logs = log_dir();
    let mut child = Command::new(env!("CARGO_BIN_EXE_robotd"))
        .arg("--set")
        .arg(format!("telemetry.log_dir={}", logs.path().display()))
        .args(settings)
        .arg("fake-niryo")
        .args(if args.contains(&"--listen") {
            &[][..]
        } else {
            &["--listen", "127.0.0.1:0"][..]
        })
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .expect("start robotd fake-niryo");
    let stdout = child.stdout.take().expect("stdout");
    let running = Running {
        child,
        name: "fake-niryo",
        logs: Some(logs),
    };
    let mut first = String::new();
    std::io::BufRead::read_line(&mut std::io::BufReader::new(stdout), &mut first)
        .expect("fake-niryo's first line");
    let port = first
        .trim()
        .rsplit(':')
        .next()
        .and_then(|p| p.parse().ok())
        .unwrap_or_else(|| panic!("fake-niryo said {first:?}"));
    (running, port)
}

/// Starts `robotd fake-widowx` (the simulator behind the WidowX's servo bus on a pty and its
/// MJPEG camera) with the global `settings`, its device at `device` and its camera on a free
/// loopback port; returns it and the camera's URL.
pub fn start_fake_widowx(
    settings: &[&str],
    device: &std::path::Path,
    args: &[&str],
) -> (Running, String) {
    let logs = log_dir();
    let mut child = Command::new(env!("CARGO_BIN_EXE_robotd"))
        .arg("--set")
        .arg(format!("telemetry.log_dir={}", logs.path().display()))
        .args(settings)
        .arg("fake-widowx")
        .arg("--device")
        .arg(device)
        .args(["--camera-listen", "127.0.0.1:0"])
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .expect("start robotd fake-widowx");
    let stdout = child.stdout.take().expect("stdout");
    let running = Running {
        child,
        name: "fake-widowx",
        logs: Some(logs),
    };
    let mut first = String::new();
    std::io::BufRead::read_line(&mut std::io::BufReader::new(stdout), &mut first)
        .expect("fake-widowx's first line");
    let url = first
        .split_whitespace()
        .last()
        .filter(|u| u.starts_with("http://"))
        .unwrap_or_else(|| panic!("fake-widowx said {first:?}"))
        .to_owned();
    (running, url)
}

/// Starts the example actor and waits until it serves.
pub fn start_external_actor(namespace: &str) -> Running {
    let mut child = Command::new(external_actor_binary())
        .args(["--namespace", namespace])
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .expect("start the example actor");
    let stdout = child.stdout.take().expect("stdout");
    let running = Running::new(child, "external_actor");
    wait_for_line(stdout, "ready", "the example actor");
    running
}

/// `GET path` on 127.0.0.1:port; returns (status, body).
pub fn http_get(port: u16, path: &str) -> (u16, String) {
    http_request(port, "GET", path, &[], b"")
}

/// The value of the first metric line starting with `prefix` (name and labels).
pub fn metric(text: &str, prefix: &str) -> Option<f64> {
    text.lines()
        .find(|line| line.starts_with(prefix))
        .and_then(|line| line.rsplit(' ').next())
        .and_then(|v| v.parse().ok())
}

/// `method path` with extra `headers` and `body` on 127.0.0.1:port; returns (status, body).
/// Reads only the status line and what arrives within a short time (enough for refusals).
pub fn http_request(
    port: u16,
    method: &str,
    path: &str,
    headers: &[(&str, &str)],
    body: &[u8],
) -> (u16, String) {
    http_request_from(
        std::net::Ipv4Addr::LOCALHOST,
        port,
        method,
        path,
        headers,
        body,
    )
}

/// [`http_request`] from the local address `source` (any of 127.0.0.0/8 works on Linux: a
/// second client address on one machine). A `Host` in `headers` replaces the default one.
pub fn http_request_from(
    source: std::net::Ipv4Addr,
    port: u16,
    method: &str,
    path: &str,
    headers: &[(&str, &str)],
    body: &[u8],
) -> (u16, String) {
    let (status, _, body) = http_response_from(source, port, method, path, headers, body);
    (status, body)
}

/// [`http_request_from`], returning (status, response head, body).
pub fn http_response_from(
    source: std::net::Ipv4Addr,
    port: u16,
    method: &str,
    path: &str,
    headers: &[(&str, &str)],
    body: &[u8],
) -> (u16, String, String) {
    let connect = async {
        let socket = tokio::net::TcpSocket::new_v4()?;
        socket.bind((source, 0).into())?;
        socket
            .connect(([127, 0, 0, 1], port).into())
            .await?
            .into_std()
    };
    // On a thread of its own: the caller may itself be inside a tokio runtime.
    let mut stream = std::thread::scope(|s| {
        s.spawn(|| {
            tokio::runtime::Builder::new_current_thread()
                .enable_io()
                .build()
                .expect("runtime")
                .block_on(connect)
        })
        .join()
        .expect("connect thread")
    })
    .expect("connect");
    stream.set_nonblocking(false).expect("blocking");
    stream
        .set_read_timeout(Some(Duration::from_secs(5)))
        .expect("timeout");
    let mut head = format!(
        "{method} {path} HTTP/1.1\r\nConnection: close\r\nContent-Length: {}\r\n",
        body.len()
    );
    if !headers.iter().any(|(k, _)| k.eq_ignore_ascii_case("host")) {
        head.push_str(&format!("Host: 127.0.0.1:{port}\r\n"));
    }
    for (k, v) in headers {
        head.push_str(&format!("{k}: {v}\r\n"));
    }
    head.push_str("\r\n");
    stream.write_all(head.as_bytes()).expect("send head");
    // A server may refuse before reading the body; that is fine.
    let _ = stream.write_all(body);
    let mut response = Vec::new();
    let mut buf = [0u8; 4096];
    loop {
        match stream.read(&mut buf) {
            Ok(0) => break,
            Ok(n) => response.extend_from_slice(&buf[..n]),
            Err(_) => break,
        }
        if response.len() > 64 * 1024 {
            break;
        }
    }
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

/// The test venv's python (`./scripts/test.sh` installs tests/python/requirements.txt into
/// `.venv`), or `python3` when there is none.
pub fn python() -> String {
    let venv = concat!(env!("CARGO_MANIFEST_DIR"), "/.venv/bin/python");
    if std::path::Path::new(venv).exists() {
        venv.to_owned()
    } else {
        "python3".to_owned()
    }
}

/// Runs `tests/python/{script}` with the venv's python and `args`, and reads the one JSON
/// object it prints; panics with its stderr when it fails.
pub fn run_python_json(script: &str, args: &[String]) -> serde_json::Value {
    let path = format!("{}/tests/python/{script}", env!("CARGO_MANIFEST_DIR"));
    run_python_json_at(&path, args)
}

/// Runs the Python script at `path` with the venv's python and `args`, and reads the one JSON
/// object it prints; panics with its stderr when it fails.
pub fn run_python_json_at(path: &str, args: &[String]) -> serde_json::Value {
    let script = path;
    let output = Command::new(python())
        .arg(path)
        .args(args)
        .output()
        .expect("run python (install the test venv with ./scripts/test.sh)");
    let stdout = String::from_utf8_lossy(&output.stdout);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(
        output.status.success(),
        "{script} failed (is the test venv installed? ./scripts/test.sh installs \
         tests/python/requirements.txt into .venv):\n{stderr}"
    );
    serde_json::from_str(stdout.trim()).unwrap_or_else(|e| panic!("{e}: {stdout}\n{stderr}"))
}

/// Waits (at most 20 s) until `states` reports the arm moving.
pub async fn wait_until_the_arm_moves(
    states: &mut robotd_runtime::bus::Subscriber<robotd_protocol::arm::ArmState>,
) {
    let deadline = std::time::Instant::now() + Duration::from_secs(20);
    loop {
        let state = tokio::time::timeout(Duration::from_secs(5), states.recv())
            .await
            .expect("arm states")
            .expect("an arm state");
        if state.body.moving {
            return;
        }
        assert!(std::time::Instant::now() < deadline, "the arm never moved");
    }
}

/// Calls `get_detected_objects` on the robotd at `port` (it moves the arm to the observation
/// pose, from where the detection tools and the workspace model's objects come).
pub fn look_at_the_workspace(port: u16) {
    let url = format!("http://127.0.0.1:{port}/mcp");
    let looked = Command::new(env!("CARGO_BIN_EXE_robotd"))
        .args(["call", "get_detected_objects", "--url", &url])
        .output()
        .expect("robotd call");
    assert!(looked.status.success(), "{looked:?}");
}

/// A two-worker tokio runtime for a test's async part.
pub fn runtime() -> tokio::runtime::Runtime {
    tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .expect("a tokio runtime")
}

/// The simulated world's objects, as the simulator reports them on the bus.
pub async fn sim_world(
    bus: &robotd_runtime::bus::Bus,
) -> Vec<robotd_protocol::diagnostics::SimObjectState> {
    bus.client(&robotd_topics::SIM_WORLD)
        .expect("a sim/world client")
        .request(
            &robotd_protocol::diagnostics::SimWorldRequest {},
            Duration::from_secs(5),
        )
        .await
        .expect("the simulated world")
        .objects
}

/// A `redis-server` on `port`, without persistence; killed when dropped.
pub fn start_redis(port: u16) -> Running {
    start_redis_with(port, &[])
}

/// [`start_redis`] with extra server options.
pub fn start_redis_with(port: u16, options: &[&str]) -> Running {
    let child = Command::new("redis-server")
        .args(["--port", &port.to_string()])
        .args(["--bind", "127.0.0.1", "--save", "", "--appendonly", "no"])
        .args(options)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("start redis-server (./scripts/test.sh installs it)");
    let deadline = std::time::Instant::now() + Duration::from_secs(10);
    while std::net::TcpStream::connect(("127.0.0.1", port)).is_err() {
        assert!(
            std::time::Instant::now() < deadline,
            "redis-server did not listen on {port}"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    Running::new(child, "redis-server")
}
