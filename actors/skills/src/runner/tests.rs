//! The runner's decisions, one skill at a time, against scripted arm, gripper and
//! workspace-model services on a bus of the test's own, which record every command in one
//! ordered log: the order of a pick's and a place's steps and their heights, what a failed
//! step leaves (nothing more sent, the tool lifted straight up, the fingers never closed), an
//! e-stop in the middle of a descent, a motion the arm does not answer never sent again,
//! and refusals that move nothing.

use super::*;
use robotd_protocol::objects::{Dimensions, ObjectPosition};
use robotd_protocol::{Point3, RobotModel};
use robotd_runtime::bus::{Bus, BusOptions, Overflow, Service, Subscriber, Topic};
use std::sync::atomic::AtomicUsize;
use std::sync::Mutex;
use std::time::Duration;

const ARM: Service<ArmCommand, ArmReply> = Service::new("runner-test/arm");
const GRIPPER: Service<GripperCommand, GripperReply> = Service::new("runner-test/gripper");
const MODEL: Service<WorkspaceQuery, WorkspaceReply> = Service::new("runner-test/workspace");
const PROGRESS: Topic<SkillProgress> =
    Topic::new("runner-test/progress", Overflow::latest_wins(64));

/// The Ned2's sheet, x 0.163 … 0.337, y -0.087 … 0.087.
fn workspace() -> WorkspaceInfo {
    WorkspaceInfo {
        id: "niryo_ws".into(),
        robot: RobotModel::Ned2,
        upper_left: Point2::new(0.337, 0.087),
        lower_right: Point2::new(0.163, -0.087),
        observation_pose: Pose::new(0.25, 0.0, 0.3, 0.0, FRAC_PI_2, 0.0),
    }
}

/// A box `side` × `side` and `tall` high, standing on the table at (x, y).
fn object(id: &str, label: &str, x: f64, y: f64, side: f64, tall: f64) -> DetectedObject {
    DetectedObject {
        id: id.into(),
        label: label.into(),
        workspace_id: "niryo_ws".into(),
        position: ObjectPosition {
            center_of_mass: Point3::new(x, y, tall / 2.0),
            center: Point3::new(x, y, tall / 2.0),
        },
        dimensions: Dimensions {
            width_m: side,
            height_m: side,
            size_m2: side * side,
        },
        confidence: 0.99,
        ..Default::default()
    }
}

/// A 30 mm cube at (0.25, 0): grasped at 15 mm (its centre), approached at 90 mm (60 mm
/// above its top).
fn cube() -> DetectedObject {
    object("obj-1", "red cube", 0.25, 0.0, 0.03, 0.03)
}

/// A 45 mm square tile, 10 mm thick, at (0.29, 0.04).
fn tile() -> DetectedObject {
    object("obj-2", "blue square", 0.29, 0.04, 0.045, 0.01)
}

/// What the scripted services heard, in one order, and how they answer.
#[derive(Default)]
struct Script {
    heard: Mutex<Vec<String>>,
    objects: Mutex<Vec<DetectedObject>>,
    pose: Mutex<Pose>,
    /// `MoveToPose` commands so far.
    motions: AtomicUsize,
    /// The motion (by index) the arm never answers.
    silent_motion: Mutex<Option<usize>>,
    /// The motion (by index) during which the e-stop is engaged: the arm stops half way and
    /// refuses every motion after it until [`Script::release_estop`].
    estop_at_motion: Mutex<Option<usize>>,
    estopped: AtomicBool,
    /// Whether closing the fingers finds the object.
    grasps: AtomicBool,
    holding: AtomicBool,
    /// Opening leaves the object in the fingers.
    stuck_fingers: AtomicBool,
    /// A cancel that arrives while the fingers close.
    cancel_on_close: Mutex<Option<Arc<CancelFlag>>>,
}

/// A pose as the log shows it: millimetres and degrees.
fn show(p: &Pose) -> String {
    format!(
        "({:.1}, {:.1}, {:.1}) yaw {:.0}",
        p.x_m * 1000.0,
        p.y_m * 1000.0,
        p.z_m * 1000.0,
        p.yaw_rad.to_degrees()
    )
}

impl Script {
    fn log(&self, line: String) {
        self.heard.lock().unwrap().push(line);
    }

    fn heard(&self) -> Vec<String> {
        self.heard.lock().unwrap().clone()
    }

    fn release_estop(&self) {
        *self.estop_at_motion.lock().unwrap() = None;
        self.estopped.store(false, Ordering::SeqCst);
    }

    /// The arm's answer to `command`; `None`: it never answers.
    fn arm(&self, command: ArmCommand) -> Option<ArmReply> {
        let estop = || ArmReply::Error {
            error: ArmError::EStopped {
                reason: "stop button".into(),
            },
        };
        let mut pose = self.pose.lock().unwrap();
        match command {
            ArmCommand::MoveToPose { target, path } => {
                self.log(format!("arm: {path:?} to {}", show(&target)));
                let n = self.motions.fetch_add(1, Ordering::SeqCst);
                if *self.silent_motion.lock().unwrap() == Some(n) {
                    return None;
                }
                if *self.estop_at_motion.lock().unwrap() == Some(n) {
                    self.estopped.store(true, Ordering::SeqCst);
                    pose.z_m = (pose.z_m + target.z_m) / 2.0;
                    return Some(estop());
                }
                if self.estopped.load(Ordering::SeqCst) {
                    return Some(estop());
                }
                *pose = target;
            }
            ArmCommand::GoToObservationPose { workspace_id } => {
                self.log(format!("arm: observation pose of {workspace_id}"));
                if self.estopped.load(Ordering::SeqCst) {
                    return Some(estop());
                }
                *pose = workspace().observation_pose;
            }
            other => self.log(format!("arm: {other:?}")),
        }
        Some(ArmReply::Ok { pose: *pose })
    }

    fn gripper(&self, command: GripperCommand) -> GripperReply {
        self.log(format!("gripper: {command:?}"));
        match command {
            GripperCommand::Close => {
                let grasps = self.grasps.load(Ordering::SeqCst);
                self.holding.store(grasps, Ordering::SeqCst);
                if let Some(cancel) = self.cancel_on_close.lock().unwrap().as_ref() {
                    cancel.cancelled.store(true, Ordering::SeqCst);
                }
            }
            GripperCommand::GetState => {}
            _ => {
                if !self.stuck_fingers.load(Ordering::SeqCst) {
                    self.holding.store(false, Ordering::SeqCst);
                }
            }
        }
        GripperReply::State {
            holding: self.holding.load(Ordering::SeqCst),
            width_m: 0.0,
        }
    }

    fn model(&self, request: WorkspaceRequest) -> WorkspaceReply {
        match request {
            WorkspaceRequest::GetObjects { .. } => {
                self.log("model: objects seen".into());
                WorkspaceReply::Objects {
                    objects: self.objects.lock().unwrap().clone(),
                }
            }
            WorkspaceRequest::ObjectPicked { object_id } => {
                self.log(format!("model: {object_id} picked"));
                WorkspaceReply::Object { object: None }
            }
            WorkspaceRequest::ObjectPlaced { object_id, at } => {
                let (x, y) = (at.x_m * 1000.0, at.y_m * 1000.0);
                self.log(format!("model: {object_id} placed at ({x:.1}, {y:.1})"));
                WorkspaceReply::Object { object: None }
            }
            other => {
                self.log(format!("model: {other:?}"));
                WorkspaceReply::Object { object: None }
            }
        }
    }
}

/// A runner whose arm, gripper and workspace model are `script`, and its progress.
struct Rig {
    runner: Runner,
    script: Arc<Script>,
    progress: Subscriber<SkillProgress>,
    _bus: Bus,
}

impl Rig {
    async fn run(&mut self, run_id: u64, skill: Skill) -> SkillReply {
        self.runner.run(run_id, skill).await
    }

    /// The progress published so far, as "step/total message".
    fn progress(&mut self) -> Vec<String> {
        let mut seen = Vec::new();
        while let Some(p) = self.progress.try_recv().unwrap() {
            let p = p.body;
            seen.push(format!("{}/{} {}", p.step, p.total, p.message));
        }
        seen
    }
}

fn rig(test: &str, objects: Vec<DetectedObject>, command_timeout: Duration) -> Rig {
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    let namespace = format!(
        "test-runner-{}-{}-{test}",
        std::process::id(),
        COUNTER.fetch_add(1, Ordering::Relaxed)
    );
    let bus = Bus::open(BusOptions::new(&namespace, "runner-test")).unwrap();
    let script = Arc::new(Script::default());
    *script.objects.lock().unwrap() = objects;
    *script.pose.lock().unwrap() = workspace().observation_pose;

    let mut arm = bus.server(&ARM).unwrap();
    let s = script.clone();
    tokio::spawn(async move {
        let mut unanswered = Vec::new();
        while let Ok(incoming) = arm.next().await {
            let (envelope, pending) = incoming.split();
            match s.arm(envelope.body) {
                Some(reply) => {
                    let _ = arm.respond(pending, Ok(reply));
                }
                None => unanswered.push(pending),
            }
        }
    });
    let mut gripper = bus.server(&GRIPPER).unwrap();
    let s = script.clone();
    tokio::spawn(async move {
        let _ = gripper
            .serve(move |command| std::future::ready(Ok(s.gripper(command))))
            .await;
    });
    let mut model = bus.server(&MODEL).unwrap();
    let s = script.clone();
    tokio::spawn(async move {
        let _ = model
            .serve(move |query: WorkspaceQuery| std::future::ready(Ok(s.model(query.request))))
            .await;
    });

    let mut settings = SkillsSettings::new(RobotModel::Ned2, vec![workspace()]);
    settings.command_timeout = command_timeout;
    let progress = bus.subscriber(&PROGRESS).unwrap();
    let runner = Runner::new(
        settings,
        bus.client(&ARM).unwrap(),
        bus.client(&GRIPPER).unwrap(),
        bus.client(&MODEL).unwrap(),
        bus.publisher(&PROGRESS).unwrap(),
        Arc::new(CancelFlag::default()),
    );
    Rig {
        runner,
        script,
        progress,
        _bus: bus,
    }
}

const LONG: Duration = Duration::from_secs(10);

fn pick() -> Skill {
    Skill::Pick {
        object_name: "red cube".into(),
        pick_at: Point2::new(0.25, 0.0),
        z_offset_m: 0.0,
    }
}

fn pick_place(place_at: Point2, location: Location) -> Skill {
    Skill::PickPlace {
        object_name: "red cube".into(),
        pick_at: Point2::new(0.25, 0.0),
        place_at,
        location,
        z_offset_m: 0.0,
    }
}

fn failure(reply: &SkillReply) -> &SkillError {
    match reply {
        SkillReply::Failed { error, .. } => error,
        done => panic!("the skill did not fail: {done:?}"),
    }
}

/// The commands of a pick of [`cube`] up to and including `model: obj-1 picked`.
fn the_pick() -> Vec<String> {
    [
        "arm: observation pose of niryo_ws",
        "model: objects seen",
        "gripper: Open",
        "arm: Joint to (250.0, 0.0, 90.0) yaw 0",
        "arm: Linear to (250.0, 0.0, 15.0) yaw 0",
        "gripper: Close",
        "arm: Linear to (250.0, 0.0, 90.0) yaw 0",
        "gripper: GetState",
        "model: obj-1 picked",
    ]
    .map(String::from)
    .to_vec()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_pick_looks_opens_goes_above_straight_down_closes_lifts_checks_and_returns() {
    let mut rig = rig("pick", vec![cube()], LONG);
    rig.script.grasps.store(true, Ordering::SeqCst);
    let reply = rig.run(1, pick()).await;
    assert!(matches!(reply, SkillReply::Done { .. }), "{reply:?}");
    let mut expected = the_pick();
    expected.push("arm: observation pose of niryo_ws".into());
    assert_eq!(rig.script.heard(), expected);
    assert_eq!(
        rig.progress(),
        [
            "1/7 looking at workspace 'niryo_ws'",
            "2/7 opening the gripper",
            "3/7 moving above 'red cube'",
            "4/7 lowering to the grasp",
            "5/7 closing the gripper",
            "6/7 lifting",
            "7/7 returning to the observation pose",
        ]
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_place_on_top_releases_just_above_the_support_and_every_step_is_sent_once() {
    let mut rig = rig("stack", vec![cube(), tile()], LONG);
    rig.script.grasps.store(true, Ordering::SeqCst);
    let reply = rig.run(1, pick_place(tile().xy(), Location::OnTopOf)).await;
    let SkillReply::Done { to, .. } = reply else {
        panic!("{reply:?}");
    };
    assert_eq!(to, Some(tile().xy()));
    // Held 15 mm above its base: released 2 mm (the gap) + 5 mm (the stacking margin) above
    // the tile's top at 10 mm; approached 60 mm above the cube's top once on the tile.
    let mut expected = the_pick();
    expected.extend(
        [
            "arm: observation pose of niryo_ws",
            "model: objects seen",
            "arm: Joint to (290.0, 40.0, 115.0) yaw 0",
            "arm: Linear to (290.0, 40.0, 32.0) yaw 0",
            "gripper: Open",
            "arm: Linear to (290.0, 40.0, 115.0) yaw 0",
            "model: obj-1 placed at (290.0, 40.0)",
            "arm: observation pose of niryo_ws",
        ]
        .map(String::from),
    );
    assert_eq!(rig.script.heard(), expected);
    let progress = rig.progress();
    assert_eq!(progress.len(), 12, "{progress:?}");
    assert_eq!(
        progress.last().map(String::as_str),
        Some("12/12 returning to the observation pose")
    );
    // A place on the table: released 2 mm above it.
    let mut rig = rig_after_pick("table").await;
    let reply = rig
        .run(
            2,
            Skill::Place {
                place_at: Point2::new(0.3, -0.04),
                location: Location::None,
            },
        )
        .await;
    assert!(matches!(reply, SkillReply::Done { .. }), "{reply:?}");
    let heard = rig.script.heard();
    assert!(
        heard.contains(&"arm: Linear to (300.0, -40.0, 17.0) yaw 0".to_owned()),
        "{heard:?}"
    );
}

/// A rig whose gripper holds [`cube`], picked by the runner; the log starts after the pick.
async fn rig_after_pick(test: &str) -> Rig {
    let mut rig = rig(test, vec![cube(), tile()], LONG);
    rig.script.grasps.store(true, Ordering::SeqCst);
    let reply = rig.run(1, pick()).await;
    assert!(matches!(reply, SkillReply::Done { .. }), "{reply:?}");
    rig.script.heard.lock().unwrap().clear();
    rig.progress();
    rig
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn fingers_that_do_not_let_go_end_the_place_lifted_straight_up_with_a_spot_to_put_it() {
    let mut rig = rig_after_pick("stuck").await;
    rig.script.stuck_fingers.store(true, Ordering::SeqCst);
    let reply = rig
        .run(
            2,
            Skill::Place {
                place_at: Point2::new(0.3, -0.04),
                location: Location::None,
            },
        )
        .await;
    assert!(
        failure(&reply).to_string().contains("still holds"),
        "{reply:?}"
    );
    // After the failed release: the tool rises straight up from where it is, and nothing
    // else happens (no lift step, no model update, no return to the observation pose).
    let heard = rig.script.heard();
    let opened = heard.iter().position(|c| c == "gripper: Open").unwrap();
    assert_eq!(
        heard[opened + 1..],
        ["arm: GetPose", "arm: Linear to (300.0, -40.0, 105.0) yaw 0"]
    );
    let SkillReply::Failed {
        still_held,
        put_down_at,
        ..
    } = reply
    else {
        unreachable!()
    };
    assert_eq!(still_held.as_deref(), Some("red cube"));
    let spot = put_down_at.expect("a spot to put it down");
    let cube = cube();
    let held = HeldPlan {
        object: &cube,
        yaw_rad: 0.0,
        tcp_above_base_m: 0.015,
    };
    let placed = plan::place_target(&rig.runner.settings, &[tile()], &held, spot, Location::None);
    assert!(placed.is_ok(), "{spot:?}: {placed:?}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_estop_during_the_descent_ends_the_pick_with_nothing_closed_and_the_next_skill_rises_first(
) {
    let mut rig = rig("estop", vec![cube()], LONG);
    rig.script.grasps.store(true, Ordering::SeqCst);
    // Motion 1 is the descent to the grasp: the arm stops half way, at 52.5 mm.
    *rig.script.estop_at_motion.lock().unwrap() = Some(1);
    let reply = rig.run(1, pick()).await;
    let error = failure(&reply);
    assert!(
        !matches!(error, SkillError::Cancelled) && error.to_string().contains("emergency stop"),
        "{error}"
    );
    let heard = rig.script.heard();
    let down = heard
        .iter()
        .position(|c| c == "arm: Linear to (250.0, 0.0, 15.0) yaw 0")
        .unwrap();
    // One attempt to rise straight up (refused while the e-stop is engaged); never the
    // fingers, the model or a joint move.
    assert_eq!(
        heard[down + 1..],
        ["arm: GetPose", "arm: Linear to (250.0, 0.0, 90.0) yaw 0"]
    );
    assert!(matches!(
        reply,
        SkillReply::Failed {
            still_held: None,
            ..
        }
    ));
    // Released: the next skill first rises straight up from the half-way stop, then moves.
    rig.script.release_estop();
    rig.script.heard.lock().unwrap().clear();
    let reply = rig
        .run(
            2,
            Skill::GoToObservationPose {
                workspace_id: "niryo_ws".into(),
            },
        )
        .await;
    assert!(matches!(reply, SkillReply::Done { .. }), "{reply:?}");
    assert_eq!(
        rig.script.heard(),
        [
            "arm: GetPose",
            "arm: Linear to (250.0, 0.0, 90.0) yaw 0",
            "arm: observation pose of niryo_ws"
        ]
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_motion_the_arm_does_not_answer_is_never_sent_again() {
    let mut rig = rig("silent", vec![cube()], Duration::from_secs(1));
    rig.script.grasps.store(true, Ordering::SeqCst);
    *rig.script.silent_motion.lock().unwrap() = Some(1);
    let reply = rig.run(1, pick()).await;
    assert!(
        failure(&reply).to_string().contains("did not answer"),
        "{reply:?}"
    );
    let heard = rig.script.heard();
    let grasp = "arm: Linear to (250.0, 0.0, 15.0) yaw 0";
    assert_eq!(heard.iter().filter(|c| *c == grasp).count(), 1, "{heard:?}");
    assert!(!heard.contains(&"gripper: Close".to_owned()), "{heard:?}");
    // A second skill does not resend it either: it rises from wherever the tool is.
    *rig.script.silent_motion.lock().unwrap() = None;
    let reply = rig.run(2, pick()).await;
    assert!(matches!(reply, SkillReply::Done { .. }), "{reply:?}");
    let heard = rig.script.heard();
    assert_eq!(heard.iter().filter(|c| *c == grasp).count(), 2, "{heard:?}");
    for pair in heard.windows(2) {
        assert!(
            pair[0] != pair[1] || !pair[0].starts_with("arm: Linear"),
            "sent twice in a row: {heard:?}"
        );
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_cancel_while_the_fingers_close_sends_nothing_after_them() {
    let mut rig = rig("cancel", vec![cube()], LONG);
    rig.script.grasps.store(true, Ordering::SeqCst);
    *rig.script.cancel_on_close.lock().unwrap() = Some(rig.runner.cancel.clone());
    let reply = rig.run(1, pick()).await;
    assert!(
        matches!(failure(&reply), SkillError::Cancelled),
        "{reply:?}"
    );
    let heard = rig.script.heard();
    assert_eq!(heard.last().map(String::as_str), Some("gripper: Close"));
    assert_eq!(heard.len(), 6, "{heard:?}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn refusals_before_the_first_motion_move_nothing() {
    let mut rig = rig("refusals", vec![cube(), tile()], LONG);
    rig.script.grasps.store(true, Ordering::SeqCst);
    // A pick outside every workspace: not even a look.
    let outside = Skill::Pick {
        object_name: "red cube".into(),
        pick_at: Point2::new(0.5, 0.0),
        z_offset_m: 0.0,
    };
    let reply = rig.run(1, outside).await;
    assert!(
        matches!(failure(&reply), SkillError::OutsideWorkspace { .. }),
        "{reply:?}"
    );
    assert!(rig.script.heard().is_empty());
    // A cancel that came before the run started.
    rig.runner.cancel.cancel_early(2);
    let reply = rig.run(2, pick()).await;
    assert!(
        matches!(failure(&reply), SkillError::Cancelled),
        "{reply:?}"
    );
    assert!(rig.script.heard().is_empty());
    assert!(rig.progress().is_empty());
    // A pick-and-place whose place cannot work (the tile onto the smaller cube is not; the
    // cube onto a marker): it looks, and neither the fingers nor the arm move after.
    let reply = rig
        .run(3, pick_place(Point2::new(0.33, 0.08), Location::None))
        .await;
    assert!(failure(&reply).to_string().contains("marker"), "{reply:?}");
    assert_eq!(
        rig.script.heard(),
        ["arm: observation pose of niryo_ws", "model: objects seen"]
    );
    // An object the gripper cannot span; a label not there (the reply names what is).
    rig.script.heard.lock().unwrap().clear();
    *rig.script.objects.lock().unwrap() = vec![object("obj-3", "red cube", 0.25, 0.0, 0.05, 0.03)];
    let reply = rig.run(4, pick()).await;
    assert!(
        matches!(failure(&reply), SkillError::TooWide { .. }),
        "{reply:?}"
    );
    let reply = rig
        .run(
            5,
            Skill::Pick {
                object_name: "pencil".into(),
                pick_at: Point2::new(0.25, 0.0),
                z_offset_m: 0.0,
            },
        )
        .await;
    let SkillError::ObjectNotFound { nearby, .. } = failure(&reply) else {
        panic!("{reply:?}");
    };
    assert_eq!(nearby, &["red cube"]);
    let heard = rig.script.heard();
    assert!(
        heard
            .iter()
            .all(|c| c == "arm: observation pose of niryo_ws" || c == "model: objects seen"),
        "{heard:?}"
    );
}

#[test]
fn the_nearest_object_with_the_label_within_the_radius_is_picked() {
    let near = object("a", "cube", 0.26, 0.0, 0.03, 0.03);
    let nearer = object("b", "cube", 0.251, 0.0, 0.03, 0.03);
    let other = object("c", "pen", 0.25, 0.0, 0.01, 0.01);
    let far = object("d", "cube", 0.32, 0.0, 0.03, 0.03);
    let all = [near, nearer, other, far];
    let found = find_object(&all, "cube", Point2::new(0.25, 0.0), 0.05).unwrap();
    assert_eq!(found.id, "b");
    let found = find_object(&all, "cube", Point2::new(0.33, 0.0), 0.05).unwrap();
    assert_eq!(found.id, "d");
    let Err(SkillError::ObjectNotFound { nearby, .. }) =
        find_object(&all, "ball", Point2::new(0.25, 0.0), 0.05)
    else {
        panic!("a ball was found");
    };
    assert_eq!(nearby, ["cube", "cube", "pen"]);
}

#[test]
fn early_cancels_are_taken_once_and_the_oldest_forgotten_first() {
    let flag = CancelFlag::default();
    flag.cancel_early(7);
    assert!(!flag.take_early(8));
    assert!(flag.take_early(7));
    assert!(!flag.take_early(7), "taken once");
    for id in 1..=EARLY_CANCELS as u64 + 1 {
        flag.cancel_early(id);
    }
    assert!(!flag.take_early(1), "the oldest is forgotten");
    assert!(flag.take_early(2) && flag.take_early(EARLY_CANCELS as u64 + 1));
}
