//! # robotd-skills: pick, place, push — the robot-control tools as actor requests
//!
//! The skills actor serves `skills/run`: one [`Skill`](robotd_protocol::skills::Skill) at a
//! time, composed from the arm (`arm/command`), the gripper (`gripper/command`) and the
//! workspace model (`workspace/query`), with the semantics of `docs/mcp-tools.md`:
//!
//! - **Look before acting**: a pick, push or relative placement first moves to the
//!   workspace's observation pose and works from the first steady camera view taken there.
//! - **Check before moving**: every target must lie inside a workspace (plus a margin) and
//!   every pose of the plan must be reachable (inverse kinematics) — otherwise the skill is
//!   refused before anything moves, saying which coordinate or pose and why.
//! - **Real outcomes**: a pick succeeds only if the gripper reports it holds the object after
//!   the lift; a place only if it let go. The workspace model is told of picks and places.
//! - **Safe ends**: every motion skill ends at the first workspace's observation pose, so a
//!   following detection query is answered at once.
//! - **Progress and cancel**: `skills/progress` before each step; a `skills/cancel` with the
//!   run id stops the arm at once (`Stop`) and ends the skill with `Cancelled`.
//!
//! ```no_run
//! # async fn demo(bus: robotd_runtime::bus::Bus,
//! #     workspaces: Vec<robotd_protocol::workspace::WorkspaceInfo>) -> Result<(), Box<dyn std::error::Error>> {
//! use robotd_protocol::skills::{Skill, SkillRequest};
//! use robotd_protocol::{Point2, RobotModel};
//! use robotd_skills::{Skills, SkillsSettings};
//! let skills = Skills::start(&bus, SkillsSettings::new(RobotModel::Ned2, workspaces))?;
//! let client = bus.client(&robotd_topics::SKILLS_RUN)?;
//! let reply = client
//!     .request(
//!         &SkillRequest {
//!             run_id: 1,
//!             skill: Skill::Pick { object_name: "pencil".into(), pick_at: Point2::new(0.22, -0.05), z_offset_m: 0.001 },
//!         },
//!         std::time::Duration::from_secs(60),
//!     )
//!     .await?;
//! println!("{reply:?}");
//! skills.shutdown().await;
//! # Ok(()) }
//! ```

mod runner;

use robotd_placement::plan;
pub use robotd_placement::{geometry, SkillsSettings};

use robotd_protocol::arm::ArmCommand;
use robotd_protocol::skills::{SkillError, SkillReply};
use robotd_runtime::bus::{Bus, BusError};
use robotd_runtime::origin::{current_origin, with_origin};
use runner::{CancelFlag, Runner};
use std::sync::atomic::Ordering;
use std::sync::Arc;
use std::time::Duration;

/// Why the skills actor could not start.
#[derive(Debug, thiserror::Error)]
pub enum SkillsError {
    /// A bus port could not be created.
    #[error("skills actor: {0}")]
    Bus(#[from] BusError),
    /// No workspace is configured.
    #[error("skills actor: no workspace is configured")]
    NoWorkspace,
}

/// The running skills actor.
#[derive(Debug)]
pub struct Skills {
    server: tokio::task::JoinHandle<()>,
    canceller: tokio::task::JoinHandle<()>,
}

impl Skills {
    /// Starts serving `skills/run` on `bus`. Must be called inside a tokio runtime.
    pub fn start(bus: &Bus, settings: SkillsSettings) -> Result<Skills, SkillsError> {
        if settings.workspaces.is_empty() {
            return Err(SkillsError::NoWorkspace);
        }
        let cancel = Arc::new(CancelFlag::default());
        let safety = settings.safety.clone();
        let runner = Runner::new(
            settings,
            bus.client(&robotd_topics::ARM_COMMAND)?,
            bus.client(&robotd_topics::GRIPPER_COMMAND)?,
            bus.client(&robotd_topics::WORKSPACE_QUERY)?,
            bus.publisher(&robotd_topics::SKILLS_PROGRESS)?,
            cancel.clone(),
        );
        let runner = Arc::new(tokio::sync::Mutex::new(runner));
        let mut server = bus.server(&robotd_topics::SKILLS_RUN)?;
        let serve = tokio::spawn(async move {
            let served = server
                .serve(move |request| {
                    let runner = runner.clone();
                    let safety = safety.clone();
                    async move {
                        // Approval first, outside the one-skill-at-a-time lock: nothing moves
                        // before a human said yes. Every run gets the policy's grant (a
                        // human's yes when the tool needs one); its arm and gripper commands
                        // carry it, so the policy knows they belong to a decided tool run.
                        let mut origin = current_origin();
                        let mut approval = None;
                        if let Some(safety) = &safety {
                            let summary = serde_json::to_string(&request.skill).unwrap_or_default();
                            match safety
                                .approve_tool(&origin, request.skill.tool_name(), &summary)
                                .await
                            {
                                Ok(id) => approval = Some(id),
                                Err(violation) => {
                                    return Ok(SkillReply::failed(SkillError::Refused {
                                        reason: violation.reason,
                                    }))
                                }
                            }
                        }
                        if let Some(id) = approval {
                            origin.approval_id = id;
                        }
                        let reply = with_origin(origin, async {
                            let mut runner = runner.lock().await;
                            runner.run(request.run_id, request.skill).await
                        })
                        .await;
                        if let (Some(safety), Some(id)) = (&safety, approval) {
                            safety.approvals().finish(id);
                        }
                        Ok(reply)
                    }
                })
                .await;
            if let Err(error) = served {
                tracing::error!(%error, "the skills actor stopped serving");
            }
        });
        let mut cancels = bus.subscriber(&robotd_topics::SKILLS_CANCEL)?;
        let stopper = bus.client(&robotd_topics::ARM_COMMAND)?;
        let canceller = tokio::spawn(async move {
            while let Ok(envelope) = cancels.recv().await {
                let run_id = envelope.body.run_id;
                if run_id == 0 {
                    continue;
                }
                if cancel.run_id.load(Ordering::SeqCst) != run_id {
                    // Waiting for approval or behind another skill: it must never start.
                    tracing::info!(
                        run_id,
                        "cancel for a skill that has not started: it will not run"
                    );
                    cancel.cancel_early(run_id);
                    continue;
                }
                cancel.cancelled.store(true, Ordering::SeqCst);
                tracing::info!(run_id, "skill cancelled: stopping the arm");
                match stopper
                    .request(&ArmCommand::Stop, Duration::from_secs(2))
                    .await
                {
                    Ok(reply) => tracing::debug!(?reply, "arm stopped"),
                    Err(error) => tracing::error!(%error, "could not stop the arm"),
                }
            }
        });
        Ok(Skills {
            server: serve,
            canceller,
        })
    }

    /// Stops serving (a running skill is abandoned; the arm actor keeps the arm safe).
    pub async fn shutdown(self) {
        self.server.abort();
        self.canceller.abort();
        let _ = self.server.await;
        let _ = self.canceller.await;
    }
}
