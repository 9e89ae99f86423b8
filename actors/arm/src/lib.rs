//! The arm actor: plans and checks every motion, then has its driver execute it.
//!
//! The actor owns the arm's planning: inverse kinematics for pose targets, joint-limit and
//! reachability checks **before** anything moves (an unreachable target is an error naming the
//! target and the reason), straight-line tool paths as dense joint waypoints, and the
//! workspaces' observation poses. The driver only executes.
//!
//! Every motion passes the safety policy ([`robotd_safety::Safety`]) twice: the serving loop
//! admits the command (e-stop, rate limit, approval, audit) before handing it to the actor,
//! and the actor has the policy check the planned path (geofence at every sampled tool
//! position, joint margins, speed caps) right before the driver runs it: that check makes the
//! [`robotd_safety::Permit`] without which the driver's `execute` cannot be called. A
//! calibration is checked the same way (its motion to the rest pose), and clearing the
//! collision flag needs an admission and a permit too. The actor only accepts [`Admitted`]
//! commands, which only the policy can make.
//!
//! [`serve_arm`] puts it on the bus (`arm/command`). Motion commands go through the
//! supervised actor one at a time, in order. `Stop` and the queries (`GetPose`, `GetJoints`,
//! `GetCollisionState`) are answered by the serving loop itself at once, even while a motion
//! runs: a stop must never wait behind the motion it is meant to stop, and it cancels every
//! motion received before it, queued or running. The emergency stop arrives on
//! `safety/estop` and halts the motion within one control tick; the policy's release service
//! (`safety/release`, [`robotd_safety::estop`]) runs beside it.
//! [`publish_arm_state`] publishes joint states and the tool pose on `arm/state`.

use kameo::prelude::*;
use nalgebra::{Isometry3, Translation3};
pub use robotd_driver::ObservationPose;
use robotd_driver::{ArmDriver, DriverError, Motion, MotionControl};
use robotd_kinematics::{isometry_to_pose, pose_to_isometry, Kinematics};
use robotd_protocol::arm::{ArmCommand, ArmError, ArmReply, ArmState, PathKind};
use robotd_protocol::geometry::{JointState, Pose};
use robotd_protocol::validate::Validate;
use robotd_runtime::bus::{BusError, Fault, Publisher, Server};
use robotd_runtime::host::fault_from;
use robotd_runtime::supervision::Supervised;
use robotd_safety::{Admission, Outcome, Safety};
use std::convert::Infallible;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;
use std::time::Duration;
use tracing::Instrument;

/// Spacing of the waypoints of a straight tool path, metres.
const LINEAR_STEP_M: f64 = 0.005;

/// How far the tool retreats straight up after a cleared collision, metres: the first
/// reachable of these.
const COLLISION_RETREATS_M: [f64; 3] = [0.05, 0.03, 0.015];

/// What the arm actor and its serving loop share.
#[derive(Clone)]
pub struct ArmContext {
    /// The driver (sim or real).
    pub driver: Arc<dyn ArmDriver>,
    /// The arm's kinematics.
    pub kinematics: Kinematics,
    /// Stop and e-stop signals.
    pub control: MotionControl,
    /// Configured observation poses.
    pub observation_poses: Vec<ObservationPose>,
    /// The motion policy.
    pub safety: Safety,
    /// What the actor, its serving loop and its state publisher share (survives a restart of
    /// the actor).
    pub shared: Arc<ArmShared>,
}

/// State shared by the arm actor and its state publisher.
#[derive(Debug)]
pub struct ArmShared {
    /// Set when a collision flag is cleared: the next motion first retreats straight up, away
    /// from the contact.
    retreat_pending: AtomicBool,
    /// When the last motion ended, ns since the Unix epoch; 0 while one runs.
    still_since_ns: AtomicU64,
    /// Wakes the state publisher when a motion starts or ends.
    changed: tokio::sync::Notify,
}

impl Default for ArmShared {
    fn default() -> Self {
        Self {
            retreat_pending: AtomicBool::new(false),
            still_since_ns: AtomicU64::new(robotd_protocol::envelope::unix_now_ns()),
            changed: tokio::sync::Notify::new(),
        }
    }
}

impl ArmShared {
    fn motion_started(&self) {
        self.still_since_ns.store(0, Ordering::SeqCst);
        self.changed.notify_one();
    }

    fn motion_ended(&self) {
        self.still_since_ns
            .store(robotd_protocol::envelope::unix_now_ns(), Ordering::SeqCst);
        self.changed.notify_one();
    }
}

impl std::fmt::Debug for ArmContext {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ArmContext")
            .field("model", &self.kinematics.model())
            .finish_non_exhaustive()
    }
}

impl ArmContext {
    /// The current tool pose.
    pub fn tool_pose(&self) -> Result<Pose, ArmError> {
        let q = self.driver.joints().map_err(arm_error)?;
        self.kinematics
            .tool_pose(&q)
            .map(|iso| isometry_to_pose(&iso))
            .map_err(|e| ArmError::Driver {
                message: e.to_string(),
            })
    }

    /// When the arm came to rest (0 while a motion runs): the driver's word when it knows
    /// (a replayed recording), else the end of the last motion this actor ran.
    pub fn still_since_ns(&self) -> u64 {
        self.driver
            .still_since_unix_ns()
            .unwrap_or_else(|| self.shared.still_since_ns.load(Ordering::SeqCst))
    }

    /// The state published on `arm/state`.
    pub fn state(&self) -> Result<ArmState, ArmError> {
        let q = self.driver.joints().map_err(arm_error)?;
        let tool_pose = self
            .kinematics
            .tool_pose(&q)
            .map(|iso| isometry_to_pose(&iso))
            .map_err(|e| ArmError::Driver {
                message: e.to_string(),
            })?;
        let flags = self.driver.flags();
        let still_since_unix_ns = self.still_since_ns();
        Ok(ArmState {
            joints: JointState::from_positions(q, robotd_protocol::envelope::unix_now_ns()),
            tool_pose,
            moving: flags.moving || still_since_unix_ns == 0,
            still_since_unix_ns,
            collision_detected: flags.collision_detected,
            calibrated: flags.calibrated,
            estop_engaged: self.control.estop_engaged(),
        })
    }

    /// Answers the commands that need no motion (and `Stop`); `None` for motion commands.
    pub fn answer_at_once(&self, command: &ArmCommand) -> Option<ArmReply> {
        let reply = match command {
            ArmCommand::Stop => {
                self.control.request_stop();
                self.tool_pose().map(|pose| ArmReply::Ok { pose })
            }
            ArmCommand::GetPose => self.tool_pose().map(|pose| ArmReply::Ok { pose }),
            ArmCommand::GetJoints => {
                self.driver
                    .joints()
                    .map_err(arm_error)
                    .map(|q| ArmReply::Joints {
                        joints: JointState::from_positions(
                            q,
                            robotd_protocol::envelope::unix_now_ns(),
                        ),
                    })
            }
            ArmCommand::GetCollisionState => Ok(ArmReply::CollisionState {
                collision_detected: self.driver.flags().collision_detected,
            }),
            _ => return None,
        };
        Some(reply.unwrap_or_else(ArmReply::from))
    }
}

/// The supervised arm actor (motion commands).
#[derive(Actor)]
pub struct ArmActor {
    context: ArmContext,
}

impl ArmActor {
    /// An actor driving `context.driver`.
    pub fn new(context: ArmContext) -> Self {
        Self { context }
    }

    async fn run(
        &mut self,
        command: ArmCommand,
        admission: &Admission,
    ) -> Result<ArmReply, ArmError> {
        command.validate()?;
        if let Some(reply) = self.context.answer_at_once(&command) {
            return reply.into_result();
        }
        let ctx = &self.context;
        if command.moves_arm() && ctx.control.estop_engaged() {
            return Err(ArmError::EStopped {
                reason: ctx.control.estop_reason(),
            });
        }
        if command.moves_arm() && ctx.shared.retreat_pending.load(Ordering::SeqCst) {
            self.retreat(admission).await?;
        }
        let ctx = &self.context;
        match command {
            ArmCommand::MoveToPose { target, path } => self.move_to(target, path, admission).await,
            ArmCommand::ShiftPose { delta } => {
                let target = ctx.tool_pose()?.shifted(&delta);
                self.move_to(target, PathKind::Linear, admission).await
            }
            ArmCommand::MoveJoints { positions_rad } => {
                ctx.kinematics
                    .check_joints(&positions_rad)
                    .map_err(|e| joint_error(&e, &positions_rad, &ctx.kinematics))?;
                self.execute(Motion::Joints(positions_rad), admission).await
            }
            ArmCommand::GoToObservationPose { workspace_id } => {
                let Some(observation) = ctx
                    .observation_poses
                    .iter()
                    .find(|o| o.workspace_id == workspace_id)
                else {
                    return Err(ArmError::UnknownWorkspace {
                        workspace_id,
                        known: ctx
                            .observation_poses
                            .iter()
                            .map(|o| o.workspace_id.clone())
                            .collect(),
                    });
                };
                let pose = observation.pose;
                self.move_to(pose, PathKind::Joint, admission).await
            }
            ArmCommand::Calibrate => {
                let start = ctx.driver.joints().map_err(arm_error)?;
                let permit = ctx
                    .safety
                    .permit_calibration(admission, &start)
                    .map_err(|v| refusal(&ctx.safety, v))?;
                ctx.control
                    .begin_motion(admission.stop_generation())
                    .map_err(|s| arm_error(s.into()))?;
                ctx.shared.motion_started();
                let calibrated = ctx.driver.calibrate(permit).await;
                ctx.shared.motion_ended();
                calibrated.map_err(arm_error)?;
                Ok(ArmReply::Ok {
                    pose: ctx.tool_pose()?,
                })
            }
            ArmCommand::ClearCollision
            | ArmCommand::Stop
            | ArmCommand::GetPose
            | ArmCommand::GetJoints
            | ArmCommand::GetCollisionState => unreachable_query(),
        }
    }

    /// After a cleared collision: moves the tool straight up (the first reachable of
    /// [`COLLISION_RETREATS_M`]) so that the next motion does not start in contact. A collision
    /// on the way up keeps the retreat pending; when no retreat is reachable the motion goes
    /// ahead without one.
    async fn retreat(&mut self, admission: &Admission) -> Result<(), ArmError> {
        let from = self.context.tool_pose()?;
        for rise in COLLISION_RETREATS_M {
            let target = Pose {
                z_m: from.z_m + rise,
                ..from
            };
            let Ok(motion) = plan(&self.context, target, PathKind::Linear) else {
                continue;
            };
            self.execute(motion, admission).await?;
            self.context
                .shared
                .retreat_pending
                .store(false, Ordering::SeqCst);
            tracing::info!(
                rise_m = rise,
                "retreated straight up after the cleared collision"
            );
            return Ok(());
        }
        self.context
            .shared
            .retreat_pending
            .store(false, Ordering::SeqCst);
        tracing::warn!(
            z_m = from.z_m,
            "no straight retreat up is reachable after the cleared collision; moving without one"
        );
        Ok(())
    }

    async fn move_to(
        &mut self,
        target: Pose,
        path: PathKind,
        admission: &Admission,
    ) -> Result<ArmReply, ArmError> {
        let motion = plan(&self.context, target, path)?;
        self.execute(motion, admission).await
    }

    async fn execute(
        &mut self,
        motion: Motion,
        admission: &Admission,
    ) -> Result<ArmReply, ArmError> {
        let ctx = &self.context;
        if ctx.driver.flags().collision_detected {
            return Err(ArmError::Collision);
        }
        let start = ctx.driver.joints().map_err(arm_error)?;
        let permit = ctx
            .safety
            .permit_motion(admission, &start, motion)
            .map_err(|v| refusal(&ctx.safety, v))?;
        ctx.control
            .begin_motion(admission.stop_generation())
            .map_err(|s| arm_error(s.into()))?;
        ctx.shared.motion_started();
        let executed = ctx.driver.execute(permit, &ctx.control).await;
        ctx.shared.motion_ended();
        executed.map_err(|e| match e {
            DriverError::Stopped { reason } if ctx.control.estop_engaged() => {
                ArmError::EStopped { reason }
            }
            other => arm_error(other),
        })?;
        Ok(ArmReply::Ok {
            pose: ctx.tool_pose()?,
        })
    }
}

fn unreachable_query() -> Result<ArmReply, ArmError> {
    Err(ArmError::InvalidCommand {
        reason: "internal: a query reached the motion path".into(),
    })
}

/// An arm command the safety policy admitted: the only message that makes the actor move.
#[derive(Debug, Clone)]
pub struct Admitted {
    /// The command.
    pub command: ArmCommand,
    /// The policy's admission (only [`Safety::admit`] makes one).
    pub admission: Admission,
}

impl Message<Admitted> for ArmActor {
    type Reply = Result<ArmReply, Infallible>;

    async fn handle(&mut self, work: Admitted, _: &mut Context<Self, Self::Reply>) -> Self::Reply {
        Ok(self
            .run(work.command, &work.admission)
            .await
            .unwrap_or_else(ArmReply::from))
    }
}

/// Clears the collision flag (not a motion: allowed while e-stopped, never rate limited, but
/// admitted and audited: [`Safety::admit_clear_collision`]).
#[derive(Debug, Clone)]
pub struct ClearCollisionFlag {
    /// The policy's admission.
    pub admission: Admission,
}

impl Message<ClearCollisionFlag> for ArmActor {
    type Reply = Result<ArmReply, Infallible>;

    async fn handle(
        &mut self,
        work: ClearCollisionFlag,
        _: &mut Context<Self, Self::Reply>,
    ) -> Self::Reply {
        let ctx = &self.context;
        let permit = match ctx.safety.permit_clear_collision(&work.admission) {
            Ok(permit) => permit,
            Err(violation) => return Ok(refusal(&ctx.safety, violation).into()),
        };
        if ctx.driver.flags().collision_detected {
            ctx.shared.retreat_pending.store(true, Ordering::SeqCst);
        }
        let cleared = ctx
            .driver
            .clear_collision(permit)
            .await
            .map_err(arm_error)
            .and_then(|()| ctx.tool_pose())
            .map(|pose| ArmReply::Ok { pose });
        Ok(cleared.unwrap_or_else(ArmReply::from))
    }
}

/// Plans a motion to `target`: reachability and joint limits are checked before anything
/// moves; a straight path is checked waypoint by waypoint.
pub fn plan(context: &ArmContext, target: Pose, path: PathKind) -> Result<Motion, ArmError> {
    target.validate()?;
    let kin = &context.kinematics;
    let q0 = context.driver.joints().map_err(arm_error)?;
    let goal = pose_to_isometry(&target);
    let unreachable = |reason: String| ArmError::Unreachable { target, reason };
    match path {
        PathKind::Joint => {
            let q = kin
                .inverse(&goal, Some(&q0))
                .map_err(|e| unreachable(e.to_string()))?;
            Ok(Motion::Joints(q))
        }
        PathKind::Linear => {
            let start = kin.tool_pose(&q0).map_err(|e| unreachable(e.to_string()))?;
            let distance = (goal.translation.vector - start.translation.vector).norm();
            let turn = start.rotation.angle_to(&goal.rotation);
            let steps = ((distance / LINEAR_STEP_M).ceil() as usize)
                .max((turn / 0.05).ceil() as usize)
                .clamp(1, 2000);
            let mut waypoints = Vec::with_capacity(steps);
            let mut seed = q0;
            for i in 1..=steps {
                let t = i as f64 / steps as f64;
                let position = start.translation.vector.lerp(&goal.translation.vector, t);
                let rotation = start
                    .rotation
                    .try_slerp(&goal.rotation, t, 1e-9)
                    .unwrap_or(goal.rotation);
                let waypoint = Isometry3::from_parts(Translation3::from(position), rotation);
                let q = kin.inverse(&waypoint, Some(&seed)).map_err(|e| {
                    unreachable(format!(
                        "the straight path leaves the reachable space at ({:.3}, {:.3}, {:.3}): {e}",
                        position.x, position.y, position.z
                    ))
                })?;
                // A straight path must not flip the arm between waypoints.
                let jump = q
                    .iter()
                    .zip(&seed)
                    .map(|(a, b)| (a - b).abs())
                    .fold(0.0, f64::max);
                if jump > 0.5 {
                    return Err(unreachable(format!(
                        "the straight path needs a joint to jump {jump:.2} rad near ({:.3}, {:.3}, {:.3}); use a joint move",
                        position.x, position.y, position.z
                    )));
                }
                seed = q.clone();
                waypoints.push(q);
            }
            Ok(Motion::JointPath(waypoints))
        }
    }
}

fn joint_error(
    error: &robotd_kinematics::KinematicsError,
    q: &[f64],
    kin: &Kinematics,
) -> ArmError {
    for (i, (value, limit)) in q.iter().zip(kin.joint_limits()).enumerate() {
        if !(limit.min_rad..=limit.max_rad).contains(value) {
            return ArmError::JointLimit {
                joint: i as u32,
                value_rad: *value,
                min_rad: limit.min_rad,
                max_rad: limit.max_rad,
            };
        }
    }
    ArmError::InvalidCommand {
        reason: error.to_string(),
    }
}

/// The arm error of a driver error.
pub fn arm_error(error: DriverError) -> ArmError {
    match error {
        DriverError::Collision { .. } | DriverError::CollisionPending => ArmError::Collision,
        DriverError::Stopped { .. } => ArmError::Stopped,
        DriverError::NotCalibrated => ArmError::NotCalibrated,
        DriverError::OutOfRange(reason) => ArmError::InvalidCommand { reason },
        DriverError::Hardware(message) => ArmError::Driver { message },
    }
}

/// Serves `arm/command` until the bus fails: queries and `Stop` at once, motions through the
/// supervised `actor`, one at a time, each reply sent when its motion has ended.
pub async fn serve_arm(
    mut server: Server<ArmCommand, ArmReply>,
    actor: Supervised<ArmActor>,
    context: ArmContext,
) -> Result<(), BusError> {
    let (done_tx, mut done_rx) = tokio::sync::mpsc::unbounded_channel();
    loop {
        tokio::select! {
            incoming = server.next() => {
                let incoming = incoming?;
                let origin = incoming.origin.clone();
                let (envelope, pending) = incoming.split();
                let span = tracing::info_span!("arm.command", kind = command_kind(&envelope.body));
                robotd_runtime::telemetry::set_parent_from(&span, &envelope.trace);
                if let Some(reply) = context.answer_at_once(&envelope.body) {
                    let _in_span = span.enter();
                    if let Err(error) = server.respond(pending, Ok(reply)) {
                        tracing::warn!(%error, "could not send an arm reply");
                    }
                    continue;
                }
                let actor = actor.clone();
                let done = done_tx.clone();
                let safety = context.safety.clone();
                tokio::spawn(async move {
                    let reply = admit_and_run(&actor, &safety, envelope.body, &origin).await;
                    let _ = done.send((pending, reply, tracing::Span::current()));
                }.instrument(span));
            }
            Some((pending, reply, span)) = done_rx.recv() => {
                let _in_span = span.enter();
                if let Err(error) = server.respond(pending, reply) {
                    tracing::warn!(%error, "could not send an arm reply");
                }
            }
        }
    }
}

/// Passes `command` through the safety policy and, if admitted, has the actor run it; the
/// outcome goes to the audit log.
pub async fn admit_and_run(
    actor: &Supervised<ArmActor>,
    safety: &Safety,
    command: ArmCommand,
    origin: &robotd_protocol::safety::Origin,
) -> Result<ArmReply, Fault> {
    if let Err(error) = command.validate() {
        return Ok(ArmError::from(error).into());
    }
    if let ArmCommand::GoToObservationPose { workspace_id } = &command {
        // An unknown name is refused here, before admission: it never reaches the audit log,
        // and the reply carries it cut to a sane length.
        let known = safety.workspace_ids();
        if !known.contains(workspace_id) {
            return Ok(ArmError::UnknownWorkspace {
                workspace_id: robotd_safety::audit::cut(workspace_id).into_owned(),
                known: known.to_vec(),
            }
            .into());
        }
    }
    let clear = matches!(command, ArmCommand::ClearCollision);
    if !clear && !command.moves_arm() {
        return Ok(ArmError::InvalidCommand {
            reason: "queries and stop are answered at once by the serving loop, not admitted"
                .into(),
        }
        .into());
    }
    let arguments = serde_json::to_value(&command).unwrap_or_default();
    let admitted = if clear {
        safety.admit_clear_collision(origin, arguments).await
    } else {
        safety
            .admit(origin, "arm", command_kind(&command), arguments)
            .await
    };
    let admission = match admitted {
        Ok(admission) => admission,
        Err(violation) => return Ok(refusal(safety, violation).into()),
    };
    let reply = if clear {
        actor
            .ask(ClearCollisionFlag {
                admission: admission.clone(),
            })
            .await
    } else {
        actor
            .ask(Admitted {
                command,
                admission: admission.clone(),
            })
            .await
    }
    .map_err(fault_from);
    let text = match &reply {
        Ok(ArmReply::Error { error }) => Some(error.to_string()),
        Ok(_) => None,
        Err(fault) => Some(fault.to_string()),
    };
    let outcome = match (&reply, &text) {
        (
            Ok(ArmReply::Error {
                error: ArmError::Refused { limit, reason },
            }),
            _,
        ) => Outcome::Refused { limit, reason },
        (_, Some(reason)) => Outcome::Failed { reason },
        (_, None) => Outcome::Done,
    };
    safety.finish(&admission, outcome);
    reply
}

/// The arm error of a policy refusal: the e-stop keeps its own error kind.
fn refusal(safety: &Safety, violation: robotd_safety::Violation) -> ArmError {
    match safety.estop() {
        Some(reason) if violation.limit == "estop" => ArmError::EStopped { reason },
        _ => ArmError::Refused {
            limit: violation.limit.to_owned(),
            reason: violation.reason,
        },
    }
}

fn command_kind(command: &ArmCommand) -> &'static str {
    match command {
        ArmCommand::MoveToPose { .. } => "move_to_pose",
        ArmCommand::MoveJoints { .. } => "move_joints",
        ArmCommand::ShiftPose { .. } => "shift_pose",
        ArmCommand::Stop => "stop",
        ArmCommand::GoToObservationPose { .. } => "go_to_observation_pose",
        ArmCommand::Calibrate => "calibrate",
        ArmCommand::ClearCollision => "clear_collision",
        ArmCommand::GetPose => "get_pose",
        ArmCommand::GetJoints => "get_joints",
        ArmCommand::GetCollisionState => "get_collision_state",
    }
}

/// Publishes the arm's state on `arm/state`: at once when a motion starts or ends, every
/// `period` while it moves, about once a second while it rests, and at the next tick after
/// the e-stop was engaged or released. Runs until the publisher fails.
pub async fn publish_arm_state(
    publisher: Publisher<ArmState>,
    context: ArmContext,
    period: Duration,
) -> Result<(), BusError> {
    let mut ticker = tokio::time::interval(period);
    ticker.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Skip);
    let idle_every = (Duration::from_secs(1).as_secs_f64() / period.as_secs_f64()).ceil() as u64;
    let mut ticks: u64 = 0;
    let mut was_moving = false;
    let mut was_estopped = false;
    let mut published_still_since = None;
    let mut failing = false;
    loop {
        tokio::select! {
            _ = ticker.tick() => ticks += 1,
            () = context.shared.changed.notified() => {}
        }
        let still_since = context.still_since_ns();
        let moving = context.driver.flags().moving || still_since == 0;
        let estop = context.control.estop_engaged();
        if moving
            || was_moving
            || estop != was_estopped
            || published_still_since != Some(still_since)
            || ticks.is_multiple_of(idle_every.max(1))
        {
            published_still_since = Some(still_since);
            match context.state() {
                Ok(state) => {
                    publisher.publish(&state)?;
                    failing = false;
                }
                // Once per streak: a disconnected robot fails every tick.
                Err(error) if !failing => {
                    failing = true;
                    tracing::warn!(%error, "reading the arm state");
                }
                Err(_) => {}
            }
        }
        was_moving = moving;
        was_estopped = estop;
    }
}

/// The running arm: the supervised actor and its bus tasks (`arm/command`, `arm/state`,
/// `safety/estop` and `safety/release`).
pub struct RunningArm {
    /// The supervised actor.
    pub actor: Supervised<ArmActor>,
    /// Serving, publishing and e-stop tasks; aborted by [`RunningArm::shutdown`].
    pub tasks: Vec<tokio::task::JoinHandle<()>>,
}

/// Puts the arm on the bus: the actor under `supervisor` (whose safe state halts the arm
/// through the driver, not through the dead actor), `arm/command`, `arm/state` every
/// `state_period`, and the e-stop (engage on `safety/estop`, release on `safety/release`).
pub async fn start(
    bus: &robotd_runtime::bus::Bus,
    supervisor: robotd_runtime::supervision::Supervisor,
    context: ArmContext,
    state_period: Duration,
) -> Result<RunningArm, robotd_runtime::host::ActorStartError> {
    use robotd_topics::{ARM_COMMAND, ARM_STATE, SAFETY_ESTOP, SAFETY_RELEASE};
    let halt_driver = context.driver.clone();
    let actor_context = context.clone();
    let actor = supervisor
        .safe_state(robotd_runtime::supervision::safe_state_fn(
            Duration::from_secs(1),
            move |reason: String| {
                let driver = halt_driver.clone();
                async move {
                    tracing::warn!(%reason, "arm actor failed: halting the arm");
                    driver.halt().map_err(|e| e.to_string())
                }
            },
        ))
        .spawn_actor::<ArmActor>(move || ArmActor::new(actor_context.clone()))
        .await?;
    let mut tasks = Vec::new();
    let server = bus.server(&ARM_COMMAND)?;
    let (serve_actor, serve_context) = (actor.clone(), context.clone());
    tasks.push(tokio::spawn(async move {
        if let Err(error) = serve_arm(server, serve_actor, serve_context).await {
            tracing::error!(%error, "arm/command stopped serving");
        }
    }));
    let state_publisher = bus.publisher(&ARM_STATE)?;
    let state_context = context.clone();
    tasks.push(tokio::spawn(async move {
        if let Err(error) = publish_arm_state(state_publisher, state_context, state_period).await {
            tracing::error!(%error, "arm/state stopped publishing");
        }
    }));
    // The e-stop: engaged from anyone on `safety/estop`, released only by a request to the
    // policy on `safety/release` (`robotd_safety::estop`).
    let estop = bus.subscriber(&SAFETY_ESTOP)?;
    let releases = bus.server(&SAFETY_RELEASE)?;
    let halt = context.driver.clone();
    tasks.push(tokio::spawn(async move {
        let halt = move || {
            if let Err(error) = halt.halt() {
                tracing::error!(%error, "halting the arm for the emergency stop");
            }
        };
        if let Err(error) = robotd_safety::estop::serve(estop, releases, context.safety, halt).await
        {
            tracing::error!(%error, "the emergency stop stopped being served");
        }
    }));
    Ok(RunningArm { actor, tasks })
}

impl RunningArm {
    /// Stops the bus tasks and the actor.
    pub async fn shutdown(self) -> Result<(), robotd_runtime::supervision::SupervisionError> {
        for task in &self.tasks {
            task.abort();
        }
        self.actor.shutdown().await
    }
}
