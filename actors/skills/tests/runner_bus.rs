//! The skills runner on a real bus, against scripted arm, gripper and workspace-model
//! services that record every command: the order of a pick's motions, what a failure leaves
//! and how the next skill recovers from it, a cancel in the middle of a motion, and skills
//! that must not move at all.

use robotd_protocol::arm::{ArmCommand, ArmError, ArmReply, PathKind};
use robotd_protocol::gripper::{GripperCommand, GripperReply};
use robotd_protocol::objects::{DetectedObject, Dimensions, ObjectPosition};
use robotd_protocol::skills::{Skill, SkillCancel, SkillReply, SkillRequest};
use robotd_protocol::workspace::{WorkspaceInfo, WorkspaceQuery, WorkspaceReply, WorkspaceRequest};
use robotd_protocol::{Location, Point2, Point3, Pose, RobotModel};
use robotd_runtime::bus::{Bus, BusOptions};
use robotd_skills::{Skills, SkillsSettings};
use std::sync::atomic::{AtomicBool, AtomicU32, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

const TIMEOUT: Duration = Duration::from_secs(10);

/// A bus of its own for each test.
fn open_bus(test: &str) -> Bus {
    static COUNTER: AtomicU32 = AtomicU32::new(0);
    let namespace = format!(
        "test-skills-{}-{}-{test}",
        std::process::id(),
        COUNTER.fetch_add(1, Ordering::Relaxed)
    );
    Bus::open(BusOptions::new(&namespace, "skills-test")).unwrap()
}

fn workspace() -> WorkspaceInfo {
    WorkspaceInfo {
        id: "niryo_ws".into(),
        robot: RobotModel::Ned2,
        upper_left: Point2::new(0.337, 0.087),
        lower_right: Point2::new(0.163, -0.087),
        observation_pose: Pose::new(0.25, 0.0, 0.3, 0.0, std::f64::consts::FRAC_PI_2, 0.0),
    }
}

fn cube() -> DetectedObject {
    DetectedObject {
        id: "obj-1".into(),
        label: "red cube".into(),
        workspace_id: "niryo_ws".into(),
        position: ObjectPosition {
            center_of_mass: Point3::new(0.25, 0.0, 0.015),
            center: Point3::new(0.25, 0.0, 0.015),
        },
        dimensions: Dimensions {
            width_m: 0.03,
            height_m: 0.03,
            size_m2: 0.0009,
        },
        confidence: 0.99,
        ..Default::default()
    }
}

/// What the scripted services heard and do.
#[derive(Default)]
struct World {
    arm: Mutex<Vec<ArmCommand>>,
    gripper: Mutex<Vec<GripperCommand>>,
    workspace: Mutex<Vec<WorkspaceRequest>>,
    pose: Mutex<Pose>,
    /// Whether closing the fingers finds an object.
    grasps: AtomicBool,
    /// Whether the fingers hold one now.
    holding: AtomicBool,
    /// The next straight-line move up collides (the tool stays down).
    collide_lifting: AtomicBool,
    /// A straight-line move down answers only when cancelled (it then says `Stopped`).
    hang_going_down: AtomicBool,
    stopped: tokio::sync::Notify,
    going_down: tokio::sync::Notify,
}

impl World {
    fn arm_commands(&self) -> Vec<ArmCommand> {
        self.arm.lock().unwrap().clone()
    }
}

/// The scripted arm's answer to `command`.
async fn scripted_arm(w: &World, command: ArmCommand) -> ArmReply {
    w.arm.lock().unwrap().push(command.clone());
    match command {
        ArmCommand::Stop => {
            w.stopped.notify_one();
            ArmReply::Ok {
                pose: *w.pose.lock().unwrap(),
            }
        }
        ArmCommand::MoveToPose { target, path } => {
            let now = *w.pose.lock().unwrap();
            let linear = path == PathKind::Linear;
            if linear && target.z_m < now.z_m && w.hang_going_down.load(Ordering::SeqCst) {
                w.going_down.notify_one();
                w.stopped.notified().await;
                return ArmReply::Error {
                    error: ArmError::Stopped,
                };
            }
            if linear && target.z_m > now.z_m && w.collide_lifting.swap(false, Ordering::SeqCst) {
                return ArmReply::Error {
                    error: ArmError::Collision,
                };
            }
            *w.pose.lock().unwrap() = target;
            ArmReply::Ok { pose: target }
        }
        ArmCommand::GoToObservationPose { .. } => {
            let pose = workspace().observation_pose;
            *w.pose.lock().unwrap() = pose;
            ArmReply::Ok { pose }
        }
        _ => ArmReply::Ok {
            pose: *w.pose.lock().unwrap(),
        },
    }
}

/// Serves `arm/command`, `gripper/command` and `workspace/query` from `world` and starts the
/// skills actor.
fn start(bus: &Bus, world: &Arc<World>) -> Skills {
    *world.pose.lock().unwrap() = workspace().observation_pose;
    // Like the arm actor: every request handled at once in a task of its own (so `Stop`
    // reaches a motion that hangs), each reply sent when its handling ends.
    let mut arm = bus.server(&robotd_topics::ARM_COMMAND).unwrap();
    let w = world.clone();
    tokio::spawn(async move {
        let (done_tx, mut done_rx) = tokio::sync::mpsc::unbounded_channel();
        loop {
            tokio::select! {
                incoming = arm.next() => {
                    let Ok(incoming) = incoming else { return };
                    let (envelope, pending) = incoming.split();
                    let (w, done) = (w.clone(), done_tx.clone());
                    tokio::spawn(async move {
                        let reply = scripted_arm(&w, envelope.body).await;
                        let _ = done.send((pending, reply));
                    });
                }
                Some((pending, reply)) = done_rx.recv() => {
                    let _ = arm.respond(pending, Ok(reply));
                }
            }
        }
    });
    let mut gripper = bus.server(&robotd_topics::GRIPPER_COMMAND).unwrap();
    let w = world.clone();
    tokio::spawn(async move {
        gripper
            .serve(move |command: GripperCommand| {
                let w = w.clone();
                async move {
                    match command {
                        GripperCommand::Close => w
                            .holding
                            .store(w.grasps.load(Ordering::SeqCst), Ordering::SeqCst),
                        GripperCommand::GetState => {}
                        _ => w.holding.store(false, Ordering::SeqCst),
                    }
                    w.gripper.lock().unwrap().push(command);
                    let holding = w.holding.load(Ordering::SeqCst);
                    Ok(GripperReply::State {
                        holding,
                        width_m: if holding { 0.03 } else { 0.0 },
                    })
                }
            })
            .await
    });
    let mut model = bus.server(&robotd_topics::WORKSPACE_QUERY).unwrap();
    let w = world.clone();
    tokio::spawn(async move {
        model
            .serve(move |query: WorkspaceQuery| {
                let w = w.clone();
                async move {
                    w.workspace.lock().unwrap().push(query.request.clone());
                    Ok(match query.request {
                        WorkspaceRequest::GetObjects { .. } => WorkspaceReply::Objects {
                            objects: vec![cube()],
                        },
                        _ => WorkspaceReply::Object {
                            object: Some(cube()),
                        },
                    })
                }
            })
            .await
    });
    Skills::start(
        bus,
        SkillsSettings::new(RobotModel::Ned2, vec![workspace()]),
    )
    .unwrap()
}

fn pick() -> Skill {
    Skill::Pick {
        object_name: "red cube".into(),
        pick_at: Point2::new(0.25, 0.0),
        z_offset_m: 0.0,
    }
}

async fn run(bus: &Bus, run_id: u64, skill: Skill) -> SkillReply {
    let client = bus.client(&robotd_topics::SKILLS_RUN).unwrap();
    client
        .request(&SkillRequest { run_id, skill }, TIMEOUT)
        .await
        .unwrap()
}

/// The failure's text as a caller reads it; empty for a success.
fn failure(reply: &SkillReply) -> String {
    match reply {
        SkillReply::Failed { error, .. } => error.to_string(),
        _ => String::new(),
    }
}

/// The tool-centre heights of the straight-line moves, in order.
fn linear_heights(commands: &[ArmCommand]) -> Vec<f64> {
    commands
        .iter()
        .filter_map(|c| match c {
            ArmCommand::MoveToPose {
                target,
                path: PathKind::Linear,
            } => Some(target.z_m),
            _ => None,
        })
        .collect()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_pick_looks_goes_down_straight_closes_and_lifts() {
    let bus = open_bus("pick");
    let world = Arc::new(World::default());
    world.grasps.store(true, Ordering::SeqCst);
    let skills = start(&bus, &world);
    let reply = run(&bus, 1, pick()).await;
    assert!(matches!(reply, SkillReply::Done { .. }), "{reply:?}");
    let commands = world.arm_commands();
    assert!(
        matches!(commands.first(), Some(ArmCommand::GoToObservationPose { workspace_id }) if workspace_id == "niryo_ws"),
        "it looks first: {commands:?}"
    );
    // Down to the grasp in a straight line, then up again; never below the lowest height.
    let heights = linear_heights(&commands);
    let lowest = heights.iter().copied().fold(f64::INFINITY, f64::min);
    assert!(heights.len() >= 2, "{commands:?}");
    assert!(
        (0.003..0.03).contains(&lowest),
        "grasp height {lowest}: {commands:?}"
    );
    assert!(
        *heights.last().unwrap() > lowest,
        "it lifts after the grasp"
    );
    // The fingers open before going down and close at the bottom.
    let gripper = world.gripper.lock().unwrap().clone();
    assert_eq!(gripper.first(), Some(&GripperCommand::Open), "{gripper:?}");
    assert!(gripper.contains(&GripperCommand::Close), "{gripper:?}");
    // The workspace model heard that the cube is now in the gripper.
    let told = world.workspace.lock().unwrap().clone();
    assert!(
        told.iter().any(
            |r| matches!(r, WorkspaceRequest::ObjectPicked { object_id } if object_id == "obj-1")
        ),
        "{told:?}"
    );
    // Holding it, a second pick is refused without any motion.
    let before = world.arm_commands().len();
    let reply = run(&bus, 2, pick()).await;
    assert!(matches!(reply, SkillReply::Failed { .. }), "{reply:?}");
    assert_eq!(world.arm_commands().len(), before, "nothing moved");
    skills.shutdown().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn after_a_failure_near_the_table_the_tool_rises_straight_up_first() {
    let bus = open_bus("miss");
    let world = Arc::new(World::default());
    let skills = start(&bus, &world);
    // Closing on nothing: the reply says so.
    let reply = run(&bus, 1, pick()).await;
    let text = failure(&reply);
    assert!(text.contains("closed on nothing"), "{text}");
    // A place with nothing held: refused, nothing moves.
    let before = world.arm_commands().len();
    let place = Skill::Place {
        place_at: Point2::new(0.3, 0.0),
        location: Location::None,
    };
    let reply = run(&bus, 2, place).await;
    assert!(failure(&reply).contains("holds nothing"), "{reply:?}");
    assert_eq!(world.arm_commands().len(), before);
    // A collision lifting from the grasp leaves the tool down at the table: the next motion
    // is a straight rise from there, never a joint-space move from near the table.
    world.arm.lock().unwrap().clear();
    world.grasps.store(true, Ordering::SeqCst);
    world.collide_lifting.store(true, Ordering::SeqCst);
    let reply = run(&bus, 3, pick()).await;
    assert!(failure(&reply).contains("ollision"), "{reply:?}");
    let commands = world.arm_commands();
    let motions: Vec<(f64, PathKind)> = commands
        .iter()
        .filter_map(|c| match c {
            ArmCommand::MoveToPose { target, path } => Some((target.z_m, *path)),
            ArmCommand::MoveJoints { .. } | ArmCommand::GoToObservationPose { .. } => {
                Some((f64::NAN, PathKind::Joint))
            }
            _ => None,
        })
        .collect();
    let down = motions
        .iter()
        .position(|(z, path)| *path == PathKind::Linear && *z < 0.03)
        .expect("it went down");
    let low = motions[down].0;
    // motions[down + 1] is the lift that collided; the one after it rises straight up.
    let (z, path) = motions[down + 2];
    assert!(
        path == PathKind::Linear && z > low + 0.02,
        "after the collision at z {low} it rose straight up first: {commands:?}"
    );
    assert!(
        world.pose.lock().unwrap().z_m > low + 0.02,
        "and is clear of the table"
    );
    skills.shutdown().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_cancel_stops_the_arm_and_nothing_moves_after_it() {
    let bus = open_bus("cancel");
    let world = Arc::new(World::default());
    world.grasps.store(true, Ordering::SeqCst);
    world.hang_going_down.store(true, Ordering::SeqCst);
    let skills = start(&bus, &world);
    let cancels = bus.publisher(&robotd_topics::SKILLS_CANCEL).unwrap();
    let running = {
        let bus_client = bus.client(&robotd_topics::SKILLS_RUN).unwrap();
        tokio::spawn(async move {
            bus_client
                .request(
                    &SkillRequest {
                        run_id: 7,
                        skill: pick(),
                    },
                    TIMEOUT,
                )
                .await
        })
    };
    // While the arm goes down, the caller cancels run 7.
    tokio::time::timeout(TIMEOUT, world.going_down.notified())
        .await
        .expect("the pick went down");
    cancels.publish(&SkillCancel { run_id: 7 }).unwrap();
    let reply = running.await.unwrap().unwrap();
    assert!(failure(&reply).contains("ancel"), "{reply:?}");
    let commands = world.arm_commands();
    let stop = commands
        .iter()
        .position(|c| *c == ArmCommand::Stop)
        .expect("the arm was stopped");
    assert!(
        commands[stop + 1..].iter().all(|c| !matches!(
            c,
            ArmCommand::MoveToPose { .. } | ArmCommand::MoveJoints { .. }
        )),
        "no motion after the stop: {commands:?}"
    );
    assert!(
        !world
            .gripper
            .lock()
            .unwrap()
            .contains(&GripperCommand::Close),
        "the fingers never closed"
    );
    skills.shutdown().await;
}
