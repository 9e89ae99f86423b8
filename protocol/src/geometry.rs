//! Poses, points and joint states in the robot's base frame, and the robot models robotd knows.
//!
//! The frame is the one of the MCP tools: origin at the robot base, **x forward** (away from
//! the robot, "up" on the workspace), **y left**, z up, all in metres; orientations are
//! roll/pitch/yaw in radians (a tool pointing straight down has pitch +π/2).
//!
//! Rust field names carry the unit (`x_m`, `yaw_rad`); on the wire a [`Pose`] is
//! `{x, y, z, roll, pitch, yaw}` and a [`Point2`] is `[x, y]`, the shapes the Python tools use.
//!
//! ```
//! use robotd_protocol::geometry::{Point2, Pose};
//!
//! let observe = Pose::new(0.173, -0.002, 0.277, -3.042, 1.327, -3.027);
//! assert!(observe.validate().is_ok());
//! assert_eq!(observe.xy(), Point2::new(0.173, -0.002));
//! assert_eq!(observe.to_string(), "(x=0.173, y=-0.002, z=0.277, roll=-3.042, pitch=1.327, yaw=-3.027)");
//! ```

use crate::location::ParseEnumError;
use crate::validate::{finite, Validate, ValidationError};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};
use std::fmt;
use std::str::FromStr;

/// A tool pose: position in metres and orientation as roll/pitch/yaw in radians, base frame.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct Pose {
    /// Forward distance from the base, metres.
    #[serde(rename = "x")]
    pub x_m: f64,
    /// Leftward distance from the base, metres.
    #[serde(rename = "y")]
    pub y_m: f64,
    /// Height above the base, metres.
    #[serde(rename = "z")]
    pub z_m: f64,
    /// Rotation about x, radians.
    #[serde(rename = "roll")]
    pub roll_rad: f64,
    /// Rotation about y, radians (+π/2 = tool pointing down).
    #[serde(rename = "pitch")]
    pub pitch_rad: f64,
    /// Rotation about z, radians.
    #[serde(rename = "yaw")]
    pub yaw_rad: f64,
}

impl Pose {
    /// A pose from x, y, z (m) and roll, pitch, yaw (rad).
    pub const fn new(
        x_m: f64,
        y_m: f64,
        z_m: f64,
        roll_rad: f64,
        pitch_rad: f64,
        yaw_rad: f64,
    ) -> Self {
        Self {
            x_m,
            y_m,
            z_m,
            roll_rad,
            pitch_rad,
            yaw_rad,
        }
    }

    /// The position part.
    pub const fn position(&self) -> Point3 {
        Point3::new(self.x_m, self.y_m, self.z_m)
    }

    /// The position projected onto the table plane.
    pub const fn xy(&self) -> Point2 {
        Point2::new(self.x_m, self.y_m)
    }

    /// This pose moved by `delta` (each component added).
    pub fn shifted(&self, delta: &PoseDelta) -> Self {
        Self {
            x_m: self.x_m + delta.dx_m,
            y_m: self.y_m + delta.dy_m,
            z_m: self.z_m + delta.dz_m,
            roll_rad: self.roll_rad + delta.droll_rad,
            pitch_rad: self.pitch_rad + delta.dpitch_rad,
            yaw_rad: self.yaw_rad + delta.dyaw_rad,
        }
    }

    /// Straight-line distance between the positions of two poses, metres.
    pub fn distance_to(&self, other: &Pose) -> f64 {
        self.position().distance_to(&other.position())
    }

    /// Components as `[x, y, z, roll, pitch, yaw]`.
    pub const fn to_array(&self) -> [f64; 6] {
        [
            self.x_m,
            self.y_m,
            self.z_m,
            self.roll_rad,
            self.pitch_rad,
            self.yaw_rad,
        ]
    }

    /// A pose from `[x, y, z, roll, pitch, yaw]`.
    pub const fn from_array(a: [f64; 6]) -> Self {
        Self::new(a[0], a[1], a[2], a[3], a[4], a[5])
    }

    /// Refuses NaN and infinite components, naming the first bad one.
    pub fn validate(&self) -> Result<(), ValidationError> {
        finite("x", self.x_m)?;
        finite("y", self.y_m)?;
        finite("z", self.z_m)?;
        finite("roll", self.roll_rad)?;
        finite("pitch", self.pitch_rad)?;
        finite("yaw", self.yaw_rad)
    }
}

impl Validate for Pose {
    fn validate(&self) -> Result<(), ValidationError> {
        Pose::validate(self)
    }
}

impl fmt::Display for Pose {
    /// `(x=0.250, y=0.000, z=0.100, roll=0.000, pitch=1.571, yaw=0.000)`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "(x={:.3}, y={:.3}, z={:.3}, roll={:.3}, pitch={:.3}, yaw={:.3})",
            self.x_m, self.y_m, self.z_m, self.roll_rad, self.pitch_rad, self.yaw_rad
        )
    }
}

/// A relative motion of the tool: position change in metres, orientation change in radians.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct PoseDelta {
    /// Change along x, metres.
    pub dx_m: f64,
    /// Change along y, metres.
    pub dy_m: f64,
    /// Change along z, metres.
    pub dz_m: f64,
    /// Change of roll, radians.
    pub droll_rad: f64,
    /// Change of pitch, radians.
    pub dpitch_rad: f64,
    /// Change of yaw, radians.
    pub dyaw_rad: f64,
}

impl PoseDelta {
    /// A pure translation.
    pub const fn translation(dx_m: f64, dy_m: f64, dz_m: f64) -> Self {
        Self {
            dx_m,
            dy_m,
            dz_m,
            droll_rad: 0.0,
            dpitch_rad: 0.0,
            dyaw_rad: 0.0,
        }
    }

    /// Refuses NaN and infinite components.
    pub fn validate(&self) -> Result<(), ValidationError> {
        finite("dx_m", self.dx_m)?;
        finite("dy_m", self.dy_m)?;
        finite("dz_m", self.dz_m)?;
        finite("droll_rad", self.droll_rad)?;
        finite("dpitch_rad", self.dpitch_rad)?;
        finite("dyaw_rad", self.dyaw_rad)
    }
}

impl Validate for PoseDelta {
    fn validate(&self) -> Result<(), ValidationError> {
        PoseDelta::validate(self)
    }
}

/// A point on the table plane, metres. On the wire: `[x, y]`, like the tools' coordinates.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
#[serde(from = "[f64; 2]", into = "[f64; 2]")]
pub struct Point2 {
    /// Forward, metres.
    pub x_m: f64,
    /// Left, metres.
    pub y_m: f64,
}

impl Point2 {
    /// A point from x, y in metres.
    pub const fn new(x_m: f64, y_m: f64) -> Self {
        Self { x_m, y_m }
    }

    /// Euclidean distance, metres.
    pub fn distance_to(&self, other: &Point2) -> f64 {
        (self.x_m - other.x_m).hypot(self.y_m - other.y_m)
    }

    /// Refuses NaN and infinite coordinates.
    pub fn validate(&self) -> Result<(), ValidationError> {
        finite("x", self.x_m)?;
        finite("y", self.y_m)
    }
}

impl Validate for Point2 {
    fn validate(&self) -> Result<(), ValidationError> {
        Point2::validate(self)
    }
}

impl From<[f64; 2]> for Point2 {
    fn from([x_m, y_m]: [f64; 2]) -> Self {
        Self { x_m, y_m }
    }
}

impl From<Point2> for [f64; 2] {
    fn from(p: Point2) -> Self {
        [p.x_m, p.y_m]
    }
}

impl fmt::Display for Point2 {
    /// `[0.250, -0.030]`, the way tool replies print coordinates.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "[{:.3}, {:.3}]", self.x_m, self.y_m)
    }
}

/// A point in space, metres. On the wire: `{x, y, z}`, as in the object JSON.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct Point3 {
    /// Forward, metres.
    #[serde(rename = "x")]
    pub x_m: f64,
    /// Left, metres.
    #[serde(rename = "y")]
    pub y_m: f64,
    /// Up, metres.
    #[serde(rename = "z")]
    pub z_m: f64,
}

impl Point3 {
    /// A point from x, y, z in metres.
    pub const fn new(x_m: f64, y_m: f64, z_m: f64) -> Self {
        Self { x_m, y_m, z_m }
    }

    /// Drops z.
    pub const fn xy(&self) -> Point2 {
        Point2::new(self.x_m, self.y_m)
    }

    /// Euclidean distance, metres.
    pub fn distance_to(&self, other: &Point3) -> f64 {
        let (dx, dy, dz) = (
            self.x_m - other.x_m,
            self.y_m - other.y_m,
            self.z_m - other.z_m,
        );
        (dx * dx + dy * dy + dz * dz).sqrt()
    }

    /// Refuses NaN and infinite coordinates.
    pub fn validate(&self) -> Result<(), ValidationError> {
        finite("x", self.x_m)?;
        finite("y", self.y_m)?;
        finite("z", self.z_m)
    }
}

impl Validate for Point3 {
    fn validate(&self) -> Result<(), ValidationError> {
        Point3::validate(self)
    }
}

/// Joint positions (and, when known, velocities) of an arm at one instant.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct JointState {
    /// One position per joint, base to wrist, radians.
    pub positions_rad: Vec<f64>,
    /// One velocity per joint, radians per second; empty when the driver does not report them.
    pub velocities_rad_s: Vec<f64>,
    /// When the state was read, nanoseconds since the Unix epoch.
    pub timestamp_unix_ns: u64,
}

impl JointState {
    /// Positions only, no velocities.
    pub fn from_positions(positions_rad: Vec<f64>, timestamp_unix_ns: u64) -> Self {
        Self {
            positions_rad,
            velocities_rad_s: Vec::new(),
            timestamp_unix_ns,
        }
    }

    /// Refuses non-finite values and a velocity list whose length differs from the positions'.
    pub fn validate(&self) -> Result<(), ValidationError> {
        for (i, p) in self.positions_rad.iter().enumerate() {
            finite(&format!("positions_rad[{i}]"), *p)?;
        }
        if !self.velocities_rad_s.is_empty()
            && self.velocities_rad_s.len() != self.positions_rad.len()
        {
            return Err(ValidationError::WrongLength {
                field: "velocities_rad_s".into(),
                expected: self.positions_rad.len(),
                got: self.velocities_rad_s.len(),
            });
        }
        for (i, v) in self.velocities_rad_s.iter().enumerate() {
            finite(&format!("velocities_rad_s[{i}]"), *v)?;
        }
        Ok(())
    }

    /// [`validate`](Self::validate), plus one position per joint of `model`.
    pub fn validate_for(&self, model: RobotModel) -> Result<(), ValidationError> {
        if self.positions_rad.len() != model.joint_count() {
            return Err(ValidationError::WrongLength {
                field: "positions_rad".into(),
                expected: model.joint_count(),
                got: self.positions_rad.len(),
            });
        }
        self.validate()
    }
}

impl Validate for JointState {
    fn validate(&self) -> Result<(), ValidationError> {
        JointState::validate(self)
    }
}

/// The arm models robotd drives. On the wire: `"ned2"`, `"widowx250"`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum RobotModel {
    /// Niryo Ned2 (six revolute joints, TCP protocol on port 40001).
    Ned2,
    /// Trossen / Interbotix WidowX 250 6-DOF (Dynamixel Protocol 2.0).
    #[serde(rename = "widowx250")]
    WidowX250,
}

impl RobotModel {
    /// Every model.
    pub const ALL: [RobotModel; 2] = [RobotModel::Ned2, RobotModel::WidowX250];

    /// Wire and config name: `"ned2"`, `"widowx250"`.
    pub const fn as_str(&self) -> &'static str {
        match self {
            Self::Ned2 => "ned2",
            Self::WidowX250 => "widowx250",
        }
    }

    /// Name for people: `"Niryo Ned2"`, `"WidowX 250"`.
    pub const fn display_name(&self) -> &'static str {
        match self {
            Self::Ned2 => "Niryo Ned2",
            Self::WidowX250 => "WidowX 250",
        }
    }

    /// The robot type as the Python stack names it (`robot_id` of `get_system_status`):
    /// `niryo` or `widowx`.
    pub const fn robot_type(&self) -> &'static str {
        match self {
            Self::Ned2 => "niryo",
            Self::WidowX250 => "widowx",
        }
    }

    /// Number of arm joints (the gripper not counted).
    pub const fn joint_count(&self) -> usize {
        match self {
            Self::Ned2 | Self::WidowX250 => 6,
        }
    }
}

impl fmt::Display for RobotModel {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

impl FromStr for RobotModel {
    type Err = ParseEnumError;

    /// Accepts `ned2`, `niryo_ned2`, `niryo`, `widowx250`, `widowx_250`, `wx250s`, `widowx`
    /// (any case, `-` or `_` or space as separator, surrounding whitespace ignored).
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let norm: String = s
            .trim()
            .chars()
            .filter(|c| !matches!(c, '_' | '-' | ' '))
            .flat_map(char::to_lowercase)
            .collect();
        match norm.as_str() {
            "ned2" | "niryoned2" | "niryo" => Ok(Self::Ned2),
            "widowx250" | "wx250s" | "wx250" | "widowx" | "widowx2506dof" => Ok(Self::WidowX250),
            _ => Err(ParseEnumError {
                kind: "robot model",
                value: s.to_owned(),
                valid: &["ned2", "widowx250"],
            }),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pose_validate_names_the_bad_component() {
        let mut p = Pose::new(0.2, 0.0, 0.1, 0.0, 1.57, 0.0);
        assert!(p.validate().is_ok());
        p.yaw_rad = f64::NEG_INFINITY;
        assert_eq!(
            p.validate().unwrap_err().to_string(),
            "yaw: must be a finite number, got -inf"
        );
    }

    #[test]
    fn pose_wire_names_follow_python() {
        let json = serde_json::to_value(Pose::new(1.0, 2.0, 3.0, 4.0, 5.0, 6.0)).unwrap();
        assert_eq!(
            json,
            serde_json::json!({"x": 1.0, "y": 2.0, "z": 3.0, "roll": 4.0, "pitch": 5.0, "yaw": 6.0})
        );
    }

    #[test]
    fn point2_is_an_array_on_the_wire() {
        let p = Point2::new(0.25, -0.03);
        assert_eq!(
            serde_json::to_string(&p).unwrap(),
            "[0.25,-0.03]".to_string()
        );
        assert_eq!(serde_json::from_str::<Point2>("[0.25,-0.03]").unwrap(), p);
        assert!(serde_json::from_str::<Point2>("[0.25]").is_err());
        assert!(serde_json::from_str::<Point2>("[0.25, 1, 2]").is_err());
        assert_eq!(p.to_string(), "[0.250, -0.030]");
    }

    #[test]
    fn joint_state_checks_lengths() {
        let mut js = JointState::from_positions(vec![0.0; 6], 1);
        assert!(js.validate_for(RobotModel::Ned2).is_ok());
        js.velocities_rad_s = vec![0.0; 5];
        assert_eq!(
            js.validate().unwrap_err().to_string(),
            "velocities_rad_s: must have 6 entries, got 5"
        );
        let short = JointState::from_positions(vec![0.0; 5], 1);
        assert!(short.validate_for(RobotModel::WidowX250).is_err());
        let nan = JointState::from_positions(vec![0.0, f64::NAN], 1);
        assert_eq!(nan.validate().unwrap_err().field(), "positions_rad[1]");
    }

    #[test]
    fn robot_model_names() {
        assert_eq!("  Ned2 ".parse::<RobotModel>().unwrap(), RobotModel::Ned2);
        assert_eq!(
            "wx250s".parse::<RobotModel>().unwrap(),
            RobotModel::WidowX250
        );
        assert_eq!(
            "WidowX_250".parse::<RobotModel>().unwrap(),
            RobotModel::WidowX250
        );
        let err = "ur5".parse::<RobotModel>().unwrap_err().to_string();
        assert_eq!(
            err,
            "unknown robot model 'ur5'; valid values: 'ned2', 'widowx250'"
        );
        for m in RobotModel::ALL {
            assert_eq!(serde_json::to_value(m).unwrap(), m.as_str());
            assert_eq!(m.as_str().parse::<RobotModel>().unwrap(), m);
        }
    }

    #[test]
    fn shifted_adds_components() {
        let p = Pose::new(0.2, 0.0, 0.1, 0.0, 0.0, 0.0);
        let q = p.shifted(&PoseDelta::translation(0.01, -0.02, 0.03));
        assert!((q.x_m - 0.21).abs() < 1e-12);
        assert!((q.y_m + 0.02).abs() < 1e-12);
        assert!((q.z_m - 0.13).abs() < 1e-12);
        assert!(
            (p.distance_to(&q) - (0.01f64.powi(2) + 0.02f64.powi(2) + 0.03f64.powi(2)).sqrt())
                .abs()
                < 1e-12
        );
    }
}
