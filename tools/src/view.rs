//! Asking the workspace model, for the detection, workspace and label tools.
//!
//! Detection tools answer from a view the camera took with the arm resting at the
//! workspace's observation pose ([`ask_fresh`]): if the arm rests there already they are
//! answered from the workspace model at once, otherwise the arm goes there first and the
//! answer waits for the first steady frame. Workspace and label tools need no fresh view
//! ([`ask`] with `None`).

use crate::schema::ObjectJson;
use crate::skill::run_skill;
use crate::{CallHooks, Registry};
use nalgebra::UnitQuaternion;
use robotd_protocol::objects::DetectedObject;
use robotd_protocol::skills::Skill;
use robotd_protocol::workspace::{WorkspaceInfo, WorkspaceQuery, WorkspaceReply, WorkspaceRequest};
use robotd_protocol::Pose;
use schemars::JsonSchema;
use serde::Serialize;

/// The data of the tools that list objects.
#[derive(Debug, Serialize, JsonSchema)]
pub(crate) struct Objects(#[schemars(with = "Vec<ObjectJson>")] pub(crate) Vec<DetectedObject>);

/// The data of the tools that return one object.
#[derive(Debug, Serialize, JsonSchema)]
pub(crate) struct Object(#[schemars(with = "ObjectJson")] pub(crate) DetectedObject);

/// Position within which the arm counts as at the observation pose, metres.
const AT_POSE_M: f64 = 0.005;
/// Orientation within which the arm counts as at the observation pose, radians.
const AT_POSE_RAD: f64 = 0.05;

fn same_pose(a: &Pose, b: &Pose) -> bool {
    let dp = ((a.x_m - b.x_m).powi(2) + (a.y_m - b.y_m).powi(2) + (a.z_m - b.z_m).powi(2)).sqrt();
    let qa = UnitQuaternion::from_euler_angles(a.roll_rad, a.pitch_rad, a.yaw_rad);
    let qb = UnitQuaternion::from_euler_angles(b.roll_rad, b.pitch_rad, b.yaw_rad);
    dp <= AT_POSE_M && qa.angle_to(&qb) <= AT_POSE_RAD
}

/// The time after which a camera view counts as fresh: when the arm came to rest at the
/// observation pose, moving it there first if needed.
async fn fresh_view(registry: &Registry, hooks: &CallHooks) -> Result<u64, String> {
    fresh_view_of(registry, &registry.settings().workspaces[0], hooks).await
}

/// [`fresh_view`] of workspace `ws`.
pub(crate) async fn fresh_view_of(
    registry: &Registry,
    ws: &WorkspaceInfo,
    hooks: &CallHooks,
) -> Result<u64, String> {
    let rest = *registry.inner.arm_rest.borrow();
    if let Some(rest) = rest {
        if !rest.moving && same_pose(&rest.pose, &ws.observation_pose) {
            return Ok(rest.rested_since_unix_ns);
        }
    }
    let skill = Skill::GoToObservationPose {
        workspace_id: ws.id.clone(),
    };
    match run_skill(registry, skill, hooks).await {
        Ok(_) => Ok(robotd_protocol::envelope::unix_now_ns()),
        Err(failure) => Err(format!(
            "could not move to the observation pose of '{}': {}",
            ws.id,
            failure.reason()
        )),
    }
}

/// Asks the workspace model `request`, answered from a view newer than
/// `fresh_after_unix_ns` when given.
pub(crate) async fn ask(
    registry: &Registry,
    request: WorkspaceRequest,
    fresh_after_unix_ns: Option<u64>,
) -> Result<WorkspaceReply, String> {
    let query = WorkspaceQuery {
        request,
        fresh_after_unix_ns,
        max_wait_ms: 0,
    };
    match registry
        .query_client()
        .request(&query, registry.settings().query_timeout)
        .await
    {
        Ok(reply) => reply.into_result().map_err(|e| e.to_string()),
        Err(error) => Err(format!("the workspace model did not answer: {error}")),
    }
}

/// Asks `request` from a fresh view.
pub(crate) async fn ask_fresh(
    registry: &Registry,
    request: WorkspaceRequest,
    hooks: &CallHooks,
) -> Result<WorkspaceReply, String> {
    let fresh = fresh_view(registry, hooks).await?;
    ask(registry, request, Some(fresh)).await
}

/// The failure reason for a reply of the wrong kind.
pub(crate) fn unexpected(reply: &WorkspaceReply) -> String {
    format!("unexpected answer from the workspace model: {reply:?}")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn poses_compare_by_position_and_rotation() {
        let a = Pose::new(0.173, -0.002, 0.277, -3.042, 1.327, -3.027);
        // The same rotation written with other Euler angles.
        let q = UnitQuaternion::from_euler_angles(a.roll_rad, a.pitch_rad, a.yaw_rad);
        let (r, p, y) = q.euler_angles();
        let b = Pose::new(0.174, -0.002, 0.277, r, p, y);
        assert!(same_pose(&a, &b));
        let c = Pose::new(0.173, -0.002, 0.277, -3.042, 1.2, -3.027);
        assert!(!same_pose(&a, &c));
    }
}
