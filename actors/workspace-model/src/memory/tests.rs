//! Tests of the scene memory: the detection and workspace questions against a hand-checked
//! scene, labels, ids that stay stable across frames and expire, picks and places (also
//! across workspaces), free space, and views that change nothing.

use super::*;
use crate::tracker::IgnoredView;
use robotd_protocol::geometry::{Point2, Point3, Pose, RobotModel};
use robotd_protocol::location::{Location, WorkspacePoint};
use robotd_protocol::objects::{DetectedObject, Detections};
use robotd_protocol::workspace::{WorkspaceError, WorkspaceInfo, WorkspaceReply, WorkspaceRequest};

fn workspaces() -> Vec<WorkspaceInfo> {
    let niryo = WorkspaceInfo {
        id: "niryo_ws".into(),
        robot: RobotModel::Ned2,
        upper_left: Point2::new(0.337, 0.087),
        lower_right: Point2::new(0.163, -0.087),
        observation_pose: Pose::new(0.173, -0.002, 0.277, -3.042, 1.327, -3.027),
    };
    let gazebo = WorkspaceInfo {
        id: "gazebo_1".into(),
        observation_pose: Pose::new(0.18, 0.0, 0.36, 2.4, std::f64::consts::FRAC_PI_2, 2.4),
        ..niryo.clone()
    };
    vec![niryo, gazebo]
}

fn object(label: &str, x: f64, y: f64, w: f64, h: f64) -> DetectedObject {
    let mut o = DetectedObject {
        label: label.into(),
        ..Default::default()
    };
    o.position.center_of_mass = Point3::new(x, y, 0.01);
    o.position.center = o.position.center_of_mass;
    o.dimensions.width_m = w;
    o.dimensions.height_m = h;
    o.dimensions.size_m2 = w * h;
    o
}

fn view(frame_id: u64, objects: Vec<DetectedObject>) -> Detections {
    Detections {
        frame_id,
        workspace_id: "niryo_ws".into(),
        timestamp_unix_ns: frame_id * 1000,
        source: "robotd".into(),
        steady: true,
        objects,
    }
}

/// Two steady views showing `objects`, 500 ns apart, the second at `frame_id`'s time: new
/// objects are reported once two views agree. Returns what the second reports.
fn settle(m: &mut SceneMemory, frame_id: u64, objects: Vec<DetectedObject>) -> TrackedObjects {
    let mut first = view(frame_id, objects.clone());
    first.timestamp_unix_ns -= 500;
    m.apply(&first).unwrap();
    m.apply(&view(frame_id, objects)).unwrap()
}

/// A red cube (far left), a pencil (near right), a blue square (near left) and a green
/// cylinder (far right); sizes 0.0009, 0.00144, 0.002025, 0.001024 m².
fn scene() -> Vec<DetectedObject> {
    vec![
        object("red cube", 0.30, 0.05, 0.03, 0.03),
        object("pencil", 0.20, -0.05, 0.012, 0.12),
        object("blue square", 0.22, 0.05, 0.045, 0.045),
        object("green cylinder", 0.28, -0.04, 0.032, 0.032),
    ]
}

fn memory() -> SceneMemory {
    let mut m = SceneMemory::new(
        workspaces(),
        &[],
        &["red cube".into(), "pencil".into()],
        MemorySettings::default(),
    );
    settle(&mut m, 1, scene());
    m
}

fn labels_of(reply: WorkspaceReply) -> Vec<String> {
    match reply {
        WorkspaceReply::Objects { objects } => objects.into_iter().map(|o| o.label).collect(),
        WorkspaceReply::Object { object } => object.into_iter().map(|o| o.label).collect(),
        other => panic!("not objects: {other:?}"),
    }
}

fn get(location: Location, at: Option<(f64, f64)>, label: Option<&str>) -> WorkspaceRequest {
    WorkspaceRequest::GetObjects {
        location,
        coordinate: at.map(|(x, y)| Point2::new(x, y)),
        label: label.map(str::to_owned),
    }
}

#[test]
fn detection_queries_match_the_hand_checked_table() {
    let mut m = memory();
    let all = ["red cube", "pencil", "blue square", "green cylinder"];
    assert_eq!(labels_of(m.answer(&get(Location::None, None, None))), all);
    assert_eq!(
        labels_of(m.answer(&get(Location::None, None, Some("CUBE")))),
        ["red cube"]
    );
    assert_eq!(
        labels_of(m.answer(&get(Location::None, None, Some(" cyl")))),
        ["green cylinder"]
    );
    assert_eq!(
        labels_of(m.answer(&get(Location::None, None, Some("e")))),
        all
    );
    assert!(labels_of(m.answer(&get(Location::None, None, Some("banana")))).is_empty());
    // Filters around (0.25, 0): left = y > 0, right = y < 0, above = x > 0.25, below = x < 0.25.
    let c = Some((0.25, 0.0));
    assert_eq!(
        labels_of(m.answer(&get(Location::LeftNextTo, c, None))),
        ["red cube", "blue square"]
    );
    assert_eq!(
        labels_of(m.answer(&get(Location::RightNextTo, c, None))),
        ["pencil", "green cylinder"]
    );
    assert_eq!(
        labels_of(m.answer(&get(Location::Above, c, None))),
        ["red cube", "green cylinder"]
    );
    assert_eq!(
        labels_of(m.answer(&get(Location::Below, c, None))),
        ["pencil", "blue square"]
    );
    assert_eq!(
        labels_of(m.answer(&get(Location::Below, c, Some("pen")))),
        ["pencil"]
    );
    // close to = within 2 cm: only the cube is 5 mm from (0.295, 0.05).
    assert_eq!(
        labels_of(m.answer(&get(Location::CloseTo, Some((0.295, 0.05)), None))),
        ["red cube"]
    );
    assert!(labels_of(m.answer(&get(Location::OnTopOf, c, None))).is_empty());
    assert!(labels_of(m.answer(&get(Location::Inside, c, None))).is_empty());
    match m.answer(&get(Location::Above, None, None)) {
        WorkspaceReply::Error { error } => assert_eq!(
            error,
            WorkspaceError::CoordinateRequired {
                location: Location::Above
            }
        ),
        other => panic!("{other:?}"),
    }

    // Nearest within 2 cm.
    let near = |x, y, label: Option<&str>| WorkspaceRequest::GetObjectNear {
        coordinate: Point2::new(x, y),
        label: label.map(str::to_owned),
    };
    assert_eq!(
        labels_of(m.answer(&near(0.21, 0.05, None))),
        ["blue square"]
    );
    assert!(labels_of(m.answer(&near(0.25, 0.0, None))).is_empty());
    assert!(labels_of(m.answer(&near(0.21, 0.05, Some("red")))).is_empty());

    // By size: 0.0009 (cube) < 0.001024 (cylinder) < 0.00144 (pencil) < 0.002025 (square).
    assert_eq!(
        labels_of(m.answer(&WorkspaceRequest::GetLargestObject)),
        ["blue square"]
    );
    assert_eq!(
        labels_of(m.answer(&WorkspaceRequest::GetSmallestObject)),
        ["red cube"]
    );
    assert_eq!(
        labels_of(m.answer(&WorkspaceRequest::GetObjectsSorted { ascending: true })),
        ["red cube", "green cylinder", "pencil", "blue square"]
    );
    assert_eq!(
        labels_of(m.answer(&WorkspaceRequest::GetObjectsSorted { ascending: false })),
        ["blue square", "pencil", "green cylinder", "red cube"]
    );
}

#[test]
fn workspace_queries_and_unknown_workspaces() {
    let mut m = memory();
    let point = |ws: &str, p| WorkspaceRequest::GetWorkspacePoint {
        workspace_id: ws.into(),
        point: p,
    };
    assert_eq!(
        m.answer(&point("niryo_ws", WorkspacePoint::UpperRightCorner)),
        WorkspaceReply::Coordinate {
            coordinate: Point2::new(0.337, -0.087)
        }
    );
    assert_eq!(
        m.answer(&point("gazebo_1", WorkspacePoint::LowerLeftCorner)),
        WorkspaceReply::Coordinate {
            coordinate: Point2::new(0.163, 0.087)
        }
    );
    match m.answer(&point("foo_ws", WorkspacePoint::CenterPoint)) {
        WorkspaceReply::Error { error } => assert_eq!(
            error.to_string(),
            "unknown workspace 'foo_ws'; known: niryo_ws, gazebo_1"
        ),
        other => panic!("{other:?}"),
    }
    match m.answer(&WorkspaceRequest::GetObservationPose {
        workspace_id: "gazebo_1".into(),
    }) {
        WorkspaceReply::ObservationPose { pose } => assert_eq!(pose.z_m, 0.36),
        other => panic!("{other:?}"),
    }
    assert!(matches!(
        m.answer(&WorkspaceRequest::GetObservationPose {
            workspace_id: "x".into()
        }),
        WorkspaceReply::Error {
            error: WorkspaceError::UnknownWorkspace { .. }
        }
    ));
    match m.answer(&WorkspaceRequest::ListWorkspaces) {
        WorkspaceReply::Workspaces { workspaces } => assert_eq!(workspaces.len(), 2),
        other => panic!("{other:?}"),
    }
}

#[test]
fn labels_are_lower_case_and_unique() {
    let mut m = memory();
    let add = |l: &str| WorkspaceRequest::AddLabel { label: l.into() };
    assert_eq!(
        m.answer(&add(" Screwdriver ")),
        WorkspaceReply::LabelAdded {
            label: "screwdriver".into(),
            already_known: false
        }
    );
    assert_eq!(
        m.answer(&add("SCREWDRIVER")),
        WorkspaceReply::LabelAdded {
            label: "screwdriver".into(),
            already_known: true
        }
    );
    assert!(matches!(m.answer(&add("  ")), WorkspaceReply::Error { .. }));
    assert_eq!(
        m.answer(&WorkspaceRequest::GetLabels),
        WorkspaceReply::Labels {
            labels: vec!["red cube".into(), "pencil".into(), "screwdriver".into()],
            builtin: vec!["red cube".into(), "pencil".into()],
        }
    );
}

#[test]
fn an_empty_scene_answers_empty() {
    let mut m = SceneMemory::new(workspaces(), &[], &[], MemorySettings::default());
    assert!(labels_of(m.answer(&get(Location::None, None, None))).is_empty());
    assert_eq!(
        m.answer(&WorkspaceRequest::GetLargestObject),
        WorkspaceReply::Object { object: None }
    );
    assert_eq!(
        m.answer(&WorkspaceRequest::GetSmallestObject),
        WorkspaceReply::Object { object: None }
    );
    match m.answer(&WorkspaceRequest::GetLargestFreeSpace) {
        WorkspaceReply::FreeSpace { area_m2, center } => {
            // The sheet less the markers' keep-out squares (see EMPTY_SHEET_FREE_M2).
            assert!((area_m2 - EMPTY_SHEET_FREE_M2).abs() < 1e-12, "{area_m2}");
            assert!((center.x_m - 0.25).abs() < 1e-9 && center.y_m.abs() < 1e-9);
        }
        other => panic!("{other:?}"),
    }
    assert_eq!(
        m.answer(&WorkspaceRequest::GetLabels),
        WorkspaceReply::Labels {
            labels: vec![],
            builtin: vec![]
        }
    );
}

#[test]
fn ids_are_stable_and_missing_objects_expire() {
    let mut m = memory();
    let first = m.apply(&view(2, scene())).unwrap();
    let ids: Vec<String> = first.objects.iter().map(|o| o.id.clone()).collect();
    assert_eq!(ids, ["obj-1", "obj-2", "obj-3", "obj-4"]);
    // 100 frames with millimetre jitter and shuffled detector order: same ids.
    for f in 0..100u64 {
        let jitter = ((f % 7) as f64 - 3.0) * 0.001;
        let mut objects = scene();
        for o in &mut objects {
            o.position.center_of_mass.x_m += jitter;
            o.position.center_of_mass.y_m -= jitter;
        }
        objects.rotate_left((f % 4) as usize);
        let tracked = m.apply(&view(3 + f, objects)).unwrap();
        let mut got: Vec<(String, String)> = tracked
            .objects
            .iter()
            .map(|o| (o.id.clone(), o.label.clone()))
            .collect();
        got.sort();
        assert_eq!(
            got,
            [
                ("obj-1", "red cube"),
                ("obj-2", "pencil"),
                ("obj-3", "blue square"),
                ("obj-4", "green cylinder")
            ]
            .map(|(a, b)| (a.to_owned(), b.to_owned()))
        );
    }
    // Frames taken while the arm moved change nothing.
    let mut moving = view(200, vec![]);
    moving.steady = false;
    assert!(matches!(
        m.apply(&moving),
        Err(IgnoredView::Moving { frame_id: 200 })
    ));
    // The pencil is gone: missed in 3 steady views, then forgotten; a new object gets a
    // new id, never an old one.
    let without_pencil: Vec<_> = scene()
        .into_iter()
        .filter(|o| o.label != "pencil")
        .collect();
    for f in 0..2 {
        let t = m.apply(&view(300 + f, without_pencil.clone())).unwrap();
        assert_eq!(t.objects.len(), 4, "kept while missed only {} times", f + 1);
    }
    let t = m.apply(&view(302, without_pencil.clone())).unwrap();
    assert_eq!(t.objects.len(), 3);
    let mut with_new = without_pencil;
    with_new.push(object("pencil", 0.20, -0.05, 0.012, 0.12));
    // Reported once a second view agrees.
    let t = m.apply(&view(303, with_new.clone())).unwrap();
    assert_eq!(t.objects.len(), 3);
    let t = m.apply(&view(304, with_new)).unwrap();
    assert!(t
        .objects
        .iter()
        .any(|o| o.id == "obj-5" && o.label == "pencil"));
}

#[test]
fn memory_follows_picks_and_places() {
    let mut m = memory();
    let picked = m.answer(&WorkspaceRequest::ObjectPicked {
        object_id: "obj-1".into(),
    });
    assert!(
        matches!(picked, WorkspaceReply::Object { object: Some(ref o) } if o.label == "red cube")
    );
    assert_eq!(
        labels_of(m.answer(&get(Location::None, None, Some("cube")))),
        Vec::<String>::new()
    );
    // Held objects do not expire while the camera cannot see them on the table.
    for f in 0..5 {
        let rest: Vec<_> = scene()
            .into_iter()
            .filter(|o| o.label != "red cube")
            .collect();
        m.apply(&view(10 + f, rest)).unwrap();
    }
    let placed = m.answer(&WorkspaceRequest::ObjectPlaced {
        object_id: "obj-1".into(),
        at: Point2::new(0.18, 0.07),
    });
    assert!(
        matches!(placed, WorkspaceReply::Object { object: Some(ref o) } if o.xy() == Point2::new(0.18, 0.07))
    );
    let near = m.answer(&WorkspaceRequest::GetObjectNear {
        coordinate: Point2::new(0.18, 0.07),
        label: None,
    });
    assert_eq!(labels_of(near), ["red cube"]);
    // The camera confirms it there (same id) ...
    let mut moved = scene();
    moved[0].position.center_of_mass = Point3::new(0.181, 0.069, 0.015);
    let t = m.apply(&view(20, moved)).unwrap();
    assert!(t
        .objects
        .iter()
        .any(|o| o.id == "obj-1" && (o.xy().x_m - 0.181).abs() < 1e-12));
    // ... and an unknown id is refused with the ids it knows.
    match m.answer(&WorkspaceRequest::ObjectPicked {
        object_id: "obj-99".into(),
    }) {
        WorkspaceReply::Error { error } => assert!(error
            .to_string()
            .contains("unknown object id 'obj-99'; remembered: obj-1")),
        other => panic!("{other:?}"),
    }
}

fn cube_in_the_middle() -> DetectedObject {
    object("red cube", 0.25, 0.0, 0.03, 0.03)
}

fn free_space(m: &mut SceneMemory) -> (f64, Point2) {
    match m.answer(&WorkspaceRequest::GetLargestFreeSpace) {
        WorkspaceReply::FreeSpace { area_m2, center } => (area_m2, center),
        other => panic!("{other:?}"),
    }
}

/// Free space of the empty niryo_ws: the markers' keep-out squares (20 mm each side of a
/// corner, grown by half a cell's diagonal, 1.23 mm) take rows 0..=11 and 88..=99 at
/// columns 0..=11 and 88..=99 (cell centres 0.87 … 20.0 mm from the edge); the largest free
/// rectangles are rows 12..=87 × all columns and all rows × columns 12..=87, 7600 cells each;
/// the square centred in the first found (at row 87) is answered: (0.76 × 0.174)² m², centred
/// at (0.25, 0).
const EMPTY_SHEET_FREE_M2: f64 = (0.76 * 0.174) * (0.76 * 0.174);

#[test]
fn free_space_counts_the_objects_on_the_table_of_the_current_workspace() {
    let mut m = SceneMemory::new(workspaces(), &[], &[], MemorySettings::default());
    settle(&mut m, 1, vec![cube_in_the_middle()]);
    // The cube takes rows and columns 36..=63 (free_space::tests::
    // one_cube_in_the_middle_leaves_the_near_strip), the markers the corners (as on an empty
    // sheet): the near strip rows 0..=35 × columns 12..=87 (2736 cells) ties with the side
    // strips rows 12..=87 × 36 columns and is found first; the square centred in it, 36 cells
    // a side: centre (0.19432, 0).
    let (area, center) = free_space(&mut m);
    assert!(
        (area - (0.36 * 0.174) * (0.36 * 0.174)).abs() < 1e-9,
        "{area}"
    );
    assert!((center.x_m - 0.19432).abs() < 1e-9 && center.y_m.abs() < 1e-9);
    // Held: off the table, the whole sheet but its corners is free.
    m.answer(&WorkspaceRequest::ObjectPicked {
        object_id: "obj-1".into(),
    });
    let (area, _) = free_space(&mut m);
    assert!((area - EMPTY_SHEET_FREE_M2).abs() < 1e-12, "{area}");
    // Placed on the far-left corner: it blocks rows and columns 86..=99 there (free_space::
    // tests::a_corner_object_leaves_an_l_whose_larger_arm_wins). The largest rectangles, rows
    // 12..=85 × all columns and all rows × columns 12..=85, hold squares of 74 cells; rows
    // 12..=87 × columns 0..=85 (76 × 86 cells) holds one of 76, as on the empty sheet, centred
    // at x = 0.163 + (12 + 88) / 2 · 0.00174 = 0.25.
    m.answer(&WorkspaceRequest::ObjectPlaced {
        object_id: "obj-1".into(),
        at: Point2::new(0.337, 0.087),
    });
    let (area, center) = free_space(&mut m);
    assert!((area - EMPTY_SHEET_FREE_M2).abs() < 1e-9, "{area}");
    assert!((center.x_m - 0.25).abs() < 1e-9, "{center:?}");
}

#[test]
fn object_questions_follow_the_workspace_in_view() {
    let mut m = memory();
    let mut gazebo = view(2, vec![object("pencil", 0.2, 0.0, 0.01, 0.1)]);
    gazebo.workspace_id = "gazebo_1".into();
    m.apply(&gazebo).unwrap();
    gazebo.timestamp_unix_ns += 500;
    let t = m.apply(&gazebo).unwrap();
    assert_eq!(t.workspace_id, "gazebo_1");
    assert_eq!(m.current_workspace().unwrap().id, "gazebo_1");
    // Now the detection tools answer about gazebo_1 only (a new object there: obj-5).
    match m.answer(&get(Location::None, None, None)) {
        WorkspaceReply::Objects { objects } => {
            assert_eq!(objects.len(), 1);
            assert_eq!(objects[0].id, "obj-5");
            assert_eq!(objects[0].workspace_id, "gazebo_1");
        }
        other => panic!("{other:?}"),
    }
    // Back to niryo_ws: its four objects were kept (not in view, not missed).
    m.apply(&view(3, scene())).unwrap();
    assert_eq!(
        labels_of(m.answer(&get(Location::None, None, None))).len(),
        4
    );
}

#[test]
fn views_of_unknown_workspaces_change_nothing_and_say_why() {
    let mut m = memory();
    let mut other = view(2, vec![]);
    other.workspace_id = "foo_ws".into();
    let err = m.apply(&other).unwrap_err();
    assert_eq!(
        err.to_string(),
        "frame 2 shows workspace 'foo_ws', which is not configured (known: niryo_ws, \
         gazebo_1); check the scene file and the detector's workspace ids"
    );
    assert_eq!(m.current_workspace().unwrap().id, "niryo_ws");
    assert_eq!(
        labels_of(m.answer(&get(Location::None, None, None))).len(),
        4
    );
}

#[test]
fn a_placed_object_moves_to_the_workspace_it_was_put_in() {
    let far = WorkspaceInfo {
        id: "far_ws".into(),
        robot: RobotModel::Ned2,
        upper_left: Point2::new(0.337, 0.4),
        lower_right: Point2::new(0.163, 0.2),
        observation_pose: Pose::new(0.2, 0.3, 0.3, 0.0, 1.5, 0.0),
    };
    let mut all = workspaces();
    all.push(far);
    let mut m = SceneMemory::new(all, &[], &[], MemorySettings::default());
    settle(&mut m, 1, scene());
    // Placed 1 cm outside niryo_ws (within the margin): stays there.
    let placed = m.answer(&WorkspaceRequest::ObjectPlaced {
        object_id: "obj-2".into(),
        at: Point2::new(0.2, -0.097),
    });
    assert!(
        matches!(placed, WorkspaceReply::Object { object: Some(ref o) } if o.workspace_id == "niryo_ws")
    );
    // Placed on the far workspace: it belongs there now, and leaves niryo_ws's answers.
    let placed = m.answer(&WorkspaceRequest::ObjectPlaced {
        object_id: "obj-2".into(),
        at: Point2::new(0.25, 0.3),
    });
    assert!(
        matches!(placed, WorkspaceReply::Object { object: Some(ref o) } if o.workspace_id == "far_ws")
    );
    assert!(labels_of(m.answer(&get(Location::None, None, Some("pencil")))).is_empty());
    // Empty and unknown ids are refused.
    assert!(matches!(
        m.answer(&WorkspaceRequest::ObjectPlaced {
            object_id: " ".into(),
            at: Point2::new(0.25, 0.0),
        }),
        WorkspaceReply::Error {
            error: WorkspaceError::InvalidRequest { .. }
        }
    ));
    assert!(matches!(
        m.answer(&WorkspaceRequest::ObjectPlaced {
            object_id: "obj-77".into(),
            at: Point2::new(0.25, 0.0),
        }),
        WorkspaceReply::Error {
            error: WorkspaceError::InvalidRequest { .. }
        }
    ));
}

#[test]
fn a_named_object_answers_to_its_name_and_the_name_follows_the_label_rules() {
    let mut m = SceneMemory::new(
        workspaces(),
        &[],
        &["red cube".into()],
        MemorySettings {
            label_limits: crate::labels::LabelLimits {
                max_labels: 2,
                max_chars: 12,
            },
            ..MemorySettings::default()
        },
    );
    let unknown = object("unknown object", 0.25, 0.0, 0.03, 0.02);
    settle(&mut m, 1, vec![unknown.clone()]);
    let name = |id: &str, label: &str| WorkspaceRequest::LabelObject {
        object_id: id.into(),
        label: label.into(),
    };
    let error = |reply: WorkspaceReply| match reply {
        WorkspaceReply::Error { error } => error.to_string(),
        other => panic!("not an error: {other:?}"),
    };
    assert!(error(m.answer(&name("obj-9", "mug"))).contains("unknown object id 'obj-9'"));
    assert!(error(m.answer(&name("obj-1", "a very long name"))).contains("at most 12"));
    match m.answer(&name("obj-1", " Big  Mug ")) {
        WorkspaceReply::ObjectLabelled {
            object,
            previous,
            detected_as,
            label_added,
        } => {
            assert_eq!(
                (object.id.as_str(), object.label.as_str()),
                ("obj-1", "big mug")
            );
            assert_eq!(
                (previous.as_str(), detected_as.as_str()),
                ("unknown object", "unknown object")
            );
            assert!(label_added);
        }
        other => panic!("{other:?}"),
    }
    // The list is full now (red cube, big mug): a third name is refused, a known one is not.
    assert!(error(m.answer(&name("obj-1", "cup"))).contains("workspace.max_labels"));
    assert!(matches!(
        m.answer(&name("obj-1", "red cube")),
        WorkspaceReply::ObjectLabelled {
            label_added: false,
            ..
        }
    ));
    m.answer(&name("obj-1", "big mug"));
    // Seen again as an unknown object: still the big mug, found by its name.
    let tracked = m.apply(&view(2, vec![unknown])).unwrap();
    assert_eq!(tracked.objects[0].label, "big mug");
    assert_eq!(
        tracked.detection_ids,
        ["obj-1"],
        "the view's box is the big mug"
    );
    let near = m.answer(&WorkspaceRequest::GetObjectNear {
        coordinate: Point2::new(0.25, 0.0),
        label: Some("BIG MUG".into()),
    });
    assert!(matches!(near, WorkspaceReply::Object { object: Some(o) } if o.id == "obj-1"));
}
