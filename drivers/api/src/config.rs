//! `[robot]`: which arm robotd drives and the settings every driver shares (control rate,
//! camera rate), plus the simulator's own (scene, time scale, sensor noise, fault injection)
//! and each real or replay driver's section (`[robot.niryo]`, `[robot.widowx]`,
//! `[robot.replay]`).

use robotd_protocol::geometry::RobotModel;
use robotd_protocol::workspace::{builtin_workspaces, WorkspaceInfo, WorkspaceSpec};
use robotd_runtime::config::{Checks, Section};
use serde::{Deserialize, Serialize};
use std::path::PathBuf;
use std::time::Duration;

/// Which arm robotd drives.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum RobotDriver {
    /// Simulated Niryo Ned2 (the default; no hardware).
    SimNed2,
    /// Simulated WidowX.
    SimWidowx,
    /// A real Niryo Ned2 over its TCP protocol.
    Niryo,
    /// A real WidowX over Dynamixel Protocol 2.0.
    Widowx,
    /// A recording played as the robot (`[robot.replay]`): it never moves.
    Replay,
}

impl RobotDriver {
    /// The name configuration gives it (`robot.driver`): `sim-ned2`, `niryo`, ….
    pub fn name(self) -> &'static str {
        match self {
            RobotDriver::SimNed2 => "sim-ned2",
            RobotDriver::SimWidowx => "sim-widowx",
            RobotDriver::Niryo => "niryo",
            RobotDriver::Widowx => "widowx",
            RobotDriver::Replay => "replay",
        }
    }

    /// The robot model this driver always drives; `None` for the replay driver, whose model is
    /// `[robot.replay] model` (use [`RobotConfig::model`], which knows both).
    pub fn fixed_model(self) -> Option<RobotModel> {
        match self {
            RobotDriver::SimNed2 | RobotDriver::Niryo => Some(RobotModel::Ned2),
            RobotDriver::SimWidowx | RobotDriver::Widowx => Some(RobotModel::WidowX250),
            RobotDriver::Replay => None,
        }
    }

    /// Whether this driver is a simulator (needs no hardware).
    pub fn is_simulated(self) -> bool {
        matches!(self, RobotDriver::SimNed2 | RobotDriver::SimWidowx)
    }
}

/// `[robot]`
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RobotConfig {
    /// The arm driver.
    pub driver: RobotDriver,
    /// Scene file of the simulator (objects, workspaces); `None` = the built-in default scene
    /// of the simulated model.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub scene: Option<PathBuf>,
    /// Simulated motion time relative to the real robot (1.0 = realistic, 0.1 = ten times
    /// faster). Finite, from 0.001 to 100.
    #[serde(default = "defaults::time_scale")]
    pub time_scale: f64,
    /// Control ticks per second of the arm: how often a motion is advanced, checked for a stop
    /// and published on `arm/state` (1 to 1000).
    #[serde(default = "defaults::control_rate_hz")]
    pub control_rate_hz: u32,
    /// Host name or address of a networked robot (the `niryo` driver); required by it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub host: Option<String>,
    /// TCP port of a networked robot (40001 on a Ned2).
    #[serde(default = "defaults::port")]
    pub port: u16,
    /// `[robot.niryo]`: settings of the `niryo` driver.
    #[serde(default)]
    pub niryo: crate::niryo_config::NiryoConfig,
    /// `[robot.widowx]`: settings of the `widowx` driver (serial device, servos, camera).
    #[serde(default)]
    pub widowx: crate::widowx_config::WidowxConfig,
    /// `[robot.replay]`: settings of the `replay` driver (the recording, its pace).
    #[serde(default)]
    pub replay: crate::replay_config::ReplayConfig,
    /// `[robot.camera]`: the wrist camera.
    #[serde(default)]
    pub camera: CameraConfig,
    /// `[robot.faults.<arm|gripper|camera>]`: faults the simulated drivers inject on purpose.
    #[serde(default)]
    pub faults: FaultsConfig,
    /// `[[robot.workspaces]]`: the workspace sheets on the table (id, corners, observation
    /// pose), the same for the simulator and a real robot. Empty: the robot model's built-in
    /// ones ([`robotd_protocol::workspace::builtin_workspaces`]).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub workspaces: Vec<WorkspaceSpec>,
}

impl RobotConfig {
    /// The robot model: the driver's, or for the replay driver `[robot.replay] model`.
    pub fn model(&self) -> RobotModel {
        self.driver.fixed_model().unwrap_or(self.replay.model)
    }

    /// The workspaces robotd uses: `[[robot.workspaces]]`, else the model's built-in ones.
    pub fn workspaces(&self) -> Vec<WorkspaceSpec> {
        if self.workspaces.is_empty() {
            builtin_workspaces(self.model())
        } else {
            self.workspaces.clone()
        }
    }

    /// [`Self::workspaces`] as the rest of robotd describes them (tools, workspace model).
    pub fn workspace_infos(&self) -> Vec<WorkspaceInfo> {
        let model = self.model();
        self.workspaces().iter().map(|w| w.to_info(model)).collect()
    }

    /// What identifies the physical robot a commissioning measured: the model, the driver and
    /// where it is reached (host and port, servo device, camera source), as 16 hex digits
    /// (FNV-1a). Written with the measured mount; `robotd doctor` compares it.
    pub fn commissioning_fingerprint(&self) -> String {
        let identity = format!(
            "{:?}|{:?}|{:?}|{}|{}|{:?}",
            self.model(),
            self.driver,
            self.host,
            self.port,
            self.widowx.device.display(),
            self.widowx.camera_url,
        );
        let mut hash: u64 = 0xcbf2_9ce4_8422_2325;
        for byte in identity.bytes() {
            hash ^= u64::from(byte);
            hash = hash.wrapping_mul(0x0100_0000_01b3);
        }
        format!("{hash:016x}")
    }

    /// Where the wrist camera sits: `[robot.camera.mount]`, else the model's nominal mount.
    /// A mount the config checks refuse is an error naming the value.
    pub fn camera_mount(
        &self,
    ) -> Result<robotd_kinematics::CameraMount, robotd_kinematics::MountError> {
        match &self.camera.mount {
            Some(mount) => robotd_kinematics::CameraMount::from_xyz_rpy_deg(mount.to_array()),
            None => Ok(robotd_kinematics::CameraMount::default_for(self.model())),
        }
    }

    /// [`Self::control_rate_hz`] as the period of one control tick.
    pub fn control_period(&self) -> Duration {
        Duration::from_secs_f64(1.0 / f64::from(self.control_rate_hz.max(1)))
    }
}

/// `[robot.camera]`
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraConfig {
    /// Frames per second published on `camera/frames` (0.1 to 60).
    #[serde(default = "defaults::camera_fps")]
    pub fps: f64,
    /// Standard deviation of the simulated sensor noise, in 0–255 pixel units (0 to 50).
    #[serde(default = "defaults::noise_stddev")]
    pub noise_stddev: f64,
    /// Whether the simulated camera applies the lens distortion of its intrinsics.
    #[serde(default)]
    pub lens_distortion: bool,
    /// `[robot.camera.mount]`: where the wrist camera sits on the arm; absent: the model's
    /// nominal mount (`robotd_kinematics::CameraMount::default_for`). `robotd commission`
    /// measures it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mount: Option<CameraMountConfig>,
}

/// `[robot.camera.mount]`: the transform from the link the camera is fixed to (the Ned2's
/// wrist, the WidowX's tool centre point) to the camera's optical frame (z = viewing
/// direction, x = image right, y = image down). Translation in metres in the link's axes,
/// rotation as roll, pitch, yaw in degrees (R = Rz(yaw)·Ry(pitch)·Rx(roll)).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraMountConfig {
    /// Translation along the link's x axis, metres.
    pub x_m: f64,
    /// Translation along the link's y axis, metres.
    pub y_m: f64,
    /// Translation along the link's z axis, metres.
    pub z_m: f64,
    /// Rotation about x, degrees.
    pub roll_deg: f64,
    /// Rotation about y, degrees.
    pub pitch_deg: f64,
    /// Rotation about z, degrees.
    pub yaw_deg: f64,
    /// Written by `robotd commission`: the [`RobotConfig::commissioning_fingerprint`] of the
    /// robot it was measured on, so that `robotd doctor` can tell when the robot changed since.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub measured_for: Option<String>,
}

impl CameraMountConfig {
    /// `[x_m, y_m, z_m, roll_deg, pitch_deg, yaw_deg]`.
    pub fn to_array(&self) -> [f64; 6] {
        [
            self.x_m,
            self.y_m,
            self.z_m,
            self.roll_deg,
            self.pitch_deg,
            self.yaw_deg,
        ]
    }

    /// From `[x_m, y_m, z_m, roll_deg, pitch_deg, yaw_deg]`.
    pub fn from_array([x_m, y_m, z_m, roll_deg, pitch_deg, yaw_deg]: [f64; 6]) -> Self {
        Self {
            x_m,
            y_m,
            z_m,
            roll_deg,
            pitch_deg,
            yaw_deg,
            measured_for: None,
        }
    }

    fn check(&self, checks: &mut Checks) {
        let names = ["x_m", "y_m", "z_m", "roll_deg", "pitch_deg", "yaw_deg"];
        for (name, value) in names.into_iter().zip(self.to_array()) {
            let key = format!("camera.mount.{name}");
            if !value.is_finite() {
                checks.problem(&key, format!("must be a finite number, got {value}"));
            } else if name.ends_with("_m") && value.abs() > 0.3 {
                checks.problem(
                    &key,
                    format!(
                        "{value} m is farther than any wrist camera sits from its link (at most \
                         0.3 m; the translation is in metres, not millimetres)"
                    ),
                );
            } else if name.ends_with("_deg") && value.abs() > 360.0 {
                checks.problem(&key, format!("{value}° is not an angle from -360 to 360"));
            }
        }
    }
}

impl Default for CameraConfig {
    fn default() -> Self {
        Self {
            fps: defaults::camera_fps(),
            noise_stddev: defaults::noise_stddev(),
            lens_distortion: false,
            mount: None,
        }
    }
}

/// `[robot.faults]`: fault injection per simulated hardware actor.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FaultsConfig {
    /// Faults of the arm driver.
    #[serde(default)]
    pub arm: FaultConfig,
    /// Faults of the gripper driver.
    #[serde(default)]
    pub gripper: FaultConfig,
    /// Faults of the camera driver.
    #[serde(default)]
    pub camera: FaultConfig,
}

/// Faults one simulated driver injects: a failing command crashes the driver (as a driver bug
/// would), so supervision brings the actor to its safe state and restarts it.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FaultConfig {
    /// Fail every Nth command (0 = never).
    #[serde(default)]
    pub fail_every_n: u32,
    /// Fail each command with this probability (0.0 to 1.0).
    #[serde(default)]
    pub fail_probability: f64,
    /// Seed of the random failures, so a run can be repeated.
    #[serde(default)]
    pub seed: u64,
    /// A failing command first hangs this long, in ms (0 = fails at once).
    #[serde(default)]
    pub hang_ms: u64,
}

impl FaultConfig {
    /// Whether any fault is configured.
    pub fn is_active(&self) -> bool {
        self.fail_every_n > 0 || self.fail_probability > 0.0
    }
}

mod defaults {
    pub fn time_scale() -> f64 {
        1.0
    }
    pub fn control_rate_hz() -> u32 {
        50
    }
    pub fn camera_fps() -> f64 {
        15.0
    }
    pub fn noise_stddev() -> f64 {
        2.0
    }
    pub fn port() -> u16 {
        40001
    }
}

impl Section for RobotConfig {
    fn check(&self, checks: &mut Checks) {
        checks.range_f64("time_scale", self.time_scale, 0.001..=100.0, "");
        checks.range_u64("control_rate_hz", self.control_rate_hz.into(), 1..=1000, "");
        if let Some(scene) = &self.scene {
            if scene.as_os_str().is_empty() {
                checks.problem(
                    "scene",
                    "must not be empty (leave it out for the built-in scene)",
                );
            }
        }
        let mut ids: Vec<&str> = Vec::new();
        for (i, workspace) in self.workspaces.iter().enumerate() {
            for problem in workspace.problems() {
                checks.problem(
                    &format!("workspaces[{i}]"),
                    format!("'{}': {problem}", workspace.id),
                );
            }
            if ids.contains(&workspace.id.as_str()) {
                checks.problem(
                    &format!("workspaces[{i}]"),
                    format!("id '{}' is used twice", workspace.id),
                );
            }
            ids.push(&workspace.id);
        }
        checks.range_f64("camera.fps", self.camera.fps, 0.1..=60.0, "");
        if let Some(mount) = &self.camera.mount {
            mount.check(checks);
        }
        if self.driver == RobotDriver::Niryo {
            match self.host.as_deref().map(str::trim) {
                None | Some("") => checks.problem(
                    "host",
                    "the niryo driver needs the robot's address, e.g. robot.host = \"192.168.1.50\"",
                ),
                Some(host) if host.contains(char::is_whitespace) || host.contains('/') => checks
                    .problem(
                        "host",
                        format!("'{host}' is not a host name or address (no scheme, path or spaces)"),
                    ),
                Some(_) => {}
            }
            if self.port == 0 {
                checks.problem(
                    "port",
                    "must be a TCP port from 1 to 65535 (the Ned2 uses 40001)",
                );
            }
        }
        self.niryo.check(checks);
        self.widowx.check(checks);
        self.replay
            .check(checks, self.driver == RobotDriver::Replay);
        checks.range_f64(
            "camera.noise_stddev",
            self.camera.noise_stddev,
            0.0..=50.0,
            "",
        );
        for (name, fault) in [
            ("arm", &self.faults.arm),
            ("gripper", &self.faults.gripper),
            ("camera", &self.faults.camera),
        ] {
            if !(fault.fail_probability.is_finite()
                && (0.0..=1.0).contains(&fault.fail_probability))
            {
                checks.problem(
                    &format!("faults.{name}.fail_probability"),
                    format!("must be from 0.0 to 1.0, got {}", fault.fail_probability),
                );
            }
            if fault.hang_ms > 600_000 {
                checks.problem(
                    &format!("faults.{name}.hang_ms"),
                    format!("must be at most 600000 ms, got {}", fault.hang_ms),
                );
            }
        }
    }
}

#[cfg(test)]
mod name_tests {
    use super::RobotDriver;

    #[test]
    fn a_driver_is_named_as_configuration_spells_it() {
        #[derive(serde::Deserialize)]
        struct Holder {
            driver: RobotDriver,
        }
        for name in ["sim-ned2", "sim-widowx", "niryo", "widowx", "replay"] {
            let holder: Holder = toml::from_str(&format!("driver = \"{name}\"")).unwrap();
            assert_eq!(holder.driver.name(), name);
        }
    }
}
