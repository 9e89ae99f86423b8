//! The Ned2's arm over TCP: robotd's own joint plans, executed as short `MOVE_JOINTS`
//! segments, each checked against the joints the robot reached.
//!
//! Why joint moves from robotd's inverse kinematics rather than the robot's `MOVE_POSE`: the
//! safety policy checks the path robotd planned (geofence at every sampled tool position,
//! joint margins, speed caps); a pose move would let the robot's own planner choose a path
//! nobody checked. And why segments: the Ned2 has no stop command and finishes every command
//! it was sent, even after its client left, so robotd can only stop *between* commands. A
//! motion is cut into segments in which no joint moves more than `robot.niryo.segment_rad`,
//! and the stop signals (stop, e-stop, halt) are checked before each one: the worst-case stop
//! latency is one segment plus one round trip.
//!
//! After every segment the driver reads the joints back: recent robot software answers OK
//! *without moving* when it rejects a target (not calibrated, no solution), so an arm that is
//! not where it was sent is an error, not a success. A KO is a collision when the robot's
//! collision flag says so, else the robot's refusal with its message. A connection lost
//! during a segment fails the motion at once and is never re-sent.

use crate::link::{Link, LinkError, Session};
use crate::wire::{self, Param};
use robotd_driver::{
    nominal_travel_time_s, ArmDriver, ArmFlags, ArmMotion, Calibration, ClearCollision,
    DriverError, DriverFuture, HardwareInfo, Motion, MotionControl, MotorInfo, Permit,
};
use robotd_protocol::geometry::RobotModel;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicU8, Ordering};
use std::sync::Arc;
use std::time::Duration;

/// Deadline of a calibration.
pub const CALIBRATE_TIMEOUT: Duration = Duration::from_secs(120);

/// What the arm driver needs to know about the arm and the settings.
#[derive(Debug, Clone)]
pub struct ArmSettings {
    /// Joint velocity limits, rad/s (for segment lengths and deadlines).
    pub max_velocity_rad_s: Vec<f64>,
    /// Largest joint change of one segment, radians.
    pub segment_rad: f64,
    /// Largest allowed gap between a target and the joints reached, radians.
    pub arrival_tolerance_rad: f64,
}

/// The Ned2's arm.
#[derive(Debug)]
pub struct NiryoArm {
    link: Arc<Link>,
    settings: ArmSettings,
    /// Bumped by every halt; a motion stops before its next segment when it changed.
    halts: AtomicU64,
    moving: AtomicBool,
    /// The speed percentage last set on the robot (0 = not set on this connection yet).
    speed_percent: AtomicU8,
}

impl NiryoArm {
    /// The arm driver on `link`.
    pub fn new(link: Arc<Link>, settings: ArmSettings) -> Self {
        Self {
            link,
            settings,
            halts: AtomicU64::new(0),
            moving: AtomicBool::new(false),
            speed_percent: AtomicU8::new(0),
        }
    }

    /// The segments `motion` is sent as, from `start`: no joint changes by more than
    /// `segment_rad` within one.
    pub fn segments(&self, start: &[f64], motion: Motion) -> Vec<Vec<f64>> {
        let limit = self.settings.segment_rad;
        let change = |a: &[f64], b: &[f64]| {
            a.iter()
                .zip(b)
                .map(|(x, y)| (x - y).abs())
                .fold(0.0, f64::max)
        };
        match motion {
            Motion::Joints(target) => {
                let n = (change(start, &target) / limit).ceil().clamp(1.0, 10_000.0) as usize;
                (1..=n)
                    .map(|i| {
                        let t = i as f64 / n as f64;
                        start
                            .iter()
                            .zip(&target)
                            .map(|(a, b)| a + (b - a) * t)
                            .collect()
                    })
                    .collect()
            }
            // A straight tool path in dense waypoints (5 mm apart): keep waypoints at most
            // `segment_rad` and 4 waypoints (2 cm of path) apart, so that the joint-space
            // moves between them stay on the line.
            Motion::JointPath(path) => {
                let mut kept: Vec<Vec<f64>> = Vec::new();
                let mut from = start.to_vec();
                let mut since = 0;
                let last = path.len().saturating_sub(1);
                for (i, q) in path.iter().enumerate() {
                    since += 1;
                    let next_too_far = path
                        .get(i + 1)
                        .is_some_and(|next| change(&from, next) > limit);
                    if i == last || since >= 4 || next_too_far {
                        kept.push(q.clone());
                        from = q.clone();
                        since = 0;
                    }
                }
                kept
            }
        }
    }

    async fn set_speed(&self, speed_scale: f64) -> Result<(), DriverError> {
        let percent = (speed_scale * 100.0).ceil().clamp(1.0, 100.0) as u8;
        if self.speed_percent.load(Ordering::SeqCst) == percent {
            return Ok(());
        }
        self.link
            .call(
                "SET_ARM_MAX_VELOCITY",
                &[Param::Int(percent.into())],
                self.link.settings().query_timeout,
            )
            .await
            .map_err(|e| {
                DriverError::Hardware(format!(
                    "cannot set the arm's speed to {percent} % (the safety policy's cap): {e}"
                ))
            })?;
        self.speed_percent.store(percent, Ordering::SeqCst);
        Ok(())
    }

    async fn run(
        &self,
        motion: Motion,
        speed_scale: f64,
        control: &MotionControl,
    ) -> Result<(), DriverError> {
        robotd_driver::check_speed_scale(speed_scale)?;
        let halts_at_start = self.halts.load(Ordering::SeqCst);
        let known = self.link.known();
        if known.collision {
            return Err(DriverError::CollisionPending);
        }
        if !known.calibrated {
            return Err(DriverError::NotCalibrated);
        }
        let mut from = self.joints()?;
        self.set_speed(speed_scale).await?;
        for target in self.segments(&from, motion) {
            control.check()?;
            if self.halts.load(Ordering::SeqCst) != halts_at_start {
                return Err(DriverError::Stopped {
                    reason: "the arm was halted".into(),
                });
            }
            let expected_s =
                nominal_travel_time_s(&from, &target, &self.settings.max_velocity_rad_s)
                    / speed_scale;
            // The robot's own profile may be slower than the nominal one: 3× and a margin.
            let deadline =
                Duration::from_secs_f64(expected_s * 3.0) + self.link.settings().query_timeout;
            let params: Vec<Param> = target.iter().map(|q| Param::Float(*q)).collect();
            // The move and the read-back in one session: no camera image in between.
            let mut session = self.link.session().await;
            self.link.update_known(|k| k.settled = false);
            match session.call("MOVE_JOINTS", &params, deadline).await {
                Ok(_) => {}
                Err(LinkError::Refused { message, .. }) => {
                    drop(session);
                    return Err(self.refused(message).await);
                }
                Err(error) => return Err(motion_link_error(error)),
            }
            let reached = self.read_joints_in(&mut session).await?;
            drop(session);
            if let Some((joint, at, asked)) = reached
                .iter()
                .zip(&target)
                .enumerate()
                .map(|(i, (a, b))| (i, *a, *b))
                .find(|(_, a, b)| (a - b).abs() > self.settings.arrival_tolerance_rad)
            {
                return Err(DriverError::Hardware(format!(
                    "the robot answered OK but the arm did not arrive (joint {} at {at:.3} rad, sent to {asked:.3} rad): it refused the target; check that it is calibrated and in its normal mode",
                    joint + 1
                )));
            }
            from = target;
        }
        Ok(())
    }

    /// The error of a KO to a motion: a collision when the robot's flag is up.
    async fn refused(&self, message: String) -> DriverError {
        let flag = self
            .link
            .call(
                "GET_COLLISION_DETECTED",
                &[],
                self.link.settings().query_timeout,
            )
            .await
            .ok()
            .and_then(|(items, _)| items.first().and_then(wire::lenient_bool));
        let _ = self.read_joints().await;
        if flag == Some(true) {
            self.link.update_known(|k| k.collision = true);
            DriverError::Collision {
                what: "an obstacle (the robot's collision detection stopped it)".into(),
            }
        } else {
            DriverError::Hardware(format!("the robot refused the move: {message}"))
        }
    }

    /// Reads the joints from the robot and remembers them.
    pub async fn read_joints(&self) -> Result<Vec<f64>, DriverError> {
        let mut session = self.link.session().await;
        self.read_joints_in(&mut session).await
    }

    async fn read_joints_in(&self, session: &mut Session<'_>) -> Result<Vec<f64>, DriverError> {
        let (items, _) = session
            .call("GET_JOINTS", &[], self.link.settings().query_timeout)
            .await
            .map_err(link_error)?;
        let joints = wire::numbers(&items, 6, "GET_JOINTS").map_err(DriverError::Hardware)?;
        self.link.update_known(|k| {
            k.joints = Some(joints.clone());
            k.settled = true;
        });
        Ok(joints)
    }
}

/// The driver error of a link failure outside a motion.
pub fn link_error(error: LinkError) -> DriverError {
    DriverError::Hardware(error.to_string())
}

/// The driver error of a link failure during a motion.
fn motion_link_error(error: LinkError) -> DriverError {
    match error {
        LinkError::Lost { reason, .. } => DriverError::Hardware(format!(
            "connection to the robot lost during move ({reason}); the arm's position is unknown until it reconnects"
        )),
        other => link_error(other),
    }
}

struct MovingGuard<'a>(&'a AtomicBool);

impl Drop for MovingGuard<'_> {
    fn drop(&mut self) {
        self.0.store(false, Ordering::SeqCst);
    }
}

impl ArmDriver for NiryoArm {
    fn model(&self) -> RobotModel {
        RobotModel::Ned2
    }

    fn joints(&self) -> Result<Vec<f64>, DriverError> {
        self.link.known().joints.ok_or_else(|| {
            DriverError::Hardware(match self.link.status() {
                Ok(()) => "the arm's position is unknown (reading it from the robot)".into(),
                Err(reason) => format!("robot not connected: {reason}"),
            })
        })
    }

    fn flags(&self) -> ArmFlags {
        let known = self.link.known();
        ArmFlags {
            moving: self.moving.load(Ordering::SeqCst),
            collision_detected: known.collision,
            calibrated: known.calibrated,
        }
    }

    fn execute<'a>(
        &'a self,
        permit: Permit<ArmMotion>,
        control: &'a MotionControl,
    ) -> DriverFuture<'a, ()> {
        let ArmMotion {
            motion,
            speed_scale,
        } = permit.into_act();
        Box::pin(async move {
            self.moving.store(true, Ordering::SeqCst);
            let _moving = MovingGuard(&self.moving);
            self.run(motion, speed_scale, control).await
        })
    }

    fn calibrate(&self, _permit: Permit<Calibration>) -> DriverFuture<'_, ()> {
        Box::pin(async move {
            self.moving.store(true, Ordering::SeqCst);
            let _moving = MovingGuard(&self.moving);
            self.link.update_known(|k| k.settled = false);
            self.link
                .call("CALIBRATE", &[Param::Str("AUTO".into())], CALIBRATE_TIMEOUT)
                .await
                .map_err(motion_link_error)?;
            self.link.update_known(|k| k.calibrated = true);
            self.read_joints().await.map(|_| ())
        })
    }

    fn clear_collision(&self, _permit: Permit<ClearCollision>) -> DriverFuture<'_, ()> {
        Box::pin(async move {
            self.link
                .call(
                    "CLEAR_COLLISION_DETECTED",
                    &[],
                    self.link.settings().query_timeout,
                )
                .await
                .map_err(link_error)?;
            self.link.update_known(|k| k.collision = false);
            Ok(())
        })
    }

    fn halt(&self) -> Result<(), DriverError> {
        // No stop command exists: the segment under way ends, the next one is not sent.
        self.halts.fetch_add(1, Ordering::SeqCst);
        Ok(())
    }

    fn connection(&self) -> Result<(), String> {
        self.link.status()
    }

    fn hardware_info(&self) -> DriverFuture<'_, HardwareInfo> {
        Box::pin(async move {
            let known = self.link.known();
            let status = known.hardware.ok_or_else(|| {
                DriverError::Hardware(match self.link.status() {
                    Ok(()) => "the robot's hardware status is not read yet".into(),
                    Err(reason) => format!("robot not connected: {reason}"),
                })
            })?;
            Ok(hardware_info(&status, known.tool.as_ref()))
        })
    }
}

/// What `GET_HARDWARE_STATUS` tells of the robot's versions: the hardware version and each
/// motor's name and type; and the mounted tool `GET_CURRENT_TOOL_ID` named (`tool`). The TCP
/// protocol (pyniryo 1.2.5, ned_ros) has no command that reports the robot's software version
/// or the motors' firmware versions.
pub fn hardware_info(
    status: &crate::link::HardwareStatus,
    tool: Option<&Result<String, String>>,
) -> HardwareInfo {
    let mut not_reported = vec![
        "software version and motor firmware versions: the Niryo TCP protocol has no \
         command for them (GET_HARDWARE_STATUS reports the hardware version and the motor \
         types only; the robot publishes them on its ROS topic software_version)"
            .to_owned(),
    ];
    if let Some(Err(reason)) = tool {
        not_reported.push(format!("the mounted tool: {reason}"));
    }
    HardwareInfo {
        hardware_version: Some(status.hardware_version.clone()),
        software_version: None,
        motors: status
            .motors
            .iter()
            .map(|(name, kind)| MotorInfo {
                name: name.clone(),
                model: kind.clone(),
                firmware: None,
            })
            .collect(),
        tool: tool.and_then(|t| t.clone().ok()),
        not_reported,
    }
}
