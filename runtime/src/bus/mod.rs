//! The bus: typed messages between actors over iceoryx2 shared memory.
//!
//! Every actor in robotd talks to the others only through the bus, so it does not matter
//! whether the peer runs in the same process or in another one: both ends open the same
//! named iceoryx2 services in `/dev/shm`. The bus offers three things:
//!
//! - **topics** ([`Topic`], [`Publisher`], [`Subscriber`]): publish-subscribe for streams of
//!   control messages (arm state, detections, health events), encoded once with rmp-serde into a
//!   shared-memory slice, each in an [`Envelope`](robotd_protocol::envelope::Envelope) that
//!   carries type, schema version and trace context;
//! - **frames** ([`FrameTopic`], [`FramePublisher`], [`FrameSubscriber`]): camera images written
//!   once by the producer straight into shared memory and read in place by every subscriber;
//! - **services** ([`Service`], [`Client`], [`Server`]): request-response for commands, where the
//!   caller always gets an answer or an error, never silence.
//!
//! Receiving never busy-polls or sleeps in a loop: each port is paired with an iceoryx2 *event*
//! service whose listener is a file descriptor registered with tokio, so a task waiting for a
//! message is woken by the kernel when the sender notifies (or directly, without the kernel,
//! when the sender is in the same process: see `wake`); a client waiting for its server is
//! woken by the event a server raises when it attaches. (One wait is not an event: a request
//! that has waited 250 ms checks that its server's process is still alive, since a crashed
//! process cannot announce its death.)
//!
//! Overflow is declared per topic ([`Overflow`]): frames use *latest wins* (a slow viewer sees
//! the newest frame, the camera never waits), control topics use *back-pressure* (the sender
//! waits, event-driven, for the slowest subscriber and gets [`BusError::Full`] if it does not
//! catch up in time). Messages replaced on latest-wins topics are detected from sequence gaps
//! (from the first message a subscriber sees on) and counted in the `robotd_bus_dropped_total`
//! metric — nothing is lost silently.
//!
//! ```no_run
//! use robotd_runtime::bus::{Bus, BusOptions, Overflow, Topic};
//! use robotd_protocol::envelope::Message;
//! use serde::{Deserialize, Serialize};
//!
//! #[derive(Debug, Serialize, Deserialize)]
//! struct Hello { text: String }
//! impl Message for Hello { const TYPE: &'static str = "example.hello"; }
//! const HELLO: Topic<Hello> = Topic::new("example/hello", Overflow::back_pressure(16));
//!
//! # async fn demo() -> Result<(), robotd_runtime::bus::BusError> {
//! let bus = Bus::open(BusOptions::new("demo", "example"))?;
//! let mut sub = bus.subscriber(&HELLO)?;
//! let publisher = bus.publisher(&HELLO)?;
//! publisher.publish(&Hello { text: "hi".into() })?;
//! let hello = sub.recv().await?;
//! assert_eq!(hello.body.text, "hi");
//! # Ok(()) }
//! ```

mod consumed;
mod describe;
mod error;
mod frame;
mod handles;
mod pubsub;
mod rpc;
pub mod stale;
mod thread;
mod wake;

pub use describe::{
    describe, Description, Entry, EventNames, EventSettings, FramesDescription, ServiceDescription,
    TopicDescription, DESCRIPTION_VERSION,
};
pub use error::BusError;
pub use frame::{
    FrameHeader, FrameLoan, FramePublisher, FrameSample, FrameSlot, FrameSubscriber, FrameTopic,
    FRAME_BYTES, FRAME_CHANNELS, FRAME_HEIGHT, FRAME_WIDTH,
};
pub use pubsub::{Overflow, Publisher, Subscriber, Topic};
pub use rpc::{Client, Fault, FaultKind, Incoming, PendingReply, Reply, Server, Service};
pub use thread::spawn_reader_thread;

use iceoryx2::prelude::*;
use std::sync::Arc;

/// The iceoryx2 service flavour robotd uses: inter-process, ports shareable between threads
/// (tokio moves tasks between worker threads).
pub(crate) type Ipc = iceoryx2::service::ipc_threadsafe::Service;

/// How to join the bus.
#[derive(Debug, Clone)]
pub struct BusOptions {
    /// Prefix of every service name, so two robotd instances on one host do not meet.
    pub namespace: String,
    /// Name of this process's node, shown by `robotd doctor` and iceoryx2 tools.
    pub node_name: String,
    /// Remove the resources of dead nodes (crashed processes) when joining.
    pub cleanup_dead_nodes: bool,
}

impl BusOptions {
    /// Options for namespace `namespace`, node `node_name`, cleaning dead nodes on join.
    pub fn new(namespace: &str, node_name: &str) -> Self {
        Self {
            namespace: namespace.to_owned(),
            node_name: node_name.to_owned(),
            cleanup_dead_nodes: true,
        }
    }
}

/// What a dead-node clean-up did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct CleanupReport {
    /// Dead nodes whose resources were removed.
    pub removed: u64,
    /// Dead nodes that could not be removed (permissions, or another process was cleaning).
    pub failed: u64,
    /// Segments killed processes left half-created, removed first ([`stale`]).
    pub half_created: usize,
    /// Half-created segments too young to remove were there, so the dead-node clean-up was
    /// put off (iceoryx2's would wait forever on one left by a killed process); a clean-up
    /// once they are [`stale::HALF_CREATED_AFTER`] old removes them and goes on.
    pub deferred: bool,
}

/// A process's membership of the bus: one iceoryx2 node, from which ports are created.
///
/// Cheap to clone; ports created from it stay valid after the `Bus` is dropped.
#[derive(Clone)]
pub struct Bus {
    inner: Arc<BusInner>,
}

struct BusInner {
    node: Node<Ipc>,
    namespace: String,
    /// Message-topic services opened by this process, shared by their ports.
    topics: handles::Handles<pubsub::PubSubFactory>,
    /// Event services opened by this process, shared by their notifiers and listeners.
    events: handles::Handles<wake::EventService>,
}

impl std::fmt::Debug for Bus {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Bus")
            .field("namespace", &self.inner.namespace)
            .field("node", &self.inner.node.name().as_str())
            .finish()
    }
}

/// Connections to departed publishers a subscriber keeps while it still has their messages
/// to read (iceoryx2's default is 128). Every subscriber reserves room for this many plus one
/// per possible publisher, a few KB each, whether used or not: at 128 that was most of an
/// idle robotd's memory. robotd's subscribers hold one message at a time and read promptly,
/// so a few suffice; beyond them, unread messages of the oldest departed publisher are
/// dropped (iceoryx2 logs a warning), never one still being read.
const EXPIRED_CONNECTIONS_KEPT: usize = 8;

/// iceoryx2's defaults with robotd's per-node settings (they do not change what a service
/// is, so processes with other settings, like the Python package, still connect).
fn node_config() -> iceoryx2::config::Config {
    let mut config = iceoryx2::config::Config::global_config().clone();
    config
        .defaults
        .publish_subscribe
        .subscriber_expired_connection_buffer = EXPIRED_CONNECTIONS_KEPT;
    config
}

impl Bus {
    /// Joins the bus: creates this process's node and, if asked, removes stale resources left
    /// behind by processes that died.
    pub fn open(options: BusOptions) -> Result<Self, BusError> {
        validate_namespace(&options.namespace)?;
        // Before anything opens a service: iceoryx2 would wait forever on such a segment.
        stale::remove_half_created(
            std::path::Path::new(stale::SHARED_MEMORY_DIR),
            stale::HALF_CREATED_AFTER,
        );
        let node_name = NodeName::new(&options.node_name).map_err(|e| BusError::Setup {
            what: format!("node name '{}'", options.node_name),
            reason: format!("{e:?}"),
        })?;
        let node = NodeBuilder::new()
            .name(&node_name)
            .config(&node_config())
            // robotd handles SIGINT/SIGTERM itself (graceful shutdown through tokio).
            .signal_handling_mode(SignalHandlingMode::Disabled)
            .create::<Ipc>()
            .map_err(|e| BusError::Setup {
                what: "iceoryx2 node".into(),
                reason: format!(
                    "{e:?}; check that /dev/shm is mounted and writable (robotd doctor)"
                ),
            })?;
        let bus = Self {
            inner: Arc::new(BusInner {
                node,
                namespace: options.namespace,
                topics: handles::Handles::default(),
                events: handles::Handles::default(),
            }),
        };
        if options.cleanup_dead_nodes {
            let report = bus.cleanup_dead_nodes();
            if report.removed > 0 || report.failed > 0 {
                tracing::info!(
                    removed = report.removed,
                    failed = report.failed,
                    "cleaned resources of dead bus nodes"
                );
            }
        }
        Ok(bus)
    }

    /// The namespace every service name starts with.
    pub fn namespace(&self) -> &str {
        &self.inner.namespace
    }

    /// Removes the shared-memory resources of every dead node (a crashed actor process) and
    /// disconnects its ports from the services they used, so a restarted actor can take its
    /// place (a service allows one server, for instance).
    ///
    /// Segments a killed process left half-created go first: iceoryx2's clean-up would wait
    /// for them forever. One younger than [`stale::HALF_CREATED_AFTER`] cannot be told from
    /// a segment being created, so while one is there the clean-up is put off
    /// ([`CleanupReport::deferred`]): callers retry (a waiting request every 250 ms), and a
    /// supervisor removes the corpses of a process it saw die itself
    /// ([`stale::remove_half_created_after`]) before cleaning.
    pub fn cleanup_dead_nodes(&self) -> CleanupReport {
        self.cleanup_dead_nodes_in(std::path::Path::new(stale::SHARED_MEMORY_DIR), true)
    }

    /// [`cleanup_dead_nodes`](Self::cleanup_dead_nodes) for a supervisor that has just removed
    /// the young corpses of a process it saw die ([`stale::remove_half_created_after`]): a
    /// half-created segment still there is a living creator's, which iceoryx2 waits for only
    /// a moment, so the clean-up is not put off (the restarted actor needs it).
    pub fn cleanup_dead_nodes_after_sweep(&self) -> CleanupReport {
        self.cleanup_dead_nodes_in(std::path::Path::new(stale::SHARED_MEMORY_DIR), false)
    }

    fn cleanup_dead_nodes_in(&self, segments: &std::path::Path, defer: bool) -> CleanupReport {
        let half_created = stale::remove_half_created(segments, stale::HALF_CREATED_AFTER).len();
        if defer && stale::any_half_created(segments) {
            tracing::debug!(
                "dead-node clean-up put off: a half-created bus segment is too young to remove"
            );
            return CleanupReport {
                half_created,
                deferred: true,
                ..CleanupReport::default()
            };
        }
        let state = self.inner.node.try_cleanup_dead_nodes();
        CleanupReport {
            removed: state.cleanups,
            failed: state.failed_cleanups,
            half_created,
            deferred: false,
        }
    }

    pub(crate) fn node(&self) -> &Node<Ipc> {
        &self.inner.node
    }

    /// Full iceoryx2 service name for a topic or service name of robotd.
    pub(crate) fn service_name(&self, suffix: &str) -> Result<ServiceName, BusError> {
        let full = format!("{}/{}", self.inner.namespace, suffix);
        ServiceName::new(&full).map_err(|e| BusError::Setup {
            what: format!("service name '{full}'"),
            reason: format!("{e:?}"),
        })
    }
}

fn validate_namespace(namespace: &str) -> Result<(), BusError> {
    let ok = !namespace.is_empty()
        && namespace.len() <= 64
        && namespace
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-');
    if ok {
        Ok(())
    } else {
        Err(BusError::Setup {
            what: format!("bus namespace '{namespace}'"),
            reason: "use 1-64 characters from A-Z, a-z, 0-9, '_' and '-'".into(),
        })
    }
}
