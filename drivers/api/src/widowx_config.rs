//! `[robot.widowx]`: how robotd drives a real WidowX 250 s over its DYNAMIXEL servo bus
//! (`robot.driver = "widowx"`), and where its camera comes from.
//!
//! The arm has no camera protocol of its own; labs put a USB camera or an IP camera on it.
//! robotd reads either a V4L2 capture device (`camera_url = "/dev/video0"`: a USB camera)
//! or an MJPEG-over-HTTP stream (`camera_url = "http://…"`: IP cameras, mjpg-streamer,
//! `robotd fake-widowx`), with the intrinsics given here.

use robotd_protocol::camera::CameraIntrinsics;
use robotd_runtime::config::Checks;
use serde::{Deserialize, Serialize};
use std::path::PathBuf;
use std::time::Duration;

/// `[robot.widowx]`
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WidowxConfig {
    /// The serial device of the U2D2 adapter (a udev rule usually names it `/dev/ttyDXL`).
    #[serde(default = "defaults::device")]
    pub device: PathBuf,
    /// Bus speed, bits per second (the WidowX ships at 1 000 000).
    #[serde(default = "defaults::baud_rate")]
    pub baud_rate: u32,
    /// Profile Velocity written to every arm servo at start (0 = none: robotd streams smooth
    /// goals at the control rate itself). Units of 0.229 rev/min, 0 to 32767.
    #[serde(default)]
    pub profile_velocity: u32,
    /// Profile Acceleration written to every arm servo at start (0 = none). Units of
    /// 214.577 rev/min², 0 to 32767.
    #[serde(default)]
    pub profile_acceleration: u32,
    /// How far (radians) a joint may lag behind its goal of three ticks before, for 100 ms,
    /// before robotd counts it as blocked (the servos cannot feel a collision any other way)
    /// and holds the arm (0.02 to 1).
    #[serde(default = "defaults::tracking_tolerance_rad")]
    pub tracking_tolerance_rad: f64,
    /// How far (radians, per joint) the arm may end from its target (0.001 to 0.2).
    #[serde(default = "defaults::arrival_tolerance_rad")]
    pub arrival_tolerance_rad: f64,
    /// Longest wait between two attempts to reopen a lost serial port, ms (100 to 2000).
    #[serde(default = "defaults::reconnect_max_ms")]
    pub reconnect_max_ms: u64,
    /// Gripper servo (ID 9) position with the fingers closed, ticks (0 to 4095).
    #[serde(default = "defaults::gripper_closed_ticks")]
    pub gripper_closed_ticks: u16,
    /// Gripper servo position with the fingers fully open, ticks (0 to 4095).
    #[serde(default = "defaults::gripper_open_ticks")]
    pub gripper_open_ticks: u16,
    /// PWM the gripper moves with, in the servo's 0.113 % units (1 to 885).
    #[serde(default = "defaults::gripper_pwm")]
    pub gripper_pwm: u16,
    /// PWM that keeps a grasped object held (0 to 885); below `gripper_pwm` so the servo does
    /// not overheat.
    #[serde(default = "defaults::gripper_hold_pwm")]
    pub gripper_hold_pwm: u16,
    /// Present Load (0.1 % units) above which stopped fingers count as holding something
    /// (1 to 1000).
    #[serde(default = "defaults::gripper_holding_load")]
    pub gripper_holding_load: u16,
    /// The camera: a V4L2 device path (`/dev/video0`, a udev name under `/dev/`) or an
    /// MJPEG-over-HTTP stream (`http://host:port/path`); none = no camera (perception and the
    /// tools that look are then unavailable).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub camera_url: Option<String>,
    /// How old a frame is when it arrives, ms (0 to 2000): capture, encoding and transfer. A
    /// stream does not say when a frame was taken, so robotd dates each frame this much before
    /// its arrival; a frame that arrives just after the arm stopped is then not taken for a
    /// view of the arm at rest. Measure it on your camera (film a clock) and round up.
    #[serde(default = "defaults::camera_latency_ms")]
    pub camera_latency_ms: u64,
    /// The camera's intrinsics and distortion (OpenCV order); default: the simulated wrist
    /// camera's (640×480, no distortion), which is what `robotd fake-widowx` serves.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub camera_intrinsics: Option<CameraIntrinsics>,
}

impl Default for WidowxConfig {
    fn default() -> Self {
        Self {
            device: defaults::device(),
            baud_rate: defaults::baud_rate(),
            profile_velocity: 0,
            profile_acceleration: 0,
            tracking_tolerance_rad: defaults::tracking_tolerance_rad(),
            arrival_tolerance_rad: defaults::arrival_tolerance_rad(),
            reconnect_max_ms: defaults::reconnect_max_ms(),
            gripper_closed_ticks: defaults::gripper_closed_ticks(),
            gripper_open_ticks: defaults::gripper_open_ticks(),
            gripper_pwm: defaults::gripper_pwm(),
            gripper_hold_pwm: defaults::gripper_hold_pwm(),
            gripper_holding_load: defaults::gripper_holding_load(),
            camera_url: None,
            camera_latency_ms: defaults::camera_latency_ms(),
            camera_intrinsics: None,
        }
    }
}

impl WidowxConfig {
    /// [`Self::reconnect_max_ms`] as a duration.
    pub fn reconnect_max(&self) -> Duration {
        Duration::from_millis(self.reconnect_max_ms)
    }

    /// Adds the problems of these settings to `checks` (keys under `widowx.`).
    pub fn check(&self, checks: &mut Checks) {
        if self.device.as_os_str().is_empty() {
            checks.problem(
                "widowx.device",
                "must name the serial device, e.g. \"/dev/ttyDXL\"",
            );
        }
        if ![57_600, 115_200, 1_000_000, 2_000_000, 3_000_000, 4_000_000].contains(&self.baud_rate)
        {
            checks.problem(
                "widowx.baud_rate",
                format!(
                    "{} is not a DYNAMIXEL X baud rate robotd supports (57600, 115200, 1000000, \
                     2000000, 3000000, 4000000; the WidowX uses 1000000)",
                    self.baud_rate
                ),
            );
        }
        for (key, value) in [
            ("widowx.profile_velocity", self.profile_velocity),
            ("widowx.profile_acceleration", self.profile_acceleration),
        ] {
            checks.range_u64(key, value.into(), 0..=32_767, "");
        }
        checks.range_f64(
            "widowx.tracking_tolerance_rad",
            self.tracking_tolerance_rad,
            0.02..=1.0,
            "",
        );
        checks.range_f64(
            "widowx.arrival_tolerance_rad",
            self.arrival_tolerance_rad,
            0.001..=0.2,
            "",
        );
        checks.range_u64(
            "widowx.reconnect_max_ms",
            self.reconnect_max_ms,
            100..=2_000,
            "",
        );
        for (key, value) in [
            ("widowx.gripper_closed_ticks", self.gripper_closed_ticks),
            ("widowx.gripper_open_ticks", self.gripper_open_ticks),
        ] {
            checks.range_u64(key, value.into(), 0..=4095, "");
        }
        if self.gripper_open_ticks.abs_diff(self.gripper_closed_ticks) < 100 {
            checks.problem(
                "widowx.gripper_open_ticks",
                "must be at least 100 ticks away from gripper_closed_ticks",
            );
        }
        checks.range_u64("widowx.gripper_pwm", self.gripper_pwm.into(), 1..=885, "");
        checks.range_u64(
            "widowx.gripper_hold_pwm",
            self.gripper_hold_pwm.into(),
            0..=885,
            "",
        );
        checks.range_u64(
            "widowx.gripper_holding_load",
            self.gripper_holding_load.into(),
            1..=1000,
            "",
        );
        checks.range_u64(
            "widowx.camera_latency_ms",
            self.camera_latency_ms,
            0..=2000,
            "",
        );
        if let Some(url) = &self.camera_url {
            let device = url.starts_with("/dev/") && !url.contains("/../");
            let http = (url.starts_with("http://") || url.starts_with("https://"))
                && !url.contains(char::is_whitespace);
            if !device && !http {
                checks.problem(
                    "widowx.camera_url",
                    format!(
                        "'{url}' is neither a V4L2 device under /dev/ (e.g. /dev/video0) nor an \
                         http:// or https:// URL of an MJPEG stream"
                    ),
                );
            }
        }
        if let Some(intrinsics) = &self.camera_intrinsics {
            use robotd_protocol::validate::Validate;
            if let Err(problem) = intrinsics.validate() {
                checks.problem("widowx.camera_intrinsics", problem.to_string());
            }
        }
    }
}

mod defaults {
    use std::path::PathBuf;

    pub fn device() -> PathBuf {
        PathBuf::from("/dev/ttyDXL")
    }
    pub fn baud_rate() -> u32 {
        1_000_000
    }
    pub fn tracking_tolerance_rad() -> f64 {
        0.15
    }
    pub fn arrival_tolerance_rad() -> f64 {
        0.02
    }
    pub fn reconnect_max_ms() -> u64 {
        2000
    }
    pub fn gripper_closed_ticks() -> u16 {
        1600
    }
    pub fn gripper_open_ticks() -> u16 {
        2600
    }
    pub fn gripper_pwm() -> u16 {
        350
    }
    pub fn gripper_hold_pwm() -> u16 {
        150
    }
    pub fn gripper_holding_load() -> u16 {
        100
    }
    pub fn camera_latency_ms() -> u64 {
        150
    }
}
