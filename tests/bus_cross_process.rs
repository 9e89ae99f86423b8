//! Location transparency: an actor in its own process joins a running robotd's bus, calls
//! robotd, serves requests and publishes a frame that a third process reads in place.

mod common;

use robotd_protocol::diagnostics::TestPatternRequest;
use robotd_runtime::bus::{Bus, BusOptions, FRAME_BYTES};
use robotd_topics::{TEST_PATTERN, TEST_PATTERN_FRAMES};
use std::time::Duration;

#[test]
fn an_external_actor_joins_robotd_and_exchanges_requests_and_a_frame() {
    let namespace = common::fresh_namespace("xproc");
    let port = common::free_port();
    let robotd = common::start_robotd(&namespace, port, &[]);
    let actor = common::start_external_actor(&namespace);

    let runtime = tokio::runtime::Runtime::new().unwrap();
    runtime.block_on(async {
        let bus = Bus::open(BusOptions::new(&namespace, "e2e-test")).unwrap();
        let mut frames = bus.frame_subscriber(&TEST_PATTERN_FRAMES).unwrap();
        let camera = bus.client(&TEST_PATTERN).unwrap();
        assert!(camera.wait_for_server(Duration::from_secs(10)).await);

        for frame_id in [7u64, 8] {
            let seed = frame_id as u8;
            let reply = camera
                .request(
                    &TestPatternRequest { frame_id, seed },
                    Duration::from_secs(5),
                )
                .await
                .unwrap();
            assert_eq!(reply.frame_id, frame_id);
            assert_eq!(
                reply.served_by_pid,
                actor.pid(),
                "served by the actor's process"
            );
            assert!(reply.delivered_to >= 1, "our frame subscriber got it");
            assert!(
                reply
                    .robotd_said
                    .contains(&format!("robotd pid {}", robotd.pid())),
                "the actor reached robotd's own service: {}",
                reply.robotd_said
            );

            let frame = tokio::time::timeout(Duration::from_secs(5), frames.recv())
                .await
                .expect("a frame within 5 s")
                .unwrap();
            assert_eq!(frame.header().frame_id, frame_id);
            assert_eq!(frame.pixels().len(), FRAME_BYTES);
            let pixels = frame.pixels();
            for i in (0..FRAME_BYTES).step_by(997) {
                assert_eq!(pixels[i], ((i + seed as usize) % 251) as u8, "pixel {i}");
            }
        }
    });

    // robotd answered the actor's ping and counted it.
    let (status, metrics) = common::http_get(port, "/metrics");
    assert_eq!(status, 200);
    let received = common::metric(
        &metrics,
        "robotd_bus_messages_total{topic=\"system/ping/requests\",direction=\"received\"}",
    );
    assert_eq!(received, Some(1.0), "{metrics}");
    let (status, health) = common::http_get(port, "/health");
    assert_eq!(status, 200, "{health}");
    let health: serde_json::Value = serde_json::from_str(&health).unwrap();
    assert_eq!(health["pid"], robotd.pid());
}
