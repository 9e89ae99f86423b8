//! The workspace model on a real bus: fresh-view queries wait for a steady view, time out
//! with a clear error when none comes, and other queries are answered meanwhile.

use robotd_protocol::envelope::unix_now_ns;
use robotd_protocol::geometry::{Point2, Point3, Pose, RobotModel};
use robotd_protocol::location::Location;
use robotd_protocol::objects::{DetectedObject, Detections};
use robotd_protocol::workspace::{
    TrackedObjects, WorkspaceError, WorkspaceInfo, WorkspaceQuery, WorkspaceReply, WorkspaceRequest,
};
use robotd_runtime::bus::{Bus, BusOptions};
use robotd_runtime::catalog::{PERCEPTION_DETECTIONS, WORKSPACE_OBJECTS, WORKSPACE_QUERY};
use robotd_workspace_model::{MemorySettings, WorkspaceModel, WorkspaceModelSettings};
use std::time::{Duration, Instant};

fn niryo() -> WorkspaceInfo {
    WorkspaceInfo {
        id: "niryo_ws".into(),
        robot: RobotModel::Ned2,
        upper_left: Point2::new(0.337, 0.087),
        lower_right: Point2::new(0.163, -0.087),
        observation_pose: Pose::new(0.173, -0.002, 0.277, -3.042, 1.327, -3.027),
    }
}

fn cube(x: f64, y: f64) -> DetectedObject {
    let mut o = DetectedObject {
        label: "red cube".into(),
        ..Default::default()
    };
    o.position.center_of_mass = Point3::new(x, y, 0.015);
    o.dimensions.width_m = 0.03;
    o.dimensions.height_m = 0.03;
    o.dimensions.size_m2 = 0.0009;
    o
}

fn all() -> WorkspaceRequest {
    WorkspaceRequest::GetObjects {
        location: Location::None,
        coordinate: None,
        label: None,
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn fresh_queries_wait_for_a_steady_view_or_time_out() {
    let namespace = format!("test-wsm-{}", std::process::id());
    let bus = Bus::open(BusOptions::new(&namespace, "workspace-model-test")).unwrap();
    let model = WorkspaceModel::start(
        &bus,
        WorkspaceModelSettings {
            workspaces: vec![niryo()],
            labels: vec!["red cube".into()],
            builtin_labels: vec!["red cube".into()],
            memory: MemorySettings::default(),
            default_fresh_wait: Duration::from_secs(2),
        },
    )
    .unwrap();
    let client = bus.client(&WORKSPACE_QUERY).unwrap();
    assert!(client.wait_for_server(Duration::from_secs(5)).await);
    let detections = bus.publisher(&PERCEPTION_DETECTIONS).unwrap();
    let mut objects = bus.subscriber(&WORKSPACE_OBJECTS).unwrap();

    // No camera: a fresh-view query fails after its wait, saying why.
    let started = Instant::now();
    let reply = client
        .request(
            &WorkspaceQuery {
                request: all(),
                fresh_after_unix_ns: Some(unix_now_ns()),
                max_wait_ms: 200,
            },
            Duration::from_secs(5),
        )
        .await
        .unwrap();
    let waited = started.elapsed();
    match reply {
        WorkspaceReply::Error {
            error: WorkspaceError::NoFreshDetection { reason },
        } => assert!(reason.contains("observation pose"), "{reason}"),
        other => panic!("{other:?}"),
    }
    assert!(waited >= Duration::from_millis(190), "{waited:?}");

    // A fresh query waits; meanwhile an ordinary one is answered at once; then a steady view
    // arrives and the waiting query gets it.
    let asked = unix_now_ns();
    let waiting = {
        let client = bus.client(&WORKSPACE_QUERY).unwrap();
        tokio::spawn(async move {
            client
                .request(
                    &WorkspaceQuery {
                        request: all(),
                        fresh_after_unix_ns: Some(asked),
                        max_wait_ms: 3000,
                    },
                    Duration::from_secs(5),
                )
                .await
        })
    };
    tokio::time::sleep(Duration::from_millis(100)).await;
    let now = client
        .request(&WorkspaceQuery::now(all()), Duration::from_secs(1))
        .await
        .unwrap();
    assert_eq!(now, WorkspaceReply::Objects { objects: vec![] });
    assert!(!waiting.is_finished(), "answered before any view arrived");

    // A view taken while the arm moved does not count.
    let mut view = Detections {
        frame_id: 1,
        workspace_id: "niryo_ws".into(),
        timestamp_unix_ns: unix_now_ns(),
        source: "robotd".into(),
        steady: false,
        objects: vec![cube(0.3, 0.05)],
    };
    detections.publish(&view).unwrap();
    tokio::time::sleep(Duration::from_millis(100)).await;
    assert!(
        !waiting.is_finished(),
        "answered from a view taken during a motion"
    );

    view.frame_id = 2;
    view.steady = true;
    view.timestamp_unix_ns = unix_now_ns();
    detections.publish(&view).unwrap();
    let reply = tokio::time::timeout(Duration::from_secs(5), waiting)
        .await
        .unwrap()
        .unwrap()
        .unwrap();
    let WorkspaceReply::Objects { objects: found } = reply else {
        panic!("{reply:?}");
    };
    assert_eq!(found.len(), 1);
    assert_eq!(found[0].id, "obj-1");

    // The applied view is also published with its frame id.
    let tracked: TrackedObjects = loop {
        let msg = tokio::time::timeout(Duration::from_secs(2), objects.recv())
            .await
            .unwrap()
            .unwrap();
        if msg.body.frame_id == 2 {
            break msg.body;
        }
    };
    assert_eq!(tracked.objects[0].id, "obj-1");
    model.shutdown().await;
}
