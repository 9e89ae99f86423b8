//! The agent on the bus: any front end (the CLI, a dashboard, another process) publishes an
//! [`AgentRequest`] on [`AGENT_REQUEST`] and follows the [`AgentEvent`]s on [`AGENT_EVENTS`]
//! tagged with its request id — plan, each tool call and result as they happen, then exactly
//! one terminal event (answer, error or cancelled). An [`AgentCancel`](robotd_protocol::agent::AgentCancel) on [`AGENT_CANCEL`]
//! stops that request: the running LLM call or tool call (the motion stops safely), or the
//! request before it starts if it is still queued.
//!
//! Requests are worked on one at a time, in arrival order, sharing one conversation.
//!
//! ```no_run
//! # async fn demo(bus: robotd_runtime::bus::Bus, agent: robotd_agent::Agent)
//! # -> Result<(), Box<dyn std::error::Error>> {
//! use robotd_agent::actor::{self, AGENT_EVENTS, AGENT_REQUEST};
//! use robotd_protocol::agent::AgentRequest;
//!
//! let _actor = actor::spawn(&bus, agent)?;
//! let mut events = bus.subscriber(&AGENT_EVENTS)?;
//! bus.publisher(&AGENT_REQUEST)?.publish(&AgentRequest {
//!     request_id: "r1".into(),
//!     text: "Sort the objects by size".into(),
//! })?;
//! loop {
//!     let event = events.recv().await?.body;
//!     println!("{:?}", event.event);
//!     if event.event.is_terminal() { break; }
//! }
//! # Ok(()) }
//! ```

use crate::agent::Agent;
use robotd_protocol::agent::{AgentEvent, AgentEventKind, AgentRequest};
use robotd_protocol::safety::{Origin, OriginKind};
use robotd_protocol::validate::Validate;
use robotd_runtime::bus::{Bus, BusError};
use robotd_runtime::origin::with_origin;
use std::collections::HashMap;
use std::sync::{Arc, Mutex};
use tokio::sync::mpsc;
use tokio_util::sync::CancellationToken;

pub use robotd_topics::{AGENT_CANCEL, AGENT_EVENTS, AGENT_REQUEST};

/// Longest text an event carries (tool results can be long; a picture event is bounded by
/// `MAX_PICTURE_BYTES`, and the bus slice is 256 KiB).
const MAX_EVENT_TEXT: usize = 16 * 1024;

/// The running actor; dropping it stops it.
pub struct AgentActor {
    tasks: Vec<tokio::task::JoinHandle<()>>,
}

impl Drop for AgentActor {
    fn drop(&mut self) {
        for task in &self.tasks {
            task.abort();
        }
    }
}

fn clip(text: String) -> String {
    if text.len() <= MAX_EVENT_TEXT {
        return text;
    }
    let mut end = MAX_EVENT_TEXT;
    while !text.is_char_boundary(end) {
        end -= 1;
    }
    format!("{}… (shortened)", &text[..end])
}

fn clipped(event: AgentEventKind) -> AgentEventKind {
    match event {
        AgentEventKind::Plan { text } => AgentEventKind::Plan { text: clip(text) },
        AgentEventKind::ToolCall {
            call_id,
            name,
            arguments_json,
        } => AgentEventKind::ToolCall {
            call_id,
            name,
            arguments_json: clip(arguments_json),
        },
        AgentEventKind::ToolResult {
            call_id,
            name,
            text,
            ok,
        } => AgentEventKind::ToolResult {
            call_id,
            name,
            text: clip(text),
            ok,
        },
        // Bounded where it is made (`MAX_PICTURE_BYTES`); the topic takes 256 KiB.
        picture @ AgentEventKind::Picture { .. } => picture,
        AgentEventKind::Answer { text } => AgentEventKind::Answer { text: clip(text) },
        AgentEventKind::Error { message } => AgentEventKind::Error {
            message: clip(message),
        },
        AgentEventKind::Cancelled => AgentEventKind::Cancelled,
    }
}

/// Starts serving `agent` on `bus` (must be called inside a multi-thread tokio runtime).
pub fn spawn(bus: &Bus, mut agent: Agent) -> Result<AgentActor, BusError> {
    let mut requests = bus.subscriber(&AGENT_REQUEST)?;
    let mut cancels = bus.subscriber(&AGENT_CANCEL)?;
    let publisher = bus.publisher(&AGENT_EVENTS)?;
    let tokens: Arc<Mutex<HashMap<String, CancellationToken>>> = Arc::default();
    let (queue_tx, mut queue_rx) = mpsc::unbounded_channel::<(AgentRequest, CancellationToken)>();
    let (event_tx, mut event_rx) = mpsc::unbounded_channel::<AgentEvent>();

    let intake_tokens = tokens.clone();
    let intake = tokio::spawn(async move {
        loop {
            tokio::select! {
                request = requests.recv() => match request {
                    Ok(envelope) => {
                        let request = envelope.body;
                        let token = CancellationToken::new();
                        intake_tokens
                            .lock()
                            .unwrap_or_else(|e| e.into_inner())
                            .insert(request.request_id.clone(), token.clone());
                        if queue_tx.send((request, token)).is_err() {
                            return;
                        }
                    }
                    Err(error) => tracing::warn!(%error, "unreadable agent request skipped"),
                },
                cancel = cancels.recv() => match cancel {
                    Ok(envelope) => {
                        let id = envelope.body.request_id;
                        let tokens = intake_tokens.lock().unwrap_or_else(|e| e.into_inner());
                        match tokens.get(&id) {
                            Some(token) => {
                                tracing::info!(request_id = %id, "agent request cancelled");
                                token.cancel();
                            }
                            None => tracing::debug!(request_id = %id, "cancel for an unknown or finished request"),
                        }
                    }
                    Err(error) => tracing::warn!(%error, "unreadable agent cancel skipped"),
                },
            }
        }
    });

    let worker = tokio::spawn(async move {
        while let Some((request, token)) = queue_rx.recv().await {
            let id = request.request_id.clone();
            let mut seq = 0u32;
            let events = event_tx.clone();
            let mut emit = move |event: AgentEventKind| {
                let _ = events.send(AgentEvent {
                    request_id: id.clone(),
                    seq,
                    event: clipped(event),
                });
                seq += 1;
            };
            match request.validate() {
                Err(error) => emit(AgentEventKind::Error {
                    message: format!("invalid request: {error}"),
                }),
                Ok(()) if token.is_cancelled() => emit(AgentEventKind::Cancelled),
                Ok(()) => {
                    // Every motion of this request carries its id to the safety policy.
                    let origin = Origin::new(OriginKind::Agent).request(request.request_id.clone());
                    with_origin(origin, agent.run(&request.text, token, emit)).await;
                }
            }
            tokens
                .lock()
                .unwrap_or_else(|e| e.into_inner())
                .remove(&request.request_id);
        }
    });

    let publish = tokio::spawn(async move {
        while let Some(event) = event_rx.recv().await {
            // A back-pressure publish may wait for a slow reader; keep it off the workers.
            let result = tokio::task::block_in_place(|| publisher.publish(&event));
            if let Err(error) = result {
                tracing::warn!(%error, request_id = %event.request_id, "publishing an agent event failed");
            }
        }
    });

    Ok(AgentActor {
        tasks: vec![intake, worker, publish],
    })
}
