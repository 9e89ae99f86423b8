//! An actor configured to run as its own process: robotd starts it, and when it is killed
//! robotd cleans up its bus resources and restarts it; a request that was in flight gets an
//! error, never silence.

mod common;

use robotd_protocol::diagnostics::TestPatternRequest;
use robotd_runtime::bus::{Bus, BusError, BusOptions};
use robotd_topics::{HEALTH_RESTARTS, TEST_PATTERN};
use std::time::{Duration, Instant};

fn signal(pid: u32, signal: &str) {
    let status = std::process::Command::new("kill")
        .args([signal, &pid.to_string()])
        .status()
        .expect("kill");
    assert!(status.success());
}

#[test]
fn a_killed_actor_process_is_restarted_and_its_in_flight_request_fails() {
    let namespace = common::fresh_namespace("sup");
    let port = common::free_port();
    let config = std::env::temp_dir().join(format!("{namespace}.toml"));
    std::fs::write(
        &config,
        format!(
            "[actors.test_pattern]\nmode = \"process\"\ncommand = [{:?}]\nsupervision = {{ backoff_initial_ms = 20 }}\n",
            common::external_actor_binary().display().to_string()
        ),
    )
    .unwrap();
    let robotd = common::start_robotd(&namespace, port, &["--config", config.to_str().unwrap()]);

    let runtime = tokio::runtime::Runtime::new().unwrap();
    let actor_pid = runtime.block_on(async {
        let bus = Bus::open(BusOptions::new(&namespace, "e2e-test")).unwrap();
        let mut restarts = bus.subscriber(&HEALTH_RESTARTS).unwrap();
        let camera = bus.client(&TEST_PATTERN).unwrap();
        assert!(
            camera.wait_for_server(Duration::from_secs(15)).await,
            "robotd started the actor"
        );
        let request = TestPatternRequest {
            frame_id: 1,
            seed: 1,
        };
        let first = camera
            .request(&request, Duration::from_secs(5))
            .await
            .unwrap();
        let first_pid = first.served_by_pid;

        // A segment left half-created moments ago (empty, write-only), as by a process
        // killed while creating it: too young for the start-up sweep, so the supervisor
        // must take it for a corpse once its creator had time to finish.
        let young_corpse = std::path::Path::new("/dev/shm").join(format!(
            "iox2_robotd_test_young_corpse_{}",
            std::process::id()
        ));
        std::fs::write(&young_corpse, b"").unwrap();
        std::fs::set_permissions(
            &young_corpse,
            std::os::unix::fs::PermissionsExt::from_mode(0o200),
        )
        .unwrap();

        // Freeze the actor, send a request it will never answer, then kill it.
        signal(first_pid, "-STOP");
        let in_flight = {
            let started = Instant::now();
            let outcome = camera.request(&request, Duration::from_secs(10));
            tokio::pin!(outcome);
            // Its first poll sends the request (the frozen actor cannot answer it); the kill
            // comes once it is sent, not after a guessed while.
            tokio::select! {
                biased;
                early = &mut outcome => panic!("answered by a frozen actor: {early:?}"),
                () = std::future::ready(()) => signal(first_pid, "-KILL"),
            }
            (outcome.await, started.elapsed())
        };
        match in_flight {
            (Err(BusError::ServerLost { .. }), took) => {
                assert!(took < Duration::from_secs(3), "reported after {took:?}")
            }
            (other, took) => panic!("expected ServerLost, got {other:?} after {took:?}"),
        }

        // robotd restarts it; the same client reaches the new process.
        let deadline = Instant::now() + Duration::from_secs(15);
        let second = loop {
            match camera.request(&request, Duration::from_secs(2)).await {
                Ok(reply) => break reply,
                Err(_) if Instant::now() < deadline => {
                    tokio::time::sleep(Duration::from_millis(50)).await
                }
                Err(error) => panic!("the actor did not come back: {error}"),
            }
        };
        assert_ne!(second.served_by_pid, first_pid, "a new process serves");
        assert!(
            !young_corpse.exists(),
            "the restart's clean-up left the half-created segment"
        );

        // ...and told the bus about it.
        let event = tokio::time::timeout(Duration::from_secs(5), restarts.recv())
            .await
            .expect("a restart event within 5 s")
            .unwrap()
            .body;
        assert_eq!(event.actor, "test_pattern");
        assert_eq!(event.attempt, 1);
        assert!(!event.budget_exhausted);
        assert!(event.safe_state_ok, "the (empty) safe-state hook succeeded");
        second.served_by_pid
    });

    let (_, health) = common::http_get(port, "/health");
    let health: serde_json::Value = serde_json::from_str(&health).unwrap();
    let actor = health["actors"]
        .as_array()
        .and_then(|actors| actors.iter().find(|a| a["actor"] == "test_pattern"))
        .unwrap_or_else(|| panic!("no test_pattern actor in {health}"));
    assert_eq!(actor["restarts"], 1, "{health}");
    assert_eq!(actor["state"], "running", "{health}");
    let (_, metrics) = common::http_get(port, "/metrics");
    assert_eq!(
        common::metric(
            &metrics,
            "robotd_actor_restarts_total{actor=\"test_pattern\"}"
        ),
        Some(1.0),
        "{metrics}"
    );

    // If robotd itself is killed, its actor process does not live on as an orphan.
    signal(robotd.pid(), "-KILL");
    let gone = (0..100).any(|_| {
        std::thread::sleep(Duration::from_millis(20));
        !std::path::Path::new(&format!("/proc/{actor_pid}")).exists()
            || std::fs::read_to_string(format!("/proc/{actor_pid}/stat"))
                .map(|stat| stat.contains(") Z "))
                .unwrap_or(true)
    });
    assert!(gone, "actor process {actor_pid} outlived robotd");
    drop(robotd);
    let _ = std::fs::remove_file(&config);
}
