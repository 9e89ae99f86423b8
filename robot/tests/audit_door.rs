//! Issue 39, door 9: a name that is not configured never reaches the audit log.
//!
//! A `GoToObservationPose` naming an unknown 500 kB workspace id goes through the same path as
//! a bus request (`admit_and_run`) to the arm actor on the simulated Ned2: it is refused before
//! admission, with the id cut in the reply, and the audit log gets no line for it. A known
//! workspace is admitted and recorded in a keyed chain that verifies.

mod common;

use robotd_arm::{admit_and_run, ArmActor, ArmContext, ObservationPose};
use robotd_driver::MotionControl;
use robotd_kinematics::Kinematics;
use robotd_protocol::arm::{ArmCommand, ArmError, ArmReply};
use robotd_protocol::geometry::{Pose, RobotModel};
use robotd_protocol::safety::{Origin, OriginKind};
use robotd_runtime::supervision::Supervisor;
use robotd_safety::audit::verify;
use robotd_safety::{AuditConfig, AuditKey, AuditLog, Safety, SafetyConfig};
use std::time::Duration;

#[tokio::test(start_paused = true)]
async fn an_unknown_workspace_is_refused_before_admission_and_not_audited() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("empty.toml"),
        "name = \"empty\"\nrobot = \"ned2\"\n",
    )
    .unwrap();
    let mut robot = common::default_sections().robot;
    robot.scene = Some(dir.path().join("empty.toml"));
    let sim = robotd_driver_sim::open(&robot).expect("the simulator");
    let kinematics = Kinematics::new(RobotModel::Ned2);
    let key = AuditKey::from_bytes([3; 32]);
    let path = dir.path().join("audit.jsonl");
    let audit = AuditLog::start(&AuditConfig {
        path: path.clone(),
        max_file_bytes: 1 << 20,
        keep_files: 2,
        queue: 16,
        key: Some(key.clone()),
    })
    .unwrap();
    let control = MotionControl::default();
    let workspaces = robot.workspaces();
    let safety = Safety::new(
        SafetyConfig::default(),
        kinematics.clone(),
        control.clone(),
        &workspaces,
        audit.clone(),
    );
    let context = ArmContext {
        driver: sim.drivers.arm.clone(),
        kinematics,
        control,
        observation_poses: workspaces
            .iter()
            .map(|w| ObservationPose {
                workspace_id: w.id.clone(),
                pose: Pose::from_array(w.observation_pose),
            })
            .collect(),
        safety: safety.clone(),
        shared: Default::default(),
    };
    let actor = Supervisor::new("arm")
        .spawn_actor::<ArmActor>(move || ArmActor::new(context.clone()))
        .await
        .unwrap();
    let origin = Origin::new(OriginKind::Mcp).session("door-9");

    let huge = "w".repeat(500_000);
    let command = ArmCommand::GoToObservationPose { workspace_id: huge };
    let reply = admit_and_run(&actor, &safety, command, &origin)
        .await
        .unwrap();
    let ArmReply::Error {
        error: ArmError::UnknownWorkspace {
            workspace_id,
            known,
        },
    } = reply
    else {
        panic!("not refused as an unknown workspace: {reply:?}");
    };
    assert!(workspace_id.len() < 400, "{} bytes", workspace_id.len());
    assert!(
        workspace_id.ends_with("…(cut, 500000 bytes)"),
        "{workspace_id}"
    );
    assert_eq!(known.len(), workspaces.len());
    audit.flush(Duration::from_secs(10)).unwrap();
    let written = std::fs::read_to_string(&path).unwrap_or_default();
    assert_eq!(written, "", "an unknown workspace reached the audit log");

    let known_id = workspaces[0].id.clone();
    let command = ArmCommand::GoToObservationPose {
        workspace_id: known_id.clone(),
    };
    let reply = admit_and_run(&actor, &safety, command, &origin)
        .await
        .unwrap();
    assert!(matches!(reply, ArmReply::Ok { .. }), "{reply:?}");
    audit.flush(Duration::from_secs(10)).unwrap();
    let written = std::fs::read_to_string(&path).unwrap();
    assert_eq!(written.lines().count(), 2, "{written}");
    assert!(written.contains(&known_id) && written.contains("\"hmac\":\""));
    let report = verify(std::slice::from_ref(&path), Some(&key)).unwrap();
    assert_eq!((report.entries, report.keyed, report.unkeyed), (2, 2, 0));
}
