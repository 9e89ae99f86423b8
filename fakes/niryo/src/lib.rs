//! # robotd-fake-niryo: a Ned2 without the robot
//!
//! The simulator (`robotd-driver-sim`) served behind the Niryo Ned2's real TCP protocol, so
//! that the real driver (`robotd-driver-niryo`), pyniryo, and anything else that speaks to a
//! Ned2 on port 40001 can be tested without hardware. `robotd fake-niryo` runs it; the niryo
//! driver's tests (`tests/driver_against_fake.rs` here), `robotd doctor`'s tests and `robotd
//! bench niryo` start it in process.
//!
//! It is a crate of its own so that the real driver depends on no simulator: the fake depends
//! on the driver (for the wire format, `robotd_driver_niryo::wire`), never the reverse.
//!
//! It behaves like the robot where a client can tell (see `docs/niryo-tcp.md`):
//!
//! - one client at a time: a second connection is accepted by the kernel but gets no answers
//!   until the first one leaves;
//! - every command runs to its end before its reply, and keeps running when the client
//!   leaves; its reply then goes to the next client first (the robot's stale-reply race);
//! - motions run the simulated arm in the simulated world; a rejected move (not calibrated,
//!   out of range, no inverse kinematics solution) answers OK **without moving**, as recent
//!   robot software does; a collision answers KO and refuses motions until cleared;
//! - `GET_IMAGE_COMPRESSED` is the wrist camera's rendering, through the Ned2's lens
//!   distortion, as a JPEG; `GET_CAMERA_INTRINSICS` gives the Ned2's nominal intrinsics.
//!
//! [`FakeFaults`] switches on what a driver must survive: refused connections, a connection
//! dropped at the N-th command, garbage in place of a reply, a robot that goes silent.

mod commands;

use robotd_driver::MotionControl;
use robotd_driver_niryo::wire;
use robotd_driver_sim::{SimArm, SimCamera, SimGripper, SimRobot};
use serde_json::{Map, Value};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use tokio::io::AsyncWriteExt;
use tokio::net::{TcpListener, TcpStream};

/// Faults the fake robot injects. `drop_at`, `garbage_at` and `silent_at` count the commands
/// received since the faults were set (1 = the next one), only those named `only` when it is
/// set.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct FakeFaults {
    /// Close every new connection at once.
    pub refuse_connections: bool,
    /// Close the connection when this command arrives; the command still runs to its end
    /// (a pulled cable), and its reply goes to the next client.
    pub drop_at: Option<u64>,
    /// Answer this command with bytes that are not a reply.
    pub garbage_at: Option<u64>,
    /// Never answer this command (and nothing after it on that connection).
    pub silent_at: Option<u64>,
    /// Count only commands of this name (e.g. `MOVE_JOINTS`) for the faults above.
    pub only: Option<String>,
    /// Start uncalibrated (motions are ignored until `CALIBRATE`).
    pub needs_calibration: bool,
    /// Answer every move OK without moving, as the robot does with a target it rejects.
    pub ignore_moves: bool,
}

/// The fake robot's own state besides the simulated world.
#[derive(Debug)]
struct RobotFlags {
    calibrated: bool,
    handshake_seen: bool,
    speed_scale: f64,
    learning_mode: bool,
}

/// The simulated Ned2 behind the TCP protocol.
pub struct FakeNiryo {
    sim: SimRobot,
    arm: SimArm,
    gripper: SimGripper,
    camera: SimCamera,
    control: MotionControl,
    faults: Mutex<FakeFaults>,
    flags: Mutex<RobotFlags>,
    commands: AtomicU64,
    /// Commands counted for the faults since they were set.
    counted: AtomicU64,
    /// Names of the commands received, in order.
    log: Mutex<Vec<String>>,
    /// A reply the previous client left without reading.
    stale: Mutex<Option<Vec<u8>>>,
    /// How late every motion starts after its command arrived (0: at once).
    stopping_lag: Mutex<std::time::Duration>,
    /// The tool `GET_CURRENT_TOOL_ID` names ([`TOOLS`]).
    tool: Mutex<&'static str>,
}

/// The tool names a Ned2's `GET_CURRENT_TOOL_ID` answers (ned_ros's tool enumeration).
pub const TOOLS: [&str; 8] = [
    "NONE",
    "GRIPPER_1",
    "GRIPPER_2",
    "GRIPPER_3",
    "GRIPPER_4",
    "ELECTROMAGNET_1",
    "VACUUM_PUMP_1",
    "VACUUM_PUMP_2",
];

impl std::fmt::Debug for FakeNiryo {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("FakeNiryo")
            .field("commands", &self.commands.load(Ordering::SeqCst))
            .finish_non_exhaustive()
    }
}

impl FakeNiryo {
    /// A fake robot around the simulated `sim` (a Ned2), its camera rendering with the lens
    /// distortion on.
    pub fn new(sim: SimRobot, faults: FakeFaults) -> Arc<Self> {
        use robotd_driver_sim::faults::FaultInjector;
        let none = || FaultInjector::new("fake-niryo", Default::default());
        Arc::new(Self {
            arm: sim.arm(none()),
            gripper: sim.gripper(none()),
            camera: sim.camera(none()),
            sim,
            control: MotionControl::default(),
            flags: Mutex::new(RobotFlags {
                calibrated: !faults.needs_calibration,
                handshake_seen: false,
                speed_scale: 1.0,
                learning_mode: false,
            }),
            faults: Mutex::new(faults),
            commands: AtomicU64::new(0),
            counted: AtomicU64::new(0),
            log: Mutex::new(Vec::new()),
            stale: Mutex::new(None),
            stopping_lag: Mutex::new(std::time::Duration::ZERO),
            tool: Mutex::new("GRIPPER_1"),
        })
    }

    /// Says that `tool` (one of [`TOOLS`]) is mounted; the simulated gripper still grips.
    /// The default is the Ned2's standard gripper, `GRIPPER_1`.
    pub fn set_tool(&self, tool: &str) -> Result<(), String> {
        let known = TOOLS.iter().find(|t| **t == tool).ok_or_else(|| {
            format!(
                "no such Ned2 tool {tool:?}; the tools are {}",
                TOOLS.join(", ")
            )
        })?;
        *lock(&self.tool) = known;
        Ok(())
    }

    /// The tool `GET_CURRENT_TOOL_ID` names.
    pub(crate) fn tool(&self) -> &'static str {
        *lock(&self.tool)
    }

    /// Makes every motion start `lag` after its command arrived (0: at once), as a robot whose
    /// controller plans or buffers before it moves: a motion sent just before robotd's e-stop
    /// still runs to its end, so the arm keeps going up to `lag` plus a segment after it. The
    /// Ned2 has no stop command; robotd stops it by sending no further segment.
    pub fn set_stopping_lag(&self, lag: std::time::Duration) {
        *lock(&self.stopping_lag) = lag;
    }

    /// The simulated robot (ground truth for tests).
    pub fn sim(&self) -> &SimRobot {
        &self.sim
    }

    /// Changes the faults while it runs.
    pub fn set_faults(&self, change: impl FnOnce(&mut FakeFaults)) {
        let mut faults = lock(&self.faults);
        change(&mut faults);
        self.counted.store(0, Ordering::SeqCst);
    }

    /// How many commands it has received.
    pub fn commands_received(&self) -> u64 {
        self.commands.load(Ordering::SeqCst)
    }

    /// The names of the commands received so far, in order (tests: nothing sent twice).
    pub fn command_log(&self) -> Vec<String> {
        lock(&self.log).clone()
    }

    fn flags(&self) -> MutexGuard<'_, RobotFlags> {
        lock(&self.flags)
    }

    /// Serves clients on `listener`, one at a time, until the task is dropped.
    pub async fn serve(self: Arc<Self>, listener: TcpListener) {
        loop {
            let Ok((stream, peer)) = listener.accept().await else {
                continue;
            };
            if lock(&self.faults).refuse_connections {
                drop(stream);
                continue;
            }
            let _ = stream.set_nodelay(true);
            tracing::debug!(%peer, "fake-niryo: client connected");
            self.serve_client(stream).await;
            tracing::debug!(%peer, "fake-niryo: client left");
        }
    }

    async fn serve_client(&self, mut stream: TcpStream) {
        let stale = lock(&self.stale).take();
        if let Some(reply) = stale {
            if stream.write_all(&reply).await.is_err() {
                *lock(&self.stale) = Some(reply);
                return;
            }
        }
        loop {
            let request = match wire::read_json(&mut stream).await {
                Ok(request) => request,
                Err(wire::WireError::Io(_)) => return,
                Err(error) => {
                    // The robot's reader thread dies on text it cannot parse.
                    tracing::debug!(%error, "fake-niryo: unreadable request; closing");
                    return;
                }
            };
            self.commands.fetch_add(1, Ordering::SeqCst);
            let name = request
                .get("command")
                .and_then(Value::as_str)
                .unwrap_or("?")
                .to_uppercase();
            lock(&self.log).push(name.clone());
            let faults = lock(&self.faults).clone();
            let n = if faults.only.as_ref().is_none_or(|only| *only == name) {
                self.counted.fetch_add(1, Ordering::SeqCst) + 1
            } else {
                0
            };
            if faults.silent_at == Some(n) {
                // Hold the connection open and never answer again.
                let mut sink = [0u8; 256];
                use tokio::io::AsyncReadExt;
                while matches!(stream.read(&mut sink).await, Ok(k) if k > 0) {}
                return;
            }
            if faults.garbage_at == Some(n) {
                let _ = stream.write_all(b"\x05\x00garb\xffage").await;
                continue;
            }
            let dropped = faults.drop_at == Some(n);
            if dropped {
                let _ = stream.shutdown().await;
            }
            let run = self.answer(&request);
            tokio::pin!(run);
            let mut client_gone = dropped;
            let reply = if dropped {
                run.await
            } else {
                tokio::select! {
                    reply = &mut run => reply,
                    () = peer_closed(&stream) => {
                        client_gone = true;
                        run.await
                    }
                }
            };
            if client_gone || stream.write_all(&reply).await.is_err() {
                // The robot finished the command for nobody: the next client reads it first.
                *lock(&self.stale) = Some(reply);
                return;
            }
        }
    }

    /// Runs one request and frames its reply.
    async fn answer(&self, request: &Value) -> Vec<u8> {
        let (command, outcome) = match split_request(request) {
            Ok((command, params)) => {
                let outcome = self.run(&command, &params).await;
                (command, outcome)
            }
            Err(message) => (String::new(), Err(message)),
        };
        let mut reply = Map::new();
        let payload_size;
        let mut payload = Vec::new();
        match outcome {
            Ok((results, bytes)) => {
                payload_size = bytes.len();
                payload = bytes;
                reply.insert("status".into(), "OK".into());
                reply.insert("command".into(), command.into());
                reply.insert(
                    "list_ret_param".into(),
                    Value::Array(results.into_iter().map(stringify_bool).collect()),
                );
            }
            Err(message) => {
                payload_size = 0;
                let unknown = message == commands::UNKNOWN;
                let mut message = message;
                if !self.flags().handshake_seen {
                    message.push_str("\nNo handshake has been made between the client and the server. Please make sure to use the latest version of pyniryo.");
                }
                reply.insert(
                    "command".into(),
                    if unknown { String::new() } else { command }.into(),
                );
                reply.insert("status".into(), "KO".into());
                reply.insert("message".into(), message.into());
                reply.insert("list_ret_param".into(), Value::Array(Vec::new()));
            }
        }
        reply.insert("payload_size".into(), payload_size.into());
        let mut bytes = wire::frame(&Value::Object(reply)).unwrap_or_else(|e| {
            wire::frame(&serde_json::json!({"command": "", "status": "KO",
                "message": format!("reply too long: {e}"), "list_ret_param": [], "payload_size": 0}))
                .unwrap_or_default()
        });
        bytes.extend_from_slice(&payload);
        bytes
    }
}

/// The command (upper-cased) and parameters of a request with exactly the keys `command` and
/// `param_list`.
fn split_request(request: &Value) -> Result<(String, Vec<Value>), String> {
    let object = request.as_object().filter(|o| o.len() == 2);
    let command = object
        .and_then(|o| o.get("command"))
        .and_then(Value::as_str);
    let params = object
        .and_then(|o| o.get("param_list"))
        .and_then(Value::as_array);
    match (command, params) {
        (Some(command), Some(params)) => Ok((command.to_uppercase(), params.clone())),
        _ => Err("Incorrect command format".into()),
    }
}

/// Top-level booleans of a reply travel as `"True"` / `"False"`.
fn stringify_bool(value: Value) -> Value {
    match value {
        Value::Bool(b) => Value::from(if b { "True" } else { "False" }),
        other => other,
    }
}

/// Resolves when the peer has closed its side of `stream`.
async fn peer_closed(stream: &TcpStream) {
    let mut probe = [0u8; 1];
    loop {
        match stream.peek(&mut probe).await {
            Ok(0) | Err(_) => return,
            // The client sent the next request early: it is still there.
            Ok(_) => std::future::pending::<()>().await,
        }
    }
}

fn lock<T>(mutex: &Mutex<T>) -> MutexGuard<'_, T> {
    mutex.lock().unwrap_or_else(|p| p.into_inner())
}
