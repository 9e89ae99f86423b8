//! Legacy HTTP+SSE (MCP protocol 2024-11-05), which rmcp 3 ships no server for.
//!
//! `GET /sse` opens an event stream whose first event, `endpoint`, names
//! `/messages/?session_id=<id>`; the client POSTs each JSON-RPC message there (answered
//! `202 Accepted`) and reads the replies as `message` events on the stream. Each stream is one
//! rmcp session fed through a pair of channels, behind [`crate::gate`]. A `tools/call` of an
//! initialized session skips rmcp's service loop ([`super::direct_call`]): it runs on a task
//! of its own, which writes its progress and answer onto the session's stream. Closing the
//! stream ends the session and cancels its calls (a motion in flight stops); a keep-alive
//! comment every second makes a vanished client noticed within about two seconds. Opening a
//! stream takes a session place ([`super::places`]; 503 with `Retry-After` when there is
//! none); robotd ends the stream when the session never made a call within
//! `mcp.unused_session_timeout_s`, or when its client opened another at its share. A post
//! whose JSON-RPC envelope is wrong is answered 400 with a JSON-RPC error saying what is wrong
//! ([`super::envelope`]).
//!
//! Every queue of a session is bounded, so a client that stops reading its stream holds a
//! bounded amount of memory and then gets 503: the stream's queue (64 answers), the direct
//! calls waiting for room there (64), the requests rmcp holds unanswered (64,
//! [`super::sse_transport`]) and the posted messages waiting for rmcp (64).

use super::direct_call::{self, cancel_named, DirectCall};
use super::envelope::BadMessage;
use super::places::{SessionPlaces, Transport};
use super::sse_transport::{queue, SseTransport};
use crate::gate::gated;
use crate::owner::SessionOwner;
use crate::service::McpService;
use crate::sessions::CallScopes;
use axum::body::Bytes;
use axum::extract::{ConnectInfo, Query, Request, State};
use axum::http::{header, HeaderMap, StatusCode};
use axum::response::sse::{Event, KeepAlive, Sse};
use axum::response::{IntoResponse, Response};
use axum::Extension;
use futures::channel::mpsc;
use futures::{Stream, StreamExt};
use rmcp::model::{ClientJsonRpcMessage, ServerJsonRpcMessage};
use rmcp::ServiceExt;
use std::collections::HashMap;
use std::net::SocketAddr;
use std::pin::Pin;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::task::{Context, Poll};
use std::time::Duration;
use tokio_util::sync::CancellationToken;

/// The open SSE sessions by id.
pub(super) type SessionMap = Arc<Mutex<HashMap<String, SseSession>>>;

/// One sender of a bounded channel, shared by the tasks that send into it.
///
/// futures' bounded channel gives every clone of a sender a slot of its own beyond the
/// channel's capacity, so a clone per message (per POST, per call) would make it unbounded:
/// a client that stops reading its stream could pile up messages without end. Shared, the
/// sender keeps the bound, and a send waits for room.
pub(super) type SharedSender<T> = Arc<tokio::sync::Mutex<mpsc::Sender<T>>>;

/// One open SSE session.
#[derive(Clone)]
pub(super) struct SseSession {
    /// Where its posted messages go (rmcp's session, behind the gate).
    to_server: SharedSender<ClientJsonRpcMessage>,
    /// Its event stream, for the answers of direct calls (rmcp holds a sender of its own).
    to_client: SharedSender<ServerJsonRpcMessage>,
    /// Set by its gate at `notifications/initialized`.
    initialized: Arc<AtomicBool>,
    /// Its direct calls not yet written onto its stream.
    in_flight: Arc<AtomicUsize>,
    /// The service naming this session.
    service: McpService,
}

/// What the SSE routes share.
#[derive(Clone)]
pub(super) struct SseState {
    pub(super) service: McpService,
    pub(super) sessions: SessionMap,
    pub(super) shutdown: CancellationToken,
    pub(super) places: Arc<SessionPlaces>,
    /// Run tool calls of initialized sessions without rmcp's service loop.
    pub(super) direct: bool,
}

/// The event stream of one SSE session; dropping it (the client went away) ends the session.
struct SessionStream {
    id: String,
    sessions: SessionMap,
    scopes: Arc<CallScopes>,
    places: Arc<SessionPlaces>,
    inner: Pin<Box<dyn Stream<Item = Result<Event, std::convert::Infallible>> + Send>>,
}

impl Stream for SessionStream {
    type Item = Result<Event, std::convert::Infallible>;
    fn poll_next(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<Option<Self::Item>> {
        self.inner.as_mut().poll_next(cx)
    }
}

impl Drop for SessionStream {
    fn drop(&mut self) {
        // The client went away: whatever its calls started must stop.
        self.scopes.close_session(&self.id);
        self.places.release(&self.id);
        self.sessions
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .remove(&self.id);
        tracing::debug!(session = %self.id, "SSE session closed");
    }
}

fn new_session_id() -> String {
    use rand::RngCore;
    let mut bytes = [0u8; 16];
    rand::rng().fill_bytes(&mut bytes);
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// `GET /sse`: opens a session and streams its messages.
pub(super) async fn open_sse(State(state): State<SseState>, request: Request) -> Response {
    let owner = SessionOwner::of(
        request.headers(),
        request.uri().query(),
        request.extensions(),
    );
    let ticket = match state.places.admit(owner) {
        Ok(ticket) => ticket,
        Err(refusal) => return super::refusal_response(&refusal),
    };
    let id = new_session_id();
    state.service.scopes().bind_owner(&id, owner);
    ticket.open(&id, Transport::Sse);
    // Ends the stream when the session's place expires or its client gives it up.
    let closed = state.places.closed(&id);
    let (to_server, from_client) = mpsc::channel::<ClientJsonRpcMessage>(64);
    let (to_client, from_server) = mpsc::channel::<ServerJsonRpcMessage>(64);
    let to_client: SharedSender<_> = Arc::new(tokio::sync::Mutex::new(to_client));
    let service = state.service.for_sse_session(&id);
    let gate = gated(SseTransport::new(from_client, to_client.clone()));
    let entry = SseSession {
        to_server: Arc::new(tokio::sync::Mutex::new(to_server)),
        to_client,
        initialized: gate.initialized_flag(),
        in_flight: Arc::default(),
        service: service.clone(),
    };
    state
        .sessions
        .lock()
        .unwrap_or_else(|e| e.into_inner())
        .insert(id.clone(), entry);
    let session = id.clone();
    let shutdown = state.shutdown.clone();
    tokio::spawn(async move {
        match service.serve_with_ct(gate, shutdown.child_token()).await {
            Ok(running) => {
                if let Err(error) = running.waiting().await {
                    tracing::debug!(%session, %error, "SSE session ended");
                }
            }
            Err(error) => tracing::info!(%session, %error, "SSE session did not initialise"),
        }
    });
    tracing::debug!(session = %id, "SSE session opened");
    let endpoint = Event::default()
        .event("endpoint")
        .data(format!("/messages/?session_id={id}"));
    let messages = from_server.map(|message| {
        let data = serde_json::to_string(&message)
            .unwrap_or_else(|e| format!("{{\"error\":\"unserialisable message: {e}\"}}"));
        Ok(Event::default().event("message").data(data))
    });
    let events = futures::stream::once(async move { Ok(endpoint) }).chain(messages);
    let stream = SessionStream {
        id,
        sessions: state.sessions.clone(),
        scopes: state.service.scopes(),
        places: state.places.clone(),
        inner: Box::pin(events.take_until(closed)),
    };
    Sse::new(stream)
        // A comment every second: the server only learns that a client went away when a
        // write fails, and the calls of a client that went away must stop soon.
        .keep_alive(KeepAlive::new().interval(Duration::from_secs(1)))
        .into_response()
}

#[derive(serde::Deserialize)]
pub(super) struct SessionQuery {
    pub(super) session_id: Option<String>,
}

/// `POST /messages/?session_id=…`: one client message into its session.
pub(super) async fn post_message(
    State(state): State<SseState>,
    Query(query): Query<SessionQuery>,
    uri: axum::http::Uri,
    connection: Option<Extension<ConnectInfo<SocketAddr>>>,
    headers: HeaderMap,
    body: Bytes,
) -> Response {
    let Some(id) = query.session_id else {
        return (StatusCode::BAD_REQUEST, "session_id is required").into_response();
    };
    let mut extensions = axum::http::Extensions::new();
    if let Some(Extension(info)) = connection {
        extensions.insert(info);
    }
    if !state
        .service
        .scopes()
        .owned_by(&id, &SessionOwner::of(&headers, uri.query(), &extensions))
    {
        tracing::warn!(session = %id, "post into another client's SSE session refused");
        return (StatusCode::NOT_FOUND, "Could not find session").into_response();
    }
    let is_json = headers
        .get(header::CONTENT_TYPE)
        .and_then(|v| v.to_str().ok())
        .is_none_or(|v| v.starts_with("application/json"));
    if !is_json {
        return (
            StatusCode::UNSUPPORTED_MEDIA_TYPE,
            "Content-Type must be application/json",
        )
            .into_response();
    }
    let session = state
        .sessions
        .lock()
        .unwrap_or_else(|e| e.into_inner())
        .get(&id)
        .cloned();
    let Some(session) = session else {
        return (StatusCode::NOT_FOUND, "Could not find session").into_response();
    };
    let message: ClientJsonRpcMessage = match serde_json::from_slice(&body) {
        Ok(m) => m,
        Err(error) => {
            return BadMessage::of(&body, &error, StatusCode::BAD_REQUEST).into_response()
        }
    };
    state
        .places
        .touch(&id, super::streamable::is_call(&message));
    let scopes = state.service.scopes();
    cancel_named(&scopes, &id, &message);
    // Past MAX_DIRECT_IN_FLIGHT (a client that stops reading its stream), calls take rmcp's
    // queue: rmcp takes at most `MAX_UNANSWERED` requests of the session ([`SseTransport`]),
    // so the queue fills and a post is answered 503.
    let room = session.in_flight.load(Ordering::Acquire) < MAX_DIRECT_IN_FLIGHT;
    if state.direct && room && session.initialized.load(Ordering::Acquire) {
        if let Some(call) = DirectCall::in_message(message.clone()) {
            session.in_flight.fetch_add(1, Ordering::AcqRel);
            tokio::spawn(async move {
                let SseSession {
                    service,
                    to_client,
                    in_flight,
                    ..
                } = session;
                direct_call::run_onto_stream(&service, &scopes, &id, call, to_client).await;
                in_flight.fetch_sub(1, Ordering::AcqRel);
            });
            return (StatusCode::ACCEPTED, "Accepted").into_response();
        }
    }
    // Waits for room, then queues: a POST refused after the wait has queued nothing.
    let queued = async { queue(&mut *session.to_server.lock().await, message).await };
    match tokio::time::timeout(POST_QUEUE_WAIT, queued).await {
        Ok(Ok(())) => (StatusCode::ACCEPTED, "Accepted").into_response(),
        Ok(Err(_)) => (StatusCode::NOT_FOUND, "Could not find session").into_response(),
        Err(_) => {
            tracing::warn!(session = %id, "SSE session's queue stayed full: POST refused");
            (
                StatusCode::SERVICE_UNAVAILABLE,
                "the session's queue is full: its client is not reading the SSE stream",
            )
                .into_response()
        }
    }
}

/// Most direct calls of one session whose answers are not yet on its stream's queue (each
/// waits for room there: the stream's queue is bounded, [`SharedSender`]).
const MAX_DIRECT_IN_FLIGHT: usize = 64;

/// Longest a POST waits for room in its session's queue (the client reads its answers from
/// the SSE stream; one that stops reading fills the queue) before it is answered 503.
const POST_QUEUE_WAIT: std::time::Duration = std::time::Duration::from_secs(10);
