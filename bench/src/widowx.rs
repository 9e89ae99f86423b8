//! `robotd bench widowx`: the widowx driver against the fake servo bus on a pseudo-terminal.
//!
//! - a sync read of Present Position of the nine servos (instruction out, nine status packets
//!   back, checked and parsed by `dynamixel2`), beside a raw pty echo of the same byte counts in
//!   the same run, round by round interleaved;
//! - the control loop at 100 Hz for a few seconds while a motion streams goals: ticks per second
//!   achieved and overruns (ticks whose bus traffic took longer than the period);
//! - a servo fault: hardware error latched on the elbow → detected, arm held, servo rebooted,
//!   torque back on and the bus answering, timed from the latch.
//!
//! The fake and the driver both run in this process, on this machine's cores: a real bus at
//! 1 Mbps adds the wire time (about 1.5 ms for this sync read) that a pty does not have.

use super::Latency;
use anyhow::{bail, Context, Result};
use robotd_driver::{Motion, MotionControl, RobotConfig};
use robotd_driver_widowx::{bus, DxlBus};
use robotd_fake_widowx::{EchoPty, FakeServoBus};
use serde::Serialize;
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

/// Everything `robotd bench widowx` measures.
#[derive(Debug, Clone, Serialize)]
pub struct WidowxFigures {
    /// Sync read of 9 servos through dynamixel2 against the fake.
    pub sync_read: Latency,
    /// The same byte counts through a bare echoing pty.
    pub raw_echo: Latency,
    /// sync read p50 / raw echo p50.
    pub ratio_p50: f64,
    /// Control loop ticks per second achieved (asked: 100).
    pub control_rate_hz: f64,
    /// Ticks run during the control-loop measurement.
    pub ticks: u64,
    /// Ticks that overran their period.
    pub overruns: u64,
    /// From latching the hardware error to the servo answering with torque on, ms.
    pub fault_recovery_ms: f64,
    /// The driver's own measure: from the alert it read to the servo answering, ms.
    pub fault_recovery_driver_ms: f64,
    /// Round trips measured per variant.
    pub round_trips: usize,
}

impl WidowxFigures {
    /// The human-readable table.
    pub fn table(&self) -> String {
        format!(
            "measure                                   value              target\n\
             sync read, 9 servos p50 / p99             {:>7.1} / {:>7.1} µs\n\
             raw pty echo, same bytes p50 / p99        {:>7.1} / {:>7.1} µs\n\
             ratio p50                                 {:>7.2}            ≤ 1.5\n\
             control loop rate (asked 100 Hz)          {:>7.1} Hz         ≥ 100\n\
             overruns / ticks                          {:>7} / {}      0\n\
             servo fault → held → rebooted → answering {:>7.0} ms          ≤ 1000\n\
             · of which the driver's recovery          {:>7.0} ms\n",
            self.sync_read.p50_us,
            self.sync_read.p99_us,
            self.raw_echo.p50_us,
            self.raw_echo.p99_us,
            self.ratio_p50,
            self.control_rate_hz,
            self.overruns,
            self.ticks,
            self.fault_recovery_ms,
            self.fault_recovery_driver_ms,
        )
    }
}

/// The sync-read instruction: 10 header/CRC bytes + 4 + 9 parameters.
const REQUEST_BYTES: usize = 10 + 4 + 9;
/// Nine status packets of 4 data bytes: 15 bytes each.
const REPLY_BYTES: usize = 9 * 15;

/// Runs the benchmark.
pub fn run(round_trips: usize) -> Result<WidowxFigures> {
    let round_trips = round_trips.max(10);
    let dir = tempfile::tempdir().context("a temporary folder for the ptys")?;
    let sim_config: RobotConfig =
        serde_json::from_value(serde_json::json!({"driver": "sim-widowx"}))?;
    let sim = robotd_driver_sim::open(&sim_config)?.robot;
    let defaults = robotd_driver::WidowxConfig::default();
    let fake_link = dir.path().join("ttyDXL");
    let fake = FakeServoBus::start(
        sim,
        &fake_link,
        (defaults.gripper_closed_ticks, defaults.gripper_open_ticks),
    )
    .context("starting the fake servo bus")?;
    let echo_link = dir.path().join("ttyECHO");
    let _echo =
        EchoPty::start(&echo_link, REQUEST_BYTES, REPLY_BYTES).context("starting the echo pty")?;

    let (sync_read, raw_echo) = round_trips_interleaved(&fake_link, &echo_link, round_trips)?;
    let ratio_p50 = sync_read.p50_us / raw_echo.p50_us.max(1e-9);

    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .context("starting the tokio runtime")?;
    let (control_rate_hz, ticks, overruns, fault_recovery_ms, fault_recovery_driver_ms) =
        runtime.block_on(control_loop_and_fault(&fake, &fake_link))?;
    Ok(WidowxFigures {
        sync_read,
        raw_echo,
        ratio_p50,
        control_rate_hz,
        ticks,
        overruns,
        fault_recovery_ms,
        fault_recovery_driver_ms,
        round_trips,
    })
}

/// Sync reads against the fake and raw echoes of the same byte counts, round by round.
fn round_trips_interleaved(
    fake_link: &std::path::Path,
    echo_link: &std::path::Path,
    rounds: usize,
) -> Result<(Latency, Latency)> {
    let mut servos = DxlBus::open_with_buffers(fake_link, 1_000_000, vec![0; 1024], vec![0; 1024])
        .context("opening the fake servo bus")?;
    let mut echo =
        serial2::SerialPort::open(echo_link, 1_000_000).context("opening the echo pty")?;
    echo.set_read_timeout(Duration::from_millis(200))?;
    let request = [0xAAu8; REQUEST_BYTES];
    let mut reply = [0u8; REPLY_BYTES];
    let mut read_samples = Vec::with_capacity(rounds);
    let mut echo_samples = Vec::with_capacity(rounds);
    for round in 0..rounds + 20 {
        let started = Instant::now();
        let positions = bus::read_present_positions(&mut servos)
            .map_err(|e| anyhow::anyhow!("sync read: {e}"))?;
        let read = started.elapsed();
        if positions.iter().any(Option::is_none) {
            bail!("a servo did not answer the sync read: {positions:?}");
        }
        let started = Instant::now();
        echo.write_all(&request)?;
        let mut got = 0;
        while got < REPLY_BYTES {
            got += echo.read(&mut reply[got..])?;
        }
        let echoed = started.elapsed();
        if round >= 20 {
            read_samples.push(read);
            echo_samples.push(echoed);
        }
    }
    Ok((
        Latency::of(&mut read_samples),
        Latency::of(&mut echo_samples),
    ))
}

/// The driver's control loop at 100 Hz with a motion streaming, then a servo fault.
async fn control_loop_and_fault(
    fake: &FakeServoBus,
    link: &std::path::Path,
) -> Result<(f64, u64, u64, f64, f64)> {
    let mut config: RobotConfig =
        serde_json::from_value(serde_json::json!({"driver": "widowx", "control_rate_hz": 100}))?;
    config.widowx.device = link.to_path_buf();
    let widowx = robotd_driver_widowx::open(&config);
    let deadline = Instant::now() + Duration::from_secs(5);
    while widowx.drivers.arm.joints().is_err() {
        if Instant::now() > deadline {
            bail!("the driver did not connect: {:?}", widowx.bus.connection());
        }
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
    let stats = &widowx.bus.stats;
    let (ticks_before, overruns_before) = (
        stats.ticks.load(Ordering::Relaxed),
        stats.overruns.load(Ordering::Relaxed),
    );
    let started = Instant::now();
    let control = MotionControl::default();
    // The fake moves only with the policy's permit, like every robot: the default speed caps,
    // a fence wide enough for the bench's targets (the robot here is the fake on a pty).
    let policy = robotd_safety::Safety::new(
        robotd_safety::SafetyConfig {
            fence_margin_m: 10.0,
            floor_z_m: -10.0,
            ceiling_z_m: 10.0,
            max_reach_m: 10.0,
            motions_per_minute: 0,
            ..Default::default()
        },
        robotd_kinematics::Kinematics::new(robotd_protocol::RobotModel::WidowX250),
        control.clone(),
        &[],
        robotd_safety::AuditLog::disabled(),
    );
    let origin =
        robotd_protocol::safety::Origin::new(robotd_protocol::safety::OriginKind::Internal)
            .session("bench widowx");
    for target in [
        vec![0.6, -0.3, 0.4, 0.2, 0.5, 0.3],
        vec![-0.6, -0.1, 0.2, -0.2, 0.3, -0.3],
        vec![0.0, -0.2, 0.3, 0.0, 0.4, 0.0],
    ] {
        let arm = &widowx.drivers.arm;
        let admission = policy
            .admit(&origin, "arm", "move_joints", serde_json::Value::Null)
            .await
            .map_err(|v| anyhow::anyhow!("motion refused: {v}"))?;
        let start = arm.joints().map_err(|e| anyhow::anyhow!("joints: {e}"))?;
        let permit = policy
            .permit_motion(&admission, &start, Motion::Joints(target))
            .map_err(|v| anyhow::anyhow!("motion refused: {v}"))?;
        arm.execute(permit, &control)
            .await
            .map_err(|e| anyhow::anyhow!("motion: {e}"))?;
    }
    let elapsed = started.elapsed().as_secs_f64();
    let ticks = stats.ticks.load(Ordering::Relaxed) - ticks_before;
    let overruns = stats.overruns.load(Ordering::Relaxed) - overruns_before;

    let latched = Instant::now();
    fake.latch_hardware_error(4, 0x20);
    let fault = loop {
        if let Some(fault) = widowx.bus.last_fault() {
            if fault.recovered {
                break fault;
            }
            bail!("the servo was not recovered: {fault}");
        }
        if latched.elapsed() > Duration::from_secs(5) {
            bail!("the fault was not noticed within 5 s");
        }
        tokio::time::sleep(Duration::from_millis(1)).await;
    };
    let recovery = latched.elapsed();
    widowx.bus.shutdown();
    Ok((
        ticks as f64 / elapsed,
        ticks,
        overruns,
        recovery.as_secs_f64() * 1000.0,
        fault.recovery_time.as_secs_f64() * 1000.0,
    ))
}
