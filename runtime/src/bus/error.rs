//! Errors of bus operations, each with a message a user can act on.

use robotd_protocol::envelope::{DecodeError, EncodeError};

/// Why a bus operation failed.
#[derive(Debug, thiserror::Error)]
pub enum BusError {
    /// Creating a node, service or port failed.
    #[error("cannot set up {what}: {reason}")]
    Setup {
        /// What was being created.
        what: String,
        /// What iceoryx2 or the validation said.
        reason: String,
    },
    /// A message could not be encoded.
    #[error(transparent)]
    Encode(#[from] EncodeError),
    /// A received message could not be decoded (wrong type, version or bytes).
    #[error(transparent)]
    Decode(#[from] DecodeError),
    /// The message is larger than the topic allows.
    #[error("message of {size} bytes on '{topic}' exceeds the limit of {limit} bytes")]
    TooLarge {
        /// Topic or service name.
        topic: String,
        /// Encoded size.
        size: usize,
        /// Configured maximum.
        limit: usize,
    },
    /// A back-pressure topic's subscriber did not make room in time: the message was not
    /// delivered to it (and the sender is told, rather than the message vanishing).
    #[error("a subscriber of '{topic}' is full and did not catch up within {waited_ms} ms; message not delivered to it")]
    Full {
        /// Topic name.
        topic: String,
        /// How long the sender waited.
        waited_ms: u64,
    },
    /// Some subscribers of a back-pressure topic did not get the message (they never
    /// connected, or disconnected while it was sent).
    #[error("message on '{topic}' reached {delivered} of {subscribers} subscribers; the others are not connected (are they still receiving?)")]
    NotDelivered {
        /// Topic name.
        topic: String,
        /// Subscribers that received it.
        delivered: usize,
        /// Subscribers registered on the topic.
        subscribers: usize,
    },
    /// No server is attached to the service.
    #[error("no actor serves '{service}' (is it running? see `robotd doctor` and the logs)")]
    NoServer {
        /// Service name.
        service: String,
    },
    /// The server went away while the request was in flight (the actor died or restarted).
    #[error(
        "the actor serving '{service}' went away while handling the request; it was not retried"
    )]
    ServerLost {
        /// Service name.
        service: String,
    },
    /// The server answered with a fault instead of a reply.
    #[error("'{service}' could not answer: {fault}")]
    Remote {
        /// Service name.
        service: String,
        /// What the server reported.
        fault: super::rpc::Fault,
    },
    /// No reply within the deadline.
    #[error("no reply from '{service}' within {timeout_ms} ms")]
    Timeout {
        /// Service name.
        service: String,
        /// The deadline.
        timeout_ms: u64,
    },
    /// Too many requests from this client are still open.
    #[error("too many requests in flight on '{service}'")]
    Busy {
        /// Service name.
        service: String,
    },
    /// An iceoryx2 transfer failed.
    #[error("bus transfer on '{topic}' failed: {reason}")]
    Transfer {
        /// Topic or service name.
        topic: String,
        /// What iceoryx2 said.
        reason: String,
    },
    /// Waiting for a wake-up event failed at the OS level.
    #[error("waiting on '{topic}' failed: {source}")]
    Wait {
        /// Topic or service name.
        topic: String,
        /// The OS error.
        #[source]
        source: std::io::Error,
    },
}
