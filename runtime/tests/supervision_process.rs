//! Supervision of child processes: the same policy, budget, backoff, safe-state hook and
//! events as in-process actors, plus the restart-cleanup hook and killing children on stop.

use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use robotd_runtime::supervision::{
    safe_state_fn, CleanupContext, RestartPolicy, SpawnError, SupervisedState, SupervisionError,
    SupervisionEvent, SupervisionPolicy, Supervisor,
};
use tokio::process::Command;
use tokio::sync::mpsc::{unbounded_channel, UnboundedReceiver};

const WAIT: Duration = Duration::from_secs(2);

struct Events(UnboundedReceiver<SupervisionEvent>);

impl Events {
    async fn until(&mut self, stop: impl Fn(&SupervisionEvent) -> bool) -> Vec<SupervisionEvent> {
        let mut seen = Vec::new();
        loop {
            let event = tokio::time::timeout(WAIT, self.0.recv())
                .await
                .expect("timed out waiting for a supervision event")
                .expect("the supervisor dropped its observer");
            let done = stop(&event);
            seen.push(event);
            if done {
                return seen;
            }
        }
    }

    async fn until_kind(&mut self, kind: &str) -> Vec<SupervisionEvent> {
        self.until(|e| e.kind() == kind).await
    }
}

fn kinds(events: &[SupervisionEvent]) -> Vec<&'static str> {
    events.iter().map(SupervisionEvent::kind).collect()
}

fn sh(script: &'static str) -> impl Fn() -> Command + Send + Sync + 'static {
    move || {
        let mut command = Command::new("sh");
        command.arg("-c").arg(script);
        command
    }
}

fn alive(pid: u32) -> bool {
    // SAFETY: signal 0 only checks that the process exists.
    unsafe { libc::kill(pid as libc::pid_t, 0) == 0 }
}

fn policy(max_restarts: u32, initial_ms: u64, restart: RestartPolicy) -> SupervisionPolicy {
    SupervisionPolicy {
        max_restarts,
        window: Duration::from_secs(60),
        backoff_initial: Duration::from_millis(initial_ms),
        backoff_max: Duration::from_secs(1),
        backoff_multiplier: 2.0,
        restart,
    }
}

/// A supervisor whose hooks write to `log`.
fn supervisor(
    name: &str,
    policy: SupervisionPolicy,
    log: &Arc<Mutex<Vec<String>>>,
) -> (Supervisor, Events) {
    let (tx, rx) = unbounded_channel();
    let safe_log = log.clone();
    let cleanup_log = log.clone();
    let supervisor = Supervisor::new(name)
        .policy(policy)
        .observer(tx)
        .stop_timeout(Duration::from_millis(200))
        .safe_state(safe_state_fn(WAIT, move |reason: String| {
            let log = safe_log.clone();
            async move {
                log.lock().unwrap().push(format!("safe state: {reason}"));
                Ok(())
            }
        }))
        .on_restart_cleanup(move |dead: &CleanupContext| {
            cleanup_log
                .lock()
                .unwrap()
                .push(format!("cleanup {}: pid {:?}", dead.actor, dead.pid));
            Ok(())
        });
    (supervisor, Events(rx))
}

#[tokio::test]
async fn a_killed_child_is_made_safe_cleaned_up_and_restarted_after_its_backoff() {
    let log = Arc::new(Mutex::new(Vec::new()));
    let (supervisor, mut events) =
        supervisor("camera", policy(5, 50, RestartPolicy::Permanent), &log);
    let camera = supervisor.spawn_process(sh("exec sleep 30")).await.unwrap();
    let first = camera.pid().expect("a running child");
    assert!(alive(first));

    let killed = Instant::now();
    // SAFETY: sends SIGKILL to the child we just started.
    assert_eq!(
        unsafe { libc::kill(first as libc::pid_t, libc::SIGKILL) },
        0
    );
    let seen = events
        .until(|e| matches!(e, SupervisionEvent::Started { attempt: 1, .. }))
        .await;
    let took = killed.elapsed();
    assert_eq!(
        kinds(&seen),
        [
            "started",
            "failed",
            "safe_state",
            "cleanup",
            "restarted",
            "started"
        ]
    );
    assert!(matches!(
        &seen[1],
        SupervisionEvent::Failed { reason, .. } if reason == "killed by signal 9"
    ));
    assert!(matches!(
        &seen[3],
        SupervisionEvent::Cleanup { ok: true, .. }
    ));
    assert!(matches!(
        &seen[4],
        SupervisionEvent::Restarted { attempt: 1, backoff, .. } if *backoff == Duration::from_millis(50)
    ));
    assert!(
        took >= Duration::from_millis(50),
        "restarted after {took:?}"
    );

    assert_eq!(
        *log.lock().unwrap(),
        [
            "safe state: killed by signal 9".to_owned(),
            format!("cleanup camera: pid Some({first})"),
        ]
    );
    let second = camera.wait_running(WAIT).await.unwrap();
    assert_ne!(second, first);
    assert!(alive(second));
    assert_eq!(camera.state(), SupervisedState::Running { attempt: 1 });

    // An explicit stop kills the child and reports it; no safe state for a requested stop.
    camera.stop().await.unwrap();
    assert!(!alive(second));
    let seen = events.until_kind("stopped").await;
    assert_eq!(kinds(&seen), ["cleanup", "stopped"]);
    assert_eq!(camera.pid(), None);
}

#[tokio::test]
async fn a_crash_looping_child_exhausts_its_budget() {
    let log = Arc::new(Mutex::new(Vec::new()));
    let (supervisor, mut events) =
        supervisor("gripper", policy(2, 1, RestartPolicy::Permanent), &log);
    let gripper = supervisor.spawn_process(sh("exit 3")).await.unwrap();
    let seen = events.until_kind("budget_exhausted").await;
    let failures: Vec<_> = seen
        .iter()
        .filter_map(|e| match e {
            SupervisionEvent::Failed { reason, .. } => Some(reason.as_str()),
            _ => None,
        })
        .collect();
    assert_eq!(failures, ["exited with status 3"; 3]);
    assert_eq!(
        kinds(&seen).iter().filter(|k| **k == "restarted").count(),
        2
    );
    assert_eq!(
        &kinds(&seen)[seen.len() - 4..],
        ["failed", "safe_state", "cleanup", "budget_exhausted"]
    );
    assert!(matches!(
        gripper.wait_stopped().await,
        Err(SupervisionError::BudgetExhausted { restarts: 2, .. })
    ));
    assert_eq!(gripper.state(), SupervisedState::BudgetExhausted);
    // Every death was made safe and cleaned up, in that order.
    let log = log.lock().unwrap();
    assert_eq!(log.len(), 6);
    for pair in log.chunks(2) {
        assert!(
            pair[0].starts_with("safe state: exited with status 3"),
            "{pair:?}"
        );
        assert!(
            pair[1].starts_with("cleanup gripper: pid Some("),
            "{pair:?}"
        );
    }
}

#[tokio::test]
async fn a_transient_child_exiting_with_status_0_is_not_restarted() {
    let log = Arc::new(Mutex::new(Vec::new()));
    let (supervisor, mut events) =
        supervisor("homing", policy(5, 1, RestartPolicy::Transient), &log);
    let homing = supervisor.spawn_process(sh("exit 0")).await.unwrap();
    let seen = events.until_kind("stopped").await;
    assert_eq!(
        kinds(&seen),
        ["started", "safe_state", "cleanup", "stopped"]
    );
    assert_eq!(homing.wait_stopped().await, Ok(()));
    assert!(
        matches!(homing.state(), SupervisedState::Stopped { reason } if reason.contains("exited with status 0"))
    );
}

#[tokio::test]
async fn a_transient_child_failing_is_restarted() {
    let log = Arc::new(Mutex::new(Vec::new()));
    let (supervisor, mut events) =
        supervisor("homing", policy(1, 1, RestartPolicy::Transient), &log);
    let homing = supervisor.spawn_process(sh("exit 1")).await.unwrap();
    let seen = events.until_kind("budget_exhausted").await;
    assert_eq!(
        kinds(&seen).iter().filter(|k| **k == "restarted").count(),
        1
    );
    assert!(homing.wait_stopped().await.is_err());
}

#[tokio::test]
async fn a_child_that_cannot_be_spawned_is_a_spawn_error() {
    let err = Supervisor::new("tts")
        .spawn_process(|| Command::new("/nonexistent/robotd-tts"))
        .await
        .unwrap_err();
    let SpawnError::FirstStart { actor, reason } = &err;
    assert_eq!(actor, "tts");
    assert!(
        reason.contains("could not spawn `/nonexistent/robotd-tts`"),
        "{reason}"
    );
}

#[tokio::test]
async fn dropping_the_handle_kills_the_child() {
    let log = Arc::new(Mutex::new(Vec::new()));
    let (supervisor, mut events) =
        supervisor("camera", policy(5, 1, RestartPolicy::Permanent), &log);
    let camera = supervisor.spawn_process(sh("exec sleep 30")).await.unwrap();
    let pid = camera.pid().unwrap();
    drop(camera);
    let seen = events.until_kind("stopped").await;
    assert_eq!(kinds(&seen), ["started", "cleanup", "stopped"]);
    assert!(!alive(pid));
}

#[tokio::test]
async fn a_child_ignoring_sigterm_is_killed_after_the_stop_timeout() {
    // The child says "ready" through a FIFO once its trap is set, so the SIGTERM cannot come
    // before the trap.
    let fifo = std::env::temp_dir().join(format!("robotd-supervision-{}.fifo", std::process::id()));
    let _ = std::fs::remove_file(&fifo);
    let c_path = std::ffi::CString::new(fifo.to_str().unwrap()).unwrap();
    // SAFETY: `c_path` is a valid NUL-terminated path.
    assert_eq!(unsafe { libc::mkfifo(c_path.as_ptr(), 0o600) }, 0);

    let log = Arc::new(Mutex::new(Vec::new()));
    let (supervisor, _events) = supervisor("arm", policy(5, 1, RestartPolicy::Permanent), &log);
    let child_fifo = fifo.clone();
    // The loop's `sleep`s are short, so nothing outlives the test once `sh` is killed.
    let arm = supervisor
        .spawn_process(move || {
            let mut command = Command::new("sh");
            command
                .arg("-c")
                .arg(r#"trap '' TERM; echo ready > "$READY"; while :; do sleep 0.05; done"#)
                .env("READY", &child_fifo);
            command
        })
        .await
        .unwrap();
    let reader = tokio::task::spawn_blocking({
        let fifo = fifo.clone();
        move || std::fs::read_to_string(fifo)
    });
    let ready = tokio::time::timeout(WAIT, reader)
        .await
        .expect("the child never said it was ready")
        .unwrap()
        .unwrap();
    assert_eq!(ready.trim(), "ready");
    std::fs::remove_file(&fifo).unwrap();

    let pid = arm.pid().unwrap();
    let stopping = Instant::now();
    arm.stop().await.unwrap();
    let took = stopping.elapsed();
    assert!(!alive(pid));
    assert!(
        took >= Duration::from_millis(200) && took < WAIT,
        "stop took {took:?}"
    );
}
