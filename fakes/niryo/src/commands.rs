//! The fake Ned2's commands: parameters checked as the robot checks them, then run on the
//! simulator. Replies and error texts follow `docs/niryo-tcp.md`.

use crate::{lock, FakeNiryo};
use robotd_driver::{ArmDriver, CameraDriver, DriverError, Motion};
use robotd_driver_niryo::wire;
use robotd_kinematics::{isometry_to_pose, pose_to_isometry};
use robotd_protocol::geometry::Pose;
use serde_json::{json, Value};

/// The KO text of a command the robot does not know.
pub const UNKNOWN: &str = "Unknown command";

/// Prefix of the robot's execution errors (spelling as the robot sends it).
const EXECUTION_ERROR: &str = "An error occured while executing the last command : ";

type Answer = Result<(Vec<Value>, Vec<u8>), String>;

fn ok(results: Vec<Value>) -> Answer {
    Ok((results, Vec::new()))
}

/// `Err` with the robot's arity text unless `params` has one of the `expected` lengths.
fn arity(params: &[Value], expected: &[usize], handler: &str) -> Result<(), String> {
    if expected.contains(&params.len()) {
        return Ok(());
    }
    let list = expected
        .iter()
        .map(usize::to_string)
        .collect::<Vec<_>>()
        .join(", ");
    Err(format!(
        "[{list}] parameters expected but {} given\nIn function __{handler}",
        params.len()
    ))
}

fn floats(params: &[Value], what: &str) -> Result<Vec<f64>, String> {
    wire::numbers(params, params.len(), what)
}

/// A parameter that must be an integer (gripper speed and torques): a float gets the robot's
/// own (buggy) error text.
fn integer(value: &Value) -> Result<i64, String> {
    match value {
        Value::Number(n) if n.is_i64() => Ok(n.as_i64().unwrap_or(0)),
        Value::Number(_) => Err("can only concatenate str (not \"float\") to str".into()),
        other => Err(format!("Expected an integer.\nGiven: {other}")),
    }
}

fn enum_name<'a>(value: &'a Value, allowed: &[&str]) -> Result<&'a str, String> {
    let given = value.as_str().unwrap_or("");
    if allowed.contains(&given) {
        Ok(given)
    } else {
        // As the robot prints a Python list: ['MANUAL', 'AUTO'].
        let names: Vec<String> = allowed.iter().map(|a| format!("'{a}'")).collect();
        Err(format!(
            "Expected one of the following: [{}].\nGiven: {}",
            names.join(", "),
            value
                .as_str()
                .map(str::to_owned)
                .unwrap_or_else(|| value.to_string())
        ))
    }
}

fn execution_error(error: &DriverError) -> String {
    match error {
        DriverError::Collision { .. } | DriverError::CollisionPending => format!(
            "{EXECUTION_ERROR}Command has been aborted due to a collision or a motor not able to follow the given trajectory"
        ),
        other => format!("{EXECUTION_ERROR}{other}"),
    }
}

impl FakeNiryo {
    /// Runs `command` (upper-cased) with `params`.
    pub(crate) async fn run(&self, command: &str, params: &[Value]) -> Answer {
        match command {
            "HANDSHAKE" => {
                arity(params, &[1], "handshake")?;
                self.flags().handshake_seen = true;
                let version = params[0].as_str().unwrap_or("");
                if version < "1.2.0" {
                    ok(vec![
                        json!({"message": "You're using an outdated version of pyniryo. Please update it."}),
                    ])
                } else {
                    ok(vec![json!({})])
                }
            }
            "CALIBRATE" => {
                arity(params, &[1], "calibrate")?;
                enum_name(&params[0], &["MANUAL", "AUTO"])?;
                self.arm
                    .controller_calibrate()
                    .await
                    .map_err(|e| execution_error(&e))?;
                self.flags().calibrated = true;
                ok(vec![])
            }
            "UPDATE_TOOL" => {
                arity(params, &[0], "update_tool")?;
                ok(vec![])
            }
            "GET_CURRENT_TOOL_ID" => {
                arity(params, &[0], "get_current_tool_id")?;
                ok(vec![json!(self.tool())])
            }
            "GET_JOINTS" => {
                arity(params, &[0], "get_joints")?;
                ok(self.sim.joints().into_iter().map(Value::from).collect())
            }
            "GET_POSE" => {
                arity(params, &[0], "get_pose")?;
                ok(self
                    .pose()?
                    .to_array()
                    .into_iter()
                    .map(Value::from)
                    .collect())
            }
            "MOVE_JOINTS" => {
                arity(params, &[6], "move_joints")?;
                let q = floats(params, "joints")?;
                self.move_joints(q).await
            }
            "MOVE_POSE" => {
                arity(params, &[7], "move_pose")?;
                let p = floats(&params[..6], "pose")?;
                self.move_pose(Pose::from_array([p[0], p[1], p[2], p[3], p[4], p[5]]))
                    .await
            }
            "SHIFT_POSE" => {
                arity(params, &[2, 3], "shift_pose")?;
                let axis = enum_name(&params[0], &["X", "Y", "Z", "ROLL", "PITCH", "YAW"])?;
                let value = floats(&params[1..2], "shift value")?[0];
                let mut pose = self.pose()?.to_array();
                let i = ["X", "Y", "Z", "ROLL", "PITCH", "YAW"]
                    .iter()
                    .position(|a| *a == axis)
                    .unwrap_or(0);
                pose[i] += value;
                self.move_pose(Pose::from_array(pose)).await
            }
            "MOVE" => {
                arity(params, &[1, 2], "move")?;
                self.move_object(&params[0]).await
            }
            "SET_ARM_MAX_VELOCITY" => {
                arity(params, &[1], "set_arm_max_velocity")?;
                let percent = integer(&params[0])?;
                if !(1..=100).contains(&percent) {
                    return Err(format!(
                        "Expected a percentage between 1 and 100.\nGiven: {percent}"
                    ));
                }
                self.flags().speed_scale = percent as f64 / 100.0;
                ok(vec![])
            }
            "OPEN_GRIPPER" | "CLOSE_GRIPPER" => {
                arity(params, &[3], &command.to_lowercase())?;
                for p in params {
                    integer(p)?;
                }
                let done = if command == "OPEN_GRIPPER" {
                    self.gripper.controller_open().await
                } else {
                    self.gripper.controller_close().await
                };
                done.map_err(|e| execution_error(&e))?;
                ok(vec![])
            }
            "GET_COLLISION_DETECTED" => {
                arity(params, &[0], "get_collision_detected")?;
                ok(vec![Value::Bool(self.arm.flags().collision_detected)])
            }
            "CLEAR_COLLISION_DETECTED" => {
                arity(params, &[0], "clear_collision_detected")?;
                self.arm.controller_clear_collision();
                ok(vec![])
            }
            "SET_LEARNING_MODE" => {
                arity(params, &[1], "set_learning_mode")?;
                let on = wire::lenient_bool(&params[0])
                    .ok_or_else(|| format!("Expected a boolean.\nGiven: {}", params[0]))?;
                self.flags().learning_mode = on;
                let text = if on {
                    "Activating learning mode"
                } else {
                    "Deactivating learning mode"
                };
                ok(vec![json!([1, text])])
            }
            "GET_LEARNING_MODE" => {
                arity(params, &[0], "get_learning_mode")?;
                ok(vec![Value::Bool(self.flags().learning_mode)])
            }
            "GET_IMAGE_COMPRESSED" => {
                arity(params, &[0], "get_image_compressed")?;
                let (width, height) = self.camera.size();
                let mut rgb = vec![0u8; width as usize * height as usize * 3];
                self.camera
                    .capture_into(&mut rgb)
                    .map_err(|e| execution_error(&e))?;
                let jpeg = robotd_jpeg::encode_jpeg(&rgb, width, height, 90)
                    .map_err(|e| format!("{EXECUTION_ERROR}{e}"))?;
                Ok((vec![], jpeg))
            }
            "GET_CAMERA_INTRINSICS" => {
                arity(params, &[0], "get_camera_intrinsics")?;
                let k = self.camera.intrinsics();
                ok(vec![
                    json!([k.fx, 0.0, k.cx, 0.0, k.fy, k.cy, 0.0, 0.0, 1.0]),
                    json!(k.distortion),
                ])
            }
            "GET_HARDWARE_STATUS" => {
                arity(params, &[0], "get_hardware_status")?;
                let calibrated = self.flags().calibrated;
                let names = [
                    "Joint 1", "Joint 2", "Joint 3", "Joint 4", "Joint 5", "Joint 6", "Tool",
                ];
                ok(vec![
                    json!(52),
                    json!("ned2"),
                    Value::Bool(true),
                    json!("''"),
                    Value::Bool(!calibrated),
                    Value::Bool(false),
                    json!(names),
                    json!(["Stepper", "Stepper", "Stepper", "DXL", "DXL", "DXL", "DXL"]),
                    json!([35, 36, 35, 40, 41, 40, 38]),
                    json!([12.0, 12.0, 12.0, 12.1, 12.1, 12.1, 12.0]),
                    json!([0, 0, 0, 0, 0, 0, 0]),
                ])
            }
            _ => Err(UNKNOWN.into()),
        }
    }

    fn pose(&self) -> Result<Pose, String> {
        self.sim
            .kinematics()
            .tool_pose(&self.sim.joints())
            .map(|iso| isometry_to_pose(&iso))
            .map_err(|e| format!("{EXECUTION_ERROR}{e}"))
    }

    /// Moves the joints; a target the robot would reject answers OK without moving.
    async fn move_joints(&self, q: Vec<f64>) -> Answer {
        let speed = {
            let mut flags = self.flags();
            flags.learning_mode = false;
            if !flags.calibrated || lock(&self.faults).ignore_moves {
                tracing::debug!("fake-niryo: move ignored (answered OK)");
                return ok(vec![]);
            }
            flags.speed_scale
        };
        if self.sim.kinematics().check_joints(&q).is_err() {
            tracing::debug!(
                ?q,
                "fake-niryo: joints out of range, not moved (answered OK)"
            );
            return ok(vec![]);
        }
        let lag = *lock(&self.stopping_lag);
        if !lag.is_zero() {
            // The fake's model of a late robot: the motion starts this much later.
            tokio::time::sleep(lag).await;
        }
        self.arm
            .controller_move(Motion::Joints(q), speed, &self.control)
            .await
            .map_err(|e| execution_error(&e))?;
        ok(vec![])
    }

    async fn move_pose(&self, pose: Pose) -> Answer {
        let seed = self.sim.joints();
        match self
            .sim
            .kinematics()
            .inverse(&pose_to_isometry(&pose), Some(&seed))
        {
            Ok(q) => self.move_joints(q).await,
            Err(error) => {
                tracing::debug!(%error, "fake-niryo: no IK solution, not moved (answered OK)");
                ok(vec![])
            }
        }
    }

    /// pyniryo's `move()`: a pose or joints object with its metadata.
    async fn move_object(&self, object: &Value) -> Answer {
        let kind = object.get("obj_type").and_then(Value::as_str).unwrap_or("");
        let number = |key: &str| {
            object
                .get(key)
                .and_then(Value::as_f64)
                .filter(|x| x.is_finite())
                .ok_or_else(|| format!("{EXECUTION_ERROR}'{key}' missing or not a number"))
        };
        match kind {
            "JOINTS" => {
                let q = (0..6)
                    .map(|i| number(&format!("joint_{i}")))
                    .collect::<Result<Vec<_>, _>>()?;
                self.move_joints(q).await
            }
            "POSE" => {
                let millimetres = object
                    .pointer("/metadata/length_unit")
                    .and_then(Value::as_str)
                    == Some("MILLIMETERS");
                let scale = if millimetres { 0.001 } else { 1.0 };
                let pose = Pose::from_array([
                    number("x")? * scale,
                    number("y")? * scale,
                    number("z")? * scale,
                    number("roll")?,
                    number("pitch")?,
                    number("yaw")?,
                ]);
                self.move_pose(pose).await
            }
            other => Err(format!(
                "Expected one of the following: ['POSE', 'JOINTS'].\nGiven: {other}"
            )),
        }
    }
}
