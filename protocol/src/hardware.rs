//! What the robot robotd drives says about itself, asked of a running robotd on
//! `system/hardware`: its model and driver, the camera's intrinsics, its versions as the
//! driver reads them, and whether the e-stop is engaged.
//!
//! `robotd commission` asks it when it attaches to a robotd that already drives the arm: the
//! robot answers only one client, so the questions go through the robotd that holds it.
//!
//! ```
//! use robotd_protocol::hardware::{HardwareInfo, MotorInfo};
//!
//! let info = HardwareInfo {
//!     hardware_version: Some("ned2".into()),
//!     motors: vec![MotorInfo { name: "Joint 1".into(), model: "Stepper".into(), firmware: None }],
//!     ..HardwareInfo::default()
//! };
//! assert_eq!(info.motors.len(), 1);
//! ```

use crate::camera::CameraIntrinsics;
use crate::envelope::Message;
use serde::{Deserialize, Serialize};

/// One motor of the robot as it reports itself.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MotorInfo {
    /// What it moves ("waist", "Joint 1").
    pub name: String,
    /// Its model or type ("XM430-W350 (1020)", "Stepper").
    pub model: String,
    /// Its firmware version, when the robot reports one.
    pub firmware: Option<String>,
}

/// What the robot reports about its hardware and software versions.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct HardwareInfo {
    /// The robot's hardware version, when it reports one (a Ned2: `ned2`).
    pub hardware_version: Option<String>,
    /// The robot's software version, when it reports one.
    pub software_version: Option<String>,
    /// Each motor, base to tool.
    pub motors: Vec<MotorInfo>,
    /// The tool the robot reports mounted, when it reports one (a Ned2: `GRIPPER_1`, `NONE`,
    /// `VACUUM_PUMP_1`, … as its `GET_CURRENT_TOOL_ID` names them).
    #[serde(default)]
    pub tool: Option<String>,
    /// What this robot does not report over the driver's protocol, and why.
    pub not_reported: Vec<String>,
}

/// Asks the running robotd about the robot it drives (`system/hardware`).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct HardwareQuery {}

impl Message for HardwareQuery {
    const TYPE: &'static str = "system.hardware_query";
}

/// The running robotd's answer to a [`HardwareQuery`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct HardwareReport {
    /// The configured driver (`sim-ned2`, `sim-widowx`, `niryo`, `widowx`, `replay`).
    pub driver: String,
    /// Whether the process holding the robot is a `robotd commission` run (another
    /// commissioning must not work through it at the same time).
    #[serde(default)]
    pub commissioning: bool,
    /// The camera's intrinsics as the driver reports them.
    pub intrinsics: CameraIntrinsics,
    /// The versions the driver read, or why it could not read them.
    pub versions: Result<HardwareInfo, String>,
    /// The e-stop's reason while it is engaged.
    pub estop: Option<String>,
}

impl Message for HardwareReport {
    const TYPE: &'static str = "system.hardware_report";
}
