//! The envelope every control message travels in on the bus.
//!
//! An [`Envelope`] wraps a typed body with what a receiver needs to trust and trace it: the
//! message type name, the schema version the sender wrote, the W3C trace context of the span
//! that sent it, and the send time. Receivers refuse an envelope whose type or schema version
//! they do not understand, with an error that names both sides, instead of misreading it.
//!
//! ```
//! use robotd_protocol::envelope::{decode, encode, Envelope, Message};
//! use serde::{Deserialize, Serialize};
//!
//! #[derive(Debug, PartialEq, Serialize, Deserialize)]
//! struct Ping { seq: u32 }
//! impl Message for Ping { const TYPE: &'static str = "example.ping"; }
//!
//! let mut bytes = Vec::new();
//! encode(&Envelope::new(Ping { seq: 7 }), &mut bytes).unwrap();
//! let back: Envelope<Ping> = decode(&bytes).unwrap();
//! assert_eq!(back.body, Ping { seq: 7 });
//! ```

use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};
use std::time::{SystemTime, UNIX_EPOCH};

/// A typed message that can travel on the bus.
///
/// `TYPE` is a stable dotted name (`"arm.command"`); bump `SCHEMA_VERSION` whenever a change
/// to the type would make an older reader misunderstand it.
pub trait Message: Serialize + DeserializeOwned + Send + 'static {
    /// Stable wire name of the message type.
    const TYPE: &'static str;
    /// Version of the body's schema; readers refuse other versions.
    const SCHEMA_VERSION: u16 = 1;
}

/// W3C trace context (`traceparent`, `tracestate`) carried across the bus so a span started
/// at an edge continues in the actor that serves it, in this process or another.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct TraceContext {
    /// `00-<trace id>-<span id>-<flags>`, absent when the sender had no active trace.
    pub traceparent: Option<String>,
    /// Vendor-specific trace state, passed through untouched.
    pub tracestate: Option<String>,
}

/// A message body plus its type, schema version, trace context and send time.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Envelope<T> {
    /// The body's [`Message::TYPE`].
    pub msg_type: String,
    /// The body's [`Message::SCHEMA_VERSION`] as written by the sender.
    pub schema_version: u16,
    /// Trace context of the sending span.
    pub trace: TraceContext,
    /// Wall-clock send time, nanoseconds since the Unix epoch.
    pub sent_at_unix_ns: u64,
    /// The message itself.
    pub body: T,
}

impl<T: Message> Envelope<T> {
    /// Wraps `body`, stamping type, schema version and the current time; no trace context.
    pub fn new(body: T) -> Self {
        Self {
            msg_type: T::TYPE.to_owned(),
            schema_version: T::SCHEMA_VERSION,
            trace: TraceContext::default(),
            sent_at_unix_ns: unix_now_ns(),
            body,
        }
    }

    /// Sets the trace context (builder style).
    pub fn with_trace(mut self, trace: TraceContext) -> Self {
        self.trace = trace;
        self
    }
}

/// Nanoseconds since the Unix epoch (0 if the clock is before 1970).
pub fn unix_now_ns() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map(|d| d.as_nanos() as u64)
        .unwrap_or(0)
}

/// Encoding an envelope failed (a body serde cannot express in MessagePack).
#[derive(Debug, thiserror::Error)]
#[error("cannot encode a '{msg_type}' message: {source}")]
pub struct EncodeError {
    /// The type that failed.
    pub msg_type: &'static str,
    /// What rmp-serde said.
    #[source]
    pub source: rmp_serde::encode::Error,
}

/// Decoding bytes into an envelope failed.
#[derive(Debug, thiserror::Error)]
pub enum DecodeError {
    /// The bytes are not a MessagePack envelope of the expected shape.
    #[error("malformed '{expected}' message: {source}")]
    Malformed {
        /// The type the reader expected.
        expected: &'static str,
        /// What rmp-serde said.
        #[source]
        source: rmp_serde::decode::Error,
    },
    /// The envelope holds another message type.
    #[error("expected a '{expected}' message but got '{got}'")]
    WrongType {
        /// The type the reader expected.
        expected: &'static str,
        /// The type in the envelope.
        got: String,
    },
    /// The sender wrote a schema version this reader does not understand.
    #[error("'{msg_type}' schema version {got} is not supported (this build reads version {supported}); upgrade the older side")]
    UnsupportedVersion {
        /// The message type.
        msg_type: &'static str,
        /// Version in the envelope.
        got: u16,
        /// Version this build reads.
        supported: u16,
    },
}

/// Header fields read first, so type and version are checked before the body is decoded.
#[derive(Deserialize)]
struct Header {
    msg_type: String,
    schema_version: u16,
}

/// Appends the MessagePack encoding of `envelope` (fields by name) to `out`.
pub fn encode<T: Message>(envelope: &Envelope<T>, out: &mut Vec<u8>) -> Result<(), EncodeError> {
    let mut ser = rmp_serde::Serializer::new(out).with_struct_map();
    envelope.serialize(&mut ser).map_err(|source| EncodeError {
        msg_type: T::TYPE,
        source,
    })
}

/// The MessagePack encoding of `envelope` in a new buffer (see [`encode`]).
pub fn encode_to_vec<T: Message>(envelope: &Envelope<T>) -> Result<Vec<u8>, EncodeError> {
    let mut out = Vec::new();
    encode(envelope, &mut out)?;
    Ok(out)
}

/// Appends the encoding of an envelope around a borrowed `body` to `out`: the same bytes as
/// [`encode`] of `Envelope { body, trace, sent_at_unix_ns: now, .. }`, without moving the body.
pub fn encode_body<T: Message>(
    body: &T,
    trace: &TraceContext,
    out: &mut Vec<u8>,
) -> Result<(), EncodeError> {
    encode_parts(body, T::TYPE, T::SCHEMA_VERSION, trace, out)
}

/// Like [`encode_body`] for a body that is serialized like a `msg_type` message but is not
/// that type itself (a borrowed view of it, say).
pub fn encode_parts<B: Serialize + ?Sized>(
    body: &B,
    msg_type: &'static str,
    schema_version: u16,
    trace: &TraceContext,
    out: &mut Vec<u8>,
) -> Result<(), EncodeError> {
    #[derive(Serialize)]
    struct EnvelopeRef<'a, B: ?Sized> {
        msg_type: &'static str,
        schema_version: u16,
        trace: &'a TraceContext,
        sent_at_unix_ns: u64,
        body: &'a B,
    }
    let envelope = EnvelopeRef {
        msg_type,
        schema_version,
        trace,
        sent_at_unix_ns: unix_now_ns(),
        body,
    };
    let mut ser = rmp_serde::Serializer::new(out).with_struct_map();
    envelope
        .serialize(&mut ser)
        .map_err(|source| EncodeError { msg_type, source })
}

/// Decodes an envelope of `T`, refusing other message types and schema versions.
pub fn decode<T: Message>(bytes: &[u8]) -> Result<Envelope<T>, DecodeError> {
    // The common case decodes once; the header is read on its own only to explain a failure
    // or to refuse a body that happened to fit the wrong type.
    let check = |msg_type: &str, schema_version: u16| {
        if msg_type != T::TYPE {
            return Err(DecodeError::WrongType {
                expected: T::TYPE,
                got: msg_type.to_owned(),
            });
        }
        if schema_version != T::SCHEMA_VERSION {
            return Err(DecodeError::UnsupportedVersion {
                msg_type: T::TYPE,
                got: schema_version,
                supported: T::SCHEMA_VERSION,
            });
        }
        Ok(())
    };
    match rmp_serde::from_slice::<Envelope<T>>(bytes) {
        Ok(envelope) => {
            check(&envelope.msg_type, envelope.schema_version)?;
            Ok(envelope)
        }
        Err(source) => {
            // A wrong type or version explains the failure better than the syntax error.
            if let Ok(header) = rmp_serde::from_slice::<Header>(bytes) {
                check(&header.msg_type, header.schema_version)?;
            }
            Err(DecodeError::Malformed {
                expected: T::TYPE,
                source,
            })
        }
    }
}
