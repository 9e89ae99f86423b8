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
    format!("/bus/{topic}")
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

/// Every message topic of robotd's catalogue.
pub fn all() -> Vec<Box<dyn JsonTopic>> {
    vec![
        typed(catalog::ARM_STATE),
        typed(catalog::GRIPPER_STATE),
        typed(catalog::SAFETY_ESTOP),
        typed(catalog::PERCEPTION_DETECTIONS),
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
