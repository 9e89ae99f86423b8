//! # robotd-topics: the catalogue of robotd's bus topics and services
//!
//! Each topic and service of the robot: its name, message types (from `robotd-protocol`) and
//! overflow policy. The bus machinery they are declared with (`Topic`, `FrameTopic`,
//! `Service`, overflow policies, descriptions) is the runtime's, `robotd_runtime::bus`; the
//! names of this robot are here.
//!
//! Every process that joins a robotd bus (robotd itself, an actor in its own process, a test)
//! declares topics from here, so both ends always agree on names and policies — a mismatch is
//! refused by iceoryx2 when the port is created. `robotd catalog --json` prints [`entries`]
//! for actors in other languages (`python/robotd/src/robotd/catalog.json`).

use robotd_protocol::diagnostics::{
    Ping, Pong, SimWorldReply, SimWorldRequest, TestPatternReply, TestPatternRequest,
};
use robotd_runtime::bus::{Description, Entry, FrameTopic, Overflow, Service};

/// robotd's own liveness probe: any process can ping the running service.
pub const SYSTEM_PING: Service<Ping, Pong> = Service::new("system/ping");

/// What the robot the running robotd drives says about itself: driver, camera intrinsics,
/// versions, e-stop. The robot answers one client, so a tool that attaches to a running
/// robotd (`robotd commission`) asks here instead of connecting to it.
pub const SYSTEM_HARDWARE: Service<
    robotd_protocol::hardware::HardwareQuery,
    robotd_protocol::hardware::HardwareReport,
> = Service::new("system/hardware");

/// The simulator's ground truth (served only with a simulated robot): for end-to-end tests
/// and dashboards that compare what the camera sees with what is really there.
pub const SIM_WORLD: Service<SimWorldRequest, SimWorldReply> = Service::new("sim/world");

/// The example external actor's command: publish one test-pattern frame.
pub const TEST_PATTERN: Service<TestPatternRequest, TestPatternReply> =
    Service::new("example/test_pattern/command");

/// The example external actor's frames (latest wins, like every camera).
pub const TEST_PATTERN_FRAMES: FrameTopic =
    FrameTopic::new("example/test_pattern/frames", Overflow::latest_wins(2));

/// Supervision events (restarts, safe states, exhausted budgets) of every supervised actor.
/// Latest wins: a stuck dashboard must never slow down a restart; every event is also a
/// metric and a log line.
pub const HEALTH_RESTARTS: robotd_runtime::bus::Topic<robotd_protocol::health::RestartEvent> =
    robotd_runtime::bus::Topic::new("health/restarts", Overflow::latest_wins(16));

/// Commands to the arm actor (motion, queries, stop). Requests are never dropped: a caller
/// gets the reply or an error. `Stop` and the queries are answered at once, even while a
/// motion is under way.
pub const ARM_COMMAND: Service<robotd_protocol::arm::ArmCommand, robotd_protocol::arm::ArmReply> =
    Service::new("arm/command");

/// Joint states and tool pose of the arm, at the control rate while it moves and about once a
/// second while it rests. Latest wins: a slow reader only ever misses old poses.
pub const ARM_STATE: robotd_runtime::bus::Topic<robotd_protocol::arm::ArmState> =
    robotd_runtime::bus::Topic::new("arm/state", Overflow::latest_wins(8));

/// Commands to the gripper actor.
pub const GRIPPER_COMMAND: Service<
    robotd_protocol::gripper::GripperCommand,
    robotd_protocol::gripper::GripperReply,
> = Service::new("gripper/command");

/// The gripper's state after every command. Latest wins.
pub const GRIPPER_STATE: robotd_runtime::bus::Topic<robotd_protocol::gripper::GripperState> =
    robotd_runtime::bus::Topic::new("gripper/state", Overflow::latest_wins(8));

/// The wrist camera's frames (640×480 RGB, zero-copy). Latest wins: a slow consumer gets the
/// newest frame, never an old one.
pub const CAMERA_FRAMES: FrameTopic = FrameTopic::new("camera/frames", Overflow::latest_wins(2));

/// The wrist camera's intrinsics as its driver knows them now, republished about once a second
/// and at once when they change (a Ned2 sends its own calibration when it connects, which can
/// be long after robotd started). Latest wins.
pub const CAMERA_INTRINSICS: robotd_runtime::bus::Topic<robotd_protocol::camera::CameraIntrinsics> =
    robotd_runtime::bus::Topic::new("camera/intrinsics", Overflow::latest_wins(1));

/// Engage the emergency stop, from anyone. Back-pressure: an e-stop is never dropped; the
/// sender gets an error if the arm cannot take it. A message with `engaged: false` releases
/// nothing (it is ignored and audited): releasing is [`SAFETY_RELEASE`].
pub const SAFETY_ESTOP: robotd_runtime::bus::Topic<robotd_protocol::health::EmergencyStop> =
    robotd_runtime::bus::Topic::new("safety/estop", Overflow::back_pressure(16));

/// Release the emergency stop: a deliberate request to the safety policy, with
/// `confirm: "release"` and who releases it; the policy records it with the request's origin
/// and answers with the new state.
pub const SAFETY_RELEASE: Service<
    robotd_protocol::health::EStopRelease,
    robotd_protocol::health::EStopState,
> = Service::new("safety/release");

/// Objects found in each processed camera frame (built-in detector, or an external detector
/// through the Redis edge), in world coordinates, with the frame id they came from. Latest
/// wins: the workspace model only ever needs the newest view.
pub const PERCEPTION_DETECTIONS: robotd_runtime::bus::Topic<robotd_protocol::objects::Detections> =
    robotd_runtime::bus::Topic::new("perception/detections", Overflow::latest_wins(16));

/// Objects a detector outside robotd (a Python actor) found in the pixels of one camera frame;
/// perception maps them onto the table and publishes them on `perception/detections`. Latest
/// wins, like the detections themselves; up to 4 MiB (masks as pixel lists).
pub const PERCEPTION_PIXEL_DETECTIONS: robotd_runtime::bus::Topic<
    robotd_protocol::pixels::PixelDetections,
> = robotd_runtime::bus::Topic::new("perception/pixel_detections", Overflow::latest_wins(16))
    .with_max_bytes(4 * 1024 * 1024);

/// Questions to the workspace model (the detection and workspace tools), optionally asking
/// for a view fresher than a given time.
pub const WORKSPACE_QUERY: Service<
    robotd_protocol::workspace::WorkspaceQuery,
    robotd_protocol::workspace::WorkspaceReply,
> = Service::new("workspace/query");

/// The objects the workspace model remembers, with stable ids, after every applied detection.
pub const WORKSPACE_OBJECTS: robotd_runtime::bus::Topic<
    robotd_protocol::workspace::TrackedObjects,
> = robotd_runtime::bus::Topic::new("workspace/objects", Overflow::latest_wins(8));

/// The detectable-label list, at start and on every change.
pub const WORKSPACE_LABELS: robotd_runtime::bus::Topic<
    robotd_protocol::workspace::DetectableLabels,
> = robotd_runtime::bus::Topic::new("workspace/labels", Overflow::latest_wins(8));

/// Texts for the TTS actor to say. Back-pressure: a request is never silently lost (the
/// actor's own queue decides what to drop, and says so on `speech/events`); sending returns at
/// once.
pub const SPEECH_SPEAK: robotd_runtime::bus::Topic<robotd_protocol::speech::SpeakRequest> =
    robotd_runtime::bus::Topic::new("speech/speak", Overflow::back_pressure(16));

/// What happened to each text: started, finished, dropped (and why).
pub const SPEECH_EVENTS: robotd_runtime::bus::Topic<robotd_protocol::speech::SpeechEvent> =
    robotd_runtime::bus::Topic::new("speech/events", Overflow::latest_wins(16));

/// Texts to show over the video (robot speech, the user's task, system messages).
pub const OVERLAY_TEXT: robotd_runtime::bus::Topic<robotd_protocol::speech::TextOverlay> =
    robotd_runtime::bus::Topic::new("overlay/text", Overflow::latest_wins(32));

/// Pick, place, push and the other robot-control skills. One skill runs at a time; a request
/// that arrives while one runs waits its turn.
pub const SKILLS_RUN: Service<
    robotd_protocol::skills::SkillRequest,
    robotd_protocol::skills::SkillReply,
> = Service::new("skills/run");

/// Progress of the running skill (step n of total). Latest wins.
pub const SKILLS_PROGRESS: robotd_runtime::bus::Topic<robotd_protocol::skills::SkillProgress> =
    robotd_runtime::bus::Topic::new("skills/progress", Overflow::latest_wins(32));

/// Cancel a running skill: the arm stops at once. Back-pressure: a cancel is never dropped.
pub const SKILLS_CANCEL: robotd_runtime::bus::Topic<robotd_protocol::skills::SkillCancel> =
    robotd_runtime::bus::Topic::new("skills/cancel", Overflow::back_pressure(16));

/// Requests to the LLM agent (`robotd chat`, a dashboard). Back-pressure: a request is never
/// dropped.
pub const AGENT_REQUEST: robotd_runtime::bus::Topic<robotd_protocol::agent::AgentRequest> =
    robotd_runtime::bus::Topic::new("agent/request", Overflow::back_pressure(16));

/// The agent's plan, tool calls, results, the pictures it looked at and its answer per
/// request. Back-pressure: a reader never misses a tool call or the answer. Up to 256 KiB: a
/// picture event carries a JPEG of up to 160 KiB as base64.
pub const AGENT_EVENTS: robotd_runtime::bus::Topic<robotd_protocol::agent::AgentEvent> =
    robotd_runtime::bus::Topic::new("agent/events", Overflow::back_pressure(16))
        .with_max_bytes(256 * 1024);

/// Cancel an agent request (the running motion stops safely). Back-pressure: a cancel is never
/// dropped.
pub const AGENT_CANCEL: robotd_runtime::bus::Topic<robotd_protocol::agent::AgentCancel> =
    robotd_runtime::bus::Topic::new("agent/cancel", Overflow::back_pressure(16));

/// Speech to text (the STT actor, a Python actor on the bus: `python -m robotd.stt`): audio
/// in (16 kHz mono 16-bit PCM, or a WAV/WebM/Ogg file's bytes, at most
/// `robotd_protocol::stt::MAX_AUDIO_BYTES`), the transcript or what was wrong with the audio
/// out.
pub const STT_TRANSCRIBE: Service<
    robotd_protocol::stt::TranscribeRequest,
    robotd_protocol::stt::TranscribeReply,
> = Service::new("stt/transcribe");

/// Every transcript the STT actor made, as it makes it: what the robot heard, for the
/// dashboard, the agent and recordings. Latest wins: a slow reader never holds up listening.
pub const STT_TRANSCRIPTS: robotd_runtime::bus::Topic<robotd_protocol::stt::Transcript> =
    robotd_runtime::bus::Topic::new("stt/transcripts", Overflow::latest_wins(16));

/// How the STT actor is doing: its model, what it has transcribed, its last error (published
/// when the model is loaded and after every request; `/health` and `/metrics` read it).
pub const STT_STATUS: robotd_runtime::bus::Topic<robotd_protocol::stt::SttStatus> =
    robotd_runtime::bus::Topic::new("stt/status", Overflow::latest_wins(4));

/// Every entry above, in order: what `robotd catalog` prints and what an actor in another
/// language declares (see [`robotd_runtime::bus::describe`]).
pub fn entries() -> Vec<Entry> {
    vec![
        SYSTEM_PING.describe(),
        SYSTEM_HARDWARE.describe(),
        SIM_WORLD.describe(),
        TEST_PATTERN.describe(),
        TEST_PATTERN_FRAMES.describe(),
        HEALTH_RESTARTS.describe(),
        ARM_COMMAND.describe(),
        ARM_STATE.describe(),
        GRIPPER_COMMAND.describe(),
        GRIPPER_STATE.describe(),
        CAMERA_FRAMES.describe(),
        CAMERA_INTRINSICS.describe(),
        SAFETY_ESTOP.describe(),
        SAFETY_RELEASE.describe(),
        PERCEPTION_DETECTIONS.describe(),
        PERCEPTION_PIXEL_DETECTIONS.describe(),
        WORKSPACE_QUERY.describe(),
        WORKSPACE_OBJECTS.describe(),
        WORKSPACE_LABELS.describe(),
        SPEECH_SPEAK.describe(),
        SPEECH_EVENTS.describe(),
        OVERLAY_TEXT.describe(),
        SKILLS_RUN.describe(),
        SKILLS_PROGRESS.describe(),
        SKILLS_CANCEL.describe(),
        AGENT_REQUEST.describe(),
        AGENT_EVENTS.describe(),
        AGENT_CANCEL.describe(),
        STT_TRANSCRIBE.describe(),
        STT_TRANSCRIPTS.describe(),
        STT_STATUS.describe(),
    ]
}

/// The catalogue with the bus's shared settings.
pub fn description() -> Description {
    robotd_runtime::bus::describe(entries())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_constant_of_the_catalogue_is_listed_once() {
        let source = include_str!("lib.rs");
        let constants = source
            .lines()
            .filter(|line| line.starts_with("pub const "))
            .count();
        let entries = entries();
        assert_eq!(
            entries.len(),
            constants,
            "add the new constant to entries()"
        );
        let mut names: Vec<&str> = entries.iter().map(Entry::name).collect();
        names.sort_unstable();
        names.dedup();
        assert_eq!(names.len(), entries.len(), "a name is listed twice");
    }
}
