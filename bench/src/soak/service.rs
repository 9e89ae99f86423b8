//! The soak's world: robotd serve with the agent, the Redis edge, an injected gripper fault and
//! a supervised external actor, plus the redis-server it talks to; and the faults the soak
//! injects from outside (Redis going away and back, the external actor killed).

use anyhow::{bail, Context, Result};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// Every how many gripper commands the simulated gripper fails (panics), so supervision
/// restarts it during the soak.
pub const GRIPPER_FAIL_EVERY_N: u32 = 15;

/// The name of the supervised external actor in the soak's configuration.
pub const EXTERNAL_ACTOR: &str = "soak_peer";

pub use crate::Served;

/// A free loopback port.
pub fn free_port() -> Result<u16> {
    Ok(std::net::TcpListener::bind("127.0.0.1:0")?
        .local_addr()?
        .port())
}

/// A redis-server on `port` (no persistence), once it listens.
pub fn start_redis(port: u16) -> Result<Served> {
    let child = Command::new("redis-server")
        .args(["--port", &port.to_string(), "--bind", "127.0.0.1"])
        .args(["--save", "", "--appendonly", "no"])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .context("starting redis-server (the soak needs it: apt install redis-server)")?;
    let served = Served(child);
    let deadline = Instant::now() + Duration::from_secs(10);
    while std::net::TcpStream::connect(("127.0.0.1", port)).is_err() {
        if Instant::now() > deadline {
            bail!("redis-server did not listen on port {port} within 10 s");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    Ok(served)
}

/// What the soak's robotd needs to know.
pub struct ServiceSetup<'a> {
    /// The robotd binary.
    pub exe: &'a Path,
    /// Bus namespace.
    pub namespace: &'a str,
    /// HTTP port (MCP, health).
    pub port: u16,
    /// The Redis edge's URL.
    pub redis_url: &'a str,
    /// The mock LLM's OpenAI base URL.
    pub llm_base_url: &'a str,
    /// A directory for the config file and logs.
    pub dir: &'a Path,
}

/// Starts robotd serve for the soak; returns once it serves.
pub fn start_robotd(setup: &ServiceSetup<'_>) -> Result<Served> {
    let config = write_config(setup)?;
    let mut command = Command::new(setup.exe);
    command
        .args(["serve", "--config"])
        .arg(&config)
        .args(["--namespace", setup.namespace, "--http"])
        .arg(format!("127.0.0.1:{}", setup.port))
        .args(["--redis", setup.redis_url])
        .current_dir(setup.dir)
        .env("RUST_LOG", "warn")
        .env("OPENAI_API_KEY", "sk-soak-mock")
        .env("OPENAI_BASE_URL", setup.llm_base_url)
        .stdout(Stdio::null())
        .stderr(Stdio::piped());
    for v in [
        "GROQ_API_KEY",
        "GEMINI_API_KEY",
        "API_KEY",
        "LLM_BASE_URL",
        "OLLAMA_HOST",
    ] {
        command.env_remove(v);
    }
    let mut served = Served(command.spawn().context("starting robotd serve")?);
    crate::wait_until_serving(&mut served)?;
    Ok(served)
}

fn write_config(setup: &ServiceSetup<'_>) -> Result<PathBuf> {
    let path = setup.dir.join("soak.toml");
    let text = format!(
        r#"# Written by robotd bench soak.
[robot]
time_scale = 0.05

[robot.faults.gripper]
fail_every_n = {GRIPPER_FAIL_EVERY_N}

[supervision]
# Injected faults restart the gripper every few minutes: a budget that a soak does not
# exhaust (a real deployment keeps the default).
max_restarts = 1000
window_s = 60

[safety]
# MCP clients count as LLM origins, whose motions share one budget (240 a minute by default).
# The soak's visitors, one a second, each looking and moving the pencil, ask for more than that
# once no fault slows them: refusals would then starve the pencil's moves and the run would
# measure the rate limit (tested in robotd-safety, src/rate.rs), not endurance. The limiter
# stays in the path, above the load.
llm_motions_per_minute = 6000

[mcp]
# One visiting client in ten abandons its session: expire those within the warm-up, so the
# sessions open reach their steady state before memory is judged.
session_idle_timeout_s = 20

[telemetry]
log_dir = {logs:?}

[agent]
api = "openai"
model = "soak-mock"

[actors.{EXTERNAL_ACTOR}]
mode = "process"
command = [{exe:?}, "bench-peer", "bus-rtt", "--peer-namespace", {ns:?}, "--count", "0"]
supervision = {{ max_restarts = 1000, window_s = 60, backoff_initial_ms = 20 }}
"#,
        logs = setup.dir.join("logs").display().to_string(),
        exe = setup.exe.display().to_string(),
        ns = setup.namespace,
    );
    std::fs::write(&path, text).with_context(|| format!("writing {}", path.display()))?;
    Ok(path)
}

/// The pid of the child of `parent` whose command line contains `needle` (not a zombie).
pub fn child_with(parent: u32, needle: &str) -> Option<u32> {
    for entry in std::fs::read_dir("/proc").ok()?.flatten() {
        let Ok(pid) = entry.file_name().to_string_lossy().parse::<u32>() else {
            continue;
        };
        let Ok(stat) = std::fs::read_to_string(format!("/proc/{pid}/stat")) else {
            continue;
        };
        let after = stat.rsplit_once(')').map(|(_, rest)| rest).unwrap_or("");
        let mut fields = after.split_whitespace();
        let state = fields.next();
        let ppid: Option<u32> = fields.next().and_then(|p| p.parse().ok());
        if ppid == Some(parent) && state != Some("Z") {
            let cmdline = std::fs::read(format!("/proc/{pid}/cmdline")).unwrap_or_default();
            if String::from_utf8_lossy(&cmdline).contains(needle) {
                return Some(pid);
            }
        }
    }
    None
}
