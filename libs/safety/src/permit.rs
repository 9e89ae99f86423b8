//! Permits: the only keys to a driver's actuators.
//!
//! Every method of the driver traits that moves something — `ArmDriver::execute`,
//! `calibrate`, `clear_collision`, `GripperDriver::open`, `close`, `set_width` — takes a
//! [`Permit`] for exactly that act, and only this crate can make one: [`Permit`]'s fields and
//! constructor are private here. So code that holds a driver still cannot move the robot
//! without passing the policy; that is "one door", checked by the compiler rather than by
//! review.
//!
//! A permit is made right before the driver call, from an [`Admission`] (which the policy
//! made when the command arrived, after the e-stop, the approval and the rate limit):
//!
//! | act | made by | checks at that moment |
//! |---|---|---|
//! | [`ArmMotion`] | [`Safety::permit_motion`] | e-stop; the plan check (fence at every sampled tool position, joint margins, speed caps) |
//! | [`Calibration`] | [`Safety::permit_calibration`] | e-stop; the calibration's motion (current joints to the rest pose) through the same plan check |
//! | [`Calibration`] | [`Safety::admit_auto_calibration`] | a driver's own calibration on (re)connecting: admitted and audited like a command, refused while the e-stop is engaged |
//! | [`ClearCollision`] | [`Safety::permit_clear_collision`] | the admission's actor is the arm (not a motion: allowed during an e-stop) |
//! | [`Open`], [`Close`], [`SetWidth`] | [`Safety::permit_gripper`] | the admission's actor is the gripper; the e-stop again, after admission |
//!
//! A permit is not `Clone`: one permit, one driver call. It carries the motion's number in
//! the audit log ([`Permit::motion_id`]) so a driver's log lines can name it.

use crate::control::Motion;
use crate::{Admission, Safety, Violation};
use robotd_protocol::safety::{Origin, OriginKind};

/// The policy's leave for one actuator call of kind `A`. Only `robotd-safety` makes one.
#[derive(Debug, PartialEq)]
#[must_use = "a permit is for a driver call"]
pub struct Permit<A> {
    motion_id: u64,
    act: A,
}

impl<A> Permit<A> {
    fn new(motion_id: u64, act: A) -> Self {
        Self { motion_id, act }
    }

    /// The motion's number in the audit log.
    pub fn motion_id(&self) -> u64 {
        self.motion_id
    }

    /// What is permitted.
    pub fn act(&self) -> &A {
        &self.act
    }

    /// What is permitted, taken out (the driver runs it).
    pub fn into_act(self) -> A {
        self.act
    }
}

/// An arm motion that passed the plan check, at the speed scale that keeps it under its
/// origin's caps (0 < scale ≤ 1).
#[derive(Debug, Clone, PartialEq)]
pub struct ArmMotion {
    /// The motion.
    pub motion: Motion,
    /// The fraction of the joint velocity limits to run it at.
    pub speed_scale: f64,
}

/// A calibration (Ned2) or homing.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Calibration;

/// Clearing the collision flag.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ClearCollision;

/// Opening the gripper fully.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Open;

/// Closing the gripper until it is closed or blocked.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Close;

/// Moving the fingers to a width.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SetWidth {
    /// Distance between the fingers, metres.
    pub width_m: f64,
}

/// The gripper's acts ([`Open`], [`Close`], [`SetWidth`]); sealed.
pub trait GripperAct: sealed::Sealed + Send + 'static {}
impl GripperAct for Open {}
impl GripperAct for Close {}
impl GripperAct for SetWidth {}

mod sealed {
    pub trait Sealed {}
    impl Sealed for super::Open {}
    impl Sealed for super::Close {}
    impl Sealed for super::SetWidth {}
}

impl Safety {
    /// The permit for an admitted arm motion, planned from joints `start`: the e-stop and the
    /// plan check ([`Safety::check_arm_motion`]) now, right before the driver call.
    pub fn permit_motion(
        &self,
        admission: &Admission,
        start: &[f64],
        motion: Motion,
    ) -> Result<Permit<ArmMotion>, Violation> {
        expect_actor(admission, "arm")?;
        let check = self.check_arm_motion(admission, start, &motion)?;
        Ok(Permit::new(
            admission.motion_id(),
            ArmMotion {
                motion,
                speed_scale: check.speed_scale,
            },
        ))
    }

    /// The permit for an admitted calibration of the arm standing at joints `start`. A
    /// calibration ends with the arm at its rest pose (the Ned2 sweeps each motor to its
    /// reference and returns); the policy checks the joint motion from `start` to the rest
    /// pose like any other motion (fence at every sampled tool position, joint margins), so a
    /// calibration from a place the way back from which leaves the fence is refused. The
    /// sweep itself stays within each joint's own range, which the robot enforces.
    pub fn permit_calibration(
        &self,
        admission: &Admission,
        start: &[f64],
    ) -> Result<Permit<Calibration>, Violation> {
        expect_actor(admission, "arm")?;
        let rest = Motion::Joints(self.inner.kinematics.home_joints());
        self.check_arm_motion(admission, start, &rest)?;
        Ok(Permit::new(admission.motion_id(), Calibration))
    }

    /// The permit for clearing an arm's collision flag. It moves nothing, so an engaged e-stop
    /// does not refuse it; it is admitted (and audited) all the same.
    pub fn permit_clear_collision(
        &self,
        admission: &Admission,
    ) -> Result<Permit<ClearCollision>, Violation> {
        expect_actor(admission, "arm")?;
        Ok(Permit::new(admission.motion_id(), ClearCollision))
    }

    /// The permit for an admitted gripper act: the e-stop is checked again here, right before
    /// the driver call, so an e-stop engaged between admission and motion stops it.
    pub fn permit_gripper<A: GripperAct>(
        &self,
        admission: &Admission,
        act: A,
    ) -> Result<Permit<A>, Violation> {
        expect_actor(admission, "gripper")?;
        self.check_estop()?;
        Ok(Permit::new(admission.motion_id(), act))
    }

    /// A driver's own calibration when it (re)connects to a robot that needs one (the Ned2's
    /// `CALIBRATE AUTO`): admitted like a command of origin `internal` with session `driver`
    /// (audited; refused while the e-stop is engaged, and waiting for a human in supervised
    /// mode), then checked against the e-stop once more. The driver records the outcome with
    /// [`Safety::finish`] on the admission returned.
    pub async fn admit_auto_calibration(
        &self,
        driver: &str,
    ) -> Result<(Admission, Permit<Calibration>), Violation> {
        let origin = Origin::new(OriginKind::Internal).session(driver);
        let admission = self
            .admit(
                &origin,
                "arm",
                "calibrate_on_connect",
                serde_json::json!({ "driver": driver }),
            )
            .await?;
        if let Err(violation) = self.check_estop() {
            self.finish(
                &admission,
                crate::Outcome::Refused {
                    limit: violation.limit,
                    reason: &violation.reason,
                },
            );
            return Err(violation);
        }
        let permit = Permit::new(admission.motion_id(), Calibration);
        Ok((admission, permit))
    }
}

fn expect_actor(admission: &Admission, actor: &'static str) -> Result<(), Violation> {
    if admission.actor() == actor {
        Ok(())
    } else {
        Err(Violation {
            limit: "admission",
            reason: format!(
                "an admission for the {} cannot move the {actor}",
                admission.actor()
            ),
        })
    }
}
