//! What a recording holds, from one pass over it.
//!
//! [`Contents::inspect`] reads every message once (no image is decoded; about a second per
//! gigabyte from a warm disk) and notes the messages per channel, the time span, the robot the
//! file was recorded on (from its URDF on [`crate::ROBOT_DESCRIPTION`]), the first camera
//! header and the first arm and gripper states. A file that breaks off after some messages is
//! still described, with [`Contents::damaged`] saying where and why; one that is not MCAP is
//! an error.

use crate::camera::FrameMeta;
use crate::reader::{Messages, ReadError};
use robotd_protocol::arm::ArmState;
use robotd_protocol::geometry::RobotModel;
use robotd_protocol::gripper::GripperState;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// What one recording holds.
#[derive(Debug, Clone, PartialEq)]
pub struct Contents {
    /// The file.
    pub path: PathBuf,
    /// Its size, bytes.
    pub bytes: u64,
    /// Messages per channel topic.
    pub messages: BTreeMap<String, u64>,
    /// Earliest and latest log time of any message, ns since the Unix epoch (`None`: no
    /// message).
    pub span: Option<(u64, u64)>,
    /// The robot it was recorded on, from its URDF (`None`: no URDF, or one robotd does not
    /// know).
    pub model: Option<RobotModel>,
    /// The robot's name in the URDF, as written (for messages about an unknown one).
    pub urdf_robot: Option<String>,
    /// The header of the first camera frame.
    pub first_frame: Option<FrameMeta>,
    /// The first arm state that decodes.
    pub first_arm_state: Option<ArmState>,
    /// The first gripper state that decodes.
    pub first_gripper_state: Option<GripperState>,
    /// The widest the gripper was recorded open, metres.
    pub widest_gripper_m: Option<f64>,
    /// Why the file ended early, when it did (the messages before were read).
    pub damaged: Option<String>,
}

impl Contents {
    /// Reads `path` once and describes it.
    pub fn inspect(path: &Path) -> Result<Contents, ReadError> {
        let mut contents = Contents {
            path: path.to_path_buf(),
            bytes: std::fs::metadata(path).map(|m| m.len()).unwrap_or(0),
            messages: BTreeMap::new(),
            span: None,
            model: None,
            urdf_robot: None,
            first_frame: None,
            first_arm_state: None,
            first_gripper_state: None,
            widest_gripper_m: None,
            damaged: None,
        };
        for message in Messages::open(path)? {
            let message = match message {
                Ok(message) => message,
                Err(ReadError::Damaged { reason, .. }) => {
                    contents.damaged = Some(reason);
                    break;
                }
                Err(error) => return Err(error),
            };
            *contents
                .messages
                .entry(message.topic.to_string())
                .or_insert(0) += 1;
            let t = message.log_time;
            contents.span = Some(contents.span.map_or((t, t), |(a, b)| (a.min(t), b.max(t))));
            match &*message.topic {
                crate::ROBOT_DESCRIPTION if contents.urdf_robot.is_none() => {
                    contents.urdf_robot = urdf_robot_name(&message.data);
                    contents.model = contents.urdf_robot.as_deref().and_then(model_named);
                }
                crate::CAMERA_META if contents.first_frame.is_none() => {
                    contents.first_frame = serde_json::from_slice(&message.data).ok();
                }
                crate::ARM_STATE if contents.first_arm_state.is_none() => {
                    contents.first_arm_state = serde_json::from_slice(&message.data).ok();
                }
                crate::GRIPPER_STATE => {
                    if let Ok(state) = serde_json::from_slice::<GripperState>(&message.data) {
                        let widest = contents.widest_gripper_m.unwrap_or(0.0);
                        contents.widest_gripper_m = Some(widest.max(state.width_m));
                        contents.first_gripper_state.get_or_insert(state);
                    }
                }
                _ => {}
            }
        }
        Ok(contents)
    }

    /// Messages on `channel`.
    pub fn count(&self, channel: &str) -> u64 {
        self.messages.get(channel).copied().unwrap_or(0)
    }

    /// Camera frames (their headers: a frame without one cannot be rebuilt).
    pub fn camera_frames(&self) -> u64 {
        self.count(crate::CAMERA_META)
    }

    /// Arm states.
    pub fn arm_states(&self) -> u64 {
        self.count(crate::ARM_STATE)
    }

    /// The recorded time span, seconds.
    pub fn seconds(&self) -> f64 {
        self.span.map_or(0.0, |(a, b)| (b - a) as f64 / 1e9)
    }

    /// One line for people: span, frames, states, robot, damage.
    pub fn describe(&self) -> String {
        let size = self
            .first_frame
            .as_ref()
            .map(|f| format!(" {}×{}", f.width, f.height))
            .unwrap_or_default();
        let robot = match (&self.model, &self.urdf_robot) {
            (Some(model), _) => format!("recorded on a {}", model.display_name()),
            (None, Some(name)) => format!("recorded on an unknown robot '{name}'"),
            (None, None) => "no robot description".to_owned(),
        };
        let mut line = format!(
            "{:.1} s, {} camera frames{size}, {} arm states, {} gripper states, {robot}, {:.1} MB",
            self.seconds(),
            self.camera_frames(),
            self.arm_states(),
            self.count(crate::GRIPPER_STATE),
            self.bytes as f64 / 1e6,
        );
        if let Some(reason) = &self.damaged {
            line.push_str(&format!(
                "; the file breaks off after these messages: {reason}"
            ));
        }
        line
    }
}

/// The `name` of the `<robot>` element of the URDF in a `/robot_description` message.
fn urdf_robot_name(data: &[u8]) -> Option<String> {
    let message: serde_json::Value = serde_json::from_slice(data).ok()?;
    robot_name(message.get("data")?.as_str()?)
}

/// The `name` attribute of a URDF's root `<robot>` element, read with an XML parser (the
/// declaration, comments and other attributes before it are skipped as XML says, entities
/// unescaped); `None` when the first element is not `<robot>` or has no `name`.
fn robot_name(urdf: &str) -> Option<String> {
    use quick_xml::events::Event;
    let mut reader = quick_xml::Reader::from_str(urdf);
    loop {
        match reader.read_event().ok()? {
            Event::Start(element) | Event::Empty(element) => {
                if element.local_name().as_ref() != b"robot" {
                    return None;
                }
                let name = element.try_get_attribute("name").ok()??;
                let name = name.decode_and_unescape_value(reader.decoder()).ok()?;
                return Some(name.into_owned());
            }
            Event::Eof => return None,
            _ => {}
        }
    }
}

/// The model whose URDF (the one robotd's kinematics and recorder use) names its robot `name`.
fn model_named(name: &str) -> Option<RobotModel> {
    RobotModel::ALL.into_iter().find(|model| {
        robot_name(robotd_kinematics::Kinematics::new(*model).urdf()).as_deref() == Some(name)
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fixture::{write_recording, Recorded};

    #[test]
    fn a_session_is_counted_and_its_robot_and_first_states_found() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("s.mcap");
        let session = Recorded::short_session();
        write_recording(&path, &session);
        let contents = Contents::inspect(&path).unwrap();
        assert_eq!(contents.model, Some(RobotModel::Ned2));
        assert_eq!(contents.camera_frames(), session.frames() as u64);
        assert_eq!(contents.count(crate::CAMERA), session.frames() as u64);
        assert_eq!(contents.arm_states(), session.arm_states() as u64);
        assert_eq!(contents.seconds(), 3.0);
        assert_eq!(contents.first_frame.as_ref().unwrap().width, 16);
        assert_eq!(
            contents
                .first_arm_state
                .as_ref()
                .unwrap()
                .joints
                .positions_rad,
            session.first_arm_state().joints.positions_rad
        );
        assert_eq!(contents.widest_gripper_m, Some(0.03));
        assert!(contents.damaged.is_none());
        let line = contents.describe();
        assert!(
            line.starts_with("3.0 s, 13 camera frames 16×12, 7 arm states"),
            "{line}"
        );
        assert!(line.contains("Niryo Ned2"), "{line}");
    }

    #[test]
    fn the_robot_is_read_from_the_urdf_name() {
        for model in RobotModel::ALL {
            let urdf = robotd_kinematics::Kinematics::new(model).urdf();
            let message = serde_json::json!({ "data": urdf }).to_string();
            let name = urdf_robot_name(message.as_bytes()).unwrap();
            assert_eq!(model_named(&name), Some(model));
        }
        assert_eq!(robot_name("<robot name='ur5'>").as_deref(), Some("ur5"));
        assert_eq!(model_named("ur5"), None);
        assert_eq!(robot_name("<robot>"), None);
        assert_eq!(urdf_robot_name(b"not json"), None);
    }

    #[test]
    fn the_robot_name_is_the_name_attribute_not_a_name_inside_another() {
        let name = |urdf: &str| robot_name(urdf);
        // `name=` inside another attribute's name or value is not the name.
        assert_eq!(
            name(r#"<robot filename="x" name="ned2">"#).as_deref(),
            Some("ned2")
        );
        assert_eq!(
            name(r#"<robot doc="name='x'" name="ned2"></robot>"#).as_deref(),
            Some("ned2")
        );
        assert_eq!(name(r#"<robot filename="x"></robot>"#), None);
        // Whitespace around `=`, the XML declaration, comments, entities.
        assert_eq!(
            name("<?xml version=\"1.0\"?>\n<!-- <robot name=\"old\"> -->\n<robot name = \"wx&amp;250\"/>")
                .as_deref(),
            Some("wx&250")
        );
        // Only the root element, and only a `<robot>` one.
        assert_eq!(name(r#"<robots name="x"><robot name="y"/></robots>"#), None);
        assert_eq!(name(r#"<robot_description name="x"/>"#), None);
        assert_eq!(name(""), None);
    }

    #[test]
    fn a_damaged_file_is_described_up_to_the_damage() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("s.mcap");
        write_recording(&path, &Recorded::short_session());
        let whole = std::fs::read(&path).unwrap();
        std::fs::write(&path, &whole[..whole.len() / 2]).unwrap();
        let contents = Contents::inspect(&path).unwrap();
        assert!(contents.damaged.is_some());
        assert!(contents.arm_states() > 0);
        assert!(contents.describe().contains("breaks off"));
    }
}
