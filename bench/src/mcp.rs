//! `robotd bench mcp`: what MCP clients get from a served robotd.
//!
//! Starts `robotd serve` (this binary, simulated Ned2) as its own process on a free port,
//! moves the arm to the observation pose, then measures from this process:
//!
//! 1. latency of `get_workspace_coordinate_from_point` (no motion, one bus round trip) and of
//!    `get_detected_objects` (arm already at the observation pose: answered from the workspace
//!    model at once) over legacy SSE and streamable HTTP, one call at a time;
//! 2. the same two tools called directly on the tool registry over the bus (no MCP, no HTTP):
//!    the baseline the MCP edge adds to;
//! 3. the first tool over streamable HTTP and legacy SSE again with the leanest client
//!    ([`super::mcp_raw`], [`super::mcp_raw_sse`]): how much of the per-call cost is the
//!    server's (robotd's rmcp-based client adds ~0.1–0.3 ms on its side), interleaved with an MCP
//!    `ping` (rmcp's session pipeline without a tool) and a `GET /health` (the HTTP floor) on
//!    the streamable-HTTP connection, so the server's share splits into layers; and a loopback
//!    TCP round trip to a peer process ([`super::tcp_echo`]): the raw floor under all of them;
//! 4. calls per second with 8 and 64 concurrent streamable-HTTP clients;
//! 5. the service's resident memory (VmRSS) after the load, and after the clients left.
//!
//! With `--one-core`, this process pins itself to CPU 0 before it starts anything, so the
//! service, the peers and every thread of both run on that one CPU. On a VM where waking a
//! thread on another CPU is slow (the 2-vCPU CI machine: ~55 µs, `robotd bench bus`'s
//! "pinned to two cores"), the default figures are mostly those cross-CPU wake-ups; pinned,
//! they show what robotd's own code costs per call.

use super::{Latency, Served};
use anyhow::{bail, Context, Result};
use rmcp::model::CallToolRequestParams;
use robotd_mcp::client::{connect, McpClient};
use robotd_protocol::workspace::WorkspaceInfo;
use robotd_runtime::bus::{Bus, BusOptions};
use robotd_tools::{CallHooks, Registry, ToolSettings};
use serde::Serialize;
use serde_json::{json, Map, Value};
use std::path::Path;
use std::process::{Command, Stdio};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// Everything `robotd bench mcp` measures.
#[derive(Debug, Clone, Serialize)]
pub struct McpFigures {
    /// `get_workspace_coordinate_from_point` over SSE, µs.
    pub coordinate_sse_us_p50: f64,
    /// 99th percentile of the same, µs.
    pub coordinate_sse_us_p99: f64,
    /// `get_workspace_coordinate_from_point` over streamable HTTP, µs.
    pub coordinate_http_us_p50: f64,
    /// 99th percentile of the same, µs.
    pub coordinate_http_us_p99: f64,
    /// `get_detected_objects` at the observation pose over SSE, µs.
    pub objects_sse_us_p50: f64,
    /// 99th percentile of the same, µs.
    pub objects_sse_us_p99: f64,
    /// `get_detected_objects` at the observation pose over streamable HTTP, µs.
    pub objects_http_us_p50: f64,
    /// 99th percentile of the same, µs.
    pub objects_http_us_p99: f64,
    /// `get_workspace_coordinate_from_point` over streamable HTTP with the leanest client
    /// (plain HTTP requests, no MCP client library), µs.
    pub coordinate_http_raw_us_p50: f64,
    /// `get_workspace_coordinate_from_point` over legacy SSE with the leanest client (posted
    /// on one connection, answer read from the event stream), µs; timed interleaved with the
    /// streamable-HTTP call above.
    pub coordinate_sse_raw_us_p50: f64,
    /// MCP `ping` over streamable HTTP with the leanest client (rmcp's session pipeline, no
    /// tool), µs; timed interleaved with the call above.
    pub ping_http_raw_us_p50: f64,
    /// `GET /health` on the same connection (TCP, HTTP and the port's guard: the floor of any
    /// HTTP call), µs; timed interleaved with the two above.
    pub http_floor_us_p50: f64,
    /// Raw baseline: a loopback TCP round trip between this process and a peer process
    /// ([`super::tcp_echo`]), µs, right after the three above.
    pub tcp_echo_us_p50: f64,
    /// Baseline: `get_workspace_coordinate_from_point` on the registry directly, µs.
    pub coordinate_direct_us_p50: f64,
    /// Baseline: `get_detected_objects` on the registry directly, µs.
    pub objects_direct_us_p50: f64,
    /// Calls per second, 8 concurrent streamable-HTTP clients.
    pub calls_per_s_8_clients: f64,
    /// Calls per second, 64 concurrent streamable-HTTP clients.
    pub calls_per_s_64_clients: f64,
    /// Resident memory of the robotd service right after the load, MB (the 74 sessions open).
    pub service_rss_mb: f64,
    /// Resident memory of the robotd service 3 s after the load with the sessions still open,
    /// MB (the service returns freed memory once the calls stop for a second).
    pub service_rss_quiet_mb: f64,
    /// Resident memory of the robotd service 3 s after every client closed its session, MB.
    pub service_rss_after_clients_left_mb: f64,
    /// Sequential calls per latency measurement.
    pub calls: usize,
    /// Seconds of each throughput run.
    pub throughput_s: f64,
    /// Whether the service and this benchmark ran pinned to one CPU (`--one-core`).
    pub one_core: bool,
    /// On a VM guest with the `haltpoll` cpuidle driver, how long an idle vCPU polls before
    /// it halts (`/sys/module/haltpoll/parameters/guest_halt_poll_ns`); `None` elsewhere.
    /// With 0, every wake-up of an idle vCPU goes through the hypervisor (~50–100 µs on the
    /// 2-vCPU VM), and a call over loopback pays one on each side.
    pub guest_halt_poll_ns: Option<u64>,
}

impl McpFigures {
    /// The figures as a table with the targets.
    pub fn table(&self) -> String {
        format!(
            "measure                                             p50 / p99 µs        target\n\
             get_workspace_coordinate_from_point, SSE           {:>7.0} / {:>7.0}   p50 ≤ 500\n\
             get_workspace_coordinate_from_point, HTTP          {:>7.0} / {:>7.0}   p50 ≤ 500\n\
             get_workspace_coordinate_from_point, HTTP, raw     {:>7.0}           (lean client)\n\
             get_workspace_coordinate_from_point, SSE, raw      {:>7.0}           (lean client)\n\
             MCP ping, HTTP, raw                                {:>7.0}           (lean client)\n\
             GET /health (HTTP floor)                           {:>7.0}           (lean client)\n\
             loopback TCP round trip (raw baseline)             {:>7.0}\n\
             get_workspace_coordinate_from_point, direct        {:>7.0}\n\
             MCP overhead (p50 − direct): SSE / HTTP            {:>7.0} / {:>7.0}   (robotd's client)\n\
             MCP overhead (p50 − direct): SSE / HTTP, raw       {:>7.0} / {:>7.0}   ≤ 150\n\
             get_detected_objects at obs. pose, SSE             {:>7.0} / {:>7.0}   p50 ≤ 10,000\n\
             get_detected_objects at obs. pose, HTTP            {:>7.0} / {:>7.0}   p50 ≤ 10,000\n\
             get_detected_objects at obs. pose, direct          {:>7.0}\n\
             calls/s, 8 clients (HTTP)                          {:>9.0}\n\
             calls/s, 64 clients (HTTP)                         {:>9.0}           ≥ 5,000\n\
             service RSS right after load                       {:>9.1} MB        ≤ 80 MB\n\
             service RSS 3 s after load, sessions open          {:>9.1} MB        ≤ 80 MB\n\
             service RSS 3 s after the clients left             {:>9.1} MB        near idle\n\
             {}\n\
             {}\n",
            self.coordinate_sse_us_p50,
            self.coordinate_sse_us_p99,
            self.coordinate_http_us_p50,
            self.coordinate_http_us_p99,
            self.coordinate_http_raw_us_p50,
            self.coordinate_sse_raw_us_p50,
            self.ping_http_raw_us_p50,
            self.http_floor_us_p50,
            self.tcp_echo_us_p50,
            self.coordinate_direct_us_p50,
            self.coordinate_sse_us_p50 - self.coordinate_direct_us_p50,
            self.coordinate_http_us_p50 - self.coordinate_direct_us_p50,
            self.coordinate_sse_raw_us_p50 - self.coordinate_direct_us_p50,
            self.coordinate_http_raw_us_p50 - self.coordinate_direct_us_p50,
            self.objects_sse_us_p50,
            self.objects_sse_us_p99,
            self.objects_http_us_p50,
            self.objects_http_us_p99,
            self.objects_direct_us_p50,
            self.calls_per_s_8_clients,
            self.calls_per_s_64_clients,
            self.service_rss_mb,
            self.service_rss_quiet_mb,
            self.service_rss_after_clients_left_mb,
            if self.one_core {
                "service and benchmark pinned to CPU 0 (--one-core)"
            } else {
                "threads on any CPU (--one-core pins everything to CPU 0)"
            },
            match self.guest_halt_poll_ns {
                Some(ns) => format!("VM guest halt polling: {ns} ns before an idle vCPU halts"),
                None => "no VM guest halt polling (haltpoll) on this machine".to_owned(),
            },
        )
    }
}

fn free_port() -> Result<u16> {
    Ok(std::net::TcpListener::bind("127.0.0.1:0")?
        .local_addr()?
        .port())
}

/// Starts `robotd serve` writing its logs (the MCP call log grows by ~20 MB per run) into
/// `log_dir`.
fn start_service(exe: &Path, namespace: &str, port: u16, log_dir: &Path) -> Result<Served> {
    let child = Command::new(exe)
        .args(["serve", "--namespace", namespace, "--http"])
        .arg(format!("127.0.0.1:{port}"))
        .args(["--set", "robot.time_scale=0.05"])
        .arg("--set")
        .arg(format!("telemetry.log_dir={}", log_dir.display()))
        .env("RUST_LOG", "warn")
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .context("starting robotd serve")?;
    let mut served = Served(child);
    super::wait_until_serving(&mut served)?;
    Ok(served)
}

fn args(v: Value) -> Map<String, Value> {
    v.as_object().cloned().unwrap_or_default()
}

fn coordinate_args() -> Map<String, Value> {
    args(json!({"workspace_id": "niryo_ws", "point": "center point"}))
}

async fn mcp_call(client: &McpClient, tool: &str, arguments: Map<String, Value>) -> Result<()> {
    let result = client
        .call_tool(CallToolRequestParams::new(tool.to_owned()).with_arguments(arguments))
        .await?;
    let text = result
        .content
        .first()
        .and_then(|c| c.as_text())
        .map(|t| t.text.as_str())
        .unwrap_or("");
    if !text.starts_with('✓') {
        bail!("{tool} answered {text:?}");
    }
    Ok(())
}

async fn mcp_latency(
    client: &McpClient,
    tool: &str,
    arguments: &Map<String, Value>,
    calls: usize,
) -> Result<Latency> {
    let mut samples = Vec::with_capacity(calls);
    for _ in 0..calls {
        let started = Instant::now();
        mcp_call(client, tool, arguments.clone()).await?;
        samples.push(started.elapsed());
    }
    Ok(Latency::of(&mut samples))
}

async fn direct_latency(
    registry: &Registry,
    tool: &str,
    arguments: &Map<String, Value>,
    calls: usize,
) -> Result<Latency> {
    let mut samples = Vec::with_capacity(calls);
    for _ in 0..calls {
        let started = Instant::now();
        let out = registry
            .call(tool, Some(arguments.clone()), CallHooks::default())
            .await?;
        if out.is_failure {
            bail!("{tool} answered {:?}", out.text);
        }
        samples.push(started.elapsed());
    }
    Ok(Latency::of(&mut samples))
}

/// Connected clients, still holding their sessions.
struct Clients(Vec<Arc<McpClient>>);

impl Clients {
    /// The clients leave: each closes its session.
    async fn leave(self) {
        for client in self.0 {
            if let Ok(client) = Arc::try_unwrap(client) {
                let _ = client.cancel().await;
            }
        }
    }
}

/// Calls per second of `clients` concurrent clients for `run_for`; the clients stay connected.
async fn throughput(url: &str, clients: usize, run_for: Duration) -> Result<(f64, Clients)> {
    let mut sessions = Vec::with_capacity(clients);
    for _ in 0..clients {
        sessions.push(Arc::new(connect(url, None).await?));
    }
    let started = Instant::now();
    let deadline = started + run_for;
    let mut tasks = Vec::with_capacity(clients);
    for client in &sessions {
        let client = client.clone();
        tasks.push(tokio::spawn(async move {
            let mut calls = 0u64;
            while Instant::now() < deadline {
                mcp_call(
                    &client,
                    "get_workspace_coordinate_from_point",
                    coordinate_args(),
                )
                .await?;
                calls += 1;
            }
            Ok::<u64, anyhow::Error>(calls)
        }));
    }
    let mut total = 0;
    for task in tasks {
        total += task.await??;
    }
    let elapsed = started.elapsed().as_secs_f64();
    Ok((total as f64 / elapsed, Clients(sessions)))
}

/// How long an idle vCPU of this VM guest polls before halting, when the `haltpoll` cpuidle
/// driver is loaded.
fn guest_halt_poll_ns() -> Option<u64> {
    std::fs::read_to_string("/sys/module/haltpoll/parameters/guest_halt_poll_ns")
        .ok()?
        .trim()
        .parse()
        .ok()
}

fn rss_mb(pid: u32) -> Result<f64> {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status"))?;
    let kb: f64 = status
        .lines()
        .find_map(|l| l.strip_prefix("VmRSS:"))
        .and_then(|v| v.split_whitespace().next())
        .and_then(|v| v.parse().ok())
        .context("VmRSS in /proc/<pid>/status")?;
    Ok(kb / 1024.0)
}

/// The CPUs process `pid` may run on, as Linux lists them (`0`, `0-1`, ...).
fn cpus_allowed(pid: u32) -> Result<String> {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status"))?;
    status
        .lines()
        .find_map(|l| l.strip_prefix("Cpus_allowed_list:"))
        .map(|v| v.trim().to_owned())
        .context("Cpus_allowed_list in /proc/<pid>/status")
}

/// Runs the benchmark against a robotd this function starts.
/// With `one_core`, everything runs on CPU 0 (see the module's documentation).
pub fn run(exe: &Path, calls: usize, throughput_s: f64, one_core: bool) -> Result<McpFigures> {
    if one_core {
        // Threads and child processes inherit the affinity: pin before starting any.
        super::bus::pin_current_thread(0).context("--one-core")?;
    }
    let namespace = format!("bench-mcp-{}", std::process::id());
    let port = free_port()?;
    // Removed when the run ends (each run used to leave its logs in the temp directory).
    let logs = tempfile::Builder::new()
        .prefix("robotd-bench-mcp-")
        .tempdir()
        .context("a temporary directory for the service's logs")?;
    let served = start_service(exe, &namespace, port, logs.path())?;
    let pid = served.0.id();
    if one_core {
        // Figures labelled "one core" must come from a pinned service.
        let allowed = cpus_allowed(pid)?;
        if allowed != "0" {
            bail!("--one-core: the service may run on CPUs {allowed}, not only on CPU 0");
        }
    }
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()?;
    let figures = runtime.block_on(async {
        let sse = connect(&format!("http://127.0.0.1:{port}/sse"), None).await?;
        let http_url = format!("http://127.0.0.1:{port}/mcp");
        let http = connect(&http_url, None).await?;
        // The first detection call moves the arm to the observation pose.
        mcp_call(&http, "get_detected_objects", Map::new()).await?;
        let objects = Map::new();
        let coordinate = coordinate_args();
        let coordinate_sse = mcp_latency(
            &sse,
            "get_workspace_coordinate_from_point",
            &coordinate,
            calls,
        )
        .await?;
        let coordinate_http = mcp_latency(
            &http,
            "get_workspace_coordinate_from_point",
            &coordinate,
            calls,
        )
        .await?;
        let objects_sse = mcp_latency(&sse, "get_detected_objects", &objects, calls).await?;
        let objects_http = mcp_latency(&http, "get_detected_objects", &objects, calls).await?;
        let raw = super::mcp_raw::layers(
            std::net::SocketAddr::from(([127, 0, 0, 1], port)),
            "get_workspace_coordinate_from_point",
            &coordinate,
            calls,
        )
        .await?;
        let echo_exe = exe.to_owned();
        let tcp_echo =
            tokio::task::spawn_blocking(move || super::tcp_echo::latency(&echo_exe, calls))
                .await
                .context("the TCP echo baseline")??;

        let bus = Bus::open(BusOptions::new(&namespace, "bench-mcp"))?;
        let workspaces = vec![WorkspaceInfo {
            id: "niryo_ws".into(),
            robot: robotd_protocol::RobotModel::Ned2,
            upper_left: robotd_protocol::Point2::new(0.337, 0.087),
            lower_right: robotd_protocol::Point2::new(0.163, -0.087),
            observation_pose: robotd_protocol::Pose::new(
                0.173, -0.002, 0.277, -3.042, 1.327, -3.027,
            ),
        }];
        let registry = Registry::connect(&bus, ToolSettings::new("bench", workspaces))?;
        // Let the registry see the arm's state before timing.
        tokio::time::sleep(Duration::from_millis(1500)).await;
        let coordinate_direct = direct_latency(
            &registry,
            "get_workspace_coordinate_from_point",
            &coordinate,
            calls,
        )
        .await?;
        let objects_direct =
            direct_latency(&registry, "get_detected_objects", &objects, calls).await?;

        let run_for = Duration::from_secs_f64(throughput_s);
        let (calls_8, clients_8) = throughput(&http_url, 8, run_for).await?;
        let (calls_64, clients_64) = throughput(&http_url, 64, run_for).await?;
        let service_rss_mb = rss_mb(pid)?;
        // The service gives freed memory back once the calls have stopped for a second.
        tokio::time::sleep(Duration::from_secs(3)).await;
        let service_rss_quiet_mb = rss_mb(pid)?;
        clients_8.leave().await;
        clients_64.leave().await;
        let _ = sse.cancel().await;
        let _ = http.cancel().await;
        // The service returns freed memory one second after the last session closed.
        tokio::time::sleep(Duration::from_secs(3)).await;
        let service_rss_after_clients_left_mb = rss_mb(pid)?;
        Ok::<_, anyhow::Error>(McpFigures {
            coordinate_sse_us_p50: coordinate_sse.p50_us,
            coordinate_sse_us_p99: coordinate_sse.p99_us,
            coordinate_http_us_p50: coordinate_http.p50_us,
            coordinate_http_us_p99: coordinate_http.p99_us,
            objects_sse_us_p50: objects_sse.p50_us,
            objects_sse_us_p99: objects_sse.p99_us,
            objects_http_us_p50: objects_http.p50_us,
            objects_http_us_p99: objects_http.p99_us,
            coordinate_http_raw_us_p50: raw.call.p50_us,
            coordinate_sse_raw_us_p50: raw.sse_call.p50_us,
            ping_http_raw_us_p50: raw.ping.p50_us,
            http_floor_us_p50: raw.http.p50_us,
            tcp_echo_us_p50: tcp_echo.p50_us,
            coordinate_direct_us_p50: coordinate_direct.p50_us,
            objects_direct_us_p50: objects_direct.p50_us,
            calls_per_s_8_clients: calls_8,
            calls_per_s_64_clients: calls_64,
            service_rss_mb,
            service_rss_quiet_mb,
            service_rss_after_clients_left_mb,
            calls,
            throughput_s,
            one_core,
            guest_halt_poll_ns: guest_halt_poll_ns(),
        })
    })?;
    drop(served);
    drop(logs);
    Ok(figures)
}
