//! What robotd knows of each robot's hardware that a real driver and the simulator must agree
//! on: the gripper's opening and the Ned2 wrist camera's nominal intrinsics.
//!
//! They live here, beside the traits, so that a real driver reads them without depending on
//! the simulator (`drivers/sim`), and the simulator (with its renderer) uses the same numbers.

use robotd_protocol::camera::CameraIntrinsics;
use robotd_protocol::geometry::RobotModel;

/// The gripper's largest opening between the fingers, metres: 40 mm for the Ned2's standard
/// gripper, 44 mm for the WidowX 250 s.
/// (`robotd_protocol::gripper_geometry`, where the fingers' and palm's sizes are too).
pub fn gripper_max_width(model: RobotModel) -> f64 {
    robotd_protocol::gripper_geometry::GripperGeometry::for_model(model).max_opening_m
}

/// The Niryo Ned2 wrist camera: 640×480, fx 508.069, fy 506.445, cx 332.821, cy 242.984,
/// distortion k1 −0.4146402, k2 0.2407384, p1 0, p2 0, k3 −0.1040042 (what the robot's
/// `GET_CAMERA_INTRINSICS` answers). The simulator renders its wrist camera with these
/// (`robotd_render::Intrinsics::ned2`, checked equal in `drivers/sim`).
pub fn ned2_camera_intrinsics() -> CameraIntrinsics {
    CameraIntrinsics {
        width: 640,
        height: 480,
        fx: 508.069,
        fy: 506.445,
        cx: 332.821,
        cy: 242.984,
        distortion: [-0.4146402, 0.2407384, 0.0, 0.0, -0.1040042],
    }
}
