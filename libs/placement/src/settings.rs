//! The skills' settings: the gripper's sizes, heights, margins and time limits every check
//! and every motion of a skill uses. [`SkillsSettings::new`] has the defaults for a robot.

use robotd_protocol::workspace::WorkspaceInfo;
use robotd_protocol::RobotModel;
use robotd_safety::Safety;
use std::time::Duration;

/// How the skills work; [`SkillsSettings::new`] has the defaults.
#[derive(Debug, Clone)]
pub struct SkillsSettings {
    /// The arm model (for the reach checks).
    pub robot: RobotModel,
    /// The workspaces targets must lie in; the first is where motion skills end.
    pub workspaces: Vec<WorkspaceInfo>,
    /// How far outside a workspace rectangle a target may lie, metres.
    pub workspace_margin_m: f64,
    /// Objects further than this from the given coordinate are not picked, metres.
    pub pick_radius_m: f64,
    /// Widest object the gripper closes around, metres.
    pub gripper_max_width_m: f64,
    /// Height above an object's top for approaches, metres.
    pub approach_height_m: f64,
    /// Lowest tool-centre-point height ever commanded, metres.
    pub min_tcp_z_m: f64,
    /// Extra height above the surface when releasing, metres.
    pub release_gap_m: f64,
    /// Height of a container's floor for `inside` placements, metres.
    pub container_floor_m: f64,
    /// How far a finger reaches from the tool centre across the closing axis (the side that
    /// pushes), metres.
    pub finger_reach_m: f64,
    /// Finger length above the tool centre point, metres (taller objects meet the palm too).
    pub finger_length_m: f64,
    /// How far the palm reaches from the tool centre across the closing axis, metres.
    pub palm_reach_m: f64,
    /// How far the palm reaches from the tool centre along the closing axis, metres (a bit
    /// more than the open fingers on both robots).
    pub palm_half_length_m: f64,
    /// Extra release height when stacking onto another object, whose height the camera
    /// measures to a few millimetres, metres.
    pub stack_height_margin_m: f64,
    /// A finger's thickness along the closing axis: the open fingers sweep half the maximum
    /// opening plus this each side of the tool centre, metres.
    pub finger_thickness_m: f64,
    /// Placed and pushed objects keep this far (each side) from the centre of every workspace
    /// corner marker, so that the camera keeps seeing the workspace, metres.
    pub marker_keep_out_m: f64,
    /// Gap between the gripper and the object when a push starts, metres.
    pub push_gap_m: f64,
    /// Tool height while pushing (at most half the object's height), metres.
    pub push_z_m: f64,
    /// Longest one arm or gripper command may take.
    pub command_timeout: Duration,
    /// The motion policy, for skills that need a human's approval before they start (`None`:
    /// none do; the arm and gripper still check every motion).
    pub safety: Option<Safety>,
}

impl SkillsSettings {
    /// The defaults for `robot` on `workspaces`.
    pub fn new(robot: RobotModel, workspaces: Vec<WorkspaceInfo>) -> Self {
        // The gripper's sizes are the simulator's too: what the checks accept, it can do.
        let gripper = robotd_protocol::gripper_geometry::GripperGeometry::for_model(robot);
        Self {
            robot,
            workspaces,
            workspace_margin_m: 0.02,
            pick_radius_m: 0.05,
            gripper_max_width_m: gripper.max_opening_m,
            approach_height_m: 0.06,
            min_tcp_z_m: 0.003,
            release_gap_m: 0.002,
            container_floor_m: 0.004,
            finger_reach_m: gripper.finger_width_m / 2.0,
            finger_length_m: gripper.finger_length_m,
            palm_reach_m: gripper.palm_m[2] / 2.0,
            palm_half_length_m: gripper.palm_m[1] / 2.0,
            finger_thickness_m: gripper.finger_thickness_m,
            stack_height_margin_m: 0.005,
            marker_keep_out_m: 0.02,
            push_gap_m: 0.010,
            push_z_m: 0.012,
            command_timeout: Duration::from_secs(60),
            safety: None,
        }
    }
}
