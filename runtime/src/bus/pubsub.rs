//! Typed publish-subscribe topics for control messages.
//!
//! A [`Topic`] names a stream of one message type and declares what happens when a subscriber
//! falls behind ([`Overflow`]). Messages are encoded once with rmp-serde, inside an envelope
//! carrying the trace context, directly into a shared-memory slice; every subscriber decodes
//! from that slice. A subscriber receives everything published after it was created (the port
//! is registered before [`Bus::subscriber`] returns, and publishers connect new subscribers
//! before every send).

use super::consumed::ConsumedWaiter;
use super::wake::{consumed_event, data_event, joined_event, subscribed_event, Notify, Wake};
use super::{Bus, BusError, Ipc};
use crate::metrics::{Direction, Metrics};
use iceoryx2::port::update_connections::UpdateConnections;
use iceoryx2::port::BackpressureInfo;
use iceoryx2::prelude::*;
use robotd_protocol::envelope::{self, Envelope, Message};
use std::cell::RefCell;
use std::collections::HashMap;
use std::marker::PhantomData;
use std::sync::Arc;
use std::time::Duration;

/// What happens when a subscriber's buffer is full.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Overflow {
    /// The oldest unread message is replaced by the newest (camera frames, poses): the sender
    /// never waits. Replaced messages are counted as dropped (`robotd_bus_dropped_total`).
    LatestWins {
        /// Messages buffered per subscriber.
        depth: usize,
    },
    /// The sender waits (event-driven, woken when the subscriber consumes) for room; if the
    /// subscriber does not catch up within `max_wait`, [`Publisher::publish`] returns
    /// [`BusError::Full`]. Nothing is dropped silently.
    BackPressure {
        /// Messages buffered per subscriber.
        depth: usize,
        /// Longest time a sender waits for a full subscriber.
        max_wait: Duration,
    },
}

impl Overflow {
    /// Latest wins with `depth` buffered messages.
    pub const fn latest_wins(depth: usize) -> Self {
        Overflow::LatestWins { depth }
    }

    /// Back-pressure with `depth` buffered messages; senders wait up to 1 s.
    pub const fn back_pressure(depth: usize) -> Self {
        Overflow::BackPressure {
            depth,
            max_wait: Duration::from_secs(1),
        }
    }

    pub(crate) fn depth(&self) -> usize {
        match *self {
            Overflow::LatestWins { depth } | Overflow::BackPressure { depth, .. } => depth.max(1),
        }
    }

    pub(crate) fn is_latest_wins(&self) -> bool {
        matches!(self, Overflow::LatestWins { .. })
    }
}

/// A named stream of `T` messages with its overflow policy and size limit.
#[derive(Debug)]
pub struct Topic<T> {
    name: &'static str,
    overflow: Overflow,
    max_bytes: usize,
    _message: PhantomData<fn() -> T>,
}

impl<T> Clone for Topic<T> {
    fn clone(&self) -> Self {
        *self
    }
}
impl<T> Copy for Topic<T> {}

impl<T: Message> Topic<T> {
    /// A topic called `name` (slash-separated, e.g. `"arm/state"`) with up to 64 KiB messages.
    pub const fn new(name: &'static str, overflow: Overflow) -> Self {
        Self {
            name,
            overflow,
            max_bytes: 64 * 1024,
            _message: PhantomData,
        }
    }

    /// Sets the largest encoded message the topic accepts.
    pub const fn with_max_bytes(mut self, max_bytes: usize) -> Self {
        self.max_bytes = max_bytes;
        self
    }

    /// The topic's name.
    pub const fn name(&self) -> &'static str {
        self.name
    }

    /// The topic's overflow policy.
    pub const fn overflow(&self) -> Overflow {
        self.overflow
    }
}

/// A topic as the bus sees it at run time (names may be built at run time, e.g. per client).
#[derive(Debug, Clone)]
pub(crate) struct TopicSpec {
    pub(crate) name: String,
    /// Name used in metrics (bounded cardinality: per-client topics share one label).
    pub(crate) label: String,
    pub(crate) overflow: Overflow,
    pub(crate) max_bytes: usize,
    pub(crate) max_subscribers: usize,
    pub(crate) max_publishers: usize,
    /// Whether a new back-pressure publisher waits (bounded) for existing subscribers to
    /// connect before its first message.
    pub(crate) handshake: bool,
}

impl<T: Message> From<&Topic<T>> for TopicSpec {
    fn from(topic: &Topic<T>) -> Self {
        Self {
            name: topic.name.to_owned(),
            label: topic.name.to_owned(),
            overflow: topic.overflow,
            max_bytes: topic.max_bytes,
            max_subscribers: TOPIC_MAX_SUBSCRIBERS,
            max_publishers: 16,
            handshake: true,
        }
    }
}

/// Type name of [`MessageHeader`] (the `type_name` attribute below; a test keeps them equal).
pub(crate) const MESSAGE_HEADER_TYPE: &str = "robotd.MessageHeader.v1";

/// Subscriber ports a message topic admits (all processes together). robotd's own actors and
/// edges open at most six on one topic; the rest is room for external actors and tools.
///
/// Memory: a publisher's samples are `subscribers × (depth + borrowed) + loaned`, each with
/// an 8-byte counter in the publisher's heap and `max_bytes` of (sparse) shared memory.
pub(crate) const TOPIC_MAX_SUBSCRIBERS: usize = 16;

/// Samples a topic subscriber holds at once: robotd (Rust and Python) copies each message out
/// and releases it before taking the next.
pub(crate) const TOPIC_MAX_BORROWED_SAMPLES: usize = 1;

/// Nodes a message topic admits.
pub(crate) const TOPIC_MAX_NODES: usize = 64;

/// Per-message header in shared memory: the publisher's sequence number, so subscribers can
/// tell when latest-wins replaced messages they never saw.
#[derive(Debug, Default, Clone, Copy, ZeroCopySend)]
#[repr(C)]
#[type_name("robotd.MessageHeader.v1")]
pub(crate) struct MessageHeader {
    pub(crate) seq: u64,
}

pub(crate) type PubSubFactory =
    iceoryx2::service::port_factory::publish_subscribe::PortFactory<Ipc, [u8], MessageHeader>;

/// The topic's service handle: the one this process already holds (shared by its ports), or
/// a new one.
fn open_service(bus: &Bus, spec: &TopicSpec) -> Result<Arc<PubSubFactory>, BusError> {
    // The settings are part of the key: a port asking for others gets iceoryx2's own check.
    let key = format!(
        "{}|{:?}|{}|{}",
        spec.name, spec.overflow, spec.max_subscribers, spec.max_publishers
    );
    bus.inner
        .topics
        .get_or_open(&key, || open_service_handle(bus, spec))
}

fn open_service_handle(bus: &Bus, spec: &TopicSpec) -> Result<PubSubFactory, BusError> {
    let name = spec.name.as_str();
    let overflow = spec.overflow;
    bus.node()
        .service_builder(&bus.service_name(name)?)
        .publish_subscribe::<[u8]>()
        .user_header::<MessageHeader>()
        .enable_safe_overflow(overflow.is_latest_wins())
        .subscriber_max_buffer_size(overflow.depth())
        .subscriber_max_borrowed_samples(TOPIC_MAX_BORROWED_SAMPLES)
        .history_size(0)
        .max_publishers(spec.max_publishers)
        .max_subscribers(spec.max_subscribers)
        .max_nodes(TOPIC_MAX_NODES)
        .open_or_create()
        .map_err(|e| BusError::Setup {
            what: format!("topic '{name}'"),
            reason: format!(
                "{e:?} (a topic's overflow policy and depth must match in every process)"
            ),
        })
}

/// How long a new back-pressure publisher waits for existing subscribers to connect.
const HANDSHAKE_TIMEOUT: Duration = Duration::from_millis(100);

thread_local! {
    static ENCODE_BUFFER: RefCell<Vec<u8>> = RefCell::new(Vec::with_capacity(4096));
}

/// Sends `T` messages on a topic.
pub struct Publisher<T: Message> {
    factory: Arc<PubSubFactory>,
    port: iceoryx2::port::publisher::Publisher<Ipc, [u8], MessageHeader>,
    notify: Notify,
    topic: TopicSpec,
    seq: std::sync::atomic::AtomicU64,
    _message: PhantomData<fn(T)>,
}

impl<T: Message> std::fmt::Debug for Publisher<T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Publisher")
            .field("topic", &self.topic.name.as_str())
            .finish()
    }
}

impl Bus {
    /// Creates a publisher on `topic`.
    pub fn publisher<T: Message>(&self, topic: &Topic<T>) -> Result<Publisher<T>, BusError> {
        self.publisher_for(topic.into())
    }

    pub(crate) fn publisher_for<T: Message>(
        &self,
        topic: TopicSpec,
    ) -> Result<Publisher<T>, BusError> {
        let service = open_service(self, &topic)?;
        // One static segment of `samples × max_bytes`: the pages of a sample are only backed
        // by memory once a message is written into them (the segment is a sparse shared-memory
        // file, and the pool hands the most recently freed sample out first), so a topic's
        // size limit costs address space, not RAM. A dynamic (growing) segment would instead
        // reserve, in this process and in every subscriber, a table for the 255 segments it
        // may grow into: ~0.3 MB per publisher, most of an idle robotd's heap.
        let mut builder = service
            .publisher_builder()
            .initial_max_slice_len(topic.max_bytes)
            .allocation_strategy(AllocationStrategy::Static);
        let mut consumed = None;
        if let Overflow::BackPressure { max_wait, .. } = topic.overflow {
            // The sender waits on the subscribers' "consumed" event; every wake-up retries.
            let waiter = ConsumedWaiter::new(self, &consumed_event(&topic.name));
            let in_handler = waiter.clone();
            builder = builder
                .backpressure_strategy(BackpressureStrategy::RetryUntilDelivered)
                .set_backpressure_handler(move |info: &BackpressureInfo| {
                    in_handler.on_full(info, max_wait)
                });
            consumed = Some(waiter);
        }
        let port = builder.create().map_err(|e| BusError::Setup {
            what: format!("publisher on '{}'", topic.name),
            reason: format!("{e:?}"),
        })?;
        let publisher = Publisher {
            port,
            notify: Notify::new(self, &data_event(&topic.name))?,
            topic,
            seq: std::sync::atomic::AtomicU64::new(0),
            factory: service,
            _message: PhantomData,
        };
        publisher.handshake(self, consumed.as_ref())?;
        Ok(publisher)
    }

    /// Creates a subscriber on `topic`. It receives every message published after this
    /// returns. Must be called inside a tokio runtime.
    pub fn subscriber<T: Message>(&self, topic: &Topic<T>) -> Result<Subscriber<T>, BusError> {
        self.subscriber_for(topic.into())
    }

    pub(crate) fn subscriber_for<T: Message>(
        &self,
        topic: TopicSpec,
    ) -> Result<Subscriber<T>, BusError> {
        let service = open_service(self, &topic)?;
        let port = service
            .subscriber_builder()
            .buffer_size(topic.overflow.depth())
            .create()
            .map_err(|e| BusError::Setup {
                what: format!("subscriber on '{}'", topic.name),
                reason: format!("{e:?}"),
            })?;
        // Handshake, subscriber side: connect to every publisher that already exists now, and
        // to every later one as soon as it announces itself (see `Publisher::handshake`).
        let port = Arc::new(port);
        port.update_connections().map_err(|e| BusError::Setup {
            what: format!("subscriber on '{}'", topic.name),
            reason: format!("cannot connect to the publishers: {e:?}"),
        })?;
        // On a back-pressure topic a new publisher waits for each subscriber to connect and
        // acknowledge, so a task listens for new publishers. On a latest-wins topic nobody
        // waits: the subscriber connects to a new publisher at its next receive (iceoryx2's
        // `receive` updates the connections first), which the publisher's first message wakes
        // it for. That spares a listener (a socket, a port, a shared-memory segment) and a task
        // per subscriber; frame subscribers have always worked this way.
        let (consumed, connector) = match topic.overflow {
            Overflow::BackPressure { .. } => {
                let consumed = Arc::new(Notify::new(self, &consumed_event(&topic.name))?);
                let joined = Wake::new(self, &joined_event(&topic.name))?;
                let connector = tokio::spawn(connect_new_publishers(
                    joined,
                    port.clone(),
                    consumed.clone(),
                ));
                (Some(consumed), Some(connector))
            }
            Overflow::LatestWins { .. } => (None, None),
        };
        // Tell whoever waits for a subscriber (a client waiting for its server) that one is here.
        Notify::new(self, &subscribed_event(&topic.name))?.notify();
        Ok(Subscriber {
            port,
            _service: service,
            wake: Wake::new(self, &data_event(&topic.name))?,
            consumed,
            topic,
            last_seq: HashMap::new(),
            connector,
            _message: PhantomData,
        })
    }
}

/// Keeps a subscriber connected to publishers created after it: woken by each new publisher's
/// announcement, it connects and acknowledges (back-pressure publishers wait for that).
async fn connect_new_publishers(
    joined: Wake,
    port: Arc<iceoryx2::port::subscriber::Subscriber<Ipc, [u8], MessageHeader>>,
    ack: Arc<Notify>,
) {
    while joined.sleep().await.is_ok() {
        // Rearmed before connecting: a publisher announced later wakes the next sleep.
        joined.rearm();
        if let Err(e) = port.update_connections() {
            tracing::warn!(error = ?e, "subscriber could not connect to a new publisher");
        }
        ack.notify();
    }
}

impl<T: Message> Publisher<T> {
    /// Handshake, publisher side: connect to the existing subscribers; on a back-pressure topic
    /// also announce this publisher so they connect to it now rather than at their next
    /// receive, and wait (bounded) for their acknowledgements, so the first messages cannot
    /// overflow an unconnected subscriber.
    fn handshake(&self, bus: &Bus, consumed: Option<&ConsumedWaiter>) -> Result<(), BusError> {
        self.port
            .update_connections()
            .map_err(|e| BusError::Setup {
                what: format!("publisher on '{}'", self.topic.name),
                reason: format!("cannot connect to the subscribers: {e:?}"),
            })?;
        // Only back-pressure subscribers listen for new publishers (see `subscriber_for`).
        let Some(consumed) = consumed else {
            return Ok(());
        };
        let subscribers = self.factory.dynamic_config().number_of_subscribers() as u64;
        let awaited = self.topic.handshake && subscribers > 0;
        // Listening before the announcement, so that no acknowledgement is missed.
        let listener = if awaited {
            Some(consumed.listen()?)
        } else {
            None
        };
        Notify::new(bus, &joined_event(&self.topic.name))?.notify();
        let Some(listener) = listener else {
            return Ok(());
        };
        let wait_for_acks = || {
            let deadline = std::time::Instant::now() + HANDSHAKE_TIMEOUT;
            let mut acknowledged = 0u64;
            while acknowledged < subscribers {
                let now = std::time::Instant::now();
                if now >= deadline {
                    tracing::debug!(
                        topic = %self.topic.name,
                        acknowledged,
                        subscribers,
                        "not every subscriber acknowledged a new publisher in time"
                    );
                    break;
                }
                let _ = listener.timed_wait(
                    |activation| acknowledged += activation.count.max(1),
                    deadline - now,
                );
            }
        };
        // The wait is a blocking kernel wait. On a multi-thread tokio runtime other workers
        // keep running (the acknowledging task may live in this process); on a current-thread
        // runtime blocking would stall the very task that acknowledges, so there is no wait:
        // subscribers then connect at their next receive.
        match tokio::runtime::Handle::try_current().map(|h| h.runtime_flavor()) {
            Ok(tokio::runtime::RuntimeFlavor::MultiThread) => {
                tokio::task::block_in_place(wait_for_acks)
            }
            Ok(_) => {}
            Err(_) => wait_for_acks(),
        }
        consumed.stop_listening();
        Ok(())
    }

    /// Number of subscriber ports attached to the topic right now.
    pub(crate) fn subscriber_count(&self) -> usize {
        self.factory.dynamic_config().number_of_subscribers()
    }

    /// Ids of the subscriber ports attached to the topic right now.
    pub(crate) fn subscriber_ids(&self) -> Vec<u128> {
        let mut ids = Vec::new();
        self.factory.dynamic_config().list_subscribers(|details| {
            ids.push(details.subscriber_id.value());
            CallbackProgression::Continue
        });
        ids
    }

    /// Publishes `message` to every current subscriber and returns how many received it.
    ///
    /// On a back-pressure topic this may block the calling thread while a subscriber is full
    /// (at most the topic's `max_wait`), then fails with [`BusError::Full`].
    pub fn publish(&self, message: &T) -> Result<usize, BusError> {
        self.publish_serializable(message, T::TYPE, T::SCHEMA_VERSION)
    }

    /// Publishes any serializable body under the envelope header of `msg_type`.
    pub(crate) fn publish_serializable<B: serde::Serialize>(
        &self,
        body: &B,
        msg_type: &'static str,
        schema_version: u16,
    ) -> Result<usize, BusError> {
        let trace = crate::telemetry::current_trace_context();
        ENCODE_BUFFER.with(|buffer| {
            let mut buffer = buffer.borrow_mut();
            buffer.clear();
            envelope::encode_parts(body, msg_type, schema_version, &trace, &mut buffer)?;
            self.send_bytes(&buffer)
        })
    }

    fn send_bytes(&self, bytes: &[u8]) -> Result<usize, BusError> {
        let name = self.topic.name.as_str();
        let label = self.topic.label.as_str();
        if bytes.len() > self.topic.max_bytes {
            return Err(BusError::TooLarge {
                topic: name.to_owned(),
                size: bytes.len(),
                limit: self.topic.max_bytes,
            });
        }
        let mut sample =
            self.port
                .loan_slice_uninit(bytes.len())
                .map_err(|e| BusError::Transfer {
                    topic: name.to_owned(),
                    reason: format!("cannot loan {} bytes: {e:?}", bytes.len()),
                })?;
        sample.user_header_mut().seq = self.seq.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let sample = sample.write_from_slice(bytes);
        let subscribers_before = self.factory.dynamic_config().number_of_subscribers();
        let started = std::time::Instant::now();
        let delivered = sample.send().map_err(|e| match e {
            iceoryx2::port::SendError::UnableToDeliver => BusError::Full {
                topic: name.to_owned(),
                waited_ms: started.elapsed().as_millis() as u64,
            },
            other => BusError::Transfer {
                topic: name.to_owned(),
                reason: format!("{other:?}"),
            },
        });
        // Wake the subscribers even when one of them was full: the others got the message.
        self.notify.notify();
        if let Err(BusError::Full { .. }) = &delivered {
            Metrics::global().bus_dropped(label, "subscriber_full");
        }
        let delivered = delivered?;
        if !self.topic.overflow.is_latest_wins() {
            // Compared with the subscribers registered before the send, so one that joins
            // meanwhile is not mistaken for one that missed the message.
            let subscribers = subscribers_before;
            if delivered < subscribers {
                Metrics::global().bus_dropped(label, "subscriber_not_connected");
                return Err(BusError::NotDelivered {
                    topic: name.to_owned(),
                    delivered,
                    subscribers,
                });
            }
        }
        Metrics::global().bus_message(label, Direction::Sent);
        Ok(delivered)
    }
}

/// Receives `T` messages from a topic.
pub struct Subscriber<T: Message> {
    port: Arc<iceoryx2::port::subscriber::Subscriber<Ipc, [u8], MessageHeader>>,
    /// Keeps the topic's shared service handle open while the port lives.
    _service: Arc<PubSubFactory>,
    wake: Wake,
    consumed: Option<Arc<Notify>>,
    topic: TopicSpec,
    last_seq: HashMap<u128, u64>,
    /// Listens for new publishers (back-pressure topics only).
    connector: Option<tokio::task::JoinHandle<()>>,
    _message: PhantomData<fn() -> T>,
}

impl<T: Message> Drop for Subscriber<T> {
    fn drop(&mut self) {
        if let Some(connector) = &self.connector {
            connector.abort();
        }
    }
}

impl<T: Message> std::fmt::Debug for Subscriber<T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Subscriber")
            .field("topic", &self.topic.name.as_str())
            .finish()
    }
}

impl<T: Message> Subscriber<T> {
    /// The topic's label in metrics.
    pub(crate) fn label(&self) -> &str {
        &self.topic.label
    }

    /// Waits for the next message.
    ///
    /// A message that cannot be decoded (another schema version, corrupt bytes) is returned as
    /// an error; the subscriber stays usable.
    pub async fn recv(&mut self) -> Result<Envelope<T>, BusError> {
        loop {
            if let Some(message) = self.try_recv()? {
                return Ok(message);
            }
            self.wake.rearm();
            if let Some(message) = self.try_recv()? {
                return Ok(message);
            }
            self.wake.sleep().await?;
        }
    }

    /// Returns the next message if one is waiting.
    pub fn try_recv(&mut self) -> Result<Option<Envelope<T>>, BusError> {
        match self.try_recv_with(envelope::decode::<T>)? {
            None => Ok(None),
            Some(decoded) => {
                let message = decoded?;
                let latency_ns = envelope::unix_now_ns().saturating_sub(message.sent_at_unix_ns);
                Metrics::global().bus_latency(&self.topic.label, latency_ns as f64 / 1e9);
                Ok(Some(message))
            }
        }
    }

    /// Waits for the next message and hands its raw bytes to `read`.
    pub(crate) async fn recv_with<R>(
        &mut self,
        mut read: impl FnMut(&[u8]) -> R,
    ) -> Result<R, BusError> {
        loop {
            if let Some(result) = self.try_recv_with(&mut read)? {
                return Ok(result);
            }
            self.wake.rearm();
            if let Some(result) = self.try_recv_with(&mut read)? {
                return Ok(result);
            }
            self.wake.sleep().await?;
        }
    }

    /// Makes the next message wake [`sleep_timeout`](Self::sleep_timeout); check for
    /// messages again before sleeping (see [`Wake::rearm`]).
    pub(crate) fn rearm(&self) {
        self.wake.rearm();
    }

    /// Sleeps up to `timeout` for a message announced since the last
    /// [`rearm`](Self::rearm); `Ok(false)` when none was.
    pub(crate) async fn sleep_timeout(&self, timeout: Duration) -> Result<bool, BusError> {
        self.wake.sleep_timeout(timeout).await
    }

    /// Takes the next sample if one is waiting and hands its bytes to `read`; counts it, and
    /// any messages that latest-wins replaced before it.
    pub(crate) fn try_recv_with<R>(
        &mut self,
        read: impl FnOnce(&[u8]) -> R,
    ) -> Result<Option<R>, BusError> {
        let name = self.topic.name.as_str();
        let label = self.topic.label.as_str();
        let sample = self.port.receive().map_err(|e| BusError::Transfer {
            topic: name.to_owned(),
            reason: format!("{e:?}"),
        })?;
        let Some(sample) = sample else {
            return Ok(None);
        };
        let metrics = Metrics::global();
        let publisher = sample.header().publisher_id().value();
        let seq = sample.user_header().seq;
        if let Some(previous) = self.last_seq.insert(publisher, seq) {
            let missed = seq.saturating_sub(previous.saturating_add(1));
            for _ in 0..missed.min(1_000) {
                metrics.bus_dropped(label, "overwritten_latest_wins");
            }
        }
        let result = read(sample.payload());
        drop(sample);
        if let Some(consumed) = &self.consumed {
            consumed.notify();
        }
        metrics.bus_message(label, Direction::Received);
        Ok(Some(result))
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::bus::BusOptions;
    use robotd_protocol::diagnostics::Ping;

    /// Listeners attached to event service `event` right now.
    pub(crate) fn listeners(bus: &Bus, event: &str) -> usize {
        super::super::wake::event_service(bus, event)
            .unwrap()
            .dynamic_config()
            .number_of_listeners()
    }

    /// Loses a wake-up of `subscriber`, as a consume racing a notifier can: the topic is
    /// notified and the datagram read before tokio's reactor sees it. `bus` must be another
    /// node than the subscriber's (a notifier of its own node sends it no datagram).
    pub(crate) fn lose_a_wake_up<T: Message>(bus: &Bus, subscriber: &Subscriber<T>) {
        Notify::new(bus, &data_event(&subscriber.topic.name))
            .unwrap()
            .notify();
        assert_eq!(subscriber.wake.swallow_datagrams(), 1);
    }

    pub(crate) fn ping(seq: u64) -> Ping {
        Ping {
            seq,
            payload: vec![],
        }
    }

    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn only_back_pressure_subscribers_listen_for_new_publishers() {
        const LATEST: Topic<Ping> = Topic::new("latest", Overflow::latest_wins(4));
        const LOSSLESS: Topic<Ping> = Topic::new("lossless", Overflow::back_pressure(4));
        let namespace = format!("test-joined-{}", std::process::id());
        let bus = Bus::open(BusOptions::new(&namespace, "joined")).unwrap();
        let mut latest = bus.subscriber(&LATEST).unwrap();
        let mut lossless = bus.subscriber(&LOSSLESS).unwrap();
        assert_eq!(listeners(&bus, &joined_event("latest")), 0);
        assert_eq!(listeners(&bus, &joined_event("lossless")), 1);

        // Without that listener, a publisher created later still reaches the subscriber
        // from its first message on: the message wakes it and its receive connects.
        let latest_publisher = bus.publisher(&LATEST).unwrap();
        let lossless_publisher = bus.publisher(&LOSSLESS).unwrap();
        latest_publisher.publish(&ping(1)).unwrap();
        lossless_publisher.publish(&ping(2)).unwrap();
        let second = Duration::from_secs(1);
        let first = tokio::time::timeout(second, latest.recv()).await.unwrap();
        assert_eq!(first.unwrap().body.seq, 1);
        let first = tokio::time::timeout(second, lossless.recv()).await.unwrap();
        assert_eq!(first.unwrap().body.seq, 2);
    }
}
