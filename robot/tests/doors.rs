//! Issue 39: the side doors 2, 3 and 6, each closed, against the simulator behind drivers that
//! record every actuator call (door 1, the Niryo driver's own calibration, is tested against
//! the fake Ned2 in `fakes/niryo/tests/driver_against_fake.rs`; the property test over every
//! origin is `one_door.rs`). Each test failed on the code before the one door: calibrations
//! went straight to the driver, the gripper actor ran what it was given, approval was asked
//! only by the skills actor, and rate limits counted per session.

mod common;

use common::{fresh_config, rig, RecordingGripper};
use robotd_kinematics::{pose_to_isometry, Kinematics};
use robotd_protocol::arm::{ArmCommand, ArmError, ArmReply};
use robotd_protocol::geometry::{Pose, RobotModel};
use robotd_protocol::gripper::{GripperCommand, GripperError, GripperReply};
use robotd_protocol::safety::{Origin, OriginKind};
use robotd_runtime::origin::with_origin;
use robotd_runtime::supervision::Supervisor;
use robotd_safety::config::KeepOutBox;
use robotd_topics::{ARM_COMMAND, GRIPPER_COMMAND};
use std::f64::consts::FRAC_PI_2;
use std::sync::Arc;
use std::time::{Duration, Instant};

const TIMEOUT: Duration = Duration::from_secs(20);

fn down(x: f64, y: f64, z: f64) -> Pose {
    Pose::new(x, y, z, 0.0, FRAC_PI_2, 0.0)
}

/// Door 2: a calibration ends at the rest pose, and the policy checks that motion like any
/// other. With a keep-out box around the rest pose's tool position, `Calibrate` is refused
/// naming the box, and the driver's `calibrate` is never called.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_calibration_passes_the_plan_check_of_its_motion() {
    let kinematics = Kinematics::new(RobotModel::Ned2);
    let rest = kinematics
        .tool_pose(&kinematics.home_joints())
        .unwrap()
        .translation
        .vector;
    let mut config = fresh_config(0.05);
    config.safety.keep_out = vec![KeepOutBox {
        name: "fixture at the rest pose".into(),
        min: [rest.x - 0.03, rest.y - 0.03, rest.z - 0.03],
        max: [rest.x + 0.03, rest.y + 0.03, rest.z + 0.03],
    }];
    let rig = rig(&config).await;
    let away = kinematics
        .inverse(
            &pose_to_isometry(&down(0.25, 0.0, 0.15)),
            Some(&kinematics.home_joints()),
        )
        .unwrap();
    rig.sim.teleport(&away).unwrap();
    let arm = rig.bus.client(&ARM_COMMAND).unwrap();
    let reply = arm.request(&ArmCommand::Calibrate, TIMEOUT).await.unwrap();
    match &reply {
        ArmReply::Error {
            error: ArmError::Refused { limit, reason },
        } => {
            assert_eq!(limit, "keep_out", "{reason}");
            assert!(reason.contains("fixture at the rest pose"), "{reason}");
        }
        other => panic!("the calibration was not refused: {other:?}"),
    }
    assert_eq!(rig.calls.count("calibrate"), 0);
    // Without the box in the way it runs.
    config.safety.keep_out.clear();
    let free = rig_without_box(&config, &away).await;
    assert_eq!(free, 1);
    rig.hardware.shutdown().await;
}

async fn rig_without_box(config: &common::TestConfig, start: &[f64]) -> usize {
    let mut config = config.clone();
    config.namespace.push_str("-free");
    let rig = rig(&config).await;
    rig.sim.teleport(start).unwrap();
    let arm = rig.bus.client(&ARM_COMMAND).unwrap();
    let reply = arm.request(&ArmCommand::Calibrate, TIMEOUT).await.unwrap();
    assert!(matches!(reply, ArmReply::Ok { .. }), "{reply:?}");
    let count = rig.calls.count("calibrate");
    rig.hardware.shutdown().await;
    count
}

/// Door 3: the gripper actor takes only admitted commands, and checks the e-stop again right
/// before the driver call: an admission made before the e-stop moves nothing after it, and an
/// admission for the arm does not move the gripper.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_gripper_actor_rechecks_the_estop_after_admission() {
    let config = fresh_config(0.05);
    let rig = rig(&config).await;
    let calls = common::Calls::default();
    let sim = robotd_driver_sim::open(&config.robot).unwrap();
    let driver = Arc::new(RecordingGripper {
        inner: sim.drivers.gripper.clone(),
        calls: calls.clone(),
        control: rig.safety.control().clone(),
    });
    let safety = rig.safety.clone();
    let actor = Supervisor::new("gripper-door-3")
        .spawn_actor::<robotd_gripper::GripperActor>(move || {
            robotd_gripper::GripperActor::new(driver.clone(), safety.clone(), None)
        })
        .await
        .unwrap();
    let origin = Origin::new(OriginKind::Bus);
    let admit = |actor: &'static str| {
        let safety = rig.safety.clone();
        let origin = origin.clone();
        async move {
            safety
                .admit(&origin, actor, "close", serde_json::Value::Null)
                .await
                .unwrap()
        }
    };

    // Admitted, then the e-stop: refused at the driver's door.
    let admission = admit("gripper").await;
    rig.safety.control().set_estop(true, "hand in the gripper");
    let reply = actor
        .ask(robotd_gripper::Admitted {
            command: GripperCommand::Close,
            admission,
        })
        .await
        .unwrap();
    assert!(
        matches!(
            &reply,
            GripperReply::Error {
                error: GripperError::EStopped { reason }
            } if reason == "hand in the gripper"
        ),
        "{reply:?}"
    );
    rig.safety.control().set_estop(false, "");

    // An admission for the arm does not open the gripper's door.
    let admission = admit("arm").await;
    let reply = actor
        .ask(robotd_gripper::Admitted {
            command: GripperCommand::Close,
            admission,
        })
        .await
        .unwrap();
    assert!(
        matches!(
            &reply,
            GripperReply::Error {
                error: GripperError::Refused { limit, .. }
            } if limit == "admission"
        ),
        "{reply:?}"
    );
    assert_eq!(calls.count("close"), 0);

    // A proper one closes it.
    let admission = admit("gripper").await;
    let reply = actor
        .ask(robotd_gripper::Admitted {
            command: GripperCommand::Close,
            admission,
        })
        .await
        .unwrap();
    assert!(matches!(reply, GripperReply::State { .. }), "{reply:?}");
    assert_eq!(calls.count("close"), 1);
    actor.shutdown().await.unwrap();
    rig.hardware.shutdown().await;
}

/// Door 6, approval: with `push_object` needing approval, a client that sends `arm/command`
/// directly (no tool run's grant) waits for a human like the tool would; denied, nothing
/// moves. A tool run the policy granted (not listed: no human needed) moves without asking.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_bare_arm_command_needs_the_approval_its_tools_need() {
    let mut config = fresh_config(0.05);
    config.safety.approval_tools = vec!["push_object".into()];
    config.safety.approval_timeout_s = 20;
    let rig = rig(&config).await;
    let arm = rig.bus.client(&ARM_COMMAND).unwrap();
    let target = ArmCommand::move_to(down(0.25, 0.02, 0.12));

    let bare = {
        let arm = rig.bus.client(&ARM_COMMAND).unwrap();
        let target = target.clone();
        tokio::spawn(with_origin(Origin::new(OriginKind::Bus), async move {
            arm.request(&target, TIMEOUT).await.unwrap()
        }))
    };
    let asked = Instant::now();
    let request = loop {
        if let Some(request) = rig.safety.approvals().pending().first().cloned() {
            break request;
        }
        assert!(asked.elapsed() < TIMEOUT, "no approval was asked for");
        tokio::time::sleep(Duration::from_millis(5)).await;
    };
    assert_eq!(request.action, "move_to_pose");
    rig.safety
        .approvals()
        .answer(request.id, false, "the operator")
        .unwrap();
    let reply = bare.await.unwrap();
    assert!(
        matches!(
            &reply,
            ArmReply::Error { error: ArmError::Refused { limit, reason } }
                if limit == "approval" && reason.contains("denied by the operator")
        ),
        "{reply:?}"
    );
    assert_eq!(rig.calls.count("execute"), 0);

    // A tool run (pick_object is not listed): the policy grants it without a human, and its
    // commands carry the grant.
    let origin = Origin::new(OriginKind::Mcp).session("s1");
    let grant = rig
        .safety
        .approve_tool(&origin, "pick_object", "pick 'pencil'")
        .await
        .unwrap();
    let mut run = origin.clone();
    run.approval_id = grant;
    let reply = with_origin(run, arm.request(&target, TIMEOUT))
        .await
        .unwrap();
    assert!(matches!(reply, ArmReply::Ok { .. }), "{reply:?}");
    assert!(rig.safety.approvals().pending().is_empty());
    assert_eq!(rig.calls.count("execute"), 1);
    rig.safety.approvals().finish(grant);
    rig.hardware.shutdown().await;
}

/// Door 6, rate limits: the count is per origin kind, all sessions together; a new session
/// does not start a new one. Another kind has its own count.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_new_session_does_not_reset_the_rate_limit() {
    let mut config = fresh_config(0.05);
    config.safety.llm_motions_per_minute = 2;
    let rig = rig(&config).await;
    let gripper = rig.bus.client(&GRIPPER_COMMAND).unwrap();
    let from = |kind, session: &str| Origin::new(kind).session(session);
    for session in ["a", "b"] {
        let reply = with_origin(
            from(OriginKind::Mcp, session),
            gripper.request(&GripperCommand::Open, TIMEOUT),
        )
        .await
        .unwrap();
        assert!(matches!(reply, GripperReply::State { .. }), "{reply:?}");
    }
    let reply = with_origin(
        from(OriginKind::Mcp, "c"),
        gripper.request(&GripperCommand::Open, TIMEOUT),
    )
    .await
    .unwrap();
    assert!(
        matches!(
            &reply,
            GripperReply::Error { error: GripperError::Refused { limit, reason } }
                if limit == "rate" && reason.contains("all sessions together")
        ),
        "{reply:?}"
    );
    let reply = with_origin(
        from(OriginKind::Agent, "a"),
        gripper.request(&GripperCommand::Open, TIMEOUT),
    )
    .await
    .unwrap();
    assert!(matches!(reply, GripperReply::State { .. }), "{reply:?}");
    assert_eq!(rig.calls.count("open"), 3);
    rig.hardware.shutdown().await;
}
