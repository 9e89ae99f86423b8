//! The supervisors' side of `/health`: a board of every supervised actor's state, kept current
//! by their supervision events, and the bridge that publishes each restart on the bus
//! (`health/restarts`).

use robotd_config::Config;
use robotd_protocol::health::{ActorHealth, ActorState, RestartEvent};
use robotd_runtime::bus::Publisher;
use robotd_runtime::supervision::{observer_fn, SupervisionEvent, SupervisionObserver};
use std::collections::BTreeMap;
use std::sync::{Arc, Mutex};
use std::time::Instant;

/// What /health says about the robot.
pub struct RobotInfo {
    pub model: String,
    pub scene: String,
}

/// Health of every supervised actor, kept current by the supervisors' events.
#[derive(Default)]
pub struct HealthBoard {
    actors: Mutex<BTreeMap<String, ActorHealth>>,
}

impl HealthBoard {
    pub fn apply(&self, event: &SupervisionEvent) {
        let Ok(mut actors) = self.actors.lock() else {
            return;
        };
        let entry = actors
            .entry(event.actor().to_owned())
            .or_insert_with(|| ActorHealth::new(event.actor(), ActorState::Starting));
        match event {
            SupervisionEvent::Started { .. } => entry.state = ActorState::Running,
            SupervisionEvent::Failed { reason, .. } => {
                entry.state = ActorState::SafeState;
                entry.last_error = Some(reason.clone());
            }
            SupervisionEvent::SafeState { .. } | SupervisionEvent::Cleanup { .. } => {
                entry.state = ActorState::Restarting
            }
            SupervisionEvent::Restarted { .. } => entry.restarts += 1,
            SupervisionEvent::BudgetExhausted { .. } => entry.state = ActorState::Failed,
            SupervisionEvent::Stopped { .. } => entry.state = ActorState::Stopped,
        }
    }

    pub fn report(
        &self,
        config: &Config,
        robot: &RobotInfo,
        started: Instant,
    ) -> serde_json::Value {
        let actors: Vec<ActorHealth> = self
            .actors
            .lock()
            .map(|a| a.values().cloned().collect())
            .unwrap_or_default();
        let all_up = actors.iter().all(|a| a.state == ActorState::Running);
        // The robot can be used when its arm, gripper and camera actors all run.
        let robot_available = ["arm", "gripper", "camera"].iter().all(|name| {
            actors
                .iter()
                .any(|a| a.actor == *name && a.state == ActorState::Running)
        });
        serde_json::json!({
            "status": if all_up { "ok" } else { "degraded" },
            "service": config.service.name,
            "version": env!("CARGO_PKG_VERSION"),
            "pid": std::process::id(),
            "uptime_ms": started.elapsed().as_millis() as u64,
            "bus_namespace": config.bus.namespace,
            "robot": {
                "driver": config.robot.driver,
                "available": robot_available,
                "model": robot.model,
                "scene": robot.scene,
            },
            "actors": actors,
        })
    }
}

/// Turns a supervision event into the bus's restart event, when it is one. `safe_state_ok` is
/// the outcome of the safe-state hook that ran before this restart.
fn restart_event(event: &SupervisionEvent, safe_state_ok: bool) -> Option<RestartEvent> {
    match event {
        SupervisionEvent::Restarted {
            actor,
            attempt,
            backoff,
        } => Some(RestartEvent {
            actor: actor.clone(),
            attempt: *attempt,
            reason: "restarted after a failure".into(),
            backoff_ms: backoff.as_millis() as u64,
            safe_state_ok,
            budget_exhausted: false,
        }),
        SupervisionEvent::BudgetExhausted {
            actor, restarts, ..
        } => Some(RestartEvent {
            actor: actor.clone(),
            attempt: *restarts,
            reason: event.to_string(),
            backoff_ms: 0,
            safe_state_ok,
            budget_exhausted: true,
        }),
        _ => None,
    }
}

/// The observer of one supervised actor: keeps the health board current, and publishes every
/// restart (with the outcome of the safe-state hook before it) on `health/restarts`.
pub fn supervision_observer(
    board: Arc<HealthBoard>,
    publisher: Arc<Mutex<Publisher<RestartEvent>>>,
) -> impl SupervisionObserver {
    let last_safe_state_ok = std::sync::atomic::AtomicBool::new(true);
    observer_fn(move |event: &SupervisionEvent| {
        board.apply(event);
        if let SupervisionEvent::SafeState { ok, .. } = event {
            last_safe_state_ok.store(*ok, std::sync::atomic::Ordering::Relaxed);
        }
        let safe_state_ok = last_safe_state_ok.load(std::sync::atomic::Ordering::Relaxed);
        if let Some(restart) = restart_event(event, safe_state_ok) {
            if let Ok(publisher) = publisher.lock() {
                if let Err(error) = publisher.publish(&restart) {
                    tracing::warn!(%error, "publishing a restart event");
                }
            }
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn started(actor: &str) -> SupervisionEvent {
        SupervisionEvent::Started {
            actor: actor.into(),
            attempt: 0,
        }
    }

    #[test]
    fn the_robot_is_available_only_while_arm_gripper_and_camera_run() {
        let board = HealthBoard::default();
        let robot = RobotInfo {
            model: "Niryo Ned2".into(),
            scene: "default".into(),
        };
        let config = Config::default();
        let available = |board: &HealthBoard| {
            board.report(&config, &robot, Instant::now())["robot"]["available"].clone()
        };
        board.apply(&started("arm"));
        board.apply(&started("gripper"));
        assert_eq!(available(&board), false, "the camera has not started yet");
        board.apply(&started("camera"));
        board.apply(&started("tts"));
        assert_eq!(available(&board), true);
        board.apply(&SupervisionEvent::Failed {
            actor: "arm".into(),
            reason: "driver crashed".into(),
        });
        assert_eq!(available(&board), false, "the arm is in its safe state");
        board.apply(&started("arm"));
        board.apply(&SupervisionEvent::Failed {
            actor: "tts".into(),
            reason: "espeak-ng died".into(),
        });
        assert_eq!(available(&board), true, "speech is not the robot");
    }
}
