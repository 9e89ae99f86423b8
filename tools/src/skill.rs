//! Running one skill on the skills actor, for the motion tools.
//!
//! [`run_skill`] sends the request, forwards the skill's progress to the call's hooks and
//! waits for the reply. Cancelling the call — or dropping it, when a client goes away
//! mid-motion — publishes a cancel for the run, which stops the arm.

use crate::schema::ObjectJson;
use crate::{CallHooks, Progress, Registry};
use robotd_protocol::objects::DetectedObject;
use robotd_protocol::skills::{Skill, SkillCancel, SkillReply, SkillRequest};
use robotd_protocol::{Location, Point2};
use schemars::JsonSchema;
use serde::Serialize;
use std::sync::atomic::Ordering;
use tokio::sync::mpsc;

/// How a skill call ended, other than success.
pub(crate) enum SkillFailure {
    /// The skill ran and failed; the reason a user can act on.
    Failed(String),
    /// The skills actor could not be asked at all.
    Unavailable(String),
}

impl SkillFailure {
    /// Why, in words.
    pub(crate) fn reason(&self) -> &str {
        match self {
            SkillFailure::Failed(r) | SkillFailure::Unavailable(r) => r,
        }
    }
}

/// The data of a motion tool: the object moved and where from and to.
#[derive(Debug, Serialize, JsonSchema)]
pub(crate) struct Motion {
    /// The object as it was before the motion, when the skill acted on one.
    #[schemars(with = "Option<ObjectJson>")]
    pub(crate) object: Option<DetectedObject>,
    /// Where the object (or gripper) started, `[x, y]` metres.
    pub(crate) from: Option<[f64; 2]>,
    /// Where it ended, `[x, y]` metres.
    pub(crate) to: Option<[f64; 2]>,
}

/// Publishes a cancel for the run when dropped before it finished (a client that went away
/// mid-motion stops the arm).
struct CancelOnDrop<'a> {
    registry: &'a Registry,
    run_id: u64,
    armed: bool,
}

impl CancelOnDrop<'_> {
    fn cancel(&mut self) {
        if !self.armed {
            return;
        }
        self.armed = false;
        let publisher = self
            .registry
            .inner
            .cancel
            .lock()
            .unwrap_or_else(|e| e.into_inner());
        if let Err(error) = publisher.publish(&SkillCancel {
            run_id: self.run_id,
        }) {
            tracing::error!(%error, run_id = self.run_id, "could not send a skill cancel");
        }
    }
}

impl Drop for CancelOnDrop<'_> {
    fn drop(&mut self) {
        self.registry
            .inner
            .progress_routes
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .remove(&self.run_id);
        self.cancel();
    }
}

/// Runs `skill` and waits for it, reporting progress and honouring cancellation.
pub(crate) async fn run_skill(
    registry: &Registry,
    skill: Skill,
    hooks: &CallHooks,
) -> Result<Motion, SkillFailure> {
    let inner = &registry.inner;
    let run_id = inner.next_run.fetch_add(1, Ordering::Relaxed);
    let (tx, mut progress) = mpsc::unbounded_channel();
    inner
        .progress_routes
        .lock()
        .unwrap_or_else(|e| e.into_inner())
        .insert(run_id, tx);
    let mut guard = CancelOnDrop {
        registry,
        run_id,
        armed: true,
    };
    let request = SkillRequest { run_id, skill };
    let reply = inner.skills.request(&request, inner.settings.skill_timeout);
    tokio::pin!(reply);
    let mut cancel_sent = false;
    let reply = loop {
        tokio::select! {
            reply = &mut reply => break reply,
            Some(p) = progress.recv() => {
                if let Some(report) = &hooks.progress {
                    report(Progress { step: p.step, total: p.total, message: p.message });
                }
            }
            _ = hooks.cancel.cancelled(), if !cancel_sent => {
                cancel_sent = true;
                tracing::info!(run_id, "tool call cancelled; stopping the skill");
                guard.cancel();
            }
        }
    };
    guard.armed = false;
    match reply {
        Ok(SkillReply::Done { object, from, to }) => Ok(Motion {
            object: object.map(|o| *o),
            from: from.map(point_xy),
            to: to.map(point_xy),
        }),
        Ok(SkillReply::Failed {
            error,
            still_held: None,
            ..
        }) => Err(SkillFailure::Failed(error.to_string())),
        Ok(SkillReply::Failed {
            error,
            still_held: Some(label),
            put_down_at,
        }) => Err(SkillFailure::Failed(match put_down_at {
            Some(p) => format!(
                "{error}; '{label}' is still held: put it down with place_object, e.g. at \
                 [{:.3}, {:.3}]",
                p.x_m, p.y_m
            ),
            None => format!("{error}; '{label}' is still held: put it down with place_object"),
        })),
        Err(error) => Err(SkillFailure::Unavailable(format!(
            "the skills actor did not answer: {error}"
        ))),
    }
}

fn point_xy(p: Point2) -> [f64; 2] {
    crate::tools::xy(p)
}

/// `" at"` or `" <location> coordinate"`, how placement replies name the target.
pub(crate) fn location_text(location: Location) -> String {
    match location {
        Location::None => " at".to_owned(),
        other => format!(" {other} coordinate"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn placement_is_worded_with_its_location() {
        assert_eq!(location_text(Location::None), " at");
        assert_eq!(
            location_text(Location::RightNextTo),
            " right next to coordinate"
        );
    }
}
