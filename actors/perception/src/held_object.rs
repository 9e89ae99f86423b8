//! Telling the object in the gripper from objects on the table.
//!
//! While the gripper holds something, it hangs in the wrist camera's view, close to the lens,
//! and reaches into the picture from its edge on the gripper's side. Mapped onto the table
//! plane, it looks like an object lying under the tool that comes in over the sheet's edge
//! (the pixels beyond the sheet are not searched). A detection is taken for the held object
//! when both hold:
//! - its footprint, grown by a centimetre, covers the tool's position on the table;
//! - it reaches the sheet's outer edge (the markers' rectangle and the printed border around
//!   it), where nothing placed by the skills lies, because they refuse places that stick out.
//!
//! An object on the table that merely reaches towards the tool — a pencil lying along the
//! arm's direction a few centimetres inside the sheet — stays an object.

use robotd_protocol::objects::DetectedObject;
use robotd_protocol::workspace::WorkspaceInfo;
use robotd_protocol::Pose;

/// How far around the tool a held object's image may reach on the table plane, metres.
const HELD_OBJECT_MARGIN_M: f64 = 0.01;
/// The printed border of the sheet beyond its markers' centres, metres.
const SHEET_BORDER_M: f64 = 0.012;
/// How close to the sheet's outer edge a footprint must come to be cut by it, metres.
const EDGE_SLACK_M: f64 = 0.004;

/// Whether `object` is the image of what the gripper at `tool` holds, seen above the sheet of
/// `workspace` (see the module's text).
pub fn is_held_object(object: &DetectedObject, tool: &Pose, workspace: &WorkspaceInfo) -> bool {
    let c = object.xy();
    let (half_x, half_y) = (
        object.dimensions.height_m / 2.0,
        object.dimensions.width_m / 2.0,
    );
    let under_tool = (tool.x_m - c.x_m).abs() <= half_x + HELD_OBJECT_MARGIN_M
        && (tool.y_m - c.y_m).abs() <= half_y + HELD_OBJECT_MARGIN_M;
    let (ul, lr) = (workspace.upper_left, workspace.lower_right);
    let reach = SHEET_BORDER_M - EDGE_SLACK_M;
    let cut_by_edge = c.x_m - half_x <= ul.x_m.min(lr.x_m) - reach
        || c.x_m + half_x >= ul.x_m.max(lr.x_m) + reach
        || c.y_m - half_y <= ul.y_m.min(lr.y_m) - reach
        || c.y_m + half_y >= ul.y_m.max(lr.y_m) + reach;
    under_tool && cut_by_edge
}

#[cfg(test)]
mod tests {
    use super::*;
    use robotd_protocol::Point2;

    fn object_at(x: f64, y: f64, along_x: f64, along_y: f64) -> DetectedObject {
        let mut o = DetectedObject::default();
        o.position.center_of_mass.x_m = x;
        o.position.center_of_mass.y_m = y;
        o.position.center = o.position.center_of_mass;
        o.dimensions.height_m = along_x;
        o.dimensions.width_m = along_y;
        o
    }

    #[test]
    fn only_what_comes_in_over_the_sheets_edge_under_the_tool_is_the_held_object() {
        // The Ned2's sheet: markers at x 0.163 … 0.337, y -0.087 … 0.087; the observation pose
        // puts the tool over x 0.173.
        let workspace = WorkspaceInfo {
            id: "niryo_ws".into(),
            robot: robotd_protocol::RobotModel::Ned2,
            upper_left: Point2::new(0.337, 0.087),
            lower_right: Point2::new(0.163, -0.087),
            observation_pose: Pose::default(),
        };
        let tool = Pose {
            x_m: 0.173,
            y_m: -0.002,
            z_m: 0.277,
            ..Pose::default()
        };
        // A held pencil seen from the wrist: from the sheet's near edge (x 0.151) inwards.
        let held = object_at(0.190, -0.007, 0.078, 0.036);
        assert!(is_held_object(&held, &tool, &workspace));
        // A pencil lying on the table along the arm, its near end 7 mm from the tool, 3 cm
        // inside the sheet's edge: an object on the table.
        let pencil = object_at(0.237, -0.002, 0.115, 0.012);
        assert!(!is_held_object(&pencil, &tool, &workspace));
        // Something cut by the far edge, away from the tool: not what the gripper holds.
        let far = object_at(0.335, 0.0, 0.04, 0.04);
        assert!(!is_held_object(&far, &tool, &workspace));
    }
}
