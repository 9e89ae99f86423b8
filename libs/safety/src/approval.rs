//! Approval: motions that wait for a human's yes.
//!
//! A tool listed in `[safety] approval_tools` (or any motion in `supervised` mode) is held
//! before anything moves: [`Approvals::ask`] puts a request in the queue and waits. A human
//! answers it through robotd's HTTP API (`GET /approvals`, `POST /approvals/{id}`), the
//! dashboard or the bus. No answer within the timeout is a refusal; so is a denial. Nothing
//! moves before the yes.
//!
//! An approval id is random (64 bits) and stays valid while the approved work runs, so the
//! arm can check that a motion claiming an approval really has one.

use robotd_protocol::safety::Origin;
use serde::Serialize;
use std::collections::HashMap;
use std::hash::{BuildHasher, Hasher};
use std::sync::Mutex;
use std::time::Duration;
use tokio::sync::oneshot;

/// One request waiting for a human.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ApprovalRequest {
    /// Its id (answer with it).
    pub id: u64,
    /// Who asked.
    pub origin: Origin,
    /// The tool or command, e.g. `push_object`.
    pub action: String,
    /// What would happen, in words.
    pub summary: String,
    /// When it was asked, ns since the Unix epoch.
    pub asked_at_unix_ns: u64,
    /// When it will be refused unless answered, ns since the Unix epoch.
    pub expires_at_unix_ns: u64,
}

/// Why a request was not approved.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum NotApproved {
    /// A human said no.
    #[error("denied by {by}")]
    Denied {
        /// Who denied it.
        by: String,
    },
    /// Nobody answered in time.
    #[error("nobody approved it within {after_s} s")]
    TimedOut {
        /// The timeout, seconds.
        after_s: u64,
    },
}

/// Why an answer was not taken.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum AnswerError {
    /// No request with this id is waiting (answered, timed out or never asked).
    #[error("no approval request {id} is waiting (already answered, timed out, or unknown)")]
    NotWaiting {
        /// The id given.
        id: u64,
    },
}

struct Waiting {
    request: ApprovalRequest,
    answer: oneshot::Sender<Result<(), String>>,
}

/// The approval queue, shared by everything that moves.
#[derive(Default)]
pub struct Approvals {
    waiting: Mutex<HashMap<u64, Waiting>>,
    granted: Mutex<HashMap<u64, String>>,
}

impl std::fmt::Debug for Approvals {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Approvals")
            .field("waiting", &self.pending().len())
            .finish()
    }
}

impl Approvals {
    /// Queues `action` for approval and waits up to `timeout` for the answer. `Ok(id)` once
    /// approved: the id stays granted until [`Approvals::finish`].
    pub async fn ask(
        &self,
        origin: &Origin,
        action: &str,
        summary: &str,
        timeout: Duration,
    ) -> Result<u64, NotApproved> {
        let id = random_id();
        let now = robotd_protocol::envelope::unix_now_ns();
        let request = ApprovalRequest {
            id,
            origin: origin.clone(),
            action: action.to_owned(),
            summary: summary.to_owned(),
            asked_at_unix_ns: now,
            expires_at_unix_ns: now.saturating_add(timeout.as_nanos() as u64),
        };
        let (tx, rx) = oneshot::channel();
        tracing::warn!(id, %origin, action, summary, "waiting for a human's approval");
        self.lock_waiting().insert(
            id,
            Waiting {
                request,
                answer: tx,
            },
        );
        let answer = tokio::time::timeout(timeout, rx).await;
        self.lock_waiting().remove(&id);
        match answer {
            Ok(Ok(Ok(()))) => {
                self.lock_granted().insert(id, action.to_owned());
                Ok(id)
            }
            Ok(Ok(Err(by))) => Err(NotApproved::Denied { by }),
            Ok(Err(_)) | Err(_) => Err(NotApproved::TimedOut {
                after_s: timeout.as_secs(),
            }),
        }
    }

    /// Answers request `id`: approve or deny, by whom.
    pub fn answer(&self, id: u64, approve: bool, by: &str) -> Result<(), AnswerError> {
        let waiting = self
            .lock_waiting()
            .remove(&id)
            .ok_or(AnswerError::NotWaiting { id })?;
        tracing::warn!(id, approve, by, action = %waiting.request.action, "approval answered");
        let answer = if approve { Ok(()) } else { Err(by.to_owned()) };
        waiting
            .answer
            .send(answer)
            .map_err(|_| AnswerError::NotWaiting { id })
    }

    /// The requests waiting, oldest first.
    pub fn pending(&self) -> Vec<ApprovalRequest> {
        let mut list: Vec<_> = self
            .lock_waiting()
            .values()
            .map(|w| w.request.clone())
            .collect();
        list.sort_by_key(|r| r.asked_at_unix_ns);
        list
    }

    /// Whether approval `id` was granted and its work has not finished.
    pub fn is_granted(&self, id: u64) -> bool {
        id != 0 && self.lock_granted().contains_key(&id)
    }

    /// Grants `action` (a tool the policy lets run without a human) a fresh id without
    /// asking anyone: the tool run's token, valid until [`Approvals::finish`]. The arm and
    /// gripper commands the run sends carry it, so the policy knows they belong to a tool
    /// whose approval it already decided.
    pub fn grant(&self, action: &str) -> u64 {
        let id = random_id();
        self.lock_granted().insert(id, action.to_owned());
        id
    }

    /// The approved work ended: the id no longer admits motions.
    pub fn finish(&self, id: u64) {
        self.lock_granted().remove(&id);
    }

    fn lock_waiting(&self) -> std::sync::MutexGuard<'_, HashMap<u64, Waiting>> {
        self.waiting.lock().unwrap_or_else(|e| e.into_inner())
    }

    fn lock_granted(&self) -> std::sync::MutexGuard<'_, HashMap<u64, String>> {
        self.granted.lock().unwrap_or_else(|e| e.into_inner())
    }
}

/// The arm and gripper commands (their audit `action` names) each motion tool sends, through
/// the skills actor. A command that arrives without a tool run's grant (a client talking to
/// `arm/command` or `gripper/command` directly) needs a human's approval when a tool listed
/// in `approval_tools` could have sent it: the policy cannot tell which tool a bare command
/// serves, so it takes the strictest. A command's own name may be listed too
/// (`"move_joints"`).
pub const TOOL_ACTIONS: &[(&str, &[&str])] = &[
    ("pick_object", MOTIONS),
    ("place_object", MOTIONS),
    ("pick_place_object", MOTIONS),
    ("push_object", MOTIONS),
    ("move2by", MOTIONS),
    ("move2observation_pose", &["go_to_observation_pose"]),
    ("calibrate", &["calibrate"]),
    ("clear_collision_detected", &["clear_collision"]),
];

/// The commands a pick, place, push or move-by is made of.
const MOTIONS: &[&str] = &[
    "move_to_pose",
    "shift_pose",
    "move_joints",
    "go_to_observation_pose",
    "open",
    "close",
    "set_width",
];

/// Whether a bare command `action` (not part of a granted tool run) needs a human's approval
/// under `approval_tools`: see [`TOOL_ACTIONS`].
pub fn bare_command_needs_approval(approval_tools: &[String], action: &str) -> bool {
    approval_tools.iter().any(|tool| {
        tool == action
            || TOOL_ACTIONS
                .iter()
                .any(|(name, actions)| name == tool && actions.contains(&action))
    })
}

/// A random non-zero id (SipHash with the process's random keys over the time and a counter).
fn random_id() -> u64 {
    static COUNTER: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    let mut hasher = std::collections::hash_map::RandomState::new().build_hasher();
    hasher.write_u64(robotd_protocol::envelope::unix_now_ns());
    hasher.write_u64(COUNTER.fetch_add(1, std::sync::atomic::Ordering::Relaxed));
    hasher.finish().max(1)
}

#[cfg(test)]
mod tests {
    use super::*;
    use robotd_protocol::safety::OriginKind;
    use std::sync::Arc;

    #[tokio::test]
    async fn approve_deny_and_time_out() {
        let approvals = Arc::new(Approvals::default());
        let origin = Origin::new(OriginKind::Mcp);
        let asker = approvals.clone();
        let o = origin.clone();
        let waiting = tokio::spawn(async move {
            asker
                .ask(
                    &o,
                    "push_object",
                    "push 'cube' up 3 cm",
                    Duration::from_secs(5),
                )
                .await
        });
        let id = loop {
            if let Some(r) = approvals.pending().first() {
                break r.id;
            }
            tokio::task::yield_now().await;
        };
        approvals.answer(id, true, "alice").unwrap();
        assert_eq!(waiting.await.unwrap(), Ok(id));
        assert!(approvals.is_granted(id));
        approvals.finish(id);
        assert!(!approvals.is_granted(id));
        assert_eq!(
            approvals.answer(id, true, "alice"),
            Err(AnswerError::NotWaiting { id })
        );

        let asker = approvals.clone();
        let o = origin.clone();
        let waiting = tokio::spawn(async move {
            asker
                .ask(&o, "pick_object", "", Duration::from_secs(5))
                .await
        });
        let id = loop {
            if let Some(r) = approvals.pending().first() {
                break r.id;
            }
            tokio::task::yield_now().await;
        };
        approvals.answer(id, false, "bob").unwrap();
        assert_eq!(
            waiting.await.unwrap(),
            Err(NotApproved::Denied { by: "bob".into() })
        );
    }

    #[test]
    fn a_bare_command_needs_approval_when_a_listed_tool_could_have_sent_it() {
        let listed = |tools: &[&str]| tools.iter().map(|t| t.to_string()).collect::<Vec<_>>();
        let push = listed(&["push_object"]);
        for action in [
            "move_to_pose",
            "shift_pose",
            "close",
            "go_to_observation_pose",
        ] {
            assert!(bare_command_needs_approval(&push, action), "{action}");
        }
        assert!(!bare_command_needs_approval(&push, "calibrate"));
        assert!(!bare_command_needs_approval(&push, "clear_collision"));
        let observe = listed(&["move2observation_pose"]);
        assert!(bare_command_needs_approval(
            &observe,
            "go_to_observation_pose"
        ));
        assert!(!bare_command_needs_approval(&observe, "move_to_pose"));
        // A command's own name may be listed.
        assert!(bare_command_needs_approval(
            &listed(&["move_joints"]),
            "move_joints"
        ));
        assert!(!bare_command_needs_approval(&[], "move_joints"));
    }

    #[test]
    fn a_grant_is_valid_until_its_work_finishes() {
        let approvals = Approvals::default();
        let id = approvals.grant("pick_object");
        assert!(approvals.is_granted(id));
        assert!(approvals.pending().is_empty(), "nobody was asked");
        approvals.finish(id);
        assert!(!approvals.is_granted(id));
    }

    #[tokio::test(start_paused = true)]
    async fn no_answer_is_a_refusal() {
        let approvals = Approvals::default();
        let result = approvals
            .ask(
                &Origin::default(),
                "push_object",
                "",
                Duration::from_secs(30),
            )
            .await;
        assert_eq!(result, Err(NotApproved::TimedOut { after_s: 30 }));
        assert!(approvals.pending().is_empty());
    }
}
