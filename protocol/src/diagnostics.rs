//! Messages for checking the bus itself: liveness probes, benchmarks, and the example
//! external actor's test-pattern camera.
//!
//! They carry no robot meaning; they let `robotd doctor`, `robotd bench` and the tests exchange
//! real traffic with an actor in another process.

use crate::envelope::Message;
use serde::{Deserialize, Serialize};

/// A probe with an opaque payload (64 bytes in the round-trip benchmark).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Ping {
    /// Sequence number, echoed back.
    pub seq: u64,
    /// Opaque bytes, echoed back (MessagePack bin).
    #[serde(with = "serde_bytes")]
    pub payload: Vec<u8>,
}

impl Message for Ping {
    const TYPE: &'static str = "diagnostics.ping";
}

/// The answer to a [`Ping`].
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Pong {
    /// The ping's sequence number.
    pub seq: u64,
    /// The ping's payload.
    #[serde(with = "serde_bytes")]
    pub payload: Vec<u8>,
    /// Process id of the answering actor (shows where it ran).
    pub served_by_pid: u32,
}

impl Message for Pong {
    const TYPE: &'static str = "diagnostics.pong";
}

/// Asks the example test-pattern camera to publish one frame.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct TestPatternRequest {
    /// Frame id to stamp on the frame.
    pub frame_id: u64,
    /// Seed of the pattern: pixel `i` is `(i + seed) % 251`.
    pub seed: u8,
}

impl Message for TestPatternRequest {
    const TYPE: &'static str = "diagnostics.test_pattern_request";
}

/// Reply of the test-pattern camera once the frame is published.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct TestPatternReply {
    /// The frame id published.
    pub frame_id: u64,
    /// Number of subscribers that received the frame.
    pub delivered_to: u64,
    /// Process id of the camera.
    pub served_by_pid: u32,
    /// What robotd's system service said when the actor joined (proves the actor can call
    /// robotd, not only be called).
    pub robotd_said: String,
}

impl Message for TestPatternReply {
    const TYPE: &'static str = "diagnostics.test_pattern_reply";
}

/// Asks the simulator for its ground truth (what the world really holds, not what the camera
/// sees). Served as `sim/world` only when the robot is simulated.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct SimWorldRequest {}

impl Message for SimWorldRequest {
    const TYPE: &'static str = "diagnostics.sim_world_request";
}

/// One object of the simulated world.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SimObjectState {
    /// The scene's label, e.g. `"red cube"`.
    pub label: String,
    /// Centre of the object's bounding box, base frame, metres.
    pub x_m: f64,
    /// Centre y, metres.
    pub y_m: f64,
    /// Centre z, metres.
    pub z_m: f64,
    /// Rotation about the vertical, radians.
    pub yaw_rad: f64,
    /// Height of the object's base above the table, metres.
    pub bottom_z_m: f64,
    /// Height of its top, metres.
    pub top_z_m: f64,
    /// Whether the gripper holds it.
    pub held: bool,
}

/// The simulator's ground truth.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SimWorldReply {
    /// The scene's name.
    pub scene: String,
    /// Every object.
    pub objects: Vec<SimObjectState>,
}

impl Message for SimWorldReply {
    const TYPE: &'static str = "diagnostics.sim_world_reply";
}
