//! End-to-end tests of `robotd doctor --json`: the built binary, its JSON report, its exit code,
//! a real redis-server, and that secrets never reach the output.

use serde_json::Value;
use std::net::{TcpListener, TcpStream};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

const SECRET: &str = "sk-test-secret-value";
const CHECKS: [&str; 8] = [
    "shm",
    "disk",
    "iceoryx2",
    "redis",
    "redis-edge",
    "espeak-ng",
    "audio",
    "llm-keys",
];

fn free_port() -> u16 {
    TcpListener::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .map(|a| a.port())
        .expect("bind an ephemeral port")
}

/// What one `robotd doctor` run printed and how it exited.
struct Run {
    code: Option<i32>,
    stdout: String,
    stderr: String,
}

impl Run {
    fn json(&self) -> Value {
        serde_json::from_str(&self.stdout).unwrap_or_else(|e| {
            panic!(
                "stdout is not JSON ({e})\nstdout:\n{}\nstderr:\n{}",
                self.stdout, self.stderr
            )
        })
    }
}

/// Runs `robotd doctor --json <args>` with a controlled environment; fails the test if the
/// doctor does not finish within 30 s (every check is meant to be bounded).
fn doctor(args: &[&str]) -> Run {
    let mut child = Command::new(env!("CARGO_BIN_EXE_robotd"))
        .arg("doctor")
        .arg("--json")
        .args(args)
        .env("OPENAI_API_KEY", SECRET)
        .env_remove("REDIS_HOST")
        .env_remove("REDIS_PORT")
        .env_remove("REDIS_PASSWORD")
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("start robotd doctor");
    // Drain the pipes on threads so a chatty child cannot block on a full pipe.
    let mut out = child.stdout.take().expect("stdout");
    let mut err = child.stderr.take().expect("stderr");
    let out_reader = std::thread::spawn(move || {
        let mut s = String::new();
        let _ = std::io::Read::read_to_string(&mut out, &mut s);
        s
    });
    let err_reader = std::thread::spawn(move || {
        let mut s = String::new();
        let _ = std::io::Read::read_to_string(&mut err, &mut s);
        s
    });
    let deadline = Instant::now() + Duration::from_secs(30);
    let status = loop {
        if let Some(status) = child.try_wait().expect("wait for robotd doctor") {
            break status;
        }
        if Instant::now() > deadline {
            let _ = child.kill();
            let _ = child.wait();
            panic!("robotd doctor did not finish within 30 s");
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    Run {
        code: status.code(),
        stdout: out_reader.join().expect("stdout reader"),
        stderr: err_reader.join().expect("stderr reader"),
    }
}

fn row<'a>(report: &'a Value, name: &str) -> &'a Value {
    report["checks"]
        .as_array()
        .expect("checks is an array")
        .iter()
        .find(|c| c["name"] == name)
        .unwrap_or_else(|| panic!("no '{name}' row in {report}"))
}

fn assert_no_secret(run: &Run) {
    assert!(
        !run.stdout.contains(SECRET) && !run.stderr.contains(SECRET),
        "the OPENAI_API_KEY value was printed:\n{}\n{}",
        run.stdout,
        run.stderr
    );
}

/// A redis-server on a free port, killed when dropped.
struct RedisServer {
    child: Child,
    port: u16,
}

impl RedisServer {
    /// Fails the test, naming the package, when redis-server is not installed.
    fn start() -> Self {
        let port = free_port();
        let child = match Command::new("redis-server")
            .args(["--port", &port.to_string(), "--bind", "127.0.0.1"])
            .args(["--save", "", "--appendonly", "no"])
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
        {
            Ok(child) => child,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => panic!(
                "redis-server is not installed: `apt-get install redis-server` \
                 (./scripts/test.sh installs what the tests need)"
            ),
            Err(e) => panic!("could not start redis-server: {e}"),
        };
        let server = RedisServer { child, port };
        let deadline = Instant::now() + Duration::from_secs(10);
        while TcpStream::connect(("127.0.0.1", port)).is_err() {
            assert!(
                Instant::now() < deadline,
                "redis-server did not listen on {port} within 10 s"
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

#[test]
fn doctor_json_has_a_row_per_check_and_hides_secrets() {
    let run = doctor(&[]);
    assert_no_secret(&run);
    let report = run.json();
    let rows = report["checks"].as_array().expect("checks is an array");
    let names: Vec<&str> = rows.iter().filter_map(|c| c["name"].as_str()).collect();
    for name in CHECKS {
        assert!(names.contains(&name), "no '{name}' row in {names:?}");
    }
    for check in rows {
        let status = check["status"].as_str().expect("status is a string");
        assert!(
            ["ok", "warn", "problem"].contains(&status),
            "bad status in {check}"
        );
        assert!(check["found"].is_string(), "no 'found' in {check}");
        if status != "ok" {
            assert!(
                check["fix"].is_string(),
                "a {status} row without a fix: {check}"
            );
        }
    }
    let llm = row(&report, "llm-keys");
    assert!(
        llm["found"]
            .as_str()
            .unwrap_or_default()
            .contains("OPENAI_API_KEY set (from env)"),
        "{llm}"
    );
    let problems = rows.iter().filter(|c| c["status"] == "problem").count();
    assert_eq!(
        run.code,
        Some(if problems > 0 { 1 } else { 0 }),
        "exit code must be 1 exactly when there are problems: {report}"
    );
}

#[test]
fn doctor_unreachable_redis_is_a_problem_and_exits_1() {
    let port = free_port(); // bound and released: nothing listens there now
    let url = format!("redis://127.0.0.1:{port}");
    let start = Instant::now();
    let run = doctor(&["--redis", &url]);
    assert!(
        start.elapsed() < Duration::from_secs(15),
        "took {:?}",
        start.elapsed()
    );
    assert_no_secret(&run);
    let report = run.json();
    let redis = row(&report, "redis");
    assert_eq!(redis["status"], "problem", "{redis}");
    assert!(
        redis["fix"]
            .as_str()
            .unwrap_or_default()
            .contains("redis-server"),
        "{redis}"
    );
    assert_eq!(run.code, Some(1), "stderr: {}", run.stderr);
}

#[test]
fn doctor_reaches_a_real_redis_server() {
    let server = RedisServer::start();
    let url = format!("redis://127.0.0.1:{}", server.port);
    let run = doctor(&["--redis", &url]);
    assert_no_secret(&run);
    let report = run.json();
    let redis = row(&report, "redis");
    assert_eq!(redis["status"], "ok", "{redis}");
    assert!(
        redis["found"].as_str().unwrap_or_default().contains("PONG"),
        "{redis}"
    );
    drop(server);
}
