//! The servo bus: one thread owns the serial port and runs the control loop.
//!
//! Every control tick (`robot.control_rate_hz`) the thread
//! 1. writes the pending joint goals (one sync write; a goal is taken once, so it is never
//!    sent twice) and the pending gripper PWM,
//! 2. runs the queued one-off jobs (gripper reads, reboots),
//! 3. sync-reads Present Position of all nine servos into a [`Snapshot`], and
//! 4. wakes whoever waits for the next tick.
//!
//! A status packet with the Alert bit set means a servo latched a hardware error: the thread
//! reads Hardware Error Status, holds the arm where it is, reboots that servo, turns its torque
//! back on and reports the fault ([`Fault`]) to the motion that was running. A serial port that
//! fails (USB unplugged) or servos that stop answering make the robot unavailable with the
//! reason; the thread reopens the port (100 ms, doubling to `reconnect_max`) and brings the bus
//! up again. The per-tick sync read frames the replies itself (dynamixel2 0.9.1's reader panics on
//! a status packet with a length field below 4); the other transfers (bring-up, gripper reads,
//! fault recovery) go through dynamixel2, and the thread catches a panic there, drops the port
//! and reopens it, so nothing from the wire can take robotd down.

use crate::control_table::{
    address, hardware_error_reasons, servo_name, ALL_IDS, GRIPPER_ID, JOINT_IDS,
};
use crate::packet::{Deframer, Instruction, STATUS};
use crate::startup::{self, StartupSettings};
use crate::DxlBus;
use robotd_driver::DriverError;
use robotd_runtime::backoff::Backoff;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{mpsc, Arc, Mutex, MutexGuard};
use std::time::{Duration, Instant};

/// How the bus thread runs.
#[derive(Debug, Clone)]
pub struct BusSettings {
    /// Serial device.
    pub device: PathBuf,
    /// Baud rate.
    pub baud_rate: u32,
    /// One control tick.
    pub control_period: Duration,
    /// Longest wait between reopen attempts.
    pub reconnect_max: Duration,
    /// What bring-up writes.
    pub startup: StartupSettings,
}

/// Consecutive ticks a servo may miss before the robot counts as not connected.
const SILENT_TICKS: u32 = 5;
/// How long a rebooted servo may stay deaf.
const REBOOT_DEADLINE: Duration = Duration::from_millis(800);

/// The positions of one tick.
#[derive(Debug, Clone, PartialEq)]
pub struct Snapshot {
    /// Present Position by servo (index = ID − 1), ticks; `None` when it did not answer.
    pub positions: [Option<i32>; 9],
    /// Control tick number.
    pub tick: u64,
}

impl Snapshot {
    /// Present positions of the six joint masters, or `None` if one is missing.
    pub fn joint_ticks(&self) -> Option<[i32; 6]> {
        let mut out = [0; 6];
        for (slot, id) in out.iter_mut().zip(JOINT_IDS) {
            *slot = self.positions[usize::from(id - 1)]?;
        }
        Some(out)
    }

    /// The gripper servo's position.
    pub fn gripper_ticks(&self) -> Option<i32> {
        self.positions[usize::from(GRIPPER_ID - 1)]
    }
}

/// A servo hardware fault and what the bus did about it.
#[derive(Debug, Clone, PartialEq)]
pub struct Fault {
    /// The servo.
    pub id: u8,
    /// What its Hardware Error Status said.
    pub reasons: Vec<&'static str>,
    /// Whether it was rebooted and answers again.
    pub recovered: bool,
    /// From the alert to the servo answering with torque on again.
    pub recovery_time: Duration,
    /// Counts faults, so a motion can tell a new one from an old one.
    pub generation: u64,
}

impl std::fmt::Display for Fault {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "servo {} ({}) reported {}; the arm was held",
            self.id,
            servo_name(self.id),
            self.reasons.join(" and ")
        )?;
        if self.recovered {
            write!(
                f,
                " and the servo rebooted (back in {} ms)",
                self.recovery_time.as_millis()
            )
        } else {
            write!(f, "; rebooting the servo failed")
        }
    }
}

/// One-off work for the bus thread.
type Job = Box<dyn FnOnce(&mut DxlBus) + Send>;

struct Shared {
    connection: Result<(), String>,
    snapshot: Option<Snapshot>,
    goal: Option<[i32; 6]>,
    gripper_pwm: Option<i16>,
    last_fault: Option<Fault>,
}

/// Counters of the control loop.
#[derive(Debug, Default)]
pub struct BusStats {
    /// Ticks run while connected.
    pub ticks: AtomicU64,
    /// Ticks whose work took longer than one control period.
    pub overruns: AtomicU64,
    /// Goal sync writes sent.
    pub goal_writes: AtomicU64,
    /// Successful (re)connections.
    pub connections: AtomicU64,
}

/// The servo bus, shared by the arm and gripper drivers.
pub struct ServoBus {
    settings: BusSettings,
    shared: Mutex<Shared>,
    ticks: tokio::sync::watch::Sender<u64>,
    jobs: Mutex<mpsc::Sender<Job>>,
    stop: AtomicBool,
    /// Control-loop counters.
    pub stats: BusStats,
}

impl std::fmt::Debug for ServoBus {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ServoBus")
            .field("device", &self.settings.device)
            .finish_non_exhaustive()
    }
}

impl ServoBus {
    /// Starts the bus thread; it opens the port and keeps it open.
    pub fn start(settings: BusSettings) -> Arc<ServoBus> {
        let (jobs_tx, jobs_rx) = mpsc::channel();
        let bus = Arc::new(ServoBus {
            shared: Mutex::new(Shared {
                connection: Err(format!(
                    "opening the servo bus on {}",
                    settings.device.display()
                )),
                snapshot: None,
                goal: None,
                gripper_pwm: None,
                last_fault: None,
            }),
            settings,
            ticks: tokio::sync::watch::channel(0).0,
            jobs: Mutex::new(jobs_tx),
            stop: AtomicBool::new(false),
            stats: BusStats::default(),
        });
        let runner = bus.clone();
        std::thread::Builder::new()
            .name("widowx-bus".into())
            .spawn(move || runner.run(jobs_rx))
            .map_err(|e| tracing::error!(error = %e, "cannot start the servo bus thread"))
            .ok();
        bus
    }

    /// Stops the bus thread (the servos keep holding their last goals).
    pub fn shutdown(&self) {
        self.stop.store(true, Ordering::SeqCst);
    }

    fn lock(&self) -> MutexGuard<'_, Shared> {
        self.shared.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// `Err(reason)` while the bus is not up.
    pub fn connection(&self) -> Result<(), String> {
        self.lock().connection.clone()
    }

    /// The latest positions.
    pub fn snapshot(&self) -> Option<Snapshot> {
        self.lock().snapshot.clone()
    }

    /// The latest servo fault.
    pub fn last_fault(&self) -> Option<Fault> {
        self.lock().last_fault.clone()
    }

    /// Sets the joint goals written at the next tick (replacing any not yet written).
    pub fn set_joint_goal(&self, ticks: [i32; 6]) {
        self.lock().goal = Some(ticks);
    }

    /// Holds the arm where it is now: the next tick writes the present positions as goals.
    pub fn hold(&self) {
        let mut shared = self.lock();
        if let Some(here) = shared.snapshot.as_ref().and_then(Snapshot::joint_ticks) {
            shared.goal = Some(here);
        }
    }

    /// Sets the gripper's Goal PWM written at the next tick.
    pub fn set_gripper_pwm(&self, pwm: i16) {
        self.lock().gripper_pwm = Some(pwm);
    }

    /// Waits for the next control tick (or fails when the bus is down).
    pub async fn next_tick(&self) -> Result<u64, DriverError> {
        let mut rx = self.ticks.subscribe();
        let wait = tokio::time::timeout(
            self.settings.control_period * 20 + Duration::from_millis(200),
            rx.changed(),
        )
        .await;
        self.connection().map_err(not_connected)?;
        match wait {
            Ok(Ok(())) => Ok(*rx.borrow()),
            _ => Err(DriverError::Hardware(
                "the servo bus stopped ticking (its thread is gone or stuck)".into(),
            )),
        }
    }

    /// Runs `job` on the bus thread between two ticks and returns its result.
    pub async fn call<T: Send + 'static>(
        &self,
        job: impl FnOnce(&mut DxlBus) -> Result<T, String> + Send + 'static,
    ) -> Result<T, DriverError> {
        self.connection().map_err(not_connected)?;
        let (tx, rx) = tokio::sync::oneshot::channel();
        let boxed: Job = Box::new(move |bus| {
            let _ = tx.send(job(bus));
        });
        self.jobs
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .send(boxed)
            .map_err(|_| DriverError::Hardware("the servo bus thread is gone".into()))?;
        match tokio::time::timeout(Duration::from_secs(2), rx).await {
            Ok(Ok(result)) => result.map_err(DriverError::Hardware),
            Ok(Err(_)) => {
                Err(not_connected(self.connection().err().unwrap_or_else(
                    || "the servo bus dropped the request".into(),
                )))
            }
            Err(_) => Err(DriverError::Hardware(
                "the servo bus did not run the request within 2 s".into(),
            )),
        }
    }

    fn set_connection(&self, connection: Result<(), String>) {
        let mut shared = self.lock();
        if shared.connection != connection {
            match &connection {
                Ok(()) => tracing::info!(device = %self.settings.device.display(), "servo bus up"),
                Err(reason) => tracing::warn!(%reason, "servo bus not available"),
            }
        }
        if connection.is_err() {
            shared.snapshot = None;
            shared.goal = None;
            shared.gripper_pwm = None;
        }
        shared.connection = connection;
    }

    /// The bus thread: open, bring up, tick; reopen after a failure.
    fn run(self: Arc<Self>, jobs: mpsc::Receiver<Job>) {
        let mut backoff = Backoff::up_to(self.settings.reconnect_max);
        while !self.stop.load(Ordering::SeqCst) {
            let mut bus = match self.open_and_bring_up() {
                Ok(bus) => bus,
                Err(reason) => {
                    self.set_connection(Err(reason));
                    drain(&jobs);
                    self.ticks.send_modify(|t| *t += 1);
                    std::thread::sleep(backoff.next_delay());
                    continue;
                }
            };
            backoff.reset();
            self.stats.connections.fetch_add(1, Ordering::Relaxed);
            self.set_connection(Ok(()));
            let lost = self.control_loop(&mut bus, &jobs);
            self.set_connection(Err(lost));
            drain(&jobs);
            self.ticks.send_modify(|t| *t += 1);
        }
    }

    fn open_and_bring_up(&self) -> Result<DxlBus, String> {
        let settings = &self.settings;
        let device = settings.device.display();
        let mut bus = DxlBus::open_with_buffers(
            &settings.device,
            settings.baud_rate,
            vec![0; 1024],
            vec![0; 1024],
        )
        .map_err(|e| match e.kind() {
            std::io::ErrorKind::NotFound => format!(
                "serial port {device} not found: is the U2D2 plugged in (and the udev rule installed)?"
            ),
            std::io::ErrorKind::PermissionDenied => format!(
                "no permission to open {device}: add your user to the dialout group (then log in again)"
            ),
            _ => format!("cannot open serial port {device}: {e}"),
        })?;
        match catch_unwind(AssertUnwindSafe(|| {
            startup::bring_up(&mut bus, settings.startup)
        })) {
            Ok(Ok(())) => Ok(bus),
            Ok(Err(e)) => Err(e.to_string()),
            Err(_) => Err("the servo bus library failed on a malformed packet".into()),
        }
    }

    /// Ticks until the port fails or servos go silent; returns why.
    fn control_loop(&self, bus: &mut DxlBus, jobs: &mpsc::Receiver<Job>) -> String {
        let period = self.settings.control_period;
        let mut next = Instant::now();
        let mut silent = [0u32; 9];
        let mut recovery_attempts: [Option<Instant>; 9] = [None; 9];
        let mut tick: u64 = 0;
        loop {
            if self.stop.load(Ordering::SeqCst) {
                return "robotd is shutting down".into();
            }
            let started = Instant::now();
            let outcome = catch_unwind(AssertUnwindSafe(|| self.tick(bus, jobs, tick)));
            let snapshot = match outcome {
                Ok(Ok(snapshot)) => snapshot,
                Ok(Err(reason)) => return reason,
                Err(_) => {
                    return "the servo bus library failed on a malformed packet; reopening the port"
                        .into()
                }
            };
            let mut snapshot = snapshot;
            let previous = self.snapshot();
            for (index, count) in silent.iter_mut().enumerate() {
                if snapshot.positions[index].is_some() {
                    *count = 0;
                } else {
                    // A reply lost or late this tick: the last position stands, for a few
                    // ticks (SILENT_TICKS) before the servo counts as gone.
                    *count += 1;
                    snapshot.positions[index] = previous.as_ref().and_then(|p| p.positions[index]);
                }
            }
            let alerts: Vec<u8> = ALL_IDS
                .iter()
                .zip(snapshot.alerts)
                .filter(|(_, alert)| *alert)
                .map(|(id, _)| *id)
                .collect();
            self.lock().snapshot = Some(snapshot.into());
            if let Some((index, _)) = silent.iter().enumerate().find(|(_, c)| **c >= SILENT_TICKS) {
                let id = ALL_IDS[index];
                return format!(
                    "servo {id} ({}) stopped answering; check its cable and power",
                    servo_name(id)
                );
            }
            for id in alerts {
                // A servo that stays faulted after its reboot is retried once a second, not
                // every tick.
                let attempt = &mut recovery_attempts[usize::from(id - 1)];
                if attempt.is_none_or(|at| at.elapsed() >= Duration::from_secs(1)) {
                    *attempt = Some(Instant::now());
                    // The recovery's reads go through dynamixel2's reader, which can panic on a
                    // malformed reply (see `sync_read_positions`): as in a tick, that drops the
                    // port, where an uncaught panic would have ended this thread.
                    if catch_unwind(AssertUnwindSafe(|| self.recover(bus, id))).is_err() {
                        return "the servo bus library failed on a malformed packet; reopening \
                                the port"
                            .into();
                    }
                }
            }
            self.stats.ticks.fetch_add(1, Ordering::Relaxed);
            self.ticks.send_modify(|t| *t += 1);
            tick += 1;
            next += period;
            let now = Instant::now();
            if now > next {
                if now - started > period {
                    self.stats.overruns.fetch_add(1, Ordering::Relaxed);
                }
                next = now;
            } else {
                std::thread::sleep(next - now);
            }
        }
    }

    /// One tick's bus traffic. `Err` = the port failed.
    fn tick(
        &self,
        bus: &mut DxlBus,
        jobs: &mpsc::Receiver<Job>,
        tick: u64,
    ) -> Result<TickSnapshot, String> {
        let (goal, pwm) = {
            let mut shared = self.lock();
            (shared.goal.take(), shared.gripper_pwm.take())
        };
        if let Some(goal) = goal {
            startup::write_joint_goals(bus, &goal).map_err(port_failed)?;
            self.stats.goal_writes.fetch_add(1, Ordering::Relaxed);
        }
        if let Some(pwm) = pwm {
            // The gripper's write is acknowledged; a refusal is logged, the port is fine.
            if let Err(e) = bus.write_u16(GRIPPER_ID, address::GOAL_PWM, pwm as u16) {
                if is_port_failure_transfer(&e) {
                    return Err(port_failed_transfer(e));
                }
                tracing::warn!(error = %e, "writing the gripper's Goal PWM");
            }
        }
        while let Ok(job) = jobs.try_recv() {
            job(bus);
        }
        let mut snapshot = TickSnapshot {
            positions: [None; 9],
            alerts: [false; 9],
            tick,
        };
        let port_error = sync_read_positions(bus, &mut snapshot).err();
        if let Some(error) = port_error {
            return Err(format!(
                "serial port {} failed: {error}; was the U2D2 unplugged?",
                self.settings.device.display()
            ));
        }
        Ok(snapshot)
    }

    /// Reads servo `id`'s hardware error, holds the arm, reboots the servo and restores it.
    fn recover(&self, bus: &mut DxlBus, id: u8) {
        let started = Instant::now();
        let status = bus
            .read_u8(id, address::HARDWARE_ERROR_STATUS)
            .map(|r| r.data)
            .unwrap_or(0);
        let reasons = hardware_error_reasons(status);
        let reasons = if reasons.is_empty() {
            vec!["a hardware error"]
        } else {
            reasons
        };
        tracing::error!(id, servo = servo_name(id), reasons = ?reasons, "servo hardware error: holding the arm and rebooting the servo");
        // Hold: every joint's goal at its present position (a motion in progress stops here).
        if let Some(here) = self.snapshot().as_ref().and_then(Snapshot::joint_ticks) {
            self.lock().goal = None;
            if let Err(e) = startup::write_joint_goals(bus, &here) {
                tracing::warn!(error = %e, "holding the arm before the reboot");
            }
        }
        let recovered = reboot_and_restore(bus, id);
        let mut shared = self.lock();
        let generation = shared.last_fault.as_ref().map_or(1, |f| f.generation + 1);
        let fault = Fault {
            id,
            reasons,
            recovered,
            recovery_time: started.elapsed(),
            generation,
        };
        tracing::warn!(%fault, "servo fault handled");
        shared.last_fault = Some(fault);
    }
}

/// What one tick read: positions and which servos raised the Alert bit.
struct TickSnapshot {
    positions: [Option<i32>; 9],
    alerts: [bool; 9],
    tick: u64,
}

impl From<TickSnapshot> for Snapshot {
    fn from(t: TickSnapshot) -> Self {
        Snapshot {
            positions: t.positions,
            tick: t.tick,
        }
    }
}

/// Sync-reads Present Position of the nine servos once, as the control loop does every tick
/// (for `robotd bench widowx`): by servo (index = ID − 1), `None` for a missing reply.
pub fn read_present_positions(bus: &mut DxlBus) -> Result<[Option<i32>; 9], String> {
    let mut snapshot = TickSnapshot {
        positions: [None; 9],
        alerts: [false; 9],
        tick: 0,
    };
    sync_read_positions(bus, &mut snapshot)?;
    Ok(snapshot.positions)
}

/// Sync-reads Present Position of every servo into `snapshot`, with one deadline for all the
/// replies (as the vendor SDK does): a lost reply costs one timeout per tick, not one per
/// servo after it. `Err` = the port failed.
///
/// The replies are read from the port and framed here, not by dynamixel2's
/// `read_status_response_deadline`: dynamixel2 0.9.1 panics on a status packet whose length
/// field is below 4 (an arithmetic overflow for 0 and 1 in debug builds; a slice out of range
/// for 2 and 3 with a matching CRC, in every build), so one corrupted length byte dropped the
/// port to reopen it. [`Deframer`] (shared with the fake servo bus) frames them (a status
/// packet is framed like an instruction: CRC over the stuffed bytes, then unstuffing; anything
/// malformed skipped). Fuzzed by `tests/fuzz_packets.rs` and, on a pty, `tests/fuzz_status.rs`.
fn sync_read_positions(bus: &mut DxlBus, snapshot: &mut TickSnapshot) -> Result<(), String> {
    const SYNC_READ: u8 = 0x82;
    const BROADCAST: u8 = 0xFE;
    let at = address::PRESENT_POSITION.to_le_bytes();
    // This also throws away whatever was waiting on the port.
    bus.write_instruction(BROADCAST, SYNC_READ, 4 + ALL_IDS.len(), |params| {
        params[..4].copy_from_slice(&[at[0], at[1], 4, 0]);
        params[4..].copy_from_slice(&ALL_IDS);
    })
    .map_err(|e| e.to_string())?;
    // 15 bytes per reply at the bus speed, plus the SDK's flat 34 ms allowance.
    let bytes = 15 * ALL_IDS.len() as u64;
    let transfer = Duration::from_micros(bytes * 10_000_000 / u64::from(bus.baud_rate().max(1)));
    let deadline = Instant::now() + transfer + Duration::from_millis(34);
    let mut deframer = Deframer::default();
    let mut buffer = [0u8; 256];
    // Packets framed, good or not. Once there are as many as servos, only what has already
    // arrived is read: a corrupt reply does not cost a wait for the deadline, and an extra
    // packet (noise) does not cost the reply after it.
    let mut replies = 0;
    loop {
        match deframer.next_packet() {
            Some(Ok(packet)) => {
                replies += 1;
                take_position(&packet, snapshot);
            }
            Some(Err(problem)) => {
                // A corrupt reply: that servo misses this tick.
                replies += 1;
                tracing::debug!(%problem, "a servo's sync-read reply");
            }
            None => {
                if snapshot.positions.iter().all(Option::is_some) {
                    break;
                }
                let until = if replies >= ALL_IDS.len() {
                    Instant::now()
                } else {
                    deadline
                };
                match read_before(bus, &mut buffer, until) {
                    Ok(0) => break,
                    Ok(n) => deframer.push(&buffer[..n]),
                    Err(e) => return Err(e.to_string()),
                }
            }
        }
    }
    Ok(())
}

/// The position in a sync-read reply: a status packet (0x55) whose error byte has no error
/// number (the Alert bit alone still comes with the data) and four bytes of Present Position.
fn take_position(packet: &Instruction, snapshot: &mut TickSnapshot) {
    let index = usize::from(packet.id.wrapping_sub(1));
    match (packet.instruction, packet.params.as_slice()) {
        (STATUS, [error, data @ ..]) if error & 0x7F == 0 => {
            match (<[u8; 4]>::try_from(data), snapshot.positions.get_mut(index)) {
                (Ok(bytes), Some(slot)) => {
                    *slot = Some(i32::from_le_bytes(bytes));
                    snapshot.alerts[index] = error & 0x80 != 0;
                }
                _ => tracing::debug!(
                    id = packet.id,
                    length = data.len(),
                    "a sync-read reply of an unknown servo or of the wrong length"
                ),
            }
        }
        (STATUS, [error, ..]) => {
            tracing::debug!(id = packet.id, error, "a servo refused the sync read")
        }
        (instruction, _) => tracing::debug!(
            id = packet.id,
            instruction,
            "a malformed sync-read reply (not a status packet, or no error byte)"
        ),
    }
}

/// Reads what the port has, waiting until `deadline` at most: `Ok(0)` when nothing came by
/// then (with a deadline already passed, only what is there now is read).
fn read_before(bus: &DxlBus, buffer: &mut [u8], deadline: Instant) -> std::io::Result<usize> {
    use rustix::event::{poll, PollFd, PollFlags, Timespec};
    use rustix::io::Errno;
    let port = bus.serial_port();
    loop {
        let left = deadline.saturating_duration_since(Instant::now());
        let timeout = Timespec {
            tv_sec: left.as_secs() as _,
            tv_nsec: left.subsec_nanos() as _,
        };
        let mut fds = [PollFd::new(port, PollFlags::IN)];
        match poll(&mut fds, Some(&timeout)) {
            Ok(0) => return Ok(0),
            Ok(_) => {}
            Err(Errno::INTR) => continue,
            Err(e) => return Err(e.into()),
        }
        match rustix::io::read(port, &mut *buffer) {
            Ok(n) if n > 0 => return Ok(n),
            // Readable but nothing there (a hang-up): as before, the replies are late until
            // the deadline; without spinning meanwhile.
            Ok(_) | Err(Errno::AGAIN) if left.is_zero() => return Ok(0),
            Ok(_) => std::thread::sleep(Duration::from_millis(1)),
            Err(Errno::AGAIN | Errno::INTR) => continue,
            Err(e) => return Err(e.into()),
        }
    }
}

/// Reboots servo `id`, waits until it answers, restores its torque; whether that worked.
fn reboot_and_restore(bus: &mut DxlBus, id: u8) -> bool {
    if let Err(e) = bus.reboot(id) {
        tracing::warn!(id, error = %e, "rebooting the servo");
    }
    let deadline = Instant::now() + REBOOT_DEADLINE;
    while Instant::now() < deadline {
        if bus.ping(id).is_ok() {
            return match startup::restore_after_reboot(bus, id) {
                Ok(()) => true,
                Err(e) => {
                    tracing::warn!(error = %e, "restoring the rebooted servo");
                    false
                }
            };
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    false
}

fn drain(jobs: &mpsc::Receiver<Job>) {
    // Dropping a job drops its reply channel: the caller hears "not connected".
    while jobs.try_recv().is_ok() {}
}

fn not_connected(reason: String) -> DriverError {
    DriverError::Hardware(format!("robot not connected: {reason}"))
}

fn port_failed(e: dynamixel2::WriteError) -> String {
    format!("writing to the serial port failed: {e}; was the U2D2 unplugged?")
}

fn is_port_failure_transfer(e: &dynamixel2::TransferError) -> bool {
    match e {
        dynamixel2::TransferError::WriteError(_) => true,
        dynamixel2::TransferError::ReadError(dynamixel2::ReadError::Io(io)) => {
            io.kind() != std::io::ErrorKind::TimedOut
        }
        _ => false,
    }
}

fn port_failed_transfer(e: dynamixel2::TransferError) -> String {
    format!("the serial port failed: {e}; was the U2D2 unplugged?")
}
