//! `robotd serve` sees: with the arm at the observation pose, the workspace model answers with
//! the default scene's objects, found in the camera's pixels, with stable ids; a query for a
//! view fresher than "now" waits for the next steady frame; `robotd bench perception --json`
//! reports its figures.

mod common;

use robotd_protocol::arm::{ArmCommand, ArmReply};
use robotd_protocol::envelope::unix_now_ns;
use robotd_protocol::location::{Location, WorkspacePoint};
use robotd_protocol::workspace::{WorkspaceQuery, WorkspaceReply, WorkspaceRequest};
use robotd_runtime::bus::{Bus, BusOptions};
use robotd_topics::{ARM_COMMAND, WORKSPACE_QUERY};
use std::process::Command;
use std::time::Duration;

#[test]
fn the_served_workspace_model_knows_the_default_scene_from_pixels() {
    let namespace = common::fresh_namespace("perc");
    let port = common::free_port();
    let _robotd = common::start_robotd(&namespace, port, &["--set", "robot.time_scale=0.05"]);

    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .unwrap();
    runtime.block_on(async {
        let bus = Bus::open(BusOptions::new(&namespace, "perception-test-client")).unwrap();
        let arm = bus.client(&ARM_COMMAND).unwrap();
        let workspace = bus.client(&WORKSPACE_QUERY).unwrap();
        assert!(arm.wait_for_server(Duration::from_secs(5)).await);
        assert!(workspace.wait_for_server(Duration::from_secs(5)).await);

        // Workspace questions need no camera.
        let reply = workspace
            .request(
                &WorkspaceQuery::now(WorkspaceRequest::GetWorkspacePoint {
                    workspace_id: "niryo_ws".into(),
                    point: WorkspacePoint::CenterPoint,
                }),
                Duration::from_secs(5),
            )
            .await
            .unwrap();
        let WorkspaceReply::Coordinate { coordinate } = reply else {
            panic!("{reply:?}");
        };
        assert!((coordinate.x_m - 0.25).abs() < 1e-9);

        let reply = arm
            .request(
                &ArmCommand::GoToObservationPose {
                    workspace_id: "niryo_ws".into(),
                },
                Duration::from_secs(20),
            )
            .await
            .unwrap();
        assert!(matches!(reply, ArmReply::Ok { .. }), "{reply:?}");

        // A view taken after now: the answer waits for the next steady frame.
        let all = || WorkspaceRequest::GetObjects {
            location: Location::None,
            coordinate: None,
            label: None,
        };
        let asked = unix_now_ns();
        let reply = workspace
            .request(
                &WorkspaceQuery {
                    request: all(),
                    fresh_after_unix_ns: Some(asked),
                    max_wait_ms: 3000,
                },
                Duration::from_secs(5),
            )
            .await
            .unwrap();
        let WorkspaceReply::Objects { objects } = reply else {
            panic!("{reply:?}");
        };
        let mut labels: Vec<&str> = objects.iter().map(|o| o.label.as_str()).collect();
        labels.sort();
        assert_eq!(
            labels,
            ["blue square", "green cylinder", "pencil", "red cube"],
            "{objects:#?}"
        );
        let pencil = objects.iter().find(|o| o.label == "pencil").unwrap();
        // config/scenes/default.toml: the pencil lies at (0.22, −0.05), along x, 120 mm long.
        assert!(
            (pencil.xy().x_m - 0.22).abs() < 0.003
                && (pencil.dimensions.height_m - 0.12).abs() < 0.006
                && (pencil.xy().y_m + 0.05).abs() < 0.003,
            "{pencil:?}"
        );
        assert!(pencil.timestamp_unix_s * 1e9 > asked as f64);

        // The same objects keep their ids from frame to frame: a view taken after this one
        // (1 ms after: a time in f64 seconds is only good to ~0.2 µs, so "1 ns after" could
        // name this very view again; frames come 66 ms apart).
        let again = workspace
            .request(
                &WorkspaceQuery {
                    request: all(),
                    fresh_after_unix_ns: Some((pencil.timestamp_unix_s * 1e9) as u64 + 1_000_000),
                    max_wait_ms: 3000,
                },
                Duration::from_secs(5),
            )
            .await
            .unwrap();
        let WorkspaceReply::Objects { objects: later } = again else {
            panic!("{again:?}");
        };
        let ids = |v: &[robotd_protocol::objects::DetectedObject]| {
            let mut ids: Vec<(String, String)> =
                v.iter().map(|o| (o.label.clone(), o.id.clone())).collect();
            ids.sort();
            ids
        };
        assert_eq!(ids(&objects), ids(&later));
        let seen_again = later.iter().find(|o| o.label == "pencil").unwrap();
        assert!(
            seen_again.timestamp_unix_s > pencil.timestamp_unix_s,
            "not a later view: {seen_again:?}"
        );

        // /health says the camera sees the workspace from its observation pose.
        let (code, body) = common::http_get(port, "/health");
        assert_eq!(code, 200);
        let health: serde_json::Value = serde_json::from_str(&body).unwrap();
        let view = &health["workspace_view"];
        assert_eq!(view["visible"], true, "{health:#}");
        assert_eq!(view["workspace_id"], "niryo_ws");
        assert_eq!(health["status"], "ok", "{health:#}");
    });
}

#[test]
fn bench_perception_json_reports_every_figure() {
    let output = Command::new(env!("CARGO_BIN_EXE_robotd"))
        .args([
            "bench",
            "perception",
            "--json",
            "--scenes",
            "5",
            "--bus-frames",
            "5",
        ])
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&output.stdout);
    assert!(
        output.status.success(),
        "{stdout}{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let figures: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    for key in [
        "fps_one_core",
        "pos_err_p95_mm",
        "recall",
        "frame_to_objects_ms_p50",
    ] {
        assert!(
            figures[key].as_f64().is_some_and(|v| v > 0.0),
            "{key} in {stdout}"
        );
    }
    assert_eq!(figures["false_positives"].as_u64(), Some(0), "{stdout}");
    assert_eq!(figures["recall"].as_f64(), Some(1.0), "{stdout}");
}
