//! The one connection to the robot: commands strictly one at a time, each with its own
//! deadline, and a reconnector that brings the robot back by itself.
//!
//! The Ned2 serves one client, answers each command when it has finished, and has no stop
//! command. [`Link::call`] therefore holds the connection for exactly one request and its
//! reply (the arm, gripper and camera drivers take turns, first come first served), and
//! never sends a request twice: when the socket fails, the reply is garbage or the deadline
//! passes, the connection is dropped, the caller gets the reason, and the reconnector opens a
//! new one. A reply whose `command` is not the request's (the robot finishing a previous
//! connection's command and sending its reply to the next client) is dropped.
//!
//! After connecting, the reconnector greets the robot, reads its hardware status, calibrates
//! when the robot needs it (and `auto_calibrate` allows), updates the tool, reads the camera's
//! intrinsics, the collision flag and the joints, and only then lets commands through: so no
//! command is ever accepted while the arm's position is unknown.
//!
//! The automatic calibration is a motion like any other: it asks the motion policy first
//! ([`robotd_safety::Safety::admit_auto_calibration`], audited) and sends `CALIBRATE AUTO`
//! only with its permit. While the e-stop is engaged the policy refuses it; the link then
//! holds the connection, says why in its status (which `/health` shows as the arm's
//! connection), and asks again once the e-stop is released. A link without a policy (a
//! benchmark's) never calibrates by itself.

use crate::wire::{self, Param, Reply, WireError};
use robotd_runtime::backoff::Backoff;
use robotd_safety::{Calibration, Outcome, Permit, Safety};
use serde_json::Value;
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::Duration;
use tokio::net::TcpStream;
use tokio::sync::Notify;

/// The client version robotd announces in its handshake: the pyniryo release whose protocol
/// it speaks.
pub const CLIENT_VERSION: &str = "1.2.5";

/// How to reach the robot and how patient to be.
#[derive(Debug, Clone)]
pub struct LinkSettings {
    /// Host name or address of the robot.
    pub host: String,
    /// TCP port (40001 on a Ned2).
    pub port: u16,
    /// Deadline of a TCP connect and of the handshake.
    pub connect_timeout: Duration,
    /// Deadline of a command that does not move anything.
    pub query_timeout: Duration,
    /// Longest wait between two connection attempts (the wait doubles up to it).
    pub reconnect_max: Duration,
    /// Calibrate on connecting when the robot says it needs it.
    pub auto_calibrate: bool,
    /// Deadline of a calibration.
    pub calibrate_timeout: Duration,
}

/// Why a command did not get its answer.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum LinkError {
    /// There is no connection (the reason is the last failure).
    #[error("robot not connected: {0}")]
    NotConnected(String),
    /// The robot answered KO.
    #[error("the robot refused {command}: {message}")]
    Refused {
        /// The command.
        command: String,
        /// The robot's message.
        message: String,
    },
    /// The connection broke, the reply was garbage or did not come in time; the connection
    /// was dropped and will be reopened.
    #[error("connection to the robot lost during {command}: {reason}")]
    Lost {
        /// The command that was under way.
        command: String,
        /// What happened.
        reason: String,
    },
    /// The request could not be written (nothing was sent).
    #[error("{0}")]
    Unsendable(String),
}

/// What robotd knows about the robot from its last replies.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Known {
    /// Joint positions, radians; `None` while unknown (not connected, or lost mid-motion).
    pub joints: Option<Vec<f64>>,
    /// Whether `joints` were read after the last motion command ended (a camera image taken
    /// while this is false could show the arm elsewhere).
    pub settled: bool,
    /// Whether the robot is calibrated.
    pub calibrated: bool,
    /// Whether the robot has raised its collision flag.
    pub collision: bool,
    /// Camera matrix (fx, fy, cx, cy) and distortion (k1, k2, p1, p2, k3) read from the
    /// robot, once read.
    pub intrinsics: Option<([f64; 4], [f64; 5])>,
    /// The robot's hardware status at the last connect.
    pub hardware: Option<HardwareStatus>,
    /// The tool the robot reported mounted at the last connect (`GET_CURRENT_TOOL_ID`, after
    /// `UPDATE_TOOL`: `GRIPPER_1`, `NONE`, …), or why it could not be read.
    pub tool: Option<Result<String, String>>,
}

/// The parts of `GET_HARDWARE_STATUS` robotd reports.
#[derive(Debug, Clone, PartialEq)]
pub struct HardwareStatus {
    /// Raspberry Pi temperature, °C.
    pub rpi_temperature_c: f64,
    /// Hardware version (`ned2`).
    pub hardware_version: String,
    /// The robot's error message (empty when none).
    pub error_message: String,
    /// Whether the robot must be calibrated.
    pub calibration_needed: bool,
    /// Motors with a non-zero hardware error code: (name, code).
    pub motor_errors: Vec<(String, i64)>,
    /// Each motor's name and type (items 6 and 7: `Joint 1`, `Stepper`).
    pub motors: Vec<(String, String)>,
}

impl HardwareStatus {
    /// Reads the 11 items of a `GET_HARDWARE_STATUS` reply.
    pub fn parse(items: &[Value]) -> Result<Self, String> {
        if items.len() < 11 {
            return Err(format!(
                "GET_HARDWARE_STATUS: 11 items expected, got {}",
                items.len()
            ));
        }
        let flag = |i: usize| {
            wire::lenient_bool(&items[i])
                .ok_or_else(|| format!("GET_HARDWARE_STATUS item {i} is not a boolean"))
        };
        let names: Vec<String> = items[6]
            .as_array()
            .map(|a| {
                a.iter()
                    .map(|n| n.as_str().unwrap_or("?").to_owned())
                    .collect()
            })
            .unwrap_or_default();
        let motor_errors = items[10]
            .as_array()
            .map(|codes| {
                codes
                    .iter()
                    .enumerate()
                    .filter_map(|(i, c)| c.as_i64().filter(|c| *c != 0).map(|c| (i, c)))
                    .map(|(i, c)| {
                        (
                            names
                                .get(i)
                                .cloned()
                                .unwrap_or_else(|| format!("motor {i}")),
                            c,
                        )
                    })
                    .collect()
            })
            .unwrap_or_default();
        Ok(HardwareStatus {
            rpi_temperature_c: items[0].as_f64().unwrap_or(f64::NAN),
            hardware_version: items[1].as_str().unwrap_or("").to_owned(),
            error_message: items[3]
                .as_str()
                .unwrap_or("")
                .trim_matches('\'')
                .to_owned(),
            calibration_needed: flag(4)?,
            motors: names
                .iter()
                .enumerate()
                .map(|(i, name)| {
                    let kind = items[7].get(i).and_then(Value::as_str).unwrap_or("?");
                    (name.clone(), kind.to_owned())
                })
                .collect(),
            motor_errors,
        })
    }
}

/// How often a calibration refused for an engaged e-stop looks again whether it was released.
const ESTOP_RECHECK: Duration = Duration::from_millis(100);

/// The connection, shared by the arm, gripper and camera drivers.
pub struct Link {
    settings: LinkSettings,
    /// The motion policy that admits the automatic calibration (`None`: never calibrate).
    policy: Option<Safety>,
    connection: tokio::sync::Mutex<Option<TcpStream>>,
    /// `Ok(())` while connected, else why not.
    status: Mutex<Result<(), String>>,
    known: Mutex<Known>,
    /// Wakes the reconnector after a connection was dropped.
    dropped: Notify,
    /// Wakes whoever waits for the connection to come up.
    connected: Notify,
}

impl std::fmt::Debug for Link {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Link")
            .field(
                "robot",
                &format!("{}:{}", self.settings.host, self.settings.port),
            )
            .field("status", &self.status())
            .finish_non_exhaustive()
    }
}

impl Link {
    /// A link to the robot of `settings`, not connected yet: [`Link::run_reconnector`]
    /// connects it. `policy` admits the automatic calibration on connecting; without one a
    /// robot that needs calibration is not calibrated by the link.
    pub fn new(settings: LinkSettings, policy: Option<Safety>) -> Arc<Self> {
        Arc::new(Link {
            settings,
            policy,
            connection: tokio::sync::Mutex::new(None),
            status: Mutex::new(Err("not connected yet".into())),
            known: Mutex::new(Known::default()),
            dropped: Notify::new(),
            connected: Notify::new(),
        })
    }

    /// The settings.
    pub fn settings(&self) -> &LinkSettings {
        &self.settings
    }

    /// `Ok(())` while connected, else the reason.
    pub fn status(&self) -> Result<(), String> {
        lock(&self.status).clone()
    }

    /// What robotd knows about the robot.
    pub fn known(&self) -> Known {
        lock(&self.known).clone()
    }

    /// Changes what robotd knows.
    pub fn update_known(&self, change: impl FnOnce(&mut Known)) {
        change(&mut lock(&self.known));
    }

    /// Waits until connected or `timeout` passes; the connection status either way.
    pub async fn wait_connected(&self, timeout: Duration) -> Result<(), String> {
        let deadline = tokio::time::Instant::now() + timeout;
        loop {
            let notified = self.connected.notified();
            let status = self.status();
            if status.is_ok() {
                return status;
            }
            if tokio::time::timeout_at(deadline, notified).await.is_err() {
                return self.status();
            }
        }
    }

    /// Sends `command` and waits up to `timeout` for its reply: `Ok((results, payload))`.
    /// Never retried: a failure after the request was written drops the connection.
    pub async fn call(
        &self,
        command: &str,
        params: &[Param],
        timeout: Duration,
    ) -> Result<(Vec<Value>, Vec<u8>), LinkError> {
        self.session().await.call(command, params, timeout).await
    }

    /// The connection for several commands in a row, with nothing of the other drivers in
    /// between (a move and the read-back of the joints it reached).
    pub async fn session(&self) -> Session<'_> {
        Session {
            link: self,
            connection: self.connection.lock().await,
        }
    }

    fn set_down(&self, reason: &str) {
        *lock(&self.status) = Err(reason.to_owned());
        self.update_known(|k| k.joints = None);
        self.dropped.notify_one();
    }

    /// Keeps the robot connected until the process ends: connects, prepares the robot (see
    /// the module docs), and after a drop tries again, waiting 100 ms, then twice as long
    /// each time up to `reconnect_max`.
    pub async fn run_reconnector(self: Arc<Self>) {
        let mut backoff = Backoff::up_to(self.settings.reconnect_max);
        loop {
            if self.status().is_ok() {
                self.dropped.notified().await;
                if self.status().is_ok() {
                    continue;
                }
                backoff.reset();
            }
            match self.connect().await {
                Ok(()) => {
                    tracing::info!(
                        robot = %format!("{}:{}", self.settings.host, self.settings.port),
                        "connected to the Niryo robot"
                    );
                    self.connected.notify_waiters();
                }
                Err(reason) => {
                    tracing::debug!(%reason, "connecting to the robot");
                    *lock(&self.status) = Err(reason);
                    self.connected.notify_waiters();
                    tokio::time::sleep(backoff.next_delay()).await;
                }
            }
        }
    }

    /// One connection attempt, holding the command lock so that nothing else is sent before
    /// the robot is known.
    async fn connect(&self) -> Result<(), String> {
        let s = &self.settings;
        let mut connection = self.connection.lock().await;
        let (mut stream, hardware) = greet(s).await.map_err(|e| e.to_string())?;
        let mut calibrated = !hardware.calibration_needed;
        if !calibrated && s.auto_calibrate {
            self.calibrate_on_connect(&mut stream).await?;
            calibrated = true;
        }
        ask(&mut stream, "UPDATE_TOOL", vec![], s.query_timeout).await?;
        let tool = ask(&mut stream, "GET_CURRENT_TOOL_ID", vec![], s.query_timeout)
            .await
            .and_then(|items| match items.first().and_then(Value::as_str) {
                Some(name) if items.len() == 1 && !name.trim().is_empty() => {
                    Ok(name.trim().to_owned())
                }
                _ => Err(format!(
                    "GET_CURRENT_TOOL_ID answered {items:?}, not a tool name"
                )),
            });
        if let Err(reason) = &tool {
            tracing::warn!(%reason, "the robot does not say which tool is mounted");
        }
        let intrinsics = match ask(
            &mut stream,
            "GET_CAMERA_INTRINSICS",
            vec![],
            s.query_timeout,
        )
        .await
        {
            Ok(items) => match parse_intrinsics(&items) {
                Ok(k) => Some(k),
                Err(e) => {
                    tracing::warn!(error = %e, "the robot's camera intrinsics are unreadable; using the Ned2's nominal ones");
                    None
                }
            },
            Err(e) => {
                tracing::warn!(error = %e, "no camera intrinsics from the robot; using the Ned2's nominal ones");
                None
            }
        };
        let collision = ask(
            &mut stream,
            "GET_COLLISION_DETECTED",
            vec![],
            s.query_timeout,
        )
        .await?
        .first()
        .and_then(wire::lenient_bool)
        .ok_or("GET_COLLISION_DETECTED did not answer a boolean")?;
        let joints = wire::numbers(
            &ask(&mut stream, "GET_JOINTS", vec![], s.query_timeout).await?,
            6,
            "GET_JOINTS",
        )?;
        if !hardware.motor_errors.is_empty() {
            tracing::warn!(errors = ?hardware.motor_errors, "the robot reports motor hardware errors");
        }
        self.update_known(|k| {
            *k = Known {
                joints: Some(joints),
                settled: true,
                calibrated,
                collision,
                intrinsics: intrinsics.or(k.intrinsics),
                hardware: Some(hardware),
                tool: Some(tool),
            }
        });
        *connection = Some(stream);
        *lock(&self.status) = Ok(());
        Ok(())
    }
}

impl Link {
    /// The automatic calibration of a robot that needs one: admitted by the policy first;
    /// while the e-stop refuses it, the status says so and the link waits for the release.
    async fn calibrate_on_connect(&self, stream: &mut TcpStream) -> Result<(), String> {
        let Some(policy) = &self.policy else {
            return Err(
                "the robot needs calibration, and this link has no motion policy to \
                        admit an automatic one; calibrate it (the calibrate tool)"
                    .into(),
            );
        };
        let (admission, permit) = loop {
            match policy.admit_auto_calibration("niryo").await {
                Ok(admitted) => break admitted,
                Err(violation) if violation.limit == "estop" => {
                    let reason = format!(
                        "connected, but the robot needs calibration and the motion policy \
                         refused the automatic one: {}; it waits for the e-stop's release",
                        violation.reason
                    );
                    tracing::warn!(%reason, "automatic calibration held");
                    *lock(&self.status) = Err(reason);
                    self.connected.notify_waiters();
                    while policy.estop().is_some() {
                        tokio::time::sleep(ESTOP_RECHECK).await;
                    }
                }
                Err(violation) => {
                    return Err(format!(
                        "the robot needs calibration, and the motion policy refused the \
                         automatic one: {}",
                        violation.reason
                    ))
                }
            }
        };
        tracing::info!(
            motion = admission.motion_id(),
            "the robot needs calibration: calibrating (robot.niryo.auto_calibrate, admitted by the motion policy)"
        );
        let done = calibrate(stream, permit, self.settings.calibrate_timeout).await;
        match &done {
            Ok(()) => policy.finish(&admission, Outcome::Done),
            Err(reason) => policy.finish(&admission, Outcome::Failed { reason }),
        }
        done
    }
}

/// `CALIBRATE AUTO` on `stream`, with the policy's permit.
async fn calibrate(
    stream: &mut TcpStream,
    _permit: Permit<Calibration>,
    timeout: Duration,
) -> Result<(), String> {
    ask(
        stream,
        "CALIBRATE",
        vec![Param::Str("AUTO".into())],
        timeout,
    )
    .await
    .map(|_| ())
}

/// Why [`greet`] failed, by step (each wants another fix).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum GreetError {
    /// No TCP connection (robot off, wrong address, network).
    #[error("{0}")]
    Connect(String),
    /// Connected, but no answer to the handshake (usually: another client is being served).
    #[error("{0}")]
    Handshake(String),
    /// The hardware status was refused or unreadable.
    #[error("{0}")]
    Status(String),
}

/// Connects to the robot of `settings`, greets it and reads its hardware status: the first
/// steps of every connection, and all that `robotd doctor` does (it moves nothing).
pub async fn greet(s: &LinkSettings) -> Result<(TcpStream, HardwareStatus), GreetError> {
    let robot = format!("{}:{}", s.host, s.port);
    let mut stream = tokio::time::timeout(
        s.connect_timeout,
        TcpStream::connect((s.host.as_str(), s.port)),
    )
    .await
    .map_err(|_| {
        GreetError::Connect(format!(
            "no answer from {robot} within {} ms",
            s.connect_timeout.as_millis()
        ))
    })?
    .map_err(|e| GreetError::Connect(format!("cannot connect to {robot}: {e}")))?;
    let _ = stream.set_nodelay(true);
    ask(
        &mut stream,
        "HANDSHAKE",
        vec![Param::Str(CLIENT_VERSION.into())],
        s.connect_timeout,
    )
    .await
    .map_err(|e| {
        GreetError::Handshake(format!(
            "{robot} accepted the connection but did not answer the handshake ({e}); another \
             client (pyniryo, Niryo Studio, a running robotd) may be connected: the robot serves \
             one at a time"
        ))
    })?;
    let hardware = ask(&mut stream, "GET_HARDWARE_STATUS", vec![], s.query_timeout)
        .await
        .and_then(|items| HardwareStatus::parse(&items))
        .map_err(GreetError::Status)?;
    Ok((stream, hardware))
}

/// One command during the connect sequence: its results, or the reason as text.
async fn ask(
    stream: &mut TcpStream,
    command: &'static str,
    params: Vec<Param>,
    timeout: Duration,
) -> Result<Vec<Value>, String> {
    let request = wire::encode_request(command, &params).map_err(|e| e.to_string())?;
    let reply = exchange(stream, command, &request, timeout).await?;
    reply
        .outcome
        .map_err(|message| format!("the robot refused {command}: {message}"))
}

/// The connection held for a run of commands; see [`Link::session`].
pub struct Session<'a> {
    link: &'a Link,
    connection: tokio::sync::MutexGuard<'a, Option<TcpStream>>,
}

impl Session<'_> {
    /// As [`Link::call`], within this session.
    pub async fn call(
        &mut self,
        command: &str,
        params: &[Param],
        timeout: Duration,
    ) -> Result<(Vec<Value>, Vec<u8>), LinkError> {
        let request = wire::encode_request(command, params)
            .map_err(|e| LinkError::Unsendable(e.to_string()))?;
        let Some(stream) = self.connection.as_mut() else {
            return Err(LinkError::NotConnected(
                self.link
                    .status()
                    .err()
                    .unwrap_or_else(|| "not connected".into()),
            ));
        };
        match exchange(stream, command, &request, timeout).await {
            Ok(reply) => match reply.outcome {
                Ok(results) => Ok((results, reply.payload)),
                Err(message) => Err(LinkError::Refused {
                    command: command.to_owned(),
                    message,
                }),
            },
            Err(reason) => {
                *self.connection = None;
                self.link
                    .set_down(&format!("connection lost during {command}: {reason}"));
                tracing::warn!(command, %reason, "connection to the robot dropped");
                Err(LinkError::Lost {
                    command: command.to_owned(),
                    reason,
                })
            }
        }
    }
}

/// Writes `request` and reads replies until the one for `command` arrives, all within
/// `timeout`. Replies to other commands (stale ones of an earlier connection) are dropped.
async fn exchange(
    stream: &mut TcpStream,
    command: &str,
    request: &[u8],
    timeout: Duration,
) -> Result<Reply, String> {
    let exchange = async {
        wire::write_frame(stream, request).await?;
        for _ in 0..8 {
            let reply = wire::read_reply(stream).await?;
            // An unknown command is answered with an empty command name.
            if reply.command.eq_ignore_ascii_case(command)
                || (reply.command.is_empty() && reply.outcome.is_err())
            {
                return Ok(reply);
            }
            tracing::warn!(sent = command, got = %reply.command, "dropped a reply to another command (stale, from before a reconnect)");
        }
        Err(WireError::Malformed(format!(
            "8 replies in a row were not for {command}"
        )))
    };
    match tokio::time::timeout(timeout, exchange).await {
        Ok(Ok(reply)) => Ok(reply),
        Ok(Err(WireError::Io(e))) if e.kind() == std::io::ErrorKind::UnexpectedEof => {
            Err("the robot closed the connection".into())
        }
        Ok(Err(e)) => Err(e.to_string()),
        Err(_) => Err(format!("no reply within {:.1} s", timeout.as_secs_f64())),
    }
}

/// Reads `GET_CAMERA_INTRINSICS`: the flat 9 numbers of the camera matrix (or 3 rows of 3)
/// and the 5 distortion coefficients (or one row of 5).
pub fn parse_intrinsics(items: &[Value]) -> Result<([f64; 4], [f64; 5]), String> {
    let flat = |v: &Value| -> Vec<Value> {
        match v {
            Value::Array(rows) if rows.iter().all(Value::is_array) => rows
                .iter()
                .flat_map(|r| r.as_array().cloned().unwrap_or_default())
                .collect(),
            Value::Array(items) => items.clone(),
            _ => Vec::new(),
        }
    };
    let [matrix, distortion] = items else {
        return Err(format!(
            "GET_CAMERA_INTRINSICS: 2 lists expected, got {} items",
            items.len()
        ));
    };
    let m = wire::numbers(&flat(matrix), 9, "camera matrix")?;
    let d = wire::numbers(&flat(distortion), 5, "distortion")?;
    if m[0] <= 0.0 || m[4] <= 0.0 {
        return Err(format!(
            "camera matrix with focal lengths {} and {}",
            m[0], m[4]
        ));
    }
    Ok(([m[0], m[4], m[2], m[5]], [d[0], d[1], d[2], d[3], d[4]]))
}

fn lock<T>(mutex: &Mutex<T>) -> MutexGuard<'_, T> {
    mutex.lock().unwrap_or_else(|p| p.into_inner())
}
