//! # robotd-fake-widowx: a WidowX servo bus without the robot
//!
//! The simulator (`robotd-driver-sim`) behind DYNAMIXEL Protocol 2.0 on a pseudo-terminal, so
//! that the real WidowX driver (`robotd-driver-widowx`), ROBOTIS's dynamixel-sdk, and anything
//! else that drives a U2D2 adapter can be tested without hardware. `robotd fake-widowx` runs
//! it (with the simulated wrist camera as an MJPEG stream); the widowx driver's tests
//! (`tests/driver_against_fake.rs` here) and `robotd bench widowx` start it in process.
//!
//! It is a crate of its own so that the real driver depends on no simulator: the fake depends
//! on the driver for what both sides of the wire share (the packet framing,
//! `robotd_driver_widowx::packet`, and the servo IDs, models and control-table addresses,
//! `robotd_driver_widowx::control_table`), never the reverse.
//!
//! [`FakeServoBus::start`] opens a pty, puts a stable symlink to its terminal end where the
//! caller asks (so `robot.widowx.device` can name it like a real `/dev/ttyDXL`), and answers
//! every instruction a controller sends there as the nine servos of a wx250s would: ping,
//! read, write, sync read, sync write, reboot; secondary IDs (the shadows execute their
//! master's packets without answering); broadcast; the EEPROM and limit rules of [`servo`].
//! Their motion is the simulated arm's ([`world`]). The vendor's own SDK (dynamixel-sdk)
//! drives it in the tests.
//!
//! Fault switches ([`FakeServoBus::faults`]) make it misbehave like hardware does: a latched
//! hardware error on one servo, packets dropped, replies with a broken CRC, a bus that stops
//! answering, and the adapter unplugged and plugged back in.

pub mod servo;
pub mod world;

use robotd_driver_sim::SimRobot;
use robotd_driver_widowx::control_table::accepted_models;
use robotd_driver_widowx::packet::{status_packet, Deframer, Instruction};
use rustix::fd::OwnedFd;
use servo::{error, Servo};
use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU32, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use world::FakeWorld;

const PING: u8 = 0x01;
const READ: u8 = 0x02;
const WRITE: u8 = 0x03;
const REBOOT: u8 = 0x08;
const SYNC_READ: u8 = 0x82;
const SYNC_WRITE: u8 = 0x83;
const BROADCAST: u8 = 0xFE;

/// Misbehaviour on demand.
#[derive(Debug, Default)]
pub struct FakeFaults {
    /// Drop (ignore) the next N instruction packets.
    pub drop_next: AtomicU32,
    /// Flip a CRC bit in the next N replies.
    pub corrupt_next: AtomicU32,
    /// Answer nothing while set.
    pub silent: AtomicBool,
}

/// What the fake saw, for tests.
#[derive(Debug, Default)]
pub struct FakeCounters {
    /// Instruction packets received intact.
    pub packets: AtomicU64,
    /// Packets thrown away (CRC, length).
    pub rejected: AtomicU64,
    /// Goal Position writes (a sync write counts once).
    pub goal_writes: AtomicU64,
    /// REBOOT instructions executed.
    pub reboots: AtomicU64,
}

struct Shared {
    servos: Vec<Servo>,
    world: FakeWorld,
}

/// A running fake servo bus.
pub struct FakeServoBus {
    link: PathBuf,
    shared: Arc<Mutex<Shared>>,
    faults: Arc<FakeFaults>,
    counters: Arc<FakeCounters>,
    stop: Arc<AtomicBool>,
    plugged: Mutex<Option<std::thread::JoinHandle<()>>>,
}

impl std::fmt::Debug for FakeServoBus {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("FakeServoBus")
            .field("link", &self.link)
            .finish_non_exhaustive()
    }
}

impl FakeServoBus {
    /// Serves the nine servos of `sim` (a wx250s) on a new pty linked at `link`; the gripper's
    /// tick range is `gripper_ticks` (closed, open), as in `[robot.widowx]`.
    pub fn start(sim: SimRobot, link: &Path, gripper_ticks: (u16, u16)) -> std::io::Result<Self> {
        let world = FakeWorld::new(sim, gripper_ticks.0, gripper_ticks.1);
        let servos = world
            .initial_positions()
            .into_iter()
            .map(|(id, ticks)| Servo::new(id, accepted_models(id)[0], ticks))
            .collect();
        let bus = FakeServoBus {
            link: link.to_path_buf(),
            shared: Arc::new(Mutex::new(Shared { servos, world })),
            faults: Arc::default(),
            counters: Arc::default(),
            stop: Arc::default(),
            plugged: Mutex::new(None),
        };
        bus.plug_in()?;
        Ok(bus)
    }

    /// Makes the joints obey every goal position `lag` late, a stop included (0: at once): an
    /// arm that keeps going after it was told to stop.
    pub fn set_stopping_lag(&self, lag: std::time::Duration) {
        let mut shared = self.shared.lock().unwrap_or_else(|p| p.into_inner());
        shared.world.set_stopping_lag(lag);
    }

    /// Where the controller opens it.
    pub fn path(&self) -> &Path {
        &self.link
    }

    /// The fault switches.
    pub fn faults(&self) -> &FakeFaults {
        &self.faults
    }

    /// What it saw.
    pub fn counters(&self) -> &FakeCounters {
        &self.counters
    }

    /// The simulator behind it.
    pub fn sim(&self) -> SimRobot {
        self.lock().world.sim().clone()
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, Shared> {
        self.shared.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// Latches hardware error `bits` (Hardware Error Status) on servo `id`, as an overload
    /// (0x20) or overheating (0x04) would.
    pub fn latch_hardware_error(&self, id: u8, bits: u8) {
        if let Some(servo) = self.lock().servos.iter_mut().find(|s| s.id == id) {
            servo.latch_hardware_error(bits);
        }
    }

    /// A servo's raw control-table bytes, for tests.
    pub fn read_table(&self, id: u8, at: u16, length: u16) -> Option<Vec<u8>> {
        let shared = self.lock();
        shared
            .servos
            .iter()
            .find(|s| s.id == id)
            .and_then(|s| s.read(at, length).ok())
    }

    /// Pulls the adapter out: the pty closes and the device path disappears.
    pub fn unplug(&self) {
        self.stop.store(true, Ordering::SeqCst);
        if let Some(thread) = self
            .plugged
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .take()
        {
            let _ = thread.join();
        }
        let _ = std::fs::remove_file(&self.link);
    }

    /// Plugs it back in: a new pty at the same path, the servos as they were.
    pub fn plug_in(&self) -> std::io::Result<()> {
        self.unplug();
        self.stop.store(false, Ordering::SeqCst);
        let (master, slave_path) = open_pty()?;
        let _ = std::fs::remove_file(&self.link);
        std::os::unix::fs::symlink(&slave_path, &self.link)?;
        // Keep a handle on the terminal side, so the pty lives between controllers.
        let keep_open = std::fs::OpenOptions::new()
            .read(true)
            .write(true)
            .open(&slave_path)?;
        make_raw(&keep_open)?;
        let server = Server {
            master: std::fs::File::from(master),
            _keep_open: keep_open,
            shared: self.shared.clone(),
            faults: self.faults.clone(),
            counters: self.counters.clone(),
            stop: self.stop.clone(),
        };
        let thread = std::thread::Builder::new()
            .name("fake-widowx".into())
            .spawn(move || server.run())?;
        *self.plugged.lock().unwrap_or_else(|p| p.into_inner()) = Some(thread);
        Ok(())
    }
}

impl Drop for FakeServoBus {
    fn drop(&mut self) {
        self.unplug();
    }
}

/// A bare pseudo-terminal that answers every `request_len` bytes it reads with `reply_len`
/// bytes: the raw baseline of `robotd bench widowx` (the same bytes over the same kind of
/// device, with no protocol and no servos behind it).
pub struct EchoPty {
    link: PathBuf,
    stop: Arc<AtomicBool>,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl EchoPty {
    /// Starts it at `link`.
    pub fn start(link: &Path, request_len: usize, reply_len: usize) -> std::io::Result<Self> {
        let (master, slave_path) = open_pty()?;
        let _ = std::fs::remove_file(link);
        std::os::unix::fs::symlink(&slave_path, link)?;
        let keep_open = std::fs::OpenOptions::new()
            .read(true)
            .write(true)
            .open(&slave_path)?;
        make_raw(&keep_open)?;
        let stop = Arc::new(AtomicBool::new(false));
        let running = stop.clone();
        let mut master = std::fs::File::from(master);
        let thread = std::thread::Builder::new()
            .name("echo-pty".into())
            .spawn(move || {
                use rustix::event::{poll, PollFd, PollFlags, Timespec};
                let _keep_open = keep_open;
                let reply = vec![0x55u8; reply_len];
                let mut buffer = [0u8; 512];
                let mut pending = 0usize;
                let timeout = Timespec {
                    tv_sec: 0,
                    tv_nsec: 20_000_000,
                };
                while !running.load(Ordering::SeqCst) {
                    let mut fds = [PollFd::new(&master, PollFlags::IN)];
                    if !matches!(poll(&mut fds, Some(&timeout)), Ok(n) if n > 0) {
                        continue;
                    }
                    let Ok(n) = master.read(&mut buffer) else {
                        continue;
                    };
                    pending += n;
                    while pending >= request_len.max(1) {
                        pending -= request_len.max(1);
                        let _ = master.write_all(&reply);
                    }
                }
            })?;
        Ok(Self {
            link: link.to_path_buf(),
            stop,
            thread: Some(thread),
        })
    }
}

impl Drop for EchoPty {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        if let Some(thread) = self.thread.take() {
            let _ = thread.join();
        }
        let _ = std::fs::remove_file(&self.link);
    }
}

fn open_pty() -> std::io::Result<(OwnedFd, PathBuf)> {
    use rustix::pty::{grantpt, openpt, ptsname, unlockpt, OpenptFlags};
    let master = openpt(OpenptFlags::RDWR | OpenptFlags::NOCTTY | OpenptFlags::CLOEXEC)?;
    grantpt(&master)?;
    unlockpt(&master)?;
    let name = ptsname(&master, Vec::new())?;
    let path = PathBuf::from(name.to_string_lossy().into_owned());
    Ok((master, path))
}

fn make_raw(file: &std::fs::File) -> std::io::Result<()> {
    use rustix::termios::{tcgetattr, tcsetattr, OptionalActions};
    let mut termios = tcgetattr(file)?;
    termios.make_raw();
    tcsetattr(file, OptionalActions::Now, &termios)?;
    Ok(())
}

/// The thread that answers on the pty.
struct Server {
    master: std::fs::File,
    _keep_open: std::fs::File,
    shared: Arc<Mutex<Shared>>,
    faults: Arc<FakeFaults>,
    counters: Arc<FakeCounters>,
    stop: Arc<AtomicBool>,
}

impl Server {
    fn run(mut self) {
        use rustix::event::{poll, PollFd, PollFlags, Timespec};
        let mut deframer = Deframer::default();
        let mut buffer = [0u8; 512];
        let timeout = Timespec {
            tv_sec: 0,
            tv_nsec: 20_000_000,
        };
        while !self.stop.load(Ordering::SeqCst) {
            let mut fds = [PollFd::new(&self.master, PollFlags::IN)];
            match poll(&mut fds, Some(&timeout)) {
                Ok(0) => continue,
                Ok(_) => {}
                Err(_) => continue,
            }
            let n = match self.master.read(&mut buffer) {
                Ok(0) => continue,
                Ok(n) => n,
                Err(_) => {
                    std::thread::sleep(Duration::from_millis(5));
                    continue;
                }
            };
            deframer.push(&buffer[..n]);
            while let Some(packet) = deframer.next_packet() {
                match packet {
                    Ok(instruction) => {
                        self.counters.packets.fetch_add(1, Ordering::Relaxed);
                        let replies = self.handle(&instruction);
                        self.send(replies);
                    }
                    Err(problem) => {
                        self.counters.rejected.fetch_add(1, Ordering::Relaxed);
                        tracing::debug!(%problem, "fake servo bus: packet thrown away");
                    }
                }
            }
        }
    }

    fn send(&mut self, replies: Vec<Vec<u8>>) {
        if replies.is_empty() || self.faults.silent.load(Ordering::SeqCst) {
            return;
        }
        let mut bytes = Vec::new();
        for mut reply in replies {
            if take_one(&self.faults.corrupt_next) {
                if let Some(last) = reply.last_mut() {
                    *last ^= 0x5A;
                }
            }
            bytes.extend_from_slice(&reply);
        }
        let _ = self.master.write_all(&bytes);
    }

    fn handle(&self, packet: &Instruction) -> Vec<Vec<u8>> {
        if take_one(&self.faults.drop_next) {
            return Vec::new();
        }
        let mut shared = self.shared.lock().unwrap_or_else(|p| p.into_inner());
        let Shared { servos, world } = &mut *shared;
        world.advance(servos);
        let now = Instant::now();
        let p = &packet.params;
        let unicast = packet.id != BROADCAST;
        let reply_error = |servos: &[Servo], code: u8| -> Vec<Vec<u8>> {
            servos
                .iter()
                .find(|s| s.id == packet.id && s.awake(now))
                .map(|s| vec![status_packet(s.id, code | s.alert(), &[])])
                .unwrap_or_default()
        };
        match packet.instruction {
            PING => servos
                .iter()
                .filter(|s| (s.id == packet.id || !unicast) && s.awake(now))
                .map(|s| {
                    let m = s.model().to_le_bytes();
                    status_packet(s.id, s.alert(), &[m[0], m[1], s.firmware()])
                })
                .collect(),
            READ => {
                if p.len() != 4 {
                    return reply_error(servos, error::DATA_LENGTH);
                }
                let (at, length) = (u16_at(p, 0), u16_at(p, 2));
                servos
                    .iter()
                    .find(|s| s.id == packet.id && s.awake(now))
                    .map(|s| match s.read(at, length) {
                        Ok(data) => vec![status_packet(s.id, s.alert(), &data)],
                        Err(code) => vec![status_packet(s.id, code | s.alert(), &[])],
                    })
                    .unwrap_or_default()
            }
            WRITE => {
                if p.len() < 3 {
                    return reply_error(servos, error::DATA_LENGTH);
                }
                let at = u16_at(p, 0);
                let mut replies = Vec::new();
                for servo in servos.iter_mut().filter(|s| s.awake(now)) {
                    let primary = servo.id == packet.id;
                    if !(primary || !unicast || servo.secondary_id() == packet.id) {
                        continue;
                    }
                    let result = servo.write(at, &p[2..]);
                    if result.is_ok()
                        && primary
                        && at == robotd_driver_widowx::control_table::address::GOAL_POSITION
                    {
                        self.counters.goal_writes.fetch_add(1, Ordering::Relaxed);
                    }
                    if primary {
                        let code = result.err().unwrap_or(0);
                        replies.push(status_packet(servo.id, code | servo.alert(), &[]));
                    }
                }
                replies
            }
            REBOOT => {
                let mut replies = Vec::new();
                for servo in servos.iter_mut() {
                    if (servo.id == packet.id || !unicast) && servo.awake(now) {
                        if unicast {
                            replies.push(status_packet(servo.id, 0, &[]));
                        }
                        servo.reboot(now);
                        self.counters.reboots.fetch_add(1, Ordering::Relaxed);
                    }
                }
                replies
            }
            SYNC_READ if !unicast && p.len() >= 5 => {
                let (at, length) = (u16_at(p, 0), u16_at(p, 2));
                p[4..]
                    .iter()
                    .filter_map(|id| servos.iter().find(|s| s.id == *id && s.awake(now)))
                    .map(|s| match s.read(at, length) {
                        Ok(data) => status_packet(s.id, s.alert(), &data),
                        Err(code) => status_packet(s.id, code | s.alert(), &[]),
                    })
                    .collect()
            }
            SYNC_WRITE if !unicast && p.len() >= 4 => {
                let (at, length) = (u16_at(p, 0), usize::from(u16_at(p, 2)));
                if length == 0 {
                    return Vec::new();
                }
                for block in p[4..].chunks_exact(length + 1) {
                    let (id, data) = (block[0], &block[1..]);
                    for servo in servos.iter_mut().filter(|s| s.awake(now)) {
                        if servo.id == id || servo.secondary_id() == id {
                            let _ = servo.write(at, data);
                        }
                    }
                }
                if at == robotd_driver_widowx::control_table::address::GOAL_POSITION {
                    self.counters.goal_writes.fetch_add(1, Ordering::Relaxed);
                }
                Vec::new()
            }
            _ if unicast => reply_error(servos, error::INSTRUCTION),
            _ => Vec::new(),
        }
    }
}

fn u16_at(p: &[u8], at: usize) -> u16 {
    u16::from_le_bytes([p[at], p[at + 1]])
}

/// Decrements `counter` if positive; whether it did.
fn take_one(counter: &AtomicU32) -> bool {
    counter
        .fetch_update(Ordering::SeqCst, Ordering::SeqCst, |n| n.checked_sub(1))
        .is_ok()
}
