//! Request-response services for commands: every request gets a reply or an error.
//!
//! A [`Service`] names a command channel between many [`Client`]s and exactly one [`Server`]
//! (one server per service, so a request can never be executed twice). It is built from two
//! back-pressure topics: requests flow to the server on `<service>/requests` (a topic that
//! admits a single subscriber), replies flow back on a topic of each client's own. The caller
//! always learns the outcome: the reply, a [`Fault`] the server reported (the actor failed, the
//! request was malformed or dropped), [`BusError::NoServer`], [`BusError::ServerLost`] when the
//! serving process died mid-request, or [`BusError::Timeout`]. Requests are never retried by
//! the bus: a command that moved an arm must not move it twice.
//!
//! (iceoryx2 has a request-response pattern of its own; robotd does not use it because
//! connecting a new client while the server serves another one can stall both for the
//! iceoryx2 creation timeout of 1 s, which the bus tests reproduced.)

use super::pubsub::{Publisher, Subscriber, TopicSpec};
use super::wake::{subscribed_event, Wake};
use super::{Bus, BusError, Overflow};
use robotd_protocol::envelope::{self, Envelope, Message, TraceContext};
use robotd_protocol::safety::Origin;
use serde::{Deserialize, Serialize};
use std::collections::HashMap;
use std::future::Future;
use std::marker::PhantomData;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};

/// A named command channel: requests `Req`, replies `Resp`.
#[derive(Debug)]
pub struct Service<Req, Resp> {
    name: &'static str,
    max_bytes: usize,
    _types: PhantomData<fn(Req) -> Resp>,
}

impl<Req, Resp> Clone for Service<Req, Resp> {
    fn clone(&self) -> Self {
        *self
    }
}
impl<Req, Resp> Copy for Service<Req, Resp> {}

impl<Req: Message, Resp: Message> Service<Req, Resp> {
    /// A service called `name` (e.g. `"arm/command"`), messages up to 1 MiB.
    pub const fn new(name: &'static str) -> Self {
        Self {
            name,
            max_bytes: 1024 * 1024,
            _types: PhantomData,
        }
    }

    /// The service's name.
    pub const fn name(&self) -> &'static str {
        self.name
    }

    pub(crate) fn requests(&self) -> TopicSpec {
        TopicSpec {
            name: format!("{}/requests", self.name),
            label: format!("{}/requests", self.name),
            overflow: Overflow::BackPressure {
                depth: 64,
                max_wait: Duration::from_secs(1),
            },
            max_bytes: self.max_bytes,
            max_subscribers: 1,
            max_publishers: MAX_CLIENTS,
            handshake: false,
        }
    }

    pub(crate) fn replies(&self, client_id: u64) -> TopicSpec {
        TopicSpec {
            name: format!("{}/replies/{client_id:016x}", self.name),
            label: format!("{}/replies", self.name),
            overflow: Overflow::BackPressure {
                depth: 16,
                max_wait: Duration::from_secs(1),
            },
            // Room for the envelope around a reply as large as the largest request.
            max_bytes: self.max_bytes + 64 * 1024,
            max_subscribers: 1,
            // The server, and briefly its successor after a restart.
            max_publishers: 2,
            handshake: false,
        }
    }
}

/// Clients one service admits at a time (live processes; dead ones are cleaned up).
const MAX_CLIENTS: usize = 128;

/// Reply publishers a server keeps open; the least recently used is closed beyond this.
const MAX_CACHED_REPLY_PUBLISHERS: usize = 32;

/// Why a server could not produce a reply.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FaultKind {
    /// The actor died (panicked) while handling the request; it was not retried.
    ActorFailed,
    /// The actor is restarting or has given up; try again later.
    Unavailable,
    /// The request could not be decoded (wrong type, schema version or bytes).
    BadRequest,
    /// The server dropped the request without answering it.
    Dropped,
    /// The request's deadline had passed before the server got to it; it was not executed.
    Expired,
    /// The server handled the request but could not send the reply (e.g. too large).
    ReplyFailed,
    /// The actor refused the request (its handler returned an error).
    Refused,
}

/// An error reported by the server instead of a reply.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize, thiserror::Error)]
#[error("{message}")]
pub struct Fault {
    /// Category.
    pub kind: FaultKind,
    /// What happened, for the user.
    pub message: String,
}

impl Fault {
    /// A fault of `kind` with `message`.
    pub fn new(kind: FaultKind, message: impl Into<String>) -> Self {
        Self {
            kind,
            message: message.into(),
        }
    }
}

/// What travels back: the reply or a fault.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Reply<T> {
    /// The server's reply.
    Ok(T),
    /// The server could not reply.
    Fault(Fault),
}

/// A request on the wire: the body plus where to send the answer.
#[derive(Debug, Serialize, Deserialize)]
struct RequestFrame<Req> {
    client_id: u64,
    request_id: u64,
    /// After this time (Unix ns) the caller has given up: the server must not execute it.
    deadline_unix_ns: u64,
    /// Who the work belongs to (absent from older or other-language senders: an unnamed client).
    #[serde(default)]
    origin: Origin,
    body: Req,
}

impl<Req: Message> Message for RequestFrame<Req> {
    const TYPE: &'static str = Req::TYPE;
    const SCHEMA_VERSION: u16 = Req::SCHEMA_VERSION;
}

/// Routing fields of a request, readable even when its body is not (to answer with a fault).
#[derive(Deserialize)]
struct Routing {
    body: RoutingFields,
}

#[derive(Deserialize)]
struct RoutingFields {
    client_id: u64,
    request_id: u64,
}

/// A reply on the wire.
#[derive(Debug, Serialize, Deserialize)]
struct ReplyFrame<Resp> {
    request_id: u64,
    reply: Reply<Resp>,
}

impl<Resp: Message> Message for ReplyFrame<Resp> {
    const TYPE: &'static str = Resp::TYPE;
    const SCHEMA_VERSION: u16 = Resp::SCHEMA_VERSION;
}

/// How often a waiting client checks that its server is still alive (a crashed process
/// cannot say goodbye).
const LIVENESS_CHECK: Duration = Duration::from_millis(250);

fn new_client_id() -> u64 {
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    let nanos = envelope::unix_now_ns();
    let pid = u64::from(std::process::id());
    let n = COUNTER.fetch_add(1, Ordering::Relaxed);
    // Unique per process (pid), per start (time) and per client (counter).
    (pid << 40) ^ (nanos & 0xFF_FFFF_FFFF) ^ n.rotate_left(20)
}

/// Sends requests to a service and waits for replies.
pub struct Client<Req: Message, Resp: Message> {
    requests: Publisher<RequestFrame<Req>>,
    replies: tokio::sync::Mutex<Subscriber<ReplyFrame<Resp>>>,
    client_id: u64,
    next_request: AtomicU64,
    service: Service<Req, Resp>,
    round_trip_label: String,
    bus: Bus,
}

impl<Req: Message, Resp: Message> std::fmt::Debug for Client<Req, Resp> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Client")
            .field("service", &self.service.name)
            .field("client_id", &self.client_id)
            .finish()
    }
}

impl Bus {
    /// Creates a client of `service`. Must be called inside a tokio runtime.
    pub fn client<Req: Message, Resp: Message>(
        &self,
        service: &Service<Req, Resp>,
    ) -> Result<Client<Req, Resp>, BusError> {
        let client_id = new_client_id();
        // The reply subscriber first, so the server's reply publisher finds it.
        let replies = self.subscriber_for(service.replies(client_id))?;
        let requests = self.publisher_for(service.requests())?;
        Ok(Client {
            requests,
            replies: tokio::sync::Mutex::new(replies),
            client_id,
            next_request: AtomicU64::new(1),
            service: *service,
            round_trip_label: format!("{}/round_trip", service.name),
            bus: self.clone(),
        })
    }

    /// Creates the server of `service`. Fails if another live server exists (one server per
    /// service); servers of dead processes are cleaned up first.
    pub fn server<Req: Message, Resp: Message>(
        &self,
        service: &Service<Req, Resp>,
    ) -> Result<Server<Req, Resp>, BusError> {
        let requests = match self.subscriber_for(service.requests()) {
            Ok(requests) => requests,
            Err(_) => {
                // A crashed predecessor may still hold the single server slot.
                self.cleanup_dead_nodes();
                self.subscriber_for(service.requests())
                    .map_err(|e| BusError::Setup {
                        what: format!("server of '{}'", service.name),
                        reason: format!("{e} (is another robotd or actor already serving it?)"),
                    })?
            }
        };
        let (abandoned_tx, abandoned_rx) = tokio::sync::mpsc::unbounded_channel();
        Ok(Server {
            requests,
            reply_publishers: HashMap::new(),
            abandoned_tx,
            abandoned_rx,
            service: *service,
            bus: self.clone(),
        })
    }
}

impl<Req: Message, Resp: Message> Client<Req, Resp> {
    /// Whether a server is attached right now.
    pub fn has_server(&self) -> bool {
        self.requests.subscriber_count() > 0
    }

    /// Waits until a server is attached, up to `timeout`. Returns whether one is.
    ///
    /// Woken by the event a server raises when it attaches; no polling. The listener for that
    /// event exists only while a caller waits (a client holds none otherwise: one socket and
    /// one port fewer per client for the service's lifetime); it is made before the next
    /// check, so a server attaching in between still wakes it.
    pub async fn wait_for_server(&self, timeout: Duration) -> bool {
        if self.has_server() {
            return true;
        }
        let deadline = Instant::now() + timeout;
        let attached = match Wake::new(&self.bus, &subscribed_event(&self.service.requests().name))
        {
            Ok(attached) => attached,
            Err(error) => {
                tracing::warn!(service = self.service.name, %error, "waiting for a server");
                return self.has_server();
            }
        };
        loop {
            if self.has_server() {
                return true;
            }
            // Check, rearm, check, sleep (see `Wake::rearm`).
            attached.rearm();
            if self.has_server() {
                return true;
            }
            let now = Instant::now();
            if now >= deadline {
                return false;
            }
            match attached.sleep_timeout(deadline - now).await {
                Ok(_) => {}
                Err(error) => {
                    tracing::warn!(service = self.service.name, %error, "waiting for a server");
                    return self.has_server();
                }
            }
        }
    }

    /// Sends `request` and waits up to `timeout` for the reply.
    pub async fn request(&self, request: &Req, timeout: Duration) -> Result<Resp, BusError> {
        Ok(self.request_envelope(request, timeout).await?.body)
    }

    /// Like [`request`](Self::request), returning the whole reply envelope.
    ///
    /// Sending blocks the calling thread (up to 1 s, then [`BusError::Full`]) only while the
    /// server's queue of 64 requests is full; requests from one client are answered one at a
    /// time. A request that times out is not executed later: it carries its deadline, and the
    /// server refuses expired requests.
    pub async fn request_envelope(
        &self,
        request: &Req,
        timeout: Duration,
    ) -> Result<Envelope<Resp>, BusError> {
        let name = self.service.name;
        let mut replies = self.replies.lock().await;
        if !self.has_server() {
            return Err(BusError::NoServer {
                service: name.to_owned(),
            });
        }
        let request_id = self.next_request.fetch_add(1, Ordering::Relaxed);
        let started = Instant::now();
        let deadline_unix_ns = envelope::unix_now_ns()
            .saturating_add(u64::try_from(timeout.as_nanos()).unwrap_or(u64::MAX));
        let delivered = self
            .requests
            .publish_ref(self.client_id, request_id, deadline_unix_ns, request)
            .map_err(|e| match e {
                BusError::NotDelivered { .. } => BusError::NoServer {
                    service: name.to_owned(),
                },
                other => other,
            })?;
        if delivered == 0 {
            return Err(BusError::NoServer {
                service: name.to_owned(),
            });
        }
        // The server that holds the request (one per service), read after the send so a
        // server that replaced another in between is the one watched.
        let Some(&server) = self.requests.subscriber_ids().first() else {
            return Err(BusError::ServerLost {
                service: name.to_owned(),
            });
        };
        // A timeout too large to represent means: no deadline in practice.
        let deadline = started
            .checked_add(timeout)
            .unwrap_or(started + Duration::from_secs(365 * 24 * 3600));
        // Check, rearm, check, sleep (see `Wake::rearm`): a reply that arrives between the
        // first check and the sleep is found by the second, or wakes the sleep.
        let mut rearmed = false;
        loop {
            while let Some(frame) = replies.try_recv()? {
                if frame.body.request_id != request_id {
                    // The late answer to an earlier request that timed out: not ours.
                    continue;
                }
                crate::metrics::Metrics::global()
                    .bus_latency(&self.round_trip_label, started.elapsed().as_secs_f64());
                return match frame.body.reply {
                    Reply::Ok(body) => Ok(Envelope {
                        msg_type: frame.msg_type,
                        schema_version: frame.schema_version,
                        trace: frame.trace,
                        sent_at_unix_ns: frame.sent_at_unix_ns,
                        body,
                    }),
                    Reply::Fault(fault) => Err(BusError::Remote {
                        service: name.to_owned(),
                        fault,
                    }),
                };
            }
            if !rearmed {
                replies.rearm();
                rearmed = true;
                continue;
            }
            rearmed = false;
            let now = Instant::now();
            if now >= deadline {
                return Err(BusError::Timeout {
                    service: name.to_owned(),
                    timeout_ms: timeout.as_millis() as u64,
                });
            }
            let woken = replies
                .sleep_timeout((deadline - now).min(LIVENESS_CHECK))
                .await?;
            if !woken {
                // No reply for a while: is the server that took the request still alive? A
                // crashed process is cleaned up here, which removes its server port.
                self.bus.cleanup_dead_nodes();
                if !self.requests.subscriber_ids().contains(&server) {
                    return Err(BusError::ServerLost {
                        service: name.to_owned(),
                    });
                }
            }
        }
    }
}

impl<Req: Message> Publisher<RequestFrame<Req>> {
    fn publish_ref(
        &self,
        client_id: u64,
        request_id: u64,
        deadline_unix_ns: u64,
        body: &Req,
    ) -> Result<usize, BusError> {
        #[derive(Serialize)]
        struct RequestRef<'a, Req> {
            client_id: u64,
            request_id: u64,
            deadline_unix_ns: u64,
            origin: &'a Origin,
            body: &'a Req,
        }
        let origin = crate::origin::current_origin();
        self.publish_serializable::<RequestRef<'_, Req>>(
            &RequestRef {
                client_id,
                request_id,
                deadline_unix_ns,
                origin: &origin,
                body,
            },
            Req::TYPE,
            Req::SCHEMA_VERSION,
        )
    }
}

/// A request received by a [`Server`], to be answered with [`Server::respond`].
pub struct Incoming<Req> {
    /// The request and its trace context.
    pub envelope: Envelope<Req>,
    /// Who the work belongs to, as the sender stated it (see [`crate::origin`]).
    pub origin: Origin,
    pending: PendingReply,
}

impl<Req: std::fmt::Debug> std::fmt::Debug for Incoming<Req> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Incoming")
            .field("envelope", &self.envelope)
            .finish()
    }
}

impl<Req> Incoming<Req> {
    /// The sender's trace context.
    pub fn trace(&self) -> &TraceContext {
        &self.envelope.trace
    }

    /// Separates the request from the handle needed to answer it.
    pub fn split(self) -> (Envelope<Req>, PendingReply) {
        (self.envelope, self.pending)
    }
}

/// The right (and duty) to answer one request. Dropping it unanswered sends the client a
/// [`FaultKind::Dropped`] fault (when the server next waits for a request) rather than leaving
/// it waiting.
pub struct PendingReply {
    client_id: u64,
    request_id: u64,
    abandoned: Option<tokio::sync::mpsc::UnboundedSender<(u64, u64)>>,
}

impl std::fmt::Debug for PendingReply {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("PendingReply")
            .field("request_id", &self.request_id)
            .finish()
    }
}

impl Drop for PendingReply {
    fn drop(&mut self) {
        if let Some(abandoned) = self.abandoned.take() {
            let _ = abandoned.send((self.client_id, self.request_id));
        }
    }
}

/// Serves one service: receives requests and sends replies.
pub struct Server<Req: Message, Resp: Message> {
    requests: Subscriber<RequestFrame<Req>>,
    reply_publishers: HashMap<u64, (Publisher<ReplyFrame<Resp>>, Instant)>,
    abandoned_tx: tokio::sync::mpsc::UnboundedSender<(u64, u64)>,
    abandoned_rx: tokio::sync::mpsc::UnboundedReceiver<(u64, u64)>,
    service: Service<Req, Resp>,
    bus: Bus,
}

impl<Req: Message, Resp: Message> std::fmt::Debug for Server<Req, Resp> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Server")
            .field("service", &self.service.name)
            .finish()
    }
}

/// One decoded request or one that must be refused.
enum Received<Req> {
    Request(Envelope<RequestFrame<Req>>),
    Malformed {
        routing: Option<(u64, u64)>,
        error: String,
    },
}

impl<Req: Message, Resp: Message> Server<Req, Resp> {
    /// Waits for the next well-formed request. Malformed requests are answered with a
    /// [`FaultKind::BadRequest`] fault and skipped; requests dropped unanswered get a
    /// [`FaultKind::Dropped`] fault.
    pub async fn next(&mut self) -> Result<Incoming<Req>, BusError> {
        let name = self.service.name;
        loop {
            let received = tokio::select! {
                biased;
                Some((client_id, request_id)) = self.abandoned_rx.recv() => {
                    let fault = Fault::new(
                        FaultKind::Dropped,
                        format!("the actor serving '{name}' dropped the request without answering"),
                    );
                    self.send_reply_or_log(client_id, request_id, Reply::Fault(fault));
                    continue;
                }
                received = self.requests.recv_with(decode_request::<Req>) => received?,
            };
            match received {
                Received::Request(envelope) => {
                    // How long the request waited for this server (`<service>/requests`):
                    // the round trip minus this is the handling and the reply's way back.
                    let waited_ns =
                        envelope::unix_now_ns().saturating_sub(envelope.sent_at_unix_ns);
                    crate::metrics::Metrics::global()
                        .bus_latency(self.requests.label(), waited_ns as f64 / 1e9);
                    let frame = envelope.body;
                    if frame.deadline_unix_ns != 0
                        && envelope::unix_now_ns() > frame.deadline_unix_ns
                    {
                        let fault = Fault::new(
                            FaultKind::Expired,
                            format!(
                                "'{name}' got the request after its caller gave up; not executed"
                            ),
                        );
                        self.send_reply_or_log(
                            frame.client_id,
                            frame.request_id,
                            Reply::Fault(fault),
                        );
                        continue;
                    }
                    return Ok(Incoming {
                        envelope: Envelope {
                            msg_type: envelope.msg_type,
                            schema_version: envelope.schema_version,
                            trace: envelope.trace,
                            sent_at_unix_ns: envelope.sent_at_unix_ns,
                            body: frame.body,
                        },
                        origin: frame.origin,
                        pending: PendingReply {
                            client_id: frame.client_id,
                            request_id: frame.request_id,
                            abandoned: Some(self.abandoned_tx.clone()),
                        },
                    });
                }
                Received::Malformed { routing, error } => {
                    tracing::warn!(service = name, %error, "refused a malformed request");
                    if let Some((client_id, request_id)) = routing {
                        let fault = Fault::new(FaultKind::BadRequest, error);
                        self.send_reply_or_log(client_id, request_id, Reply::Fault(fault));
                    }
                }
            }
        }
    }

    /// Answers the request `pending` belongs to with `reply` (or a fault).
    pub fn respond(
        &mut self,
        mut pending: PendingReply,
        reply: Result<Resp, Fault>,
    ) -> Result<(), BusError> {
        pending.abandoned = None;
        let reply = match reply {
            Ok(body) => Reply::Ok(body),
            Err(fault) => Reply::Fault(fault),
        };
        self.send_reply(pending.client_id, pending.request_id, reply)
    }

    /// Sends a reply; a failure concerns this one client only, so it is logged, not fatal.
    fn send_reply_or_log(&mut self, client_id: u64, request_id: u64, reply: Reply<Resp>) {
        if let Err(error) = self.send_reply(client_id, request_id, reply) {
            tracing::warn!(service = self.service.name, %error, "could not send a reply");
        }
    }

    fn send_reply(
        &mut self,
        client_id: u64,
        request_id: u64,
        reply: Reply<Resp>,
    ) -> Result<(), BusError> {
        if !self.reply_publishers.contains_key(&client_id) {
            let publisher: Publisher<ReplyFrame<Resp>> =
                self.bus.publisher_for(self.service.replies(client_id))?;
            if publisher.subscriber_ids().is_empty() {
                // Nobody waits on this reply topic (the client left, or the id was made up).
                return Ok(());
            }
            // A new client: close the reply topics of clients that have left.
            self.reply_publishers
                .retain(|_, (publisher, _)| !publisher.subscriber_ids().is_empty());
            if self.reply_publishers.len() >= MAX_CACHED_REPLY_PUBLISHERS {
                let oldest = self
                    .reply_publishers
                    .iter()
                    .min_by_key(|(_, (_, used))| *used)
                    .map(|(id, _)| *id);
                if let Some(oldest) = oldest {
                    self.reply_publishers.remove(&oldest);
                }
            }
            self.reply_publishers
                .insert(client_id, (publisher, Instant::now()));
        }
        let Some((publisher, used)) = self.reply_publishers.get_mut(&client_id) else {
            return Ok(());
        };
        *used = Instant::now();
        if publisher.subscriber_ids().is_empty() {
            self.reply_publishers.remove(&client_id);
            return Ok(());
        }
        let frame = ReplyFrame { request_id, reply };
        match publisher.publish(&frame) {
            Ok(_) => Ok(()),
            Err(BusError::NotDelivered { .. }) => {
                // The client went away; nobody is waiting for this answer.
                self.reply_publishers.remove(&client_id);
                Ok(())
            }
            Err(error @ BusError::TooLarge { .. }) | Err(error @ BusError::Encode(_)) => {
                let fault = Fault::new(
                    FaultKind::ReplyFailed,
                    format!("'{}' could not send its reply: {error}", self.service.name),
                );
                let frame = ReplyFrame {
                    request_id,
                    reply: Reply::Fault(fault),
                };
                publisher.publish(&frame).map(|_| ())
            }
            Err(other) => Err(other),
        }
    }

    /// Serves requests forever with `handler`, one at a time, in order.
    ///
    /// Each request is handled in its own task inside a tracing span that continues the
    /// sender's trace; if the handler panics, the caller gets a [`FaultKind::ActorFailed`]
    /// fault and the server keeps serving.
    pub async fn serve<F, Fut>(&mut self, mut handler: F) -> Result<(), BusError>
    where
        F: FnMut(Req) -> Fut,
        Fut: Future<Output = Result<Resp, Fault>> + Send + 'static,
    {
        loop {
            let incoming = self.next().await?;
            let origin = incoming.origin.clone();
            let (envelope, pending) = incoming.split();
            let span = tracing::info_span!("bus.handle", service = self.service.name);
            crate::telemetry::set_parent_from(&span, &envelope.trace);
            // The handler's own requests carry the origin of the request it serves.
            let mut task = AbortOnDrop(tokio::spawn(tracing::Instrument::instrument(
                crate::origin::with_origin(origin, handler(envelope.body)),
                span.clone(),
            )));
            let reply = match (&mut task.0).await {
                Ok(reply) => reply,
                Err(join_error) => Err(Fault::new(
                    FaultKind::ActorFailed,
                    format!(
                        "the actor serving '{}' failed while handling the request: {}",
                        self.service.name,
                        panic_message(join_error)
                    ),
                )),
            };
            // The reply carries the handler's span, so the caller's trace shows both sides.
            let _in_span = span.enter();
            if let Err(error) = self.respond(pending, reply) {
                tracing::warn!(service = self.service.name, %error, "could not send a reply");
            }
        }
    }
}

/// Aborts the handler task if `serve` is dropped mid-request (its supervisor restarts it, say),
/// so a request whose caller was told it failed cannot still finish in the background.
struct AbortOnDrop<T>(tokio::task::JoinHandle<T>);

impl<T> Drop for AbortOnDrop<T> {
    fn drop(&mut self) {
        self.0.abort();
    }
}

fn decode_request<Req: Message>(bytes: &[u8]) -> Received<Req> {
    match envelope::decode::<RequestFrame<Req>>(bytes) {
        Ok(envelope) => Received::Request(envelope),
        Err(error) => Received::Malformed {
            routing: rmp_serde::from_slice::<Routing>(bytes)
                .ok()
                .map(|r| (r.body.client_id, r.body.request_id)),
            error: error.to_string(),
        },
    }
}

fn panic_message(error: tokio::task::JoinError) -> String {
    if error.is_cancelled() {
        return "the handler was cancelled".into();
    }
    let payload = error.into_panic();
    if let Some(text) = payload.downcast_ref::<&str>() {
        (*text).to_owned()
    } else if let Some(text) = payload.downcast_ref::<String>() {
        text.clone()
    } else {
        "panic".into()
    }
}

#[cfg(test)]
#[path = "rpc_listener_tests.rs"]
mod listener_tests;
