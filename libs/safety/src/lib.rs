//! # robotd-safety: the one policy every motion passes
//!
//! Whatever asks for a motion — a skill run by an MCP tool, the agent, the Redis edge, an
//! external actor talking to `arm/command` directly — the arm and gripper actors admit it only
//! through [`Safety`]:
//!
//! 1. **Admission** ([`Safety::admit`]), when the command arrives on the bus: refused while the
//!    emergency stop is engaged (with its reason), beyond the client's rate limit
//!    ([`rate`]), or without a human's approval where one is required ([`approval`]). The
//!    decision is written to the audit log ([`audit`]) before anything moves; if the log
//!    cannot take the record, the motion is refused.
//! 2. **Plan check** ([`Safety::check_arm_motion`]), after the arm actor planned the motion:
//!    every sampled tool position inside the geofence ([`fence`]: workspaces plus a margin,
//!    table floor, ceiling, reach, keep-out boxes), every joint target inside its limits
//!    minus a margin, and the speed scale that keeps the tool under the origin's speed and
//!    acceleration caps ([`path`]). LLM origins get lower caps.
//! 3. **Outcome** ([`Safety::finish`]): what happened, to the audit log.
//!
//! **One door.** Every actuator method of the driver traits (`robotd-driver`: arm motion,
//! calibration, clear-collision, gripper open, close and width) takes a [`Permit`] for that
//! act, and only this crate can make one ([`permit`]): from an [`Admission`], right before the
//! driver call, after the e-stop and (for motions and calibrations) the plan check. A driver's
//! own automatic calibration asks here too ([`Safety::admit_auto_calibration`]). So no code
//! path reaches a driver without passing here, and the compiler checks it. Refusals are
//! [`Violation`]s: the limit's name and a reason with the values, e.g. "the tool centre would
//! go to z -0.030 m, below the table floor 0.000 m".
//!
//! Approval and rate limits are decided here for every origin, not by the caller: a tool run
//! gets a grant from [`Safety::approve_tool`] (a human's yes when the tool is listed in
//! `approval_tools`), and a command without one — a client on `arm/command` directly — waits
//! for a human when a listed tool could have sent it ([`approval::bare_command_needs_approval`]).
//! Rate limits count per origin kind, all sessions together ([`rate`]).
//!
//! This crate is a library under the drivers (`libs/safety`): the drivers take its permits,
//! the actors and edges call it. [`control`] holds what the policy and the drivers share: the
//! stop and e-stop signals ([`MotionControl`]) and the shape of a motion ([`Motion`]).
//!
//! The emergency stop's latch lives in the arm's [`MotionControl`]: engaged from any entry
//! point through the `safety/estop` topic, it halts the arm within one control tick and
//! survives restarts of the actors (the control outlives them). It is released only by a
//! deliberate request to this policy (`safety/release`, [`estop`]), never by a new command
//! nor by an `engaged: false` message on the topic (ignored and audited).

pub mod approval;
pub mod audit;
pub mod config;
pub mod control;
pub mod estop;
pub mod fence;
pub mod path;
pub mod permit;
pub mod rate;
#[cfg(feature = "testing")]
pub mod testing;

pub use approval::{ApprovalRequest, Approvals, NotApproved};
pub use audit::{AuditConfig, AuditError, AuditKey, AuditLog};
pub use config::{KeepOutBox, SafetyConfig, SafetyMode};
pub use control::{Motion, MotionControl, Stopped};
pub use fence::{BodyDepth, Fence, Violation};
pub use path::{Caps, MotionCheck};
pub use permit::{
    ArmMotion, Calibration, ClearCollision, Close, GripperAct, Open, Permit, SetWidth,
};

use robotd_kinematics::Kinematics;
use robotd_protocol::safety::Origin;
use robotd_protocol::workspace::WorkspaceSpec;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// A command the policy let through, carried to the actor that executes it. Only
/// [`Safety::admit`] (and its siblings) makes one; the actor turns it into a [`Permit`] right
/// before the driver call.
#[derive(Debug, Clone, PartialEq)]
pub struct Admission {
    motion_id: u64,
    origin: Origin,
    actor: &'static str,
    stop_generation: u64,
}

impl Admission {
    /// The motion's number in the audit log.
    pub fn motion_id(&self) -> u64 {
        self.motion_id
    }

    /// Who asked.
    pub fn origin(&self) -> &Origin {
        &self.origin
    }

    /// The actor it is for (`"arm"`, `"gripper"`).
    pub fn actor(&self) -> &'static str {
        self.actor
    }

    /// The arm's stop generation when the command arrived: a stop after that cancels it
    /// ([`MotionControl::begin_motion`]).
    pub fn stop_generation(&self) -> u64 {
        self.stop_generation
    }
}

/// The motion policy of one robot. Cheap to clone.
#[derive(Clone)]
pub struct Safety {
    inner: Arc<Inner>,
}

struct Inner {
    config: SafetyConfig,
    fence: Fence,
    kinematics: Kinematics,
    control: MotionControl,
    rates: Mutex<rate::RateLimiter>,
    approvals: Approvals,
    audit: AuditLog,
    next_motion: AtomicU64,
    workspace_ids: Vec<String>,
}

impl std::fmt::Debug for Safety {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Safety")
            .field("mode", &self.inner.config.mode)
            .field("fence", &self.inner.fence)
            .finish_non_exhaustive()
    }
}

impl Safety {
    /// The policy `config` sets, fencing `workspaces` (their rectangles and observation
    /// poses) and the arm's rest pose, writing to `audit`. `control` is the arm's stop and
    /// e-stop signals.
    pub fn new(
        config: SafetyConfig,
        kinematics: Kinematics,
        control: MotionControl,
        workspaces: &[WorkspaceSpec],
        audit: AuditLog,
    ) -> Self {
        let mut points: Vec<[f64; 2]> = Vec::new();
        for w in workspaces {
            points.push(w.upper_left);
            points.push(w.lower_right);
            points.push([w.observation_pose[0], w.observation_pose[1]]);
        }
        if let Ok(home) = kinematics.tool_pose(&kinematics.home_joints()) {
            points.push([home.translation.x, home.translation.y]);
        }
        let fence = Fence::around(&points, &config, model_reach_m(&kinematics));
        Self {
            inner: Arc::new(Inner {
                config,
                fence,
                kinematics,
                control,
                rates: Mutex::default(),
                approvals: Approvals::default(),
                audit,
                next_motion: AtomicU64::new(1),
                workspace_ids: workspaces.iter().map(|w| w.id.clone()).collect(),
            }),
        }
    }

    /// Opens the audit log `config.audit` names (or none when disabled); an empty path means
    /// `audit.jsonl` in `log_dir` (robotd's log directory). Its HMAC key is read from
    /// `key_file` (empty: `audit.key` beside the audit file), created there on the first start.
    pub fn open_audit(
        config: &SafetyConfig,
        log_dir: &std::path::Path,
    ) -> Result<AuditLog, AuditError> {
        if !config.audit.enabled {
            return Ok(AuditLog::disabled());
        }
        let path = match config.audit.path.trim() {
            "" => log_dir.join("audit.jsonl"),
            path => path.into(),
        };
        let key_file = match config.audit.key_file.trim() {
            "" => audit::default_key_file(&path),
            file => file.into(),
        };
        AuditLog::start(&AuditConfig {
            path,
            max_file_bytes: config.audit.max_file_bytes,
            keep_files: config.audit.keep_files,
            queue: config.audit.queue,
            key: Some(AuditKey::load_or_create(&key_file)?),
        })
    }

    /// The configuration.
    pub fn config(&self) -> &SafetyConfig {
        &self.inner.config
    }

    /// The geofence.
    pub fn fence(&self) -> &Fence {
        &self.inner.fence
    }

    /// The kinematics the plan checks follow.
    pub fn kinematics(&self) -> &Kinematics {
        &self.inner.kinematics
    }

    /// The arm's stop and e-stop signals, which the policy reads.
    pub fn control(&self) -> &MotionControl {
        &self.inner.control
    }

    /// The approval queue.
    pub fn approvals(&self) -> &Approvals {
        &self.inner.approvals
    }

    /// The ids of the configured workspaces: a command naming another is refused before
    /// admission, so an unknown name never reaches the audit log.
    pub fn workspace_ids(&self) -> &[String] {
        &self.inner.workspace_ids
    }

    /// The audit log.
    pub fn audit(&self) -> &AuditLog {
        &self.inner.audit
    }

    /// The e-stop's reason while it is engaged.
    pub fn estop(&self) -> Option<String> {
        let control = &self.inner.control;
        control.estop_engaged().then(|| control.estop_reason())
    }

    /// The speed and acceleration caps of `origin`: its kind's configured caps, the speed
    /// lowered to the cap the origin asks for (`speed_cap_mm_s`), never raised.
    pub fn caps(&self, origin: &Origin) -> Caps {
        let c = &self.inner.config;
        let mut caps = if origin.is_llm() {
            Caps {
                speed_m_s: c.llm_max_tcp_speed_m_s,
                acceleration_m_s2: c.llm_max_tcp_acceleration_m_s2,
            }
        } else {
            Caps {
                speed_m_s: c.max_tcp_speed_m_s,
                acceleration_m_s2: c.max_tcp_acceleration_m_s2,
            }
        };
        if origin.speed_cap_mm_s > 0 {
            caps.speed_m_s = caps
                .speed_m_s
                .min(f64::from(origin.speed_cap_mm_s) / 1000.0);
        }
        caps
    }

    /// Whether `tool` must wait for a human's approval.
    pub fn needs_approval(&self, tool: &str) -> bool {
        self.inner.config.mode == SafetyMode::Supervised
            || self.inner.config.approval_tools.iter().any(|t| t == tool)
    }

    /// For a motion tool's run: the policy's grant, waiting for a human's approval when
    /// `tool` needs one. `Ok(id)`: put the id in the work's origin (`approval_id`), so the
    /// arm and gripper commands of the run are known to belong to a decided tool, and
    /// [`Approvals::finish`] it when the work ends.
    pub async fn approve_tool(
        &self,
        origin: &Origin,
        tool: &str,
        summary: &str,
    ) -> Result<u64, Violation> {
        if !self.needs_approval(tool) {
            return Ok(self.inner.approvals.grant(tool));
        }
        self.ask_approval(origin, tool, summary).await
    }

    async fn ask_approval(
        &self,
        origin: &Origin,
        action: &str,
        summary: &str,
    ) -> Result<u64, Violation> {
        let timeout = Duration::from_secs(self.inner.config.approval_timeout_s);
        self.inner
            .approvals
            .ask(origin, action, summary, timeout)
            .await
            .map_err(|e| Violation {
                limit: "approval",
                reason: format!("{action} needs a human's approval: {e}; nothing moved"),
            })
    }

    /// Admits a motion command of `actor` (`"arm"`, `"gripper"`) from `origin`, or refuses it.
    /// `action` names the command, `arguments` are recorded in the audit log.
    pub async fn admit(
        &self,
        origin: &Origin,
        actor: &'static str,
        action: &str,
        arguments: serde_json::Value,
    ) -> Result<Admission, Violation> {
        self.admit_as(origin, actor, action, arguments, Checks::MOTION)
            .await
    }

    /// Admits clearing the arm's collision flag: not a motion, so neither the e-stop nor the
    /// rate limit refuses it, but it is audited, and a bare one waits for a human when
    /// `clear_collision_detected` is listed in `approval_tools`.
    pub async fn admit_clear_collision(
        &self,
        origin: &Origin,
        arguments: serde_json::Value,
    ) -> Result<Admission, Violation> {
        self.admit_as(origin, "arm", "clear_collision", arguments, Checks::FLAG)
            .await
    }

    async fn admit_as(
        &self,
        origin: &Origin,
        actor: &'static str,
        action: &str,
        arguments: serde_json::Value,
        checks: Checks,
    ) -> Result<Admission, Violation> {
        let motion_id = self.inner.next_motion.fetch_add(1, Ordering::Relaxed);
        let stop_generation = self.inner.control.stop_generation();
        let decision = self.decide(origin, action, checks).await;
        let mut record = serde_json::json!({
            "event": "admission",
            "motion": motion_id,
            "actor": actor,
            "action": action,
            "origin": origin,
            "arguments": arguments,
        });
        match decision {
            Ok(()) => {
                record["decision"] = "admitted".into();
                self.inner.audit.record(record).map_err(|e| Violation {
                    limit: "audit",
                    reason: e.to_string(),
                })?;
                Ok(Admission {
                    motion_id,
                    origin: origin.clone(),
                    actor,
                    stop_generation,
                })
            }
            Err(violation) => {
                record["decision"] = "refused".into();
                record["limit"] = violation.limit.into();
                record["reason"] = violation.reason.clone().into();
                if let Err(error) = self.inner.audit.record(record) {
                    tracing::error!(%error, "could not record a refused motion");
                }
                tracing::warn!(%origin, actor, action, limit = violation.limit, reason = %violation.reason, "motion refused");
                Err(violation)
            }
        }
    }

    /// The decision on a command: e-stop, approval, rate limit — the same for every origin.
    async fn decide(&self, origin: &Origin, action: &str, checks: Checks) -> Result<(), Violation> {
        if checks.estop {
            self.check_estop()?;
        }
        // A command of a tool run carries the run's grant: its tool's approval was decided
        // when the run began (`approve_tool`). A bare one is decided here.
        let config = &self.inner.config;
        let bare = !self.inner.approvals.is_granted(origin.approval_id);
        let supervised = config.mode == SafetyMode::Supervised && checks.rate;
        if bare
            && (supervised || approval::bare_command_needs_approval(&config.approval_tools, action))
        {
            self.ask_approval(origin, action, &format!("{action} from {origin}"))
                .await?;
            if checks.estop {
                self.check_estop()?;
            }
        }
        if !checks.rate {
            return Ok(());
        }
        let per_minute = if origin.is_llm() {
            self.inner.config.llm_motions_per_minute
        } else {
            self.inner.config.motions_per_minute
        };
        self.inner
            .rates
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .admit(origin, per_minute, Instant::now())
            .map_err(|reason| Violation {
                limit: "rate",
                reason,
            })
    }

    pub(crate) fn check_estop(&self) -> Result<(), Violation> {
        match self.estop() {
            Some(reason) => Err(Violation {
                limit: "estop",
                reason: format!("emergency stop engaged: {reason}; release it (release_emergency_stop) before moving"),
            }),
            None => Ok(()),
        }
    }

    /// Checks the planned `motion` of an admitted arm command from joints `start`: the
    /// geofence at every sampled tool position, joint limits with the margin, and the speed
    /// scale under the origin's caps.
    pub fn check_arm_motion(
        &self,
        admission: &Admission,
        start: &[f64],
        motion: &Motion,
    ) -> Result<MotionCheck, Violation> {
        self.check_estop()?;
        path::check_motion(
            &self.inner.kinematics,
            &self.inner.fence,
            self.inner.config.joint_margin_rad,
            start,
            motion,
            self.caps(&admission.origin),
        )
    }

    /// Records how an admitted motion ended.
    pub fn finish(&self, admission: &Admission, outcome: Outcome<'_>) {
        let mut record = serde_json::json!({
            "event": "outcome",
            "motion": admission.motion_id,
        });
        match outcome {
            Outcome::Done => record["outcome"] = "done".into(),
            Outcome::Refused { limit, reason } => {
                record["outcome"] = "refused".into();
                record["limit"] = limit.into();
                record["reason"] = reason.into();
            }
            Outcome::Failed { reason } => {
                record["outcome"] = "failed".into();
                record["reason"] = reason.into();
            }
        }
        if let Err(error) = self.inner.audit.record(record) {
            tracing::error!(%error, motion = admission.motion_id, "could not record a motion's outcome");
        }
    }
}

/// Which parts of the decision apply to a command.
#[derive(Debug, Clone, Copy)]
struct Checks {
    /// Refused while the e-stop is engaged.
    estop: bool,
    /// Counted against the rate limit (and, in supervised mode, approved like a motion).
    rate: bool,
}

impl Checks {
    /// A motion: everything.
    const MOTION: Checks = Checks {
        estop: true,
        rate: true,
    };
    /// A flag that moves nothing (clear-collision): approval of bare commands only.
    const FLAG: Checks = Checks {
        estop: false,
        rate: false,
    };
}

/// How an admitted motion ended, for the audit log.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Outcome<'a> {
    /// It did what was asked.
    Done,
    /// The plan check refused it (nothing moved).
    Refused {
        /// The limit's short name.
        limit: &'a str,
        /// Why.
        reason: &'a str,
    },
    /// It failed (collision, stop, driver error).
    Failed {
        /// Why.
        reason: &'a str,
    },
}

/// How far the tool centre can get from the base axis: the makers' stated reach (Ned2
/// 440 mm, WidowX 250 s 650 mm).
fn model_reach_m(kinematics: &Kinematics) -> f64 {
    match kinematics.model() {
        robotd_protocol::RobotModel::Ned2 => 0.44,
        robotd_protocol::RobotModel::WidowX250 => 0.65,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use robotd_protocol::safety::OriginKind;

    fn policy() -> Safety {
        let config = SafetyConfig {
            max_tcp_speed_m_s: 0.4,
            llm_max_tcp_speed_m_s: 0.2,
            ..SafetyConfig::default()
        };
        Safety::new(
            config,
            Kinematics::new(robotd_protocol::RobotModel::Ned2),
            MotionControl::default(),
            &[],
            AuditLog::disabled(),
        )
    }

    #[test]
    fn an_origin_may_lower_its_speed_cap_but_never_raise_it() {
        let policy = policy();
        let cli = Origin::new(OriginKind::Cli);
        assert_eq!(policy.caps(&cli).speed_m_s, 0.4);
        assert_eq!(policy.caps(&cli.clone().speed_cap(100)).speed_m_s, 0.1);
        assert_eq!(policy.caps(&cli.speed_cap(900)).speed_m_s, 0.4);
        let llm = Origin::new(OriginKind::Mcp).speed_cap(5_000);
        assert_eq!(policy.caps(&llm).speed_m_s, 0.2);
    }

    #[test]
    fn a_release_of_ones_own_e_stop_never_releases_another_engaged_meanwhile() {
        let cli = Origin::new(OriginKind::Cli);
        for operator_first in [false, true] {
            let policy = policy();
            let engage = |reason: &str| policy.engage_estop(reason, "test", || {});
            if operator_first {
                engage("operator");
                engage("mine");
            } else {
                engage("mine");
                engage("operator");
            }
            let reason = policy.estop().unwrap();
            assert!(
                reason.contains("operator") && reason.contains("mine"),
                "{reason}"
            );
            let refused = policy.release_estop(&cli, "release", "me", Some("mine"));
            assert!(refused.unwrap_err().reason.contains("not the one expected"));
            assert!(policy.estop().is_some(), "it stays engaged");
        }
        let policy = policy();
        policy.engage_estop("mine", "test", || {});
        policy.engage_estop("mine", "test", || {});
        assert_eq!(policy.estop().as_deref(), Some("mine"));
        policy
            .release_estop(&cli, "release", "me", Some("mine"))
            .unwrap();
        assert_eq!(policy.estop(), None);
        // Nothing engaged: an expected reason is not met either.
        assert!(policy
            .release_estop(&cli, "release", "me", Some("mine"))
            .is_err());
    }
}
