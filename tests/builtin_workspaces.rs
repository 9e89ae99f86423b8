//! Every built-in workspace of both robot models can be reached with the default
//! configuration, and the camera sees its sheet and the objects on it from there (issue 39:
//! `gazebo_1`'s observation pose was beyond the Ned2's wrist limit less the safety margin).

mod common;
#[path = "common/lab.rs"]
mod lab;

use lab::{lab_on, runtime, seen_in, Driver};
use robotd_protocol::workspace::builtin_workspaces;
use robotd_protocol::RobotModel;
use serde_json::json;

fn walk(model: RobotModel, settings: &[String]) {
    runtime().block_on(async {
        let lab = lab_on(Driver::Sim, 0.05, settings).await;
        let on_the_table = lab.truth().await.len();
        assert!(on_the_table > 0, "the default scene has objects");
        for workspace in builtin_workspaces(model) {
            let id = workspace.id.as_str();
            lab.ok("move2observation_pose", json!({ "workspace_id": id }))
                .await;
            let data = lab.ok("get_detected_objects", json!({})).await;
            let seen = seen_in(&data);
            assert_eq!(
                seen.len(),
                on_the_table,
                "from {id}'s observation pose the camera sees every object: {seen:?}"
            );
        }
    });
}

#[test]
fn every_builtin_ned2_workspace_is_reached_and_seen() {
    walk(RobotModel::Ned2, &[]);
}

#[test]
fn every_builtin_widowx_workspace_is_reached_and_seen() {
    walk(
        RobotModel::WidowX250,
        &["robot.driver=sim-widowx".to_owned()],
    );
}
