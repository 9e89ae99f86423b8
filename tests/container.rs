//! The container image (Dockerfile): built, started with the shared memory the bus needs and
//! a token, until `/health` answers from inside the container.
//!
//! Ignored by default: it needs a running Docker daemon that can pull the Rust and Debian base
//! images, and compiles robotd with the `dist` profile inside the image (a long build). Run it
//! with `cargo nextest run --test container --run-ignored only` (or
//! `cargo test --test container -- --ignored`); `ROBOTD_IMAGE_PROFILE=release` builds faster.

mod common;

use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

const IMAGE: &str = "robotd:test";
const TOKEN: &str = "container-test-token-0123456789";

fn docker(args: &[&str]) -> std::process::Output {
    Command::new("docker")
        .args(args)
        .output()
        .expect("run docker")
}

/// Removes the container when the test ends, however it ends.
struct Container(String);

impl Drop for Container {
    fn drop(&mut self) {
        let _ = docker(&["rm", "-f", &self.0]);
    }
}

#[test]
#[ignore = "needs a Docker daemon and a long image build: cargo test --test container -- --ignored"]
fn the_image_serves_health_from_a_container() {
    let info = docker(&["info"]);
    assert!(
        info.status.success(),
        "no Docker daemon: {}",
        String::from_utf8_lossy(&info.stderr)
    );
    let profile = std::env::var("ROBOTD_IMAGE_PROFILE").unwrap_or_else(|_| "dist".into());
    let built = Command::new("docker")
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .args(["build", "-t", IMAGE, "--build-arg"])
        .arg(format!("PROFILE={profile}"))
        .arg(".")
        .stdout(Stdio::inherit())
        .stderr(Stdio::inherit())
        .status()
        .expect("docker build");
    assert!(built.success(), "docker build failed");

    let port = common::free_port();
    let name = common::fresh_namespace("container");
    let run = docker(&[
        "run",
        "-d",
        "--name",
        &name,
        "--shm-size=512m",
        "-p",
        &format!("127.0.0.1:{port}:8000"),
        "-e",
        &format!("ROBOTD_MCP__TOKEN={TOKEN}"),
        IMAGE,
    ]);
    assert!(
        run.status.success(),
        "docker run: {}",
        String::from_utf8_lossy(&run.stderr)
    );
    let _container = Container(name.clone());

    let deadline = Instant::now() + Duration::from_secs(60);
    let authorization = format!("Bearer {TOKEN}");
    loop {
        // Until robotd listens, the connection is refused or reset (the helper panics then).
        let answer = std::panic::catch_unwind(|| {
            common::http_request(
                port,
                "GET",
                "/health",
                &[("Authorization", &authorization)],
                b"",
            )
        });
        let (status, body) = answer.unwrap_or((0, String::new()));
        if status == 200 {
            assert!(body.contains("\"status\""), "{body}");
            break;
        }
        if Instant::now() > deadline {
            let logs = docker(&["logs", &name]);
            panic!(
                "no /health from the container within 60 s (last status {status}); logs:\n{}",
                String::from_utf8_lossy(&logs.stderr)
            );
        }
        std::thread::sleep(Duration::from_millis(250));
    }
    // Without the token the port refuses.
    let (status, _) = common::http_get(port, "/health");
    assert_eq!(status, 401);
}
