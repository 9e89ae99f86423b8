//! The bus as data: what a process in another language must declare to join it.
//!
//! iceoryx2 refuses a port whose service settings differ from the ones the service was created
//! with (payload type name, size and alignment, user header, overflow, buffer depth, port and
//! node limits). An actor written in Python or C++ therefore needs the exact settings robotd
//! uses for every topic, frame topic and service, and the settings of the event services that
//! wake receivers. [`Description`] holds them; `robotd catalog --json` prints the catalogue's
//! description and the Python package in `python/` ships that output (a test checks that the
//! two never drift apart).

use super::frame::{FRAME_CHANNELS, FRAME_HEIGHT, FRAME_WIDTH};
use super::pubsub::TopicSpec;
use super::{FrameTopic, Overflow, Service, Topic};
use robotd_protocol::envelope::Message;
use serde::Serialize;

/// Version of the description's own layout; readers refuse other versions.
pub const DESCRIPTION_VERSION: u32 = 1;

/// The whole bus: shared settings and one entry per topic, frame topic and service.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Description {
    /// [`DESCRIPTION_VERSION`].
    pub description_version: u32,
    /// Type name of the user header of every message topic (a `u64` sequence number).
    pub message_header_type: &'static str,
    /// Type name of a frame topic's payload (header then pixels).
    pub frame_slot_type: &'static str,
    /// Event service settings (every event a topic or service uses).
    pub events: EventSettings,
    /// How event services are named after a topic `T`.
    pub event_names: EventNames,
    /// The catalogue.
    pub entries: Vec<Entry>,
}

/// Settings of every event service robotd opens.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct EventSettings {
    /// Notifiers per event service.
    pub max_notifiers: usize,
    /// Listeners per event service.
    pub max_listeners: usize,
    /// Nodes per event service.
    pub max_nodes: usize,
    /// Largest event id (robotd raises only id 0).
    pub event_id_max_value: usize,
    /// Whether the notifier created/dropped/dead events are on (they are all off).
    pub notifier_lifecycle_events: bool,
}

/// Names of the event services paired with topic `{topic}`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct EventNames {
    /// Raised by a publisher after every message.
    pub data: &'static str,
    /// Raised by a back-pressure subscriber after it consumed messages.
    pub consumed: &'static str,
    /// Raised by a new subscriber.
    pub subscribed: &'static str,
    /// Raised by a new publisher.
    pub joined: &'static str,
}

/// One catalogue entry.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Entry {
    /// Typed messages.
    Topic(TopicDescription),
    /// Camera frames in shared memory.
    Frames(FramesDescription),
    /// Request-response over a requests topic and one replies topic per client.
    Service(ServiceDescription),
}

impl Entry {
    /// The entry's name (`arm/state`).
    pub fn name(&self) -> &str {
        match self {
            Entry::Topic(t) => &t.name,
            Entry::Frames(f) => &f.name,
            Entry::Service(s) => &s.name,
        }
    }
}

/// A message topic's settings.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TopicDescription {
    /// Name under the namespace (`arm/state`; a service's replies topic ends in
    /// `{client_id:016x}`).
    pub name: String,
    /// [`Message::TYPE`] of its messages.
    pub msg_type: &'static str,
    /// [`Message::SCHEMA_VERSION`] of its messages.
    pub schema_version: u16,
    /// `latest_wins` or `back_pressure`.
    pub overflow: &'static str,
    /// Messages buffered per subscriber.
    pub depth: usize,
    /// Longest a back-pressure sender waits, ms (0 for latest wins).
    pub max_wait_ms: u64,
    /// Largest encoded message, bytes.
    pub max_bytes: usize,
    /// Publisher ports the service admits.
    pub max_publishers: usize,
    /// Subscriber ports the service admits.
    pub max_subscribers: usize,
    /// Messages one subscriber may hold at once.
    pub max_borrowed_samples: usize,
    /// Nodes the service admits.
    pub max_nodes: usize,
}

/// A frame topic's settings.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FramesDescription {
    /// Name under the namespace.
    pub name: String,
    /// `latest_wins` or `back_pressure`.
    pub overflow: &'static str,
    /// Frames buffered per subscriber.
    pub depth: usize,
    /// Frames one subscriber may hold at once.
    pub max_borrowed_samples: usize,
    /// Publisher ports.
    pub max_publishers: usize,
    /// Subscriber ports.
    pub max_subscribers: usize,
    /// Nodes.
    pub max_nodes: usize,
    /// Largest image: width, height, channels (RGB8 unless the header says BGR8).
    pub max_width: usize,
    /// See `max_width`.
    pub max_height: usize,
    /// See `max_width`.
    pub channels: usize,
}

/// A service's settings.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ServiceDescription {
    /// Name under the namespace (`arm/command`).
    pub name: String,
    /// Its requests topic (one subscriber: the server).
    pub requests: TopicDescription,
    /// Each client's replies topic.
    pub replies: TopicDescription,
}

fn overflow_name(overflow: Overflow) -> (&'static str, u64) {
    match overflow {
        Overflow::LatestWins { .. } => ("latest_wins", 0),
        Overflow::BackPressure { max_wait, .. } => ("back_pressure", max_wait.as_millis() as u64),
    }
}

fn topic_description(
    spec: TopicSpec,
    msg_type: &'static str,
    schema_version: u16,
) -> TopicDescription {
    let (overflow, max_wait_ms) = overflow_name(spec.overflow);
    TopicDescription {
        name: spec.name,
        msg_type,
        schema_version,
        overflow,
        depth: spec.overflow.depth(),
        max_wait_ms,
        max_bytes: spec.max_bytes,
        max_publishers: spec.max_publishers,
        max_subscribers: spec.max_subscribers,
        max_borrowed_samples: super::pubsub::TOPIC_MAX_BORROWED_SAMPLES,
        max_nodes: super::pubsub::TOPIC_MAX_NODES,
    }
}

impl<T: Message> Topic<T> {
    /// This topic's catalogue entry.
    pub fn describe(&self) -> Entry {
        Entry::Topic(topic_description(
            TopicSpec::from(self),
            T::TYPE,
            T::SCHEMA_VERSION,
        ))
    }
}

impl FrameTopic {
    /// This frame topic's catalogue entry.
    pub fn describe(&self) -> Entry {
        let (overflow, _) = overflow_name(self.overflow());
        let limits = super::frame::FRAME_LIMITS;
        Entry::Frames(FramesDescription {
            name: self.name().to_owned(),
            overflow,
            depth: self.overflow().depth(),
            max_borrowed_samples: limits.max_borrowed_samples,
            max_publishers: limits.max_publishers,
            max_subscribers: limits.max_subscribers,
            max_nodes: limits.max_nodes,
            max_width: FRAME_WIDTH,
            max_height: FRAME_HEIGHT,
            channels: FRAME_CHANNELS,
        })
    }
}

impl<Req: Message, Resp: Message> Service<Req, Resp> {
    /// This service's catalogue entry (the replies topic's name ends in `{client_id:016x}`).
    pub fn describe(&self) -> Entry {
        let mut replies = topic_description(self.replies(0), Resp::TYPE, Resp::SCHEMA_VERSION);
        replies.name = format!("{}/replies/{{client_id:016x}}", self.name());
        Entry::Service(ServiceDescription {
            name: self.name().to_owned(),
            requests: topic_description(self.requests(), Req::TYPE, Req::SCHEMA_VERSION),
            replies,
        })
    }
}

/// The description of a bus with these entries.
pub fn describe(entries: Vec<Entry>) -> Description {
    let events = super::wake::EVENT_LIMITS;
    Description {
        description_version: DESCRIPTION_VERSION,
        message_header_type: super::pubsub::MESSAGE_HEADER_TYPE,
        frame_slot_type: super::frame::FRAME_SLOT_TYPE,
        events: EventSettings {
            max_notifiers: events.max_notifiers,
            max_listeners: events.max_listeners,
            max_nodes: events.max_nodes,
            event_id_max_value: events.event_id_max_value,
            notifier_lifecycle_events: false,
        },
        event_names: EventNames {
            data: "{topic}/ready",
            consumed: "{topic}/consumed",
            subscribed: "{topic}/subscribed",
            joined: "{topic}/joined",
        },
        entries,
    }
}

#[cfg(test)]
mod tests {
    use super::super::frame::{FrameSlot, FRAME_SLOT_TYPE};
    use super::super::pubsub::{MessageHeader, MESSAGE_HEADER_TYPE};
    use iceoryx2::prelude::ZeroCopySend;

    #[test]
    fn the_described_type_names_are_the_ones_iceoryx2_compares() {
        // SAFETY: type_name only returns the name given by the derive's attribute.
        let (header, slot) = unsafe {
            (
                <MessageHeader as ZeroCopySend>::type_name(),
                <FrameSlot as ZeroCopySend>::type_name(),
            )
        };
        assert_eq!(header, MESSAGE_HEADER_TYPE);
        assert_eq!(slot, FRAME_SLOT_TYPE);
    }
}
