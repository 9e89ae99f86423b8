//! `robotd bench bus`: round trips and frame throughput, raw iceoryx2 beside robotd's bus.
//!
//! - `raw_rtt`: a 64-byte request/reply between two processes with plain iceoryx2
//!   (request-response service plus event services, the peer blocking on its listener: no
//!   busy wait), no robotd code on the path.
//! - `bus_rtt` / `bus_inproc_rtt`: a 64-byte [`Ping`] through robotd's bus client and server
//!   (MessagePack envelope, trace context, metrics, tokio wake-ups), across two processes and
//!   inside one.
//! - `raw_frames` / `bus_frames`: 921,600-byte frames one-way between processes, lossless
//!   (back-pressure), the receiver checking the sequence for gaps. The producer writes the
//!   header and the first and last pixel rows of each frame in shared memory; the receiver
//!   reads them in place.
//! - `restart`: panic-to-answering latency of a supervised actor whose safe-state hook runs
//!   before every restart.

use crate::stats::Latency;
use anyhow::{bail, Context, Result};
use iceoryx2::prelude::*;
use robotd_protocol::diagnostics::{Ping, Pong};
use robotd_runtime::bus::{Bus, BusOptions, FrameTopic, Overflow, Service, FRAME_BYTES};
use serde::Serialize;
use std::io::{BufRead, BufReader};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// The bus service the round-trip benchmark uses.
pub const PING: Service<Ping, Pong> = Service::new("bench/ping");
/// The frame topic of the frame benchmark (lossless: back-pressure).
pub const BENCH_FRAMES: FrameTopic = FrameTopic::new("bench/frames", Overflow::back_pressure(4));

const RAW_RTT: &str = "raw-rtt";
const RAW_RTT_WORK: &str = "raw-rtt-work";

/// Simulated handler work per hop in the `raw_rtt_work` diagnostic: about what the bus spends
/// per hop (encode, decode, metrics, trace context).
const SIMULATED_WORK: Duration = Duration::from_micros(5);

/// Keeps the CPU busy for `work` (simulated handler work; not a wait for anything).
fn simulate_work(work: Duration) {
    let started = Instant::now();
    while started.elapsed() < work {
        std::hint::spin_loop();
    }
}
const RAW_FRAMES: &str = "raw-frames";
const BUS_RTT: &str = "bus-rtt";
const BUS_FRAMES: &str = "bus-frames";

/// Sizes of one benchmark run.
#[derive(Debug, Clone, Copy)]
pub struct BenchSizes {
    /// Measured round trips per variant.
    pub round_trips: usize,
    /// Frames per variant.
    pub frames: usize,
    /// Restarts measured.
    pub restarts: usize,
}

/// Figures of one run (names are part of the JSON contract).
#[derive(Debug, Clone, Serialize)]
pub struct BusFigures {
    pub raw_rtt_p50_us: f64,
    pub raw_rtt_p99_us: f64,
    pub bus_rtt_p50_us: f64,
    pub bus_rtt_p99_us: f64,
    pub bus_inproc_rtt_p50_us: f64,
    pub bus_inproc_rtt_p99_us: f64,
    pub same_core_raw_rtt_p50_us: f64,
    pub same_core_raw_rtt_p99_us: f64,
    pub same_core_bus_rtt_p50_us: f64,
    pub same_core_bus_rtt_p99_us: f64,
    pub raw_rtt_work_p50_us: f64,
    pub raw_rtt_work_p99_us: f64,
    pub cross_core_raw_rtt_p50_us: Option<f64>,
    pub cross_core_raw_rtt_p99_us: Option<f64>,
    pub cross_core_bus_rtt_p50_us: Option<f64>,
    pub cross_core_bus_rtt_p99_us: Option<f64>,
    pub raw_frames_per_s: f64,
    pub bus_frames_per_s: f64,
    pub raw_frames_lost: u64,
    pub bus_frames_lost: u64,
    pub restart_p50_us: f64,
    pub restart_p99_us: f64,
    pub round_trips: usize,
    pub frames: usize,
    pub restarts: usize,
}

impl BusFigures {
    /// Human-readable table with the targets of the foundation issue.
    pub fn table(&self) -> String {
        let ratio = self.bus_rtt_p50_us / self.raw_rtt_p50_us;
        let mut out = String::new();
        out.push_str("measure                          value          target\n");
        out.push_str(&format!(
            "raw iceoryx2 RTT p50 / p99       {:>7.1} / {:<7.1} µs (baseline)\n",
            self.raw_rtt_p50_us, self.raw_rtt_p99_us
        ));
        out.push_str(&format!(
            "bus RTT 2 processes p50 / p99    {:>7.1} / {:<7.1} µs p50 ≤ 1.5 × raw ({:.2}×), p99 ≤ 3 × p50 ({:.2}×)\n",
            self.bus_rtt_p50_us,
            self.bus_rtt_p99_us,
            ratio,
            self.bus_rtt_p99_us / self.bus_rtt_p50_us
        ));
        out.push_str(&format!(
            "bus RTT 1 process p50 / p99      {:>7.1} / {:<7.1} µs\n",
            self.bus_inproc_rtt_p50_us, self.bus_inproc_rtt_p99_us
        ));
        out.push_str(&format!(
            "pinned to one core: raw / bus p50 {:>7.1} / {:<7.1} µs ({:.2}×)\n",
            self.same_core_raw_rtt_p50_us,
            self.same_core_bus_rtt_p50_us,
            self.same_core_bus_rtt_p50_us / self.same_core_raw_rtt_p50_us
        ));
        if let (Some(raw), Some(bus)) = (
            self.cross_core_raw_rtt_p50_us,
            self.cross_core_bus_rtt_p50_us,
        ) {
            out.push_str(&format!(
                "pinned to two cores: raw / bus p50 {raw:>6.1} / {bus:<7.1} µs ({:.2}×)\n",
                bus / raw
            ));
        }
        out.push_str(&format!(
            "raw RTT with 5 µs work per hop   {:>7.1} / {:<7.1} µs (no robotd code)\n",
            self.raw_rtt_work_p50_us, self.raw_rtt_work_p99_us
        ));
        out.push_str(&format!(
            "raw frames/s (921,600 B, lossless) {:>9.0}  lost {}\n",
            self.raw_frames_per_s, self.raw_frames_lost
        ));
        out.push_str(&format!(
            "bus frames/s (921,600 B, lossless) {:>9.0}  lost {}   target ≥ 10,000\n",
            self.bus_frames_per_s, self.bus_frames_lost
        ));
        out.push_str(&format!(
            "restart panic→answering p50/p99  {:>7.1} / {:<7.1} µs p50 ≤ 1,000\n",
            self.restart_p50_us, self.restart_p99_us
        ));
        out
    }
}

/// Runs the whole bus benchmark. `exe` is this binary (for peers), `namespace` isolates it.
pub fn run(exe: &std::path::Path, namespace: &str, sizes: BenchSizes) -> Result<BusFigures> {
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()?;
    let two_cpus = std::thread::available_parallelism().map_or(1, |n| n.get()) >= 2;
    let (raw_rtt, bus_rtt, inproc_rtt, same_core, cross_core, raw_work) =
        runtime.block_on(async {
            let n = sizes.round_trips;
            let (mut raw, mut bus) = rtt_interleaved(exe, namespace, n, Placement::Os).await?;
            let (mut same_raw, mut same_bus) =
                rtt_interleaved(exe, namespace, n, Placement::SameCore).await?;
            let cross_core = if two_cpus {
                let (mut raw, mut bus) =
                    rtt_interleaved(exe, namespace, n, Placement::CrossCore).await?;
                Some((Latency::of(&mut raw), Latency::of(&mut bus)))
            } else {
                None
            };
            let mut inproc = bus_rtt_inproc(namespace, n).await?;
            let mut raw_work = raw_rtt_with_work(exe, namespace, n)?;
            anyhow::Ok((
                Latency::of(&mut raw),
                Latency::of(&mut bus),
                Latency::of(&mut inproc),
                (Latency::of(&mut same_raw), Latency::of(&mut same_bus)),
                cross_core,
                Latency::of(&mut raw_work),
            ))
        })?;
    let raw_frames = frames_publisher(exe, namespace, sizes.frames, false)?;
    let bus_frames = frames_publisher(exe, namespace, sizes.frames, true)?;
    let mut restarts = runtime.block_on(robotd_runtime::supervision::measure_restart_latency(
        sizes.restarts,
    ))?;
    let restart = Latency::of(&mut restarts);
    Ok(BusFigures {
        raw_rtt_p50_us: raw_rtt.p50_us,
        raw_rtt_p99_us: raw_rtt.p99_us,
        bus_rtt_p50_us: bus_rtt.p50_us,
        bus_rtt_p99_us: bus_rtt.p99_us,
        bus_inproc_rtt_p50_us: inproc_rtt.p50_us,
        bus_inproc_rtt_p99_us: inproc_rtt.p99_us,
        same_core_raw_rtt_p50_us: same_core.0.p50_us,
        same_core_raw_rtt_p99_us: same_core.0.p99_us,
        same_core_bus_rtt_p50_us: same_core.1.p50_us,
        same_core_bus_rtt_p99_us: same_core.1.p99_us,
        raw_rtt_work_p50_us: raw_work.p50_us,
        raw_rtt_work_p99_us: raw_work.p99_us,
        cross_core_raw_rtt_p50_us: cross_core.map(|c| c.0.p50_us),
        cross_core_raw_rtt_p99_us: cross_core.map(|c| c.0.p99_us),
        cross_core_bus_rtt_p50_us: cross_core.map(|c| c.1.p50_us),
        cross_core_bus_rtt_p99_us: cross_core.map(|c| c.1.p99_us),
        raw_frames_per_s: raw_frames.frames_per_s,
        bus_frames_per_s: bus_frames.frames_per_s,
        raw_frames_lost: raw_frames.lost,
        bus_frames_lost: bus_frames.lost,
        restart_p50_us: restart.p50_us,
        restart_p99_us: restart.p99_us,
        round_trips: sizes.round_trips,
        frames: sizes.frames,
        restarts: sizes.restarts,
    })
}

/// A peer process that is killed when dropped.
struct Peer {
    child: Child,
    stdout: BufReader<std::process::ChildStdout>,
}

impl Peer {
    fn start(exe: &std::path::Path, role: &str, namespace: &str, count: usize) -> Result<Self> {
        Self::start_on(exe, role, namespace, count, None)
    }

    fn start_on(
        exe: &std::path::Path,
        role: &str,
        namespace: &str,
        count: usize,
        cpu: Option<usize>,
    ) -> Result<Self> {
        let mut command = Command::new(exe);
        command
            .args(["bench-peer", role, "--peer-namespace", namespace, "--count"])
            .arg(count.to_string());
        if let Some(cpu) = cpu {
            command.arg("--cpu").arg(cpu.to_string());
        }
        #[cfg(target_os = "linux")]
        {
            use std::os::unix::process::CommandExt;
            // SAFETY: prctl is async-signal-safe; the closure only calls it. A peer must not
            // outlive an interrupted benchmark.
            unsafe {
                command.pre_exec(|| {
                    libc::prctl(libc::PR_SET_PDEATHSIG, libc::SIGTERM);
                    Ok(())
                });
            }
        }
        let mut child = command
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit())
            .spawn()
            .with_context(|| format!("starting bench peer '{role}'"))?;
        let stdout = BufReader::new(child.stdout.take().context("peer stdout")?);
        let mut peer = Self { child, stdout };
        let line = peer.read_line()?;
        if line.trim() != "ready" {
            bail!("bench peer '{role}' did not start: {line}");
        }
        Ok(peer)
    }

    fn read_line(&mut self) -> Result<String> {
        let mut line = String::new();
        self.stdout.read_line(&mut line)?;
        if line.is_empty() {
            bail!("bench peer exited early (see its error above)");
        }
        Ok(line)
    }
}

impl Drop for Peer {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

fn raw_node() -> Result<Node<ipc::Service>> {
    NodeBuilder::new()
        .signal_handling_mode(SignalHandlingMode::Disabled)
        .create::<ipc::Service>()
        .map_err(|e| anyhow::anyhow!("iceoryx2 node: {e:?}"))
}

fn raw_name(namespace: &str, suffix: &str) -> Result<ServiceName> {
    ServiceName::new(&format!("{namespace}/raw/{suffix}"))
        .map_err(|e| anyhow::anyhow!("service name: {e:?}"))
}

fn raw_event(
    node: &Node<ipc::Service>,
    namespace: &str,
    suffix: &str,
) -> Result<iceoryx2::service::port_factory::event::PortFactory<ipc::Service>> {
    node.service_builder(&raw_name(namespace, suffix)?)
        .event()
        .open_or_create()
        .map_err(|e| anyhow::anyhow!("event service {suffix}: {e:?}"))
}

type RawRtt = iceoryx2::service::port_factory::request_response::PortFactory<
    ipc::Service,
    [u8; 64],
    (),
    [u8; 64],
    (),
>;

fn raw_rtt_service(node: &Node<ipc::Service>, namespace: &str) -> Result<RawRtt> {
    node.service_builder(&raw_name(namespace, "rtt")?)
        .request_response::<[u8; 64], [u8; 64]>()
        .open_or_create()
        .map_err(|e| anyhow::anyhow!("raw rtt service: {e:?}"))
}

/// Where the two processes of a round-trip measurement run. The OS's choice is what a user
/// gets; the pinned ones show the two costs it mixes: a wake-up on the same core is cheap,
/// one that must wake another (idle) core costs an inter-processor interrupt, which on a VM is
/// a trip through the hypervisor.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Placement {
    /// No pinning.
    Os,
    /// Both processes on CPU 0.
    SameCore,
    /// Client on CPU 0, peer on CPU 1.
    CrossCore,
}

impl Placement {
    fn name(self) -> &'static str {
        match self {
            Placement::Os => "os",
            Placement::SameCore => "same",
            Placement::CrossCore => "cross",
        }
    }

    fn cpus(self) -> (Option<usize>, Option<usize>) {
        match self {
            Placement::Os => (None, None),
            Placement::SameCore => (Some(0), Some(0)),
            Placement::CrossCore => (Some(0), Some(1)),
        }
    }
}

/// Pins the calling thread to `cpu`; returns the previous CPU set.
pub fn pin_current_thread(cpu: usize) -> Result<libc::cpu_set_t> {
    // SAFETY: plain libc calls on a zeroed cpu_set_t owned by this frame.
    unsafe {
        let mut previous: libc::cpu_set_t = std::mem::zeroed();
        if libc::sched_getaffinity(0, std::mem::size_of::<libc::cpu_set_t>(), &mut previous) != 0 {
            bail!("sched_getaffinity: {}", std::io::Error::last_os_error());
        }
        let mut set: libc::cpu_set_t = std::mem::zeroed();
        libc::CPU_SET(cpu, &mut set);
        if libc::sched_setaffinity(0, std::mem::size_of::<libc::cpu_set_t>(), &set) != 0 {
            bail!(
                "cannot pin to CPU {cpu}: {}",
                std::io::Error::last_os_error()
            );
        }
        Ok(previous)
    }
}

struct RestoreAffinity(libc::cpu_set_t);

impl Drop for RestoreAffinity {
    fn drop(&mut self) {
        // SAFETY: restores a CPU set read by sched_getaffinity.
        unsafe {
            libc::sched_setaffinity(0, std::mem::size_of::<libc::cpu_set_t>(), &self.0);
        }
    }
}

/// The raw iceoryx2 side of the round-trip measurement: plain ports, blocking waits.
struct RawRttClient {
    client: iceoryx2::port::client::Client<ipc::Service, [u8; 64], (), [u8; 64], ()>,
    to_server: iceoryx2::port::notifier::Notifier<ipc::Service>,
    from_server: iceoryx2::port::listener::Listener<ipc::Service>,
    _node: Node<ipc::Service>,
}

impl RawRttClient {
    fn new(namespace: &str) -> Result<Self> {
        let node = raw_node()?;
        let service = raw_rtt_service(&node, namespace)?;
        let client = service
            .client_builder()
            .create()
            .map_err(|e| anyhow::anyhow!("{e:?}"))?;
        let to_server = raw_event(&node, namespace, "rtt-req")?
            .notifier_builder()
            .create()
            .map_err(|e| anyhow::anyhow!("{e:?}"))?;
        let from_server = raw_event(&node, namespace, "rtt-resp")?
            .listener_builder()
            .create()
            .map_err(|e| anyhow::anyhow!("{e:?}"))?;
        Ok(Self {
            client,
            to_server,
            from_server,
            _node: node,
        })
    }

    fn round_trip(&self, tag: u8, work: Duration) -> Result<Duration> {
        let started = Instant::now();
        simulate_work(work);
        let pending = self
            .client
            .send_copy([tag; 64])
            .map_err(|e| anyhow::anyhow!("raw send: {e:?}"))?;
        self.to_server
            .notify()
            .map_err(|e| anyhow::anyhow!("raw notify: {e:?}"))?;
        loop {
            if let Some(reply) = pending
                .receive()
                .map_err(|e| anyhow::anyhow!("raw receive: {e:?}"))?
            {
                if reply.payload()[0] != tag {
                    bail!("raw reply out of order");
                }
                return Ok(started.elapsed());
            }
            self.from_server
                .timed_wait(|_| {}, Duration::from_secs(5))
                .map_err(|e| anyhow::anyhow!("raw wait: {e:?}"))?;
        }
    }
}

/// Raw and bus round trips between two processes, alternating one of each, so that both
/// see the same machine (these VMs change speed from second to second).
async fn rtt_interleaved(
    exe: &std::path::Path,
    namespace: &str,
    count: usize,
    placement: Placement,
) -> Result<(Vec<Duration>, Vec<Duration>)> {
    let namespace = &format!("{namespace}-{}", placement.name());
    let (own_cpu, peer_cpu) = placement.cpus();
    let previous = own_cpu.map(pin_current_thread).transpose()?;
    let raw = RawRttClient::new(namespace)?;
    let _raw_peer = Peer::start_on(exe, RAW_RTT, namespace, count, peer_cpu)?;
    let bus = Bus::open(BusOptions::new(namespace, "bench-client"))?;
    let client = bus.client(&PING)?;
    let _bus_peer = Peer::start_on(exe, BUS_RTT, namespace, count, peer_cpu)?;
    let _restore = previous.map(RestoreAffinity);
    if !client.wait_for_server(Duration::from_secs(5)).await {
        bail!("the bus bench peer did not start serving");
    }
    let warmup = (count / 10).max(100);
    let mut raw_samples = Vec::with_capacity(count);
    let mut bus_samples = Vec::with_capacity(count);
    let mut ping = Ping {
        seq: 0,
        payload: vec![7u8; 64],
    };
    for i in 0..warmup + count {
        let raw_took = raw.round_trip(i as u8, Duration::ZERO)?;
        ping.seq = i as u64;
        let started = Instant::now();
        let pong = client.request(&ping, Duration::from_secs(5)).await?;
        let bus_took = started.elapsed();
        if pong.seq != ping.seq {
            bail!("bus reply out of order: sent {} got {}", ping.seq, pong.seq);
        }
        if i >= warmup {
            raw_samples.push(raw_took);
            bus_samples.push(bus_took);
        }
    }
    Ok((raw_samples, bus_samples))
}

/// Raw iceoryx2 round trips where each side first spends [`SIMULATED_WORK`] of CPU, as a
/// handler would: shows what the scheduler does to a ping-pong that does real work.
fn raw_rtt_with_work(
    exe: &std::path::Path,
    namespace: &str,
    count: usize,
) -> Result<Vec<Duration>> {
    let namespace = &format!("{namespace}-work");
    let raw = RawRttClient::new(namespace)?;
    let _peer = Peer::start(exe, RAW_RTT_WORK, namespace, count)?;
    let warmup = (count / 10).max(100);
    let mut samples = Vec::with_capacity(count);
    for i in 0..warmup + count {
        let took = raw.round_trip(i as u8, SIMULATED_WORK)?;
        if i >= warmup {
            samples.push(took);
        }
    }
    Ok(samples)
}

async fn bus_rtt_inproc(namespace: &str, count: usize) -> Result<Vec<Duration>> {
    let inproc_ns = format!("{namespace}-inproc");
    let bus = Bus::open(BusOptions::new(&inproc_ns, "bench-inproc"))?;
    let mut server = bus.server(&PING)?;
    let serving = tokio::spawn(async move { serve_pings(&mut server).await });
    let client = bus.client(&PING)?;
    let samples = ping_loop(&client, count).await;
    serving.abort();
    samples
}

async fn ping_loop(
    client: &robotd_runtime::bus::Client<Ping, Pong>,
    count: usize,
) -> Result<Vec<Duration>> {
    let warmup = (count / 10).max(100);
    let mut samples = Vec::with_capacity(count);
    let mut ping = Ping {
        seq: 0,
        payload: vec![7u8; 64],
    };
    for i in 0..warmup + count {
        ping.seq = i as u64;
        let started = Instant::now();
        let pong = client.request(&ping, Duration::from_secs(5)).await?;
        let took = started.elapsed();
        if pong.seq != ping.seq {
            bail!("bus reply out of order: sent {} got {}", ping.seq, pong.seq);
        }
        if i >= warmup {
            samples.push(took);
        }
    }
    Ok(samples)
}

async fn serve_pings(
    server: &mut robotd_runtime::bus::Server<Ping, Pong>,
) -> Result<(), robotd_runtime::bus::BusError> {
    let pid = std::process::id();
    loop {
        let (envelope, pending) = server.next().await?.split();
        let ping = envelope.body;
        server.respond(
            pending,
            Ok(Pong {
                seq: ping.seq,
                payload: ping.payload,
                served_by_pid: pid,
            }),
        )?;
    }
}

/// Outcome of a one-way frame run, as the receiver saw it.
#[derive(Debug, Clone, Copy, Serialize, serde::Deserialize)]
struct FrameRun {
    frames_per_s: f64,
    received: u64,
    lost: u64,
}

#[derive(Debug, ZeroCopySend)]
#[repr(C)]
#[type_name("robotd.bench.RawFrame.v1")]
struct RawFrame {
    seq: u64,
    pixels: [u8; FRAME_BYTES],
}

type RawFrames =
    iceoryx2::service::port_factory::publish_subscribe::PortFactory<ipc::Service, RawFrame, ()>;

fn raw_frames_service(node: &Node<ipc::Service>, namespace: &str) -> Result<RawFrames> {
    node.service_builder(&raw_name(namespace, "frames")?)
        .publish_subscribe::<RawFrame>()
        .enable_safe_overflow(false)
        .subscriber_max_buffer_size(4)
        .open_or_create()
        .map_err(|e| anyhow::anyhow!("raw frame service: {e:?}"))
}

const ROW_BYTES: usize = 640 * 3;

fn stamp(pixels: &mut [u8; FRAME_BYTES], seq: u64) {
    let value = (seq % 251) as u8;
    pixels[..ROW_BYTES].fill(value);
    pixels[FRAME_BYTES - ROW_BYTES..].fill(value);
}

fn check_stamp(pixels: &[u8], seq: u64) -> bool {
    let value = (seq % 251) as u8;
    pixels.len() == FRAME_BYTES && pixels[0] == value && pixels[FRAME_BYTES - 1] == value
}

fn frames_publisher(
    exe: &std::path::Path,
    namespace: &str,
    count: usize,
    through_bus: bool,
) -> Result<FrameRun> {
    let role = if through_bus { BUS_FRAMES } else { RAW_FRAMES };
    if through_bus {
        let bus = Bus::open(BusOptions::new(namespace, "bench-frames"))?;
        let publisher = bus.frame_publisher(&BENCH_FRAMES)?;
        let mut peer = Peer::start(exe, role, namespace, count)?;
        for seq in 0..count as u64 {
            let mut frame = publisher.loan()?;
            frame.header_mut().frame_id = seq;
            stamp(frame.pixels_mut(), seq);
            frame.send()?;
        }
        let line = peer.read_line()?;
        Ok(serde_json::from_str(&line)?)
    } else {
        let node = raw_node()?;
        let service = raw_frames_service(&node, namespace)?;
        let publisher = service
            .publisher_builder()
            .backpressure_strategy(BackpressureStrategy::RetryUntilDelivered)
            .create()
            .map_err(|e| anyhow::anyhow!("{e:?}"))?;
        let notifier = raw_event(&node, namespace, "frames-ready")?
            .notifier_builder()
            .create()
            .map_err(|e| anyhow::anyhow!("{e:?}"))?;
        let mut peer = Peer::start(exe, role, namespace, count)?;
        for seq in 0..count as u64 {
            let mut sample = publisher
                .loan_uninit()
                .map_err(|e| anyhow::anyhow!("raw loan: {e:?}"))?;
            let slot = sample.payload_mut().as_mut_ptr();
            // SAFETY: exclusive loan of a slot in shared memory; bytes are initialised memory
            // of the mmap'd segment (see FramePublisher::loan).
            let mut sample = unsafe {
                std::ptr::addr_of_mut!((*slot).seq).write(seq);
                sample.assume_init()
            };
            stamp(&mut sample.payload_mut().pixels, seq);
            sample
                .send()
                .map_err(|e| anyhow::anyhow!("raw send: {e:?}"))?;
            notifier
                .notify()
                .map_err(|e| anyhow::anyhow!("raw notify: {e:?}"))?;
        }
        let line = peer.read_line()?;
        Ok(serde_json::from_str(&line)?)
    }
}

/// Entry of `robotd bench-peer <role>`: the other process of a two-process measurement.
pub fn run_peer(role: &str, namespace: &str, count: usize, cpu: Option<usize>) -> Result<()> {
    if let Some(cpu) = cpu {
        pin_current_thread(cpu)?;
    }
    match role {
        RAW_RTT => raw_rtt_peer(namespace, Duration::ZERO),
        RAW_RTT_WORK => raw_rtt_peer(namespace, SIMULATED_WORK),
        RAW_FRAMES => raw_frames_peer(namespace, count),
        BUS_RTT | BUS_FRAMES => {
            let runtime = tokio::runtime::Builder::new_current_thread()
                .enable_all()
                .build()?;
            runtime.block_on(async {
                let bus = Bus::open(BusOptions::new(namespace, "bench-peer"))?;
                if role == BUS_RTT {
                    let mut server = bus.server(&PING)?;
                    println!("ready");
                    serve_pings(&mut server).await?;
                    Ok(())
                } else {
                    bus_frames_peer(&bus, count).await
                }
            })
        }
        other => bail!("unknown bench peer role '{other}'"),
    }
}

fn raw_rtt_peer(namespace: &str, work: Duration) -> Result<()> {
    let node = raw_node()?;
    let service = raw_rtt_service(&node, namespace)?;
    let server = service
        .server_builder()
        .create()
        .map_err(|e| anyhow::anyhow!("{e:?}"))?;
    let requests = raw_event(&node, namespace, "rtt-req")?
        .listener_builder()
        .create()
        .map_err(|e| anyhow::anyhow!("{e:?}"))?;
    let replies = raw_event(&node, namespace, "rtt-resp")?
        .notifier_builder()
        .create()
        .map_err(|e| anyhow::anyhow!("{e:?}"))?;
    println!("ready");
    loop {
        while let Some(request) = server
            .receive()
            .map_err(|e| anyhow::anyhow!("raw receive: {e:?}"))?
        {
            let payload = *request.payload();
            simulate_work(work);
            request
                .send_copy(payload)
                .map_err(|e| anyhow::anyhow!("raw reply: {e:?}"))?;
            replies
                .notify()
                .map_err(|e| anyhow::anyhow!("raw notify: {e:?}"))?;
        }
        requests
            .blocking_wait(|_| {})
            .map_err(|e| anyhow::anyhow!("raw wait: {e:?}"))?;
    }
}

fn raw_frames_peer(namespace: &str, count: usize) -> Result<()> {
    let node = raw_node()?;
    let service = raw_frames_service(&node, namespace)?;
    let subscriber = service
        .subscriber_builder()
        .create()
        .map_err(|e| anyhow::anyhow!("{e:?}"))?;
    let ready = raw_event(&node, namespace, "frames-ready")?
        .listener_builder()
        .create()
        .map_err(|e| anyhow::anyhow!("{e:?}"))?;
    println!("ready");
    let mut counter = FrameCounter::default();
    while counter.received < count as u64 {
        match subscriber
            .receive()
            .map_err(|e| anyhow::anyhow!("raw receive: {e:?}"))?
        {
            Some(sample) => counter.count(sample.seq, &sample.pixels)?,
            None => ready
                .timed_wait(|_| {}, Duration::from_secs(5))
                .map(|_| ())
                .map_err(|e| anyhow::anyhow!("raw wait: {e:?}"))?,
        }
    }
    println!("{}", serde_json::to_string(&counter.finish())?);
    Ok(())
}

async fn bus_frames_peer(bus: &Bus, count: usize) -> Result<()> {
    let mut subscriber = bus.frame_subscriber(&BENCH_FRAMES)?;
    println!("ready");
    let mut counter = FrameCounter::default();
    while counter.received < count as u64 {
        let frame = subscriber.recv().await?;
        counter.count(frame.header().frame_id, frame.pixels())?;
    }
    println!("{}", serde_json::to_string(&counter.finish())?);
    Ok(())
}

#[derive(Default)]
struct FrameCounter {
    first: Option<Instant>,
    last: Option<Instant>,
    received: u64,
    next_seq: u64,
    lost: u64,
}

impl FrameCounter {
    fn count(&mut self, seq: u64, pixels: &[u8]) -> Result<()> {
        let now = Instant::now();
        self.first.get_or_insert(now);
        self.last = Some(now);
        if !check_stamp(pixels, seq) {
            bail!("frame {seq}: pixels do not carry the stamp the producer wrote");
        }
        self.lost += seq.saturating_sub(self.next_seq);
        self.next_seq = seq.saturating_add(1);
        self.received += 1;
        Ok(())
    }

    fn finish(&self) -> FrameRun {
        let span = match (self.first, self.last) {
            (Some(first), Some(last)) => last.duration_since(first).as_secs_f64(),
            _ => 0.0,
        };
        let frames_per_s = if span > 0.0 {
            (self.received.saturating_sub(1)) as f64 / span
        } else {
            0.0
        };
        FrameRun {
            frames_per_s,
            received: self.received,
            lost: self.lost,
        }
    }
}
