//! `[robot.niryo]`: how robotd drives a real Ned2 over its TCP protocol (`robot.driver =
//! "niryo"`, with `robot.host` and `robot.port`).

use robotd_runtime::config::Checks;
use serde::{Deserialize, Serialize};
use std::time::Duration;

/// `[robot.niryo]`
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NiryoConfig {
    /// Calibrate on connecting when the robot says it needs it (otherwise motions are refused
    /// until the `calibrate` tool ran).
    #[serde(default = "defaults::auto_calibrate")]
    pub auto_calibrate: bool,
    /// Deadline of a TCP connect and of the handshake, ms (100 to 60000).
    #[serde(default = "defaults::connect_timeout_ms")]
    pub connect_timeout_ms: u64,
    /// Deadline of a command that moves nothing (queries, images), ms (100 to 60000).
    #[serde(default = "defaults::query_timeout_ms")]
    pub query_timeout_ms: u64,
    /// Longest wait between two connection attempts, ms (100 to 2000).
    #[serde(default = "defaults::reconnect_max_ms")]
    pub reconnect_max_ms: u64,
    /// Largest joint change sent as one command, radians (0.02 to 3). The Ned2 has no stop
    /// command and finishes what it was sent, so this bounds how late a stop or the
    /// emergency stop can take effect.
    #[serde(default = "defaults::segment_rad")]
    pub segment_rad: f64,
    /// How far (radians, per joint) the arm may end from its target before the move counts
    /// as not done: the robot answers OK without moving when it rejects a target (0.001 to 0.2).
    #[serde(default = "defaults::arrival_tolerance_rad")]
    pub arrival_tolerance_rad: f64,
    /// The robot already sends undistorted images: describe its frames without distortion
    /// (false: robotd undoes the distortion the robot reports).
    #[serde(default)]
    pub images_rectified: bool,
    /// Gripper finger speed (100 to 1000, the robot's unit).
    #[serde(default = "defaults::gripper_speed")]
    pub gripper_speed: u16,
    /// Gripper maximum torque while moving, percent (0 to 100).
    #[serde(default = "defaults::gripper_max_torque_percent")]
    pub gripper_max_torque_percent: u8,
    /// Gripper torque holding an object, percent (0 to 100).
    #[serde(default = "defaults::gripper_hold_torque_percent")]
    pub gripper_hold_torque_percent: u8,
}

impl Default for NiryoConfig {
    fn default() -> Self {
        Self {
            auto_calibrate: defaults::auto_calibrate(),
            connect_timeout_ms: defaults::connect_timeout_ms(),
            query_timeout_ms: defaults::query_timeout_ms(),
            reconnect_max_ms: defaults::reconnect_max_ms(),
            segment_rad: defaults::segment_rad(),
            arrival_tolerance_rad: defaults::arrival_tolerance_rad(),
            images_rectified: false,
            gripper_speed: defaults::gripper_speed(),
            gripper_max_torque_percent: defaults::gripper_max_torque_percent(),
            gripper_hold_torque_percent: defaults::gripper_hold_torque_percent(),
        }
    }
}

impl NiryoConfig {
    /// [`Self::connect_timeout_ms`] as a duration.
    pub fn connect_timeout(&self) -> Duration {
        Duration::from_millis(self.connect_timeout_ms)
    }
    /// [`Self::query_timeout_ms`] as a duration.
    pub fn query_timeout(&self) -> Duration {
        Duration::from_millis(self.query_timeout_ms)
    }
    /// [`Self::reconnect_max_ms`] as a duration.
    pub fn reconnect_max(&self) -> Duration {
        Duration::from_millis(self.reconnect_max_ms)
    }

    /// Adds the problems of these settings to `checks` (keys under `niryo.`).
    pub fn check(&self, checks: &mut Checks) {
        checks.range_u64(
            "niryo.connect_timeout_ms",
            self.connect_timeout_ms,
            100..=60_000,
            "",
        );
        checks.range_u64(
            "niryo.query_timeout_ms",
            self.query_timeout_ms,
            100..=60_000,
            "",
        );
        checks.range_u64(
            "niryo.reconnect_max_ms",
            self.reconnect_max_ms,
            100..=2_000,
            "",
        );
        checks.range_f64("niryo.segment_rad", self.segment_rad, 0.02..=3.0, "");
        checks.range_f64(
            "niryo.arrival_tolerance_rad",
            self.arrival_tolerance_rad,
            0.001..=0.2,
            "",
        );
        checks.range_u64(
            "niryo.gripper_speed",
            self.gripper_speed.into(),
            100..=1000,
            "",
        );
        checks.range_u64(
            "niryo.gripper_max_torque_percent",
            self.gripper_max_torque_percent.into(),
            0..=100,
            "",
        );
        checks.range_u64(
            "niryo.gripper_hold_torque_percent",
            self.gripper_hold_torque_percent.into(),
            0..=100,
            "",
        );
    }
}

mod defaults {
    pub fn auto_calibrate() -> bool {
        true
    }
    pub fn connect_timeout_ms() -> u64 {
        2000
    }
    pub fn query_timeout_ms() -> u64 {
        3000
    }
    pub fn reconnect_max_ms() -> u64 {
        2000
    }
    pub fn segment_rad() -> f64 {
        0.2
    }
    pub fn arrival_tolerance_rad() -> f64 {
        0.02
    }
    pub fn gripper_speed() -> u16 {
        500
    }
    pub fn gripper_max_torque_percent() -> u8 {
        100
    }
    pub fn gripper_hold_torque_percent() -> u8 {
        30
    }
}
