"""Drive robotd's fake Ned2 (`robotd fake-niryo`) with Niryo's own client, pyniryo 1.2.5.

Usage: python pyniryo_session.py PORT

Connects, calibrates, moves (the current `move` API and the deprecated `move_joints` /
`move_pose`), grips, grabs and decodes a camera image, reads the intrinsics, and provokes
and clears a collision. Prints one JSON object with what it saw; the Rust test checks it
against the simulator. Any exception of pyniryo fails the script (exit 1).
"""

import json
import sys

import numpy as np
from pyniryo import JointsPosition, NiryoRobot, PoseObject, uncompress_image

port = int(sys.argv[1])
seen = {}

robot = NiryoRobot()  # no address: connect below, to the fake's port
robot._NiryoRobot__port = port  # pyniryo has the robot's port 40001 built in
robot.connect("127.0.0.1")

seen["need_calibration_before"] = robot.need_calibration()
robot.calibrate_auto()
seen["need_calibration_after"] = robot.need_calibration()
robot.update_tool()

status = robot.get_hardware_status()
seen["hardware_version"] = status.hardware_version
seen["motor_names"] = list(status.motor_names)
seen["tool"] = robot.get_current_tool_id().name

target = [0.2, 0.3, -0.4, 0.0, -0.5, 0.1]
robot.move(JointsPosition(*target))
seen["joints_after_move"] = list(robot.get_joints())
robot.move_joints(0.0, 0.3, -0.6, 0.0, -0.4, 0.0)
seen["joints_after_move_joints"] = list(robot.get_joints())

robot.move(PoseObject(0.25, 0.05, 0.20, 0.0, 1.57, 0.0))
pose = robot.get_pose()
seen["pose_after_move"] = [pose.x, pose.y, pose.z, pose.roll, pose.pitch, pose.yaw]
robot.move_pose(0.22, -0.03, 0.25, 0.0, 1.57, 0.0)
pose = robot.get_pose()
seen["pose_after_move_pose"] = [pose.x, pose.y, pose.z]

robot.close_gripper(speed=500, max_torque_percentage=100, hold_torque_percentage=20)
robot.open_gripper(speed=500, max_torque_percentage=100, hold_torque_percentage=30)

compressed = robot.get_img_compressed()
image = uncompress_image(compressed)
seen["image_shape"] = list(image.shape)
seen["image_std"] = float(np.std(image))
mtx, dist = robot.get_camera_intrinsics()
seen["camera_matrix"] = np.asarray(mtx).tolist()
seen["distortion"] = np.asarray(dist).tolist()

seen["collision_before"] = robot.collision_detected
try:
    # Straight down through the table: the simulated world stops the arm.
    robot.move(PoseObject(0.25, 0.0, -0.03, 0.0, 1.57, 0.0))
    seen["move_into_table"] = "ok"
except Exception as error:  # pyniryo raises on the robot's KO
    seen["move_into_table"] = f"{type(error).__name__}: {error}"
seen["collision_after"] = robot.collision_detected
robot.clear_collision_detected()
seen["collision_cleared"] = robot.collision_detected
robot.move(PoseObject(0.25, 0.0, 0.20, 0.0, 1.57, 0.0))
pose = robot.get_pose()
seen["pose_after_recovery"] = [pose.x, pose.y, pose.z]

robot.close_connection()
print(json.dumps(seen))
