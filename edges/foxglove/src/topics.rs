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
use robotd_runtime::catalog;

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

impl<T: Message> JsonTopic for Typed<T> {
    fn name(&self) -> &'static str {
        self.0.name()
    }

    fn type_name(&self) -> &'static str {
        T::TYPE
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

fn typed<T: Message>(topic: Topic<T>) -> Box<dyn JsonTopic> {
    Box::new(Typed(topic))
}

/// Every message topic of robotd's catalogue (a test holds it to [`catalog::entries`]).
pub fn all() -> Vec<Box<dyn JsonTopic>> {
    vec![
        typed(catalog::ARM_STATE),
        typed(catalog::GRIPPER_STATE),
        typed(catalog::SAFETY_ESTOP),
        typed(catalog::PERCEPTION_DETECTIONS),
        typed(catalog::PERCEPTION_PIXEL_DETECTIONS),
        typed(catalog::WORKSPACE_OBJECTS),
        typed(catalog::WORKSPACE_LABELS),
        typed(catalog::SPEECH_SPEAK),
        typed(catalog::SPEECH_EVENTS),
        typed(catalog::OVERLAY_TEXT),
        typed(catalog::SKILLS_PROGRESS),
        typed(catalog::SKILLS_CANCEL),
        typed(catalog::AGENT_REQUEST),
        typed(catalog::AGENT_EVENTS),
        typed(catalog::AGENT_CANCEL),
        typed(catalog::HEALTH_RESTARTS),
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
    const NOT_BRIDGED: [(&str, &str); 9] = [
        (
            "camera/frames",
            "frames in shared memory: their own channels, /camera (JPEG) and /camera/meta",
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
    ];

    #[test]
    fn every_message_topic_of_the_catalogue_is_bridged_with_its_type() {
        let entries = catalog::entries();
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
}
