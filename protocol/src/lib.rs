//! # robotd-protocol: the typed messages robotd's actors exchange
//!
//! Every actor in robotd — arm, gripper, camera, perception, workspace model, skills, TTS, the
//! LLM agent, the MCP and Redis edges — talks to the others only through the message types in
//! this crate. A message is a plain serde type that implements [`Message`]: a stable dotted
//! type name (`"arm.command"`) and a schema version. On the bus it travels inside an
//! [`Envelope`] encoded as MessagePack with named fields, so a receiver can refuse a message of
//! the wrong type or version instead of misreading it, a trace follows it across processes,
//! and a Python or C++ program can read it with any msgpack library.
//!
//! The crate does no I/O and depends on no other robotd crate: an actor written in its own
//! process (or a test) needs nothing else to speak the protocol.
//!
//! ## Conventions
//!
//! - **Units** are SI and named in the field: `width_m`, `yaw_rad`, `backoff_ms` (see
//!   [`units`]). Positions are in the robot base frame, x forward, y left ([`geometry`]).
//! - **Enums** are internally tagged, `{"kind": "move_to_pose", …}`, with snake-case names;
//!   word-valued tool parameters ([`Location`], [`Direction`], [`WorkspacePoint`]) are their
//!   exact spec strings.
//! - **Requests** have a matching reply enum with an `Error { error }` variant carrying a typed
//!   error whose `Display` is a reason a user can act on.
//! - **Validation**: serde checks shape, [`Validate`] checks content (finite numbers, ranges,
//!   non-empty strings). Check everything that comes from outside the process.
//!
//! ## Example
//!
//! ```
//! use robotd_protocol::arm::{ArmCommand, ArmReply};
//! use robotd_protocol::envelope::{decode, encode, DecodeError, Envelope, Message};
//! use robotd_protocol::geometry::Pose;
//! use robotd_protocol::{Location, Validate};
//!
//! // An edge parses a tool parameter and builds a command...
//! let location: Location = " Right Next To".parse()?;
//! assert_eq!(location.as_str(), "right next to");
//! let cmd = ArmCommand::move_to(Pose::new(0.25, -0.03, 0.12, 0.0, 1.571, 0.0));
//! cmd.validate()?;
//!
//! // ...sends it in an envelope...
//! let mut bytes = Vec::new();
//! encode(&Envelope::new(cmd.clone()), &mut bytes)?;
//! assert_eq!(ArmCommand::TYPE, "arm.command");
//!
//! // ...and the arm actor decodes it; a reader of another type refuses it.
//! let received: Envelope<ArmCommand> = decode(&bytes)?;
//! assert_eq!(received.body, cmd);
//! let wrong = decode::<ArmReply>(&bytes).unwrap_err();
//! assert!(matches!(wrong, DecodeError::WrongType { .. }));
//! assert_eq!(wrong.to_string(), "expected a 'arm.reply' message but got 'arm.command'");
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! ## Modules
//!
//! | module | what |
//! |---|---|
//! | [`envelope`] | [`Message`], [`Envelope`], [`TraceContext`], `encode`/`decode` |
//! | [`units`], [`geometry`] | unit conventions; [`Pose`], [`Point2`], [`Point3`], [`JointState`], [`RobotModel`] |
//! | [`location`] | [`Location`], [`Direction`], [`WorkspacePoint`] |
//! | [`validate`] | [`Validate`], [`ValidationError`] |
//! | [`arm`], [`gripper`], [`camera`] | hardware actors' commands, replies, states, frames |
//! | [`objects`], [`workspace`] | detected objects and the workspace model's queries |
//! | [`skills`] | pick, place, push and the other robot-control skills |
//! | [`speech`], [`agent`], [`health`] | TTS and overlays, the LLM agent, supervision and e-stop |
//! | [`stt`] | speech to text: audio in, transcripts out |
//! | [`diagnostics`] | bus probes and benchmarks (`robotd doctor`, `robotd bench`) |

pub mod agent;
pub mod arm;
pub mod camera;
pub mod diagnostics;
pub mod envelope;
pub mod geometry;
pub mod gripper;
pub mod gripper_geometry;
pub mod hardware;
pub mod health;
pub mod location;
pub mod named_view;
pub mod objects;
pub mod pixels;
pub mod safety;
pub mod skills;
pub mod speech;
pub mod stt;
pub mod units;
pub mod validate;
pub mod workspace;

pub use envelope::{decode, encode, DecodeError, EncodeError, Envelope, Message, TraceContext};
pub use geometry::{JointState, Point2, Point3, Pose, PoseDelta, RobotModel};
pub use location::{Direction, Location, ParseEnumError, WorkspacePoint};
pub use validate::{Validate, ValidationError};

/// `(TYPE, SCHEMA_VERSION)` of every message type defined in this crate, for bus catalogues,
/// dashboards and other-language bindings.
pub const MESSAGE_TYPES: &[(&str, u16)] = &[
    entry::<arm::ArmCommand>(),
    entry::<arm::ArmReply>(),
    entry::<arm::ArmState>(),
    entry::<gripper::GripperCommand>(),
    entry::<gripper::GripperReply>(),
    entry::<gripper::GripperState>(),
    entry::<camera::CameraFrameHeader>(),
    entry::<camera::CameraImage>(),
    entry::<camera::CameraIntrinsics>(),
    entry::<objects::Detections>(),
    entry::<workspace::WorkspaceRequest>(),
    entry::<workspace::WorkspaceReply>(),
    entry::<workspace::DetectableLabels>(),
    entry::<workspace::WorkspaceQuery>(),
    entry::<workspace::TrackedObjects>(),
    entry::<skills::SkillRequest>(),
    entry::<skills::SkillReply>(),
    entry::<skills::SkillProgress>(),
    entry::<skills::SkillCancel>(),
    entry::<speech::SpeakRequest>(),
    entry::<speech::SpeechEvent>(),
    entry::<speech::TextOverlay>(),
    entry::<stt::TranscribeRequest>(),
    entry::<stt::TranscribeReply>(),
    entry::<stt::Transcript>(),
    entry::<stt::SttStatus>(),
    entry::<agent::AgentRequest>(),
    entry::<agent::AgentEvent>(),
    entry::<agent::AgentCancel>(),
    entry::<health::ActorHealth>(),
    entry::<health::RestartEvent>(),
    entry::<health::EmergencyStop>(),
    entry::<health::EStopRelease>(),
    entry::<health::EStopState>(),
    entry::<health::SystemStatus>(),
    entry::<diagnostics::Ping>(),
    entry::<diagnostics::Pong>(),
    entry::<diagnostics::TestPatternRequest>(),
    entry::<diagnostics::TestPatternReply>(),
    entry::<diagnostics::SimWorldRequest>(),
    entry::<diagnostics::SimWorldReply>(),
];

const fn entry<T: Message>() -> (&'static str, u16) {
    (T::TYPE, T::SCHEMA_VERSION)
}

#[cfg(test)]
mod tests {
    use super::MESSAGE_TYPES;

    #[test]
    fn message_type_names_are_unique_and_dotted() {
        let mut names: Vec<&str> = MESSAGE_TYPES.iter().map(|(n, _)| *n).collect();
        for n in &names {
            let parts: Vec<&str> = n.split('.').collect();
            assert_eq!(parts.len(), 2, "{n}");
            assert!(
                parts
                    .iter()
                    .all(|p| !p.is_empty()
                        && p.chars().all(|c| c.is_ascii_lowercase() || c == '_')),
                "{n}"
            );
        }
        names.sort_unstable();
        let before = names.len();
        names.dedup();
        assert_eq!(before, names.len(), "duplicate message type names");
    }
}
