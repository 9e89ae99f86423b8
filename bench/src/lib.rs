//! `robotd bench`: measurements of robotd's own machinery, each beside its raw baseline
//! measured in the same run (these machines are noisy; only same-run ratios mean much).
//!
//! This crate holds every benchmark; the binary only hands it the parsed command line
//! ([`cli::BenchCommand`]) through [`run`]. Two-process measurements re-run the `robotd`
//! binary as a peer (`robotd bench-peer <role>`, served by [`run_peer`]), so everything
//! crosses a real process boundary. Each benchmark prints a table or, with `--json`, one JSON
//! object; BENCHMARKS.md says which command produced which figure.
//!
//! The crate sits in the binary's layer: it starts the robot, its actors and edges like
//! `robotd serve` does, and it enables the test-only parts of other crates (perception's
//! ground-truth scoring, the agent's scripted LLM server), so the service binary built
//! without the `bench` feature carries none of them.

pub mod bus;
pub mod cli;
pub mod jpeg;
pub mod mcp;
pub mod mcp_raw;
pub mod mcp_raw_sse;
pub mod niryo;
pub mod perception;
pub mod perception_randomized;
pub mod ping;
pub mod redis;
pub mod safety;
pub mod sim;
pub mod soak;
pub mod stats;
pub mod stopping;
pub mod table;
pub mod tcp_echo;
pub mod widowx;

mod dispatch;

pub use dispatch::{run, run_peer};
pub use stats::Latency;

/// A child process of a benchmark (a `robotd serve`, a redis-server): stopped with SIGTERM
/// when dropped, and killed if it has not ended 5 s later.
pub struct Served(pub std::process::Child);

impl Drop for Served {
    fn drop(&mut self) {
        let _ = std::process::Command::new("kill")
            .args(["-TERM", &self.0.id().to_string()])
            .status();
        let deadline = std::time::Instant::now() + std::time::Duration::from_secs(5);
        while std::time::Instant::now() < deadline {
            if let Ok(Some(_)) = self.0.try_wait() {
                return;
            }
            std::thread::sleep(std::time::Duration::from_millis(20));
        }
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// Waits until the `robotd serve` in `served` (started with its stderr piped) says it serves;
/// its stderr is read to the end on a thread of its own so the service never blocks on it.
pub fn wait_until_serving(served: &mut Served) -> anyhow::Result<()> {
    use anyhow::Context;
    use std::io::{BufRead, BufReader};
    let stderr = served.0.stderr.take().context("robotd's stderr")?;
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let mut ready = Some(tx);
        for line in BufReader::new(stderr).lines().map_while(Result::ok) {
            if line.contains("robotd: serving on") {
                if let Some(tx) = ready.take() {
                    let _ = tx.send(());
                }
            }
        }
    });
    rx.recv_timeout(std::time::Duration::from_secs(60))
        .context("robotd serve did not start within 60 s")
}
