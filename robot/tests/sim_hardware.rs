//! The hardware actors on the simulated Ned2, driven through the real bus exactly as the skills
//! and edges will drive them: motions in time with state on `arm/state`, reachability checked
//! before anything moves, stop and emergency stop, collisions, grasping through
//! `gripper/command`, frames on `camera/frames` that show the scene where the projection says,
//! and supervised restarts under injected faults.

mod common;
use common::{test_config, TestConfig};

use robotd_kinematics::{pose_to_isometry, Kinematics};
use robotd_protocol::arm::{ArmCommand, ArmError, ArmReply, PathKind};
use robotd_protocol::geometry::{Pose, PoseDelta, RobotModel};
use robotd_protocol::gripper::{GripperCommand, GripperReply};
use robotd_protocol::health::{EStopRelease, EmergencyStop};
use robotd_render::Intrinsics;
use robotd_robot::Hardware;
use robotd_runtime::bus::{Bus, BusError, BusOptions, FaultKind};
use robotd_runtime::supervision::{observer_fn, SupervisionEvent};
use robotd_topics::{
    ARM_COMMAND, ARM_STATE, CAMERA_FRAMES, GRIPPER_COMMAND, SAFETY_ESTOP, SAFETY_RELEASE,
};
use std::f64::consts::FRAC_PI_2;
use std::time::{Duration, Instant};

const TIMEOUT: Duration = Duration::from_secs(20);

fn fresh_config(time_scale: f64) -> TestConfig {
    // Tests leave no audit files behind (no audit log).
    let mut config = test_config("hw");
    config.robot.time_scale = time_scale;
    config.robot.control_rate_hz = 100;
    config.robot.camera.fps = 30.0;
    config.supervision.backoff_initial_ms = 5;
    config
}

async fn start(config: &TestConfig) -> (Bus, Hardware) {
    let bus = Bus::open(BusOptions::new(&config.namespace, "robotd-test")).expect("bus");
    let hardware = Hardware::start(&bus, config, |_| observer_fn(|_: &SupervisionEvent| {}))
        .await
        .expect("hardware");
    (bus, hardware)
}

fn down(x: f64, y: f64, z: f64, yaw: f64) -> Pose {
    Pose::new(x, y, z, 0.0, FRAC_PI_2, yaw)
}

/// Waits until the simulated arm's joints have left `from`: the motion is under way (instead
/// of guessing how long starting one takes).
async fn wait_moving(joints: impl Fn() -> Vec<f64>, from: &[f64]) {
    let deadline = Instant::now() + TIMEOUT;
    while joints().iter().zip(from).all(|(a, b)| (a - b).abs() < 0.01) {
        assert!(Instant::now() < deadline, "the arm never started moving");
        tokio::time::sleep(Duration::from_millis(5)).await;
    }
}

fn pose_of(reply: ArmReply) -> Pose {
    match reply {
        ArmReply::Ok { pose } => pose,
        other => panic!("expected Ok with a pose, got {other:?}"),
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_motion_runs_in_time_publishes_its_state_and_reaches_the_target() {
    let config = fresh_config(1.0);
    let (bus, hardware) = start(&config).await;
    let arm = bus.client(&ARM_COMMAND).unwrap();
    let mut states = bus.subscriber(&ARM_STATE).unwrap();

    let target = down(0.25, 0.0, 0.08, 0.0);
    let started = Instant::now();
    let reached = pose_of(
        arm.request(&ArmCommand::move_to(target), TIMEOUT)
            .await
            .unwrap(),
    );
    let took = started.elapsed();
    assert!(
        reached.position().distance_to(&target.position()) < 0.001,
        "reached {reached}, wanted {target}"
    );
    // Timed from the velocity limits: a real motion, not a jump.
    assert!(took > Duration::from_millis(20), "took only {took:?}");

    let mut moving_states = 0;
    while let Ok(Some(state)) = states.try_recv() {
        if state.body.moving {
            moving_states += 1;
        }
    }
    assert!(
        moving_states >= 3,
        "only {moving_states} moving states on arm/state"
    );

    // A straight-line move keeps the tool on the line.
    let reached = pose_of(
        arm.request(
            &ArmCommand::MoveToPose {
                target: down(0.25, 0.06, 0.08, 0.0),
                path: PathKind::Linear,
            },
            TIMEOUT,
        )
        .await
        .unwrap(),
    );
    assert!((reached.y_m - 0.06).abs() < 0.001, "{reached}");
    hardware.shutdown().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn unreachable_targets_and_bad_joints_are_refused_before_anything_moves() {
    let config = fresh_config(0.05);
    let (bus, hardware) = start(&config).await;
    let arm = bus.client(&ARM_COMMAND).unwrap();
    let before = hardware.sim.as_ref().unwrap().joints();

    let far = down(0.9, 0.0, 0.1, 0.0);
    let reply = arm
        .request(&ArmCommand::move_to(far), TIMEOUT)
        .await
        .unwrap();
    match reply {
        ArmReply::Error {
            error: ArmError::Unreachable { target, reason },
        } => {
            assert_eq!(target, far);
            assert!(!reason.is_empty());
        }
        other => panic!("expected Unreachable, got {other:?}"),
    }
    let reply = arm
        .request(
            &ArmCommand::MoveJoints {
                positions_rad: vec![0.0, 3.0, 0.0, 0.0, 0.0, 0.0],
            },
            TIMEOUT,
        )
        .await
        .unwrap();
    assert!(
        matches!(
            reply,
            ArmReply::Error {
                error: ArmError::JointLimit { joint: 1, .. }
            }
        ),
        "{reply:?}"
    );
    let reply = arm
        .request(
            &ArmCommand::GoToObservationPose {
                workspace_id: "lab".into(),
            },
            TIMEOUT,
        )
        .await
        .unwrap();
    assert_eq!(
        reply.into_result().unwrap_err().to_string(),
        "unknown workspace 'lab'; known: niryo_ws, gazebo_1"
    );
    assert_eq!(hardware.sim.as_ref().unwrap().joints(), before);
    hardware.shutdown().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_emergency_stop_halts_a_motion_within_one_control_tick() {
    let mut config = fresh_config(1.0); // realistic speed: the motion takes a while
    config.robot.control_rate_hz = 50;
    let (bus, hardware) = start(&config).await;
    let sim = hardware.sim.clone().unwrap();
    let arm = bus.client(&ARM_COMMAND).unwrap();
    let estop = bus.publisher(&SAFETY_ESTOP).unwrap();

    let from = sim.joints();
    let long_motion = {
        let arm = bus.client(&ARM_COMMAND).unwrap();
        tokio::spawn(async move {
            arm.request(&ArmCommand::move_to(down(0.33, 0.08, 0.03, 0.0)), TIMEOUT)
                .await
        })
    };
    wait_moving(|| sim.joints(), &from).await;
    let engaged_at = Instant::now();
    estop
        .publish(&EmergencyStop {
            engaged: true,
            reason: "test".into(),
            source: "test".into(),
        })
        .unwrap();
    let reply = long_motion.await.unwrap().unwrap();
    let answered = engaged_at.elapsed();
    assert!(
        matches!(
            reply,
            ArmReply::Error {
                error: ArmError::EStopped { .. }
            }
        ),
        "{reply:?}"
    );
    let halted = sim.joints();
    // One control tick is 20 ms; allow scheduling slack on a busy 2-core machine.
    assert!(answered < Duration::from_millis(120), "took {answered:?}");
    tokio::time::sleep(Duration::from_millis(100)).await;
    assert_eq!(sim.joints(), halted, "the arm kept moving after the e-stop");

    // While engaged, nothing moves.
    let reply = arm
        .request(&ArmCommand::move_to(down(0.25, 0.0, 0.1, 0.0)), TIMEOUT)
        .await
        .unwrap();
    assert!(
        matches!(
            reply,
            ArmReply::Error {
                error: ArmError::EStopped { .. }
            }
        ),
        "{reply:?}"
    );
    // Released only by a request to the policy, which answers once it is released.
    let state = bus
        .client(&SAFETY_RELEASE)
        .unwrap()
        .request(
            &EStopRelease {
                confirm: "release".into(),
                by: "test over".into(),
                only_if_reason: None,
            },
            TIMEOUT,
        )
        .await
        .unwrap();
    assert!(!state.engaged, "{state:?}");
    assert!(hardware.safety.estop().is_none());
    let reply = arm.request(&ArmCommand::GetPose, TIMEOUT).await.unwrap();
    assert!(matches!(reply, ArmReply::Ok { .. }));
    hardware.shutdown().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn stop_and_queries_are_answered_while_a_motion_runs() {
    let config = fresh_config(1.0);
    let (bus, hardware) = start(&config).await;
    let arm = bus.client(&ARM_COMMAND).unwrap();
    let sim = hardware.sim.clone().unwrap();
    let from = sim.joints();
    let motion = {
        let arm = bus.client(&ARM_COMMAND).unwrap();
        tokio::spawn(async move {
            // From the rest pose to the sheet's far corner: long enough to be stopped midway.
            arm.request(&ArmCommand::move_to(down(0.33, 0.08, 0.03, 0.0)), TIMEOUT)
                .await
        })
    };
    wait_moving(|| sim.joints(), &from).await;
    let asked = Instant::now();
    let joints = arm.request(&ArmCommand::GetJoints, TIMEOUT).await.unwrap();
    assert!(matches!(joints, ArmReply::Joints { .. }));
    let stop = arm.request(&ArmCommand::Stop, TIMEOUT).await.unwrap();
    assert!(matches!(stop, ArmReply::Ok { .. }));
    assert!(asked.elapsed() < Duration::from_millis(200));
    let reply = motion.await.unwrap().unwrap();
    assert!(
        matches!(
            reply,
            ArmReply::Error {
                error: ArmError::Stopped
            }
        ),
        "{reply:?}"
    );
    hardware.shutdown().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn moving_into_the_table_is_a_collision_until_cleared() {
    let mut config = fresh_config(0.05);
    // The safety policy's floor would refuse this motion before it starts (tested in
    // robotd-safety); lower it so the driver's own collision handling is what is tested here.
    config.safety.floor_z_m = -0.1;
    let (bus, hardware) = start(&config).await;
    let arm = bus.client(&ARM_COMMAND).unwrap();
    // An empty spot of the sheet, then straight down through the table.
    arm.request(&ArmCommand::move_to(down(0.18, 0.0, 0.06, 0.0)), TIMEOUT)
        .await
        .unwrap()
        .into_result()
        .unwrap();
    let reply = arm
        .request(
            &ArmCommand::MoveToPose {
                target: down(0.18, 0.0, -0.05, 0.0),
                path: PathKind::Linear,
            },
            TIMEOUT,
        )
        .await
        .unwrap();
    assert_eq!(
        reply,
        ArmReply::Error {
            error: ArmError::Collision
        }
    );
    let state = arm
        .request(&ArmCommand::GetCollisionState, TIMEOUT)
        .await
        .unwrap();
    assert_eq!(
        state,
        ArmReply::CollisionState {
            collision_detected: true
        }
    );
    let up = ArmCommand::ShiftPose {
        delta: PoseDelta::translation(0.0, 0.0, 0.05),
    };
    let refused = arm.request(&up, TIMEOUT).await.unwrap();
    assert!(refused.into_result().is_err());
    arm.request(&ArmCommand::ClearCollision, TIMEOUT)
        .await
        .unwrap()
        .into_result()
        .unwrap();
    arm.request(&up, TIMEOUT)
        .await
        .unwrap()
        .into_result()
        .unwrap();
    hardware.shutdown().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_gripper_grasps_only_what_it_is_really_around() {
    let config = fresh_config(0.05);
    let (bus, hardware) = start(&config).await;
    let sim = hardware.sim.clone().unwrap();
    let arm = bus.client(&ARM_COMMAND).unwrap();
    let gripper = bus.client(&GRIPPER_COMMAND).unwrap();
    let cube = sim.with_world(|w| {
        w.objects()
            .iter()
            .find(|o| o.spec.label == "red cube")
            .map(|o| (o.id, o.pose.translation.vector))
            .unwrap()
    });
    let (id, centre) = cube;

    let grasp_at = |dx: f64| {
        let arm = &arm;
        let gripper = &gripper;
        async move {
            let open = gripper
                .request(&GripperCommand::Open, TIMEOUT)
                .await
                .unwrap();
            assert!(!open.holding().unwrap());
            for z in [centre.z + 0.06, centre.z] {
                arm.request(
                    &ArmCommand::MoveToPose {
                        target: down(centre.x + dx, centre.y, z, 0.0),
                        path: PathKind::Linear,
                    },
                    TIMEOUT,
                )
                .await
                .unwrap()
                .into_result()
                .unwrap();
            }
            gripper
                .request(&GripperCommand::Close, TIMEOUT)
                .await
                .unwrap()
        }
    };

    // 1 cm off the cube's centre: the fingers close on nothing.
    let missed = grasp_at(0.010).await;
    assert!(
        matches!(missed, GripperReply::State { holding: false, .. }),
        "{missed:?}"
    );
    arm.request(
        &ArmCommand::ShiftPose {
            delta: PoseDelta::translation(0.0, 0.0, 0.06),
        },
        TIMEOUT,
    )
    .await
    .unwrap()
    .into_result()
    .unwrap();

    // Centred: it holds the cube, and the cube comes along when the arm lifts.
    let held = grasp_at(0.0).await;
    match held {
        GripperReply::State { holding, width_m } => {
            assert!(holding);
            assert!((width_m - 0.030).abs() < 0.003, "width {width_m}");
        }
        other => panic!("{other:?}"),
    }
    arm.request(
        &ArmCommand::ShiftPose {
            delta: PoseDelta::translation(0.0, 0.0, 0.05),
        },
        TIMEOUT,
    )
    .await
    .unwrap()
    .into_result()
    .unwrap();
    let lifted = sim.with_world(|w| w.object(id).unwrap().pose.translation.vector);
    assert!(
        (lifted.z - centre.z - 0.05).abs() < 0.003,
        "cube at z {} (was {})",
        lifted.z,
        centre.z
    );
    hardware.shutdown().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn frames_at_the_observation_pose_show_markers_and_objects_where_the_projection_says() {
    let mut config = fresh_config(0.05);
    config.robot.camera.noise_stddev = 2.0;
    let (bus, hardware) = start(&config).await;
    let sim = hardware.sim.clone().unwrap();
    let arm = bus.client(&ARM_COMMAND).unwrap();
    let mut frames = bus.frame_subscriber(&CAMERA_FRAMES).unwrap();
    arm.request(
        &ArmCommand::GoToObservationPose {
            workspace_id: "niryo_ws".into(),
        },
        TIMEOUT,
    )
    .await
    .unwrap()
    .into_result()
    .unwrap();
    let arrived = robotd_protocol::envelope::unix_now_ns();
    let frame = loop {
        let frame = tokio::time::timeout(TIMEOUT, frames.recv())
            .await
            .expect("a frame within the timeout")
            .unwrap();
        if frame.header().timestamp_unix_ns > arrived {
            break frame;
        }
    };
    let header = *frame.header();
    assert_eq!((header.width, header.height), (640, 480));
    let camera = pose_to_isometry(&Pose::from_array(header.camera_pose));
    let world_to_camera = camera.inverse();
    let intrinsics = Intrinsics::ned2();
    let pixels = frame.pixels();
    let pixel = |x: f64, y: f64| -> [u8; 3] {
        let (u, v) = (x.round() as usize, y.round() as usize);
        let i = (v * 640 + u) * 3;
        [pixels[i], pixels[i + 1], pixels[i + 2]]
    };

    let markers = sim.with_world(|w| w.markers());
    assert_eq!(markers.len(), 4, "niryo_ws and gazebo_1 share one sheet");
    for marker in &markers {
        let p = intrinsics
            .project(&world_to_camera, &marker.center)
            .unwrap_or_else(|| panic!("marker at {:?} behind the camera", marker.center));
        assert!(
            (0.0..640.0).contains(&p.x) && (0.0..480.0).contains(&p.y),
            "marker {:?} projects outside the image at {p:?}",
            marker.center
        );
        let [r, g, b] = pixel(p.x, p.y);
        let brightness = (u32::from(r) + u32::from(g) + u32::from(b)) / 3;
        if marker.white_centre {
            assert!(
                brightness > 180,
                "white-centre marker is {brightness} at {p:?}"
            );
        } else {
            assert!(brightness < 80, "marker centre is {brightness} at {p:?}");
        }
    }
    let objects = sim.with_world(|w| w.objects().to_vec());
    for object in &objects {
        // The centre of the object's top face.
        let top = object.pose.translation.vector
            + nalgebra::Vector3::new(0.0, 0.0, object_half_height(object));
        let p = intrinsics
            .project(&world_to_camera, &nalgebra::Point3::from(top))
            .unwrap();
        let seen = pixel(p.x, p.y);
        let want = object.spec.color;
        let dominant = |c: [u8; 3]| (0..3).max_by_key(|i| c[*i]).unwrap();
        assert_eq!(
            dominant(seen),
            dominant(want),
            "'{}' should look {want:?} at {p:?}, saw {seen:?}",
            object.spec.label
        );
    }
    hardware.shutdown().await;
}

fn object_half_height(object: &robotd_sim::SimObject) -> f64 {
    match object.spec.shape {
        robotd_sim::ObjectShape::Box { height_z_m, .. } => height_z_m / 2.0,
        robotd_sim::ObjectShape::Cylinder { height_m, .. } => height_m / 2.0,
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn injected_faults_restart_the_arm_safely_and_the_next_command_works() {
    let mut config = fresh_config(0.05);
    config.robot.faults.arm.fail_every_n = 2;
    let bus = Bus::open(BusOptions::new(&config.namespace, "robotd-test")).unwrap();
    let (events_tx, mut events) = tokio::sync::mpsc::unbounded_channel::<SupervisionEvent>();
    let hardware = Hardware::start(&bus, &config, |_| events_tx.clone())
        .await
        .unwrap();
    let arm = bus.client(&ARM_COMMAND).unwrap();
    let kin = Kinematics::new(RobotModel::Ned2);
    let home = kin.home_joints();
    let mut moved = home.clone();
    moved[0] += 0.2;

    // Command 1 works, command 2 crashes the driver: the caller is told, once.
    arm.request(
        &ArmCommand::MoveJoints {
            positions_rad: moved.clone(),
        },
        TIMEOUT,
    )
    .await
    .unwrap()
    .into_result()
    .unwrap();
    let failed = arm
        .request(
            &ArmCommand::MoveJoints {
                positions_rad: home.clone(),
            },
            TIMEOUT,
        )
        .await;
    match failed {
        Err(BusError::Remote { fault, .. }) => {
            assert_eq!(fault.kind, FaultKind::ActorFailed, "{fault:?}")
        }
        other => panic!("expected an ActorFailed fault, got {other:?}"),
    }
    hardware
        .arm
        .wait_ready(Duration::from_secs(5))
        .await
        .unwrap();
    // The restarted arm takes the next command.
    arm.request(
        &ArmCommand::MoveJoints {
            positions_rad: home.clone(),
        },
        TIMEOUT,
    )
    .await
    .unwrap()
    .into_result()
    .unwrap();

    let mut kinds = Vec::new();
    while let Ok(event) = events.try_recv() {
        if event.actor() == "arm" {
            kinds.push(event.kind());
        }
    }
    let failed_at = kinds
        .iter()
        .position(|k| *k == "failed")
        .expect("a failure event");
    assert_eq!(
        &kinds[failed_at..failed_at + 3],
        ["failed", "safe_state", "restarted"],
        "{kinds:?}"
    );
    hardware.shutdown().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_emergency_stop_stays_engaged_across_a_restart_of_the_arm_actor() {
    let mut config = fresh_config(0.05);
    // The first motion hangs for 300 ms, then crashes the driver.
    config.robot.faults.arm.fail_every_n = 1;
    config.robot.faults.arm.hang_ms = 300;
    let bus = Bus::open(BusOptions::new(&config.namespace, "robotd-test")).unwrap();
    let (events_tx, mut events) = tokio::sync::mpsc::unbounded_channel::<SupervisionEvent>();
    let hardware = Hardware::start(&bus, &config, |_| events_tx.clone())
        .await
        .unwrap();
    let arm = bus.client(&ARM_COMMAND).unwrap();
    let estop = bus.publisher(&SAFETY_ESTOP).unwrap();
    let crashing = {
        let arm = bus.client(&ARM_COMMAND).unwrap();
        tokio::spawn(async move {
            arm.request(&ArmCommand::move_to(down(0.25, 0.0, 0.1, 0.0)), TIMEOUT)
                .await
        })
    };
    // Engage while the doomed command hangs in the driver: once it is past the policy and
    // its motion has begun (the arm is no longer still).
    let deadline = Instant::now() + TIMEOUT;
    while hardware.arm_context.still_since_ns() != 0 {
        assert!(
            Instant::now() < deadline,
            "the command never reached the driver"
        );
        tokio::time::sleep(Duration::from_millis(2)).await;
    }
    estop
        .publish(&EmergencyStop {
            engaged: true,
            reason: "before the crash".into(),
            source: "test".into(),
        })
        .unwrap();
    assert!(
        crashing.await.unwrap().is_err(),
        "the command was meant to crash the driver"
    );
    // Wait for the restart.
    loop {
        let event = tokio::time::timeout(TIMEOUT, events.recv())
            .await
            .expect("supervision events")
            .unwrap();
        if event.actor() == "arm" && event.kind() == "restarted" {
            break;
        }
    }
    hardware.arm.wait_ready(TIMEOUT).await.unwrap();
    // The new incarnation still refuses motion, with the reason given before the crash.
    let reply = arm
        .request(&ArmCommand::move_to(down(0.25, 0.0, 0.1, 0.0)), TIMEOUT)
        .await
        .unwrap();
    assert_eq!(
        reply,
        ArmReply::Error {
            error: ArmError::EStopped {
                reason: "before the crash".into()
            }
        }
    );
    assert!(hardware.safety.estop().is_some());
    hardware.shutdown().await;
}
