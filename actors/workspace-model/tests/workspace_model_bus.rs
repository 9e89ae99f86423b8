//! The workspace model on a real bus: ids stay stable over 100 noisy frames, missing objects
//! expire, picks and places are followed, unknown workspaces and bad queries get clear errors,
//! label additions are published, and fresh-view queries wait for a steady view (answered at
//! once when there is one, timing out with the reason when none comes; waiting for one more
//! view when the first showed a new object that a second view must confirm) while other
//! queries are answered meanwhile.

use robotd_protocol::envelope::unix_now_ns;
use robotd_protocol::geometry::{Point2, Point3, Pose, RobotModel};
use robotd_protocol::location::Location;
use robotd_protocol::location::WorkspacePoint;
use robotd_protocol::objects::{DetectedObject, Detections};
use robotd_protocol::workspace::{
    DetectableLabels, TrackedObjects, WorkspaceError, WorkspaceInfo, WorkspaceQuery,
    WorkspaceReply, WorkspaceRequest,
};
use robotd_runtime::bus::{Bus, BusOptions, Client, Publisher, Subscriber};
use robotd_topics::{PERCEPTION_DETECTIONS, WORKSPACE_LABELS, WORKSPACE_OBJECTS, WORKSPACE_QUERY};
use robotd_workspace_model::{
    MemorySettings, WorkspaceModel, WorkspaceModelSettings, WorkspaceStartError,
};
use std::sync::atomic::{AtomicU32, Ordering};
use std::time::{Duration, Instant};

const TIMEOUT: Duration = Duration::from_secs(5);

/// A bus of its own for each test (tests of one binary share the process id).
fn open_bus(test: &str) -> Bus {
    static COUNTER: AtomicU32 = AtomicU32::new(0);
    let namespace = format!(
        "test-wsm-{}-{}-{test}",
        std::process::id(),
        COUNTER.fetch_add(1, Ordering::Relaxed)
    );
    Bus::open(BusOptions::new(&namespace, "workspace-model-test")).unwrap()
}

fn niryo() -> WorkspaceInfo {
    robotd_protocol::workspace::builtin_workspaces(RobotModel::Ned2)[0].to_info(RobotModel::Ned2)
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
    let bus = open_bus("fresh");
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

    // The first steady view shows a cube never seen before: one more view must agree before it
    // is reported, so the query waits for that one too.
    view.frame_id = 2;
    view.steady = true;
    view.timestamp_unix_ns = unix_now_ns();
    detections.publish(&view).unwrap();
    tokio::time::sleep(Duration::from_millis(100)).await;
    assert!(
        !waiting.is_finished(),
        "answered before a second view could confirm the new cube"
    );
    view.frame_id = 3;
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
        if msg.body.frame_id == 3 {
            break msg.body;
        }
    };
    assert_eq!(tracked.objects[0].id, "obj-1");
    model.shutdown().await;
}

fn object(label: &str, x: f64, y: f64, side_m: f64) -> DetectedObject {
    let mut o = DetectedObject {
        label: label.into(),
        ..Default::default()
    };
    o.position.center_of_mass = Point3::new(x, y, 0.01);
    o.position.center = o.position.center_of_mass;
    o.dimensions.width_m = side_m;
    o.dimensions.height_m = side_m;
    o.dimensions.size_m2 = side_m * side_m;
    o
}

/// A running model with a client, a detections publisher and an objects subscriber.
struct Rig {
    bus: Bus,
    model: WorkspaceModel,
    client: Client<WorkspaceQuery, WorkspaceReply>,
    detections: Publisher<Detections>,
    objects: Subscriber<TrackedObjects>,
    frame_id: u64,
}

impl Rig {
    async fn start(test: &str, workspaces: Vec<WorkspaceInfo>) -> Rig {
        let bus = open_bus(test);
        let model = WorkspaceModel::start(
            &bus,
            WorkspaceModelSettings {
                workspaces,
                labels: vec!["pencil".into()],
                builtin_labels: vec!["pencil".into(), "red cube".into()],
                memory: MemorySettings::default(),
                default_fresh_wait: Duration::from_secs(2),
            },
        )
        .unwrap();
        let client = bus.client(&WORKSPACE_QUERY).unwrap();
        assert!(client.wait_for_server(TIMEOUT).await);
        let detections = bus.publisher(&PERCEPTION_DETECTIONS).unwrap();
        let objects = bus.subscriber(&WORKSPACE_OBJECTS).unwrap();
        Rig {
            bus,
            model,
            client,
            detections,
            objects,
            frame_id: 0,
        }
    }

    /// Publishes a steady view of `workspace_id` and waits until the model has applied it.
    async fn view(&mut self, workspace_id: &str, objects: Vec<DetectedObject>) -> TrackedObjects {
        self.frame_id += 1;
        let frame_id = self.frame_id;
        self.detections
            .publish(&Detections {
                frame_id,
                workspace_id: workspace_id.into(),
                timestamp_unix_ns: unix_now_ns(),
                source: "robotd".into(),
                steady: true,
                objects,
            })
            .unwrap();
        loop {
            let msg = tokio::time::timeout(TIMEOUT, self.objects.recv())
                .await
                .unwrap_or_else(|_| panic!("frame {frame_id} was not applied"))
                .unwrap();
            if msg.body.frame_id == frame_id {
                return msg.body;
            }
        }
    }

    async fn ask(&self, request: WorkspaceRequest) -> WorkspaceReply {
        self.client
            .request(&WorkspaceQuery::now(request), TIMEOUT)
            .await
            .unwrap()
    }

    async fn objects(&self) -> Vec<DetectedObject> {
        match self.ask(all()).await {
            WorkspaceReply::Objects { objects } => objects,
            other => panic!("{other:?}"),
        }
    }
}

fn ids(objects: &[DetectedObject]) -> Vec<(String, String)> {
    let mut v: Vec<(String, String)> = objects
        .iter()
        .map(|o| (o.id.clone(), o.label.clone()))
        .collect();
    v.sort();
    v
}

fn pairs(v: &[(&str, &str)]) -> Vec<(String, String)> {
    v.iter()
        .map(|(a, b)| (a.to_string(), b.to_string()))
        .collect()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn ids_stay_stable_over_100_frames_and_missing_objects_expire() {
    let mut rig = Rig::start("ids", vec![niryo()]).await;
    let scene = || {
        vec![
            object("red cube", 0.30, 0.05, 0.03),
            object("pencil", 0.20, -0.05, 0.012),
            object("blue square", 0.22, 0.05, 0.045),
        ]
    };
    // New objects are reported once a second view agrees.
    assert!(rig.view("niryo_ws", scene()).await.objects.is_empty());
    let first = rig.view("niryo_ws", scene()).await;
    let expected = pairs(&[
        ("obj-1", "red cube"),
        ("obj-2", "pencil"),
        ("obj-3", "blue square"),
    ]);
    assert_eq!(ids(&first.objects), expected);
    for f in 0..100u64 {
        // ±1.5 mm of deterministic noise, detector order rotated.
        let noise = ((f * 37) % 7) as f64 * 0.0005 - 0.0015;
        let mut objects = scene();
        for o in &mut objects {
            o.position.center_of_mass.x_m += noise;
            o.position.center_of_mass.y_m -= noise;
        }
        objects.rotate_left((f % 3) as usize);
        let tracked = rig.view("niryo_ws", objects).await;
        assert_eq!(ids(&tracked.objects), expected, "frame {}", f + 2);
    }
    // The query answers carry the same ids.
    assert_eq!(ids(&rig.objects().await), expected);

    // The pencil is taken away: kept while missed twice, forgotten at the third miss.
    let without_pencil = || {
        scene()
            .into_iter()
            .filter(|o| o.label != "pencil")
            .collect::<Vec<_>>()
    };
    assert_eq!(
        rig.view("niryo_ws", without_pencil()).await.objects.len(),
        3
    );
    assert_eq!(
        rig.view("niryo_ws", without_pencil()).await.objects.len(),
        3
    );
    let tracked = rig.view("niryo_ws", without_pencil()).await;
    assert_eq!(
        ids(&tracked.objects),
        pairs(&[("obj-1", "red cube"), ("obj-3", "blue square")])
    );
    assert_eq!(rig.objects().await.len(), 2);
    // Put back: a new id, never the old one.
    rig.view("niryo_ws", scene()).await;
    let tracked = rig.view("niryo_ws", scene()).await;
    assert!(tracked
        .objects
        .iter()
        .any(|o| o.id == "obj-4" && o.label == "pencil"));
    rig.model.shutdown().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn picks_and_places_are_followed_until_the_camera_confirms() {
    let mut rig = Rig::start("pickplace", vec![niryo()]).await;
    let cube = || object("red cube", 0.30, 0.05, 0.03);
    let pencil = || object("pencil", 0.20, -0.05, 0.012);
    rig.view("niryo_ws", vec![cube(), pencil()]).await;
    rig.view("niryo_ws", vec![cube(), pencil()]).await;

    let picked = rig
        .ask(WorkspaceRequest::ObjectPicked {
            object_id: "obj-1".into(),
        })
        .await;
    assert!(
        matches!(picked, WorkspaceReply::Object { object: Some(ref o) } if o.label == "red cube"),
        "{picked:?}"
    );
    // Held: not on the table, and not forgotten while the camera cannot see it.
    for _ in 0..5 {
        let tracked = rig.view("niryo_ws", vec![pencil()]).await;
        assert_eq!(ids(&tracked.objects), pairs(&[("obj-2", "pencil")]));
    }
    assert!(matches!(
        rig.ask(WorkspaceRequest::GetLargestObject).await,
        WorkspaceReply::Object { object: Some(ref o) } if o.label == "pencil"
    ));

    // Placed: in memory at once where it was put ...
    let placed = rig
        .ask(WorkspaceRequest::ObjectPlaced {
            object_id: "obj-1".into(),
            at: Point2::new(0.25, 0.0),
        })
        .await;
    assert!(
        matches!(placed, WorkspaceReply::Object { object: Some(ref o) } if o.xy() == Point2::new(0.25, 0.0)),
        "{placed:?}"
    );
    let near = rig
        .ask(WorkspaceRequest::GetObjectNear {
            coordinate: Point2::new(0.255, 0.0),
            label: Some("cube".into()),
        })
        .await;
    assert!(
        matches!(near, WorkspaceReply::Object { object: Some(ref o) } if o.id == "obj-1"),
        "{near:?}"
    );
    // ... and the camera confirms it 4 mm off: same id, the measured position.
    let tracked = rig
        .view(
            "niryo_ws",
            vec![object("red cube", 0.254, 0.0, 0.03), pencil()],
        )
        .await;
    let cube_now = tracked.objects.iter().find(|o| o.id == "obj-1").unwrap();
    assert!((cube_now.xy().x_m - 0.254).abs() < 1e-12);

    // Unknown ids are refused, naming what memory holds.
    match rig
        .ask(WorkspaceRequest::ObjectPicked {
            object_id: "obj-42".into(),
        })
        .await
    {
        WorkspaceReply::Error {
            error: WorkspaceError::InvalidRequest { reason },
        } => assert_eq!(
            reason,
            "unknown object id 'obj-42'; remembered: obj-1, obj-2"
        ),
        other => panic!("{other:?}"),
    }
    rig.model.shutdown().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn workspace_questions_labels_and_bad_queries() {
    let widowx = WorkspaceInfo {
        id: "widowx_ws".into(),
        robot: RobotModel::WidowX250,
        upper_left: Point2::new(0.35, 0.10),
        lower_right: Point2::new(0.15, -0.10),
        observation_pose: Pose::new(0.30, 0.0, 0.25, 0.0, 0.0, 0.0),
    };
    let rig = Rig::start("questions", vec![niryo(), widowx]).await;
    let mut labels = rig.bus.subscriber(&WORKSPACE_LABELS).unwrap();

    assert_eq!(
        rig.ask(WorkspaceRequest::GetWorkspacePoint {
            workspace_id: "widowx_ws".into(),
            point: WorkspacePoint::LowerLeftCorner,
        })
        .await,
        WorkspaceReply::Coordinate {
            coordinate: Point2::new(0.15, 0.10)
        }
    );
    match rig
        .ask(WorkspaceRequest::GetWorkspacePoint {
            workspace_id: "gazebo_1".into(),
            point: WorkspacePoint::CenterPoint,
        })
        .await
    {
        WorkspaceReply::Error { error } => assert_eq!(
            error.to_string(),
            "unknown workspace 'gazebo_1'; known: niryo_ws, widowx_ws"
        ),
        other => panic!("{other:?}"),
    }
    assert!(matches!(
        rig.ask(WorkspaceRequest::GetObservationPose {
            workspace_id: "nope".into()
        })
        .await,
        WorkspaceReply::Error {
            error: WorkspaceError::UnknownWorkspace { .. }
        }
    ));
    match rig.ask(WorkspaceRequest::ListWorkspaces).await {
        WorkspaceReply::Workspaces { workspaces } => assert_eq!(
            workspaces.iter().map(|w| w.id.as_str()).collect::<Vec<_>>(),
            ["niryo_ws", "widowx_ws"]
        ),
        other => panic!("{other:?}"),
    }
    // Empty scene: nothing, no error; the first workspace is free but for its corners.
    assert_eq!(
        rig.ask(WorkspaceRequest::GetSmallestObject).await,
        WorkspaceReply::Object { object: None }
    );
    match rig.ask(WorkspaceRequest::GetLargestFreeSpace).await {
        WorkspaceReply::FreeSpace { area_m2, center } => {
            // The largest square clear of its corner markers' keep-out squares (memory/tests.rs).
            let side = 0.76 * 0.174;
            assert!((area_m2 - side * side).abs() < 1e-12, "{area_m2}");
            assert!((center.x_m - 0.25).abs() < 1e-9 && center.y_m.abs() < 1e-9);
        }
        other => panic!("{other:?}"),
    }

    // Labels: the configured ones, then the built-in detector's; additions are published.
    assert_eq!(
        rig.ask(WorkspaceRequest::GetLabels).await,
        WorkspaceReply::Labels {
            labels: vec!["pencil".into(), "red cube".into()],
            builtin: vec!["pencil".into(), "red cube".into()],
        }
    );
    assert_eq!(
        rig.ask(WorkspaceRequest::AddLabel {
            label: " Screwdriver ".into()
        })
        .await,
        WorkspaceReply::LabelAdded {
            label: "screwdriver".into(),
            already_known: false
        }
    );
    let published: DetectableLabels = tokio::time::timeout(TIMEOUT, labels.recv())
        .await
        .unwrap()
        .unwrap()
        .body;
    assert_eq!(published.labels, ["pencil", "red cube", "screwdriver"]);
    assert_eq!(published.builtin, ["pencil", "red cube"]);
    assert_eq!(published.added.as_deref(), Some("screwdriver"));
    assert_eq!(
        rig.ask(WorkspaceRequest::AddLabel {
            label: "SCREWDRIVER".into()
        })
        .await,
        WorkspaceReply::LabelAdded {
            label: "screwdriver".into(),
            already_known: true
        }
    );

    // Bad queries: the tools' own text for a filter without a coordinate, field errors else.
    assert_eq!(
        rig.ask(WorkspaceRequest::GetObjects {
            location: Location::CloseTo,
            coordinate: None,
            label: None,
        })
        .await,
        WorkspaceReply::Error {
            error: WorkspaceError::CoordinateRequired {
                location: Location::CloseTo
            }
        }
    );
    let too_long = WorkspaceQuery {
        request: all(),
        fresh_after_unix_ns: Some(unix_now_ns()),
        max_wait_ms: 3_600_000,
    };
    match rig.client.request(&too_long, TIMEOUT).await.unwrap() {
        WorkspaceReply::Error {
            error: WorkspaceError::InvalidRequest { reason },
        } => assert!(
            reason.starts_with("max_wait_ms: must be at most"),
            "{reason}"
        ),
        other => panic!("{other:?}"),
    }
    rig.model.shutdown().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_fresh_query_is_answered_at_once_when_memory_is_fresh_enough() {
    let mut rig = Rig::start("fresh-now", vec![niryo()]).await;
    let before = unix_now_ns();
    rig.view("niryo_ws", vec![cube(0.3, 0.05)]).await;
    // One view after `before` left a candidate. When no second view comes within the wait,
    // the query is answered from the view it has (the cube not yet reported), not refused.
    let reply = rig
        .client
        .request(
            &WorkspaceQuery {
                request: all(),
                fresh_after_unix_ns: Some(before),
                max_wait_ms: 200,
            },
            TIMEOUT,
        )
        .await
        .unwrap();
    assert_eq!(reply, WorkspaceReply::Objects { objects: vec![] });
    // With a longer wait, the query waits for the next view and gets the cube.
    let waiting = {
        let client = rig.bus.client(&WORKSPACE_QUERY).unwrap();
        tokio::spawn(async move {
            client
                .request(
                    &WorkspaceQuery {
                        request: all(),
                        fresh_after_unix_ns: Some(before),
                        max_wait_ms: 3000,
                    },
                    TIMEOUT,
                )
                .await
                .unwrap()
        })
    };
    tokio::time::sleep(Duration::from_millis(100)).await;
    assert!(!waiting.is_finished(), "answered with the cube unconfirmed");
    rig.view("niryo_ws", vec![cube(0.3, 0.05)]).await;
    let reply = tokio::time::timeout(TIMEOUT, waiting)
        .await
        .unwrap()
        .unwrap();
    assert!(matches!(reply, WorkspaceReply::Objects { ref objects } if objects.len() == 1));
    // Two views after `before`, nothing unsettled: answered at once.
    let started = Instant::now();
    let reply = rig
        .client
        .request(
            &WorkspaceQuery {
                request: all(),
                fresh_after_unix_ns: Some(before),
                max_wait_ms: 3000,
            },
            TIMEOUT,
        )
        .await
        .unwrap();
    assert!(started.elapsed() < Duration::from_millis(500));
    assert!(matches!(reply, WorkspaceReply::Objects { ref objects } if objects.len() == 1));
    rig.model.shutdown().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn shutdown_answers_waiting_queries() {
    let rig = Rig::start("shutdown", vec![niryo()]).await;
    let client = rig.bus.client(&WORKSPACE_QUERY).unwrap();
    let waiting = tokio::spawn(async move {
        client
            .request(
                &WorkspaceQuery {
                    request: all(),
                    fresh_after_unix_ns: Some(unix_now_ns()),
                    max_wait_ms: 10_000,
                },
                TIMEOUT,
            )
            .await
    });
    tokio::time::sleep(Duration::from_millis(200)).await;
    rig.model.shutdown().await;
    let reply = tokio::time::timeout(TIMEOUT, waiting)
        .await
        .unwrap()
        .unwrap()
        .unwrap();
    assert!(
        matches!(
            reply,
            WorkspaceReply::Error {
                error: WorkspaceError::Unavailable { .. }
            }
        ),
        "{reply:?}"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn start_refuses_missing_or_duplicate_workspaces() {
    let bus = open_bus("start");
    let err = WorkspaceModel::start(&bus, WorkspaceModelSettings::new(vec![])).unwrap_err();
    assert!(matches!(err, WorkspaceStartError::NoWorkspace), "{err}");
    let err = WorkspaceModel::start(&bus, WorkspaceModelSettings::new(vec![niryo(), niryo()]))
        .unwrap_err();
    assert_eq!(
        err.to_string(),
        "workspace model: workspace 'niryo_ws' is invalid: the id is used by two workspaces"
    );
}
