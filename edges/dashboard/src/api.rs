//! The dashboard's HTTP/JSON API: what the page uses, and what scripts can use too.
//!
//! | route | answers |
//! |---|---|
//! | `GET /api/status` | health (actors, restarts, e-stop, Redis edge), the arm, camera figures, recent overlays and restarts, the tool calls of the last 5 minutes with their durations, whether the agent is available (and why not), the workspaces, the geofence, the largest free space |
//! | `GET /api/objects` | `{"objects": [...]}`: the workspace model's tracked objects (id, label, position, size, …) |
//! | `GET /api/rates` | `{"interval_s": 1, "samples": [...]}`: the last 5 minutes of page frame rate, detections per second and actor restarts, one sample a second (`at_unix_s`, `page_fps`, `detections_per_s`, `restarts`) |
//! | `GET /api/camera.jpg` | the newest annotated camera frame; `X-Frame-Id`, `X-Frame-Timestamp-Ns` headers. When nobody watched, it waits (up to [`FIRST_FRAME_WAIT`]) for a frame to be encoded; 503 when none comes |
//! | `GET /api/camera.mjpg` | the same as an MJPEG stream (`multipart/x-mixed-replace`) an `<img>` shows; a slow viewer skips frames |
//! | `GET /api/events` | Server-Sent Events: `status` (the snapshot, twice a second), `agent`, `overlay`, `restart` as they happen |
//! | `POST /api/chat` | `{"text": "…"}` → Server-Sent Events of that request: `request` (`{"request_id"}`) first, then its `agent` events (plan, tool calls and results, answer), closed after the answer, an error or a cancellation; 503 with the reason when no agent runs |
//! | `POST /api/chat/{id}/cancel` | cancels it between tool calls (a motion under way finishes) |
//! | `GET /api/chat/pictures/{id}` | a picture the agent looked at (the `url` of a `picture` event), the exact file the tool returned; 404 once it is not among the newest [`crate::pictures::KEPT`] |
//!
//! The e-stop and approvals are the safety API's (`/estop`, `/estop/release`, `/approvals`),
//! on the same port behind the same guard.

use crate::live::{Live, LiveEvent};
use axum::body::{Body, Bytes};
use axum::extract::{Path, State};
use axum::http::{header, StatusCode};
use axum::response::sse::{Event, KeepAlive, Sse};
use axum::response::{IntoResponse, Response};
use axum::routing::{get, post};
use axum::{Json, Router};
use futures::{Stream, StreamExt};
use robotd_protocol::agent::{AgentCancel, AgentRequest};
use robotd_runtime::bus::Publisher;
use serde_json::{json, Value};
use std::convert::Infallible;
use std::sync::{Arc, Mutex};
use std::time::Duration;
use tokio::sync::broadcast;

/// Produces the health report (the same as `/health`).
pub type HealthReport = Arc<dyn Fn() -> Value + Send + Sync>;

/// The agent, as the page reaches it: its bus publishers, or why there is none.
pub enum AgentLink {
    /// The agent runs: requests and cancels go on the bus.
    Available {
        /// `agent/request`.
        requests: Box<Mutex<Publisher<AgentRequest>>>,
        /// `agent/cancel`.
        cancels: Box<Mutex<Publisher<AgentCancel>>>,
    },
    /// No agent runs, for this reason (no provider configured, `[agent] serve = false`, …).
    Off(String),
}

/// What the API serves from.
#[derive(Clone)]
pub struct DashboardApi {
    /// The live state.
    pub live: Arc<Live>,
    /// The health report.
    pub health: HealthReport,
    /// The workspaces (ids, corners, observation poses) as JSON.
    pub workspaces: Value,
    /// The motion policy's geofence: `{"min": [x, y, z], "max": [x, y, z], "keep_out":
    /// [{"name", "min", "max"}]}`, metres.
    pub geofence: Value,
    /// The agent.
    pub agent: Arc<AgentLink>,
    /// The tool calls of the last minutes (`[{"tool", "ms", "ok", "at_unix_s"}]`).
    pub tool_calls: HealthReport,
}

/// The API's routes.
pub fn routes(api: DashboardApi) -> Router {
    Router::new()
        .route("/api/status", get(status))
        .route("/api/objects", get(objects))
        .route("/api/rates", get(rates))
        .route("/api/camera.jpg", get(camera_jpeg))
        .route("/api/camera.mjpg", get(camera_mjpeg))
        .route("/api/events", get(events))
        .route("/api/chat", post(chat))
        .route("/api/chat/{id}/cancel", post(cancel))
        .route("/api/chat/pictures/{id}", get(picture))
        .with_state(api)
}

fn refuse(status: StatusCode, message: impl Into<String>) -> Response {
    (status, Json(json!({"error": message.into()}))).into_response()
}

fn status_json(api: &DashboardApi) -> Value {
    let snapshot = api.live.snapshot();
    let agent = match api.agent.as_ref() {
        AgentLink::Available { .. } => json!({"available": true}),
        AgentLink::Off(reason) => json!({"available": false, "reason": reason}),
    };
    json!({
        "health": (api.health)(),
        "arm": snapshot.arm,
        "camera": snapshot.camera,
        "overlays": snapshot.overlays,
        "restarts": snapshot.restarts,
        "objects": snapshot.objects,
        "agent": agent,
        "tool_calls": (api.tool_calls)(),
        "workspaces": api.workspaces,
        "geofence": api.geofence,
        "free_space": snapshot.free_space,
    })
}

async fn status(State(api): State<DashboardApi>) -> Json<Value> {
    Json(status_json(&api))
}

async fn objects(State(api): State<DashboardApi>) -> Json<Value> {
    Json(json!({"objects": api.live.snapshot().objects}))
}

async fn rates(State(api): State<DashboardApi>) -> Json<Value> {
    Json(json!({"interval_s": 1.0, "samples": api.live.rates()}))
}

/// How long `/api/camera.jpg` waits for a frame when none is encoded (nobody was watching,
/// or the camera has not sent one yet).
pub const FIRST_FRAME_WAIT: std::time::Duration = std::time::Duration::from_secs(3);

async fn camera_jpeg(State(api): State<DashboardApi>) -> Response {
    api.live.ask_for_frames();
    // Holding a receiver also keeps the live view encoding while this request waits.
    let mut frames = api.live.camera();
    let mut frame = frames.borrow_and_update().clone();
    if frame.is_none() {
        let next = async {
            while frames.changed().await.is_ok() {
                if let Some(frame) = frames.borrow_and_update().clone() {
                    return Some(frame);
                }
            }
            None
        };
        frame = tokio::time::timeout(FIRST_FRAME_WAIT, next)
            .await
            .ok()
            .flatten();
    }
    match frame {
        None => refuse(
            StatusCode::SERVICE_UNAVAILABLE,
            format!(
                "no camera frame came within {} s (is the camera actor running?)",
                FIRST_FRAME_WAIT.as_secs()
            ),
        ),
        Some(frame) => (
            [
                (header::CONTENT_TYPE, "image/jpeg".to_owned()),
                (header::CACHE_CONTROL, "no-store".to_owned()),
                (
                    header::HeaderName::from_static("x-frame-id"),
                    frame.frame_id.to_string(),
                ),
                (
                    header::HeaderName::from_static("x-frame-timestamp-ns"),
                    frame.timestamp_unix_ns.to_string(),
                ),
            ],
            frame.jpeg,
        )
            .into_response(),
    }
}

const BOUNDARY: &str = "robotdframe";

async fn camera_mjpeg(State(api): State<DashboardApi>) -> Response {
    let frames = api.live.camera();
    // Each viewer waits for the next frame and takes only the newest: a viewer that reads
    // slowly skips frames, and nothing queues for it.
    let parts = futures::stream::unfold(frames, |mut frames| async move {
        loop {
            frames.changed().await.ok()?;
            let frame = frames.borrow_and_update().clone();
            if let Some(frame) = frame {
                let head = format!(
                    "--{BOUNDARY}\r\nContent-Type: image/jpeg\r\nContent-Length: {}\r\nX-Frame-Id: {}\r\nX-Frame-Timestamp-Ns: {}\r\n\r\n",
                    frame.jpeg.len(),
                    frame.frame_id,
                    frame.timestamp_unix_ns
                );
                let mut part = Vec::with_capacity(head.len() + frame.jpeg.len() + 2);
                part.extend_from_slice(head.as_bytes());
                part.extend_from_slice(&frame.jpeg);
                part.extend_from_slice(b"\r\n");
                return Some((Ok::<_, Infallible>(Bytes::from(part)), frames));
            }
        }
    });
    (
        [
            (
                header::CONTENT_TYPE,
                format!("multipart/x-mixed-replace; boundary={BOUNDARY}"),
            ),
            (header::CACHE_CONTROL, "no-store".to_owned()),
        ],
        Body::from_stream(parts),
    )
        .into_response()
}

async fn picture(State(api): State<DashboardApi>, Path(id): Path<String>) -> Response {
    crate::pictures::response(api.live.pictures(), &id)
}

/// `event` as an SSE event named by its type.
fn sse_event(event: &LiveEvent) -> Event {
    let name = match event {
        LiveEvent::Agent(_) | LiveEvent::Picture(_) => "agent",
        LiveEvent::Overlay(_) => "overlay",
        LiveEvent::Restart(_) => "restart",
    };
    let data = serde_json::to_string(event).unwrap_or_else(|_| "{}".to_owned());
    Event::default().event(name).data(data)
}

/// Live events from `events`, skipping what a slow reader missed.
fn live_events(
    events: broadcast::Receiver<LiveEvent>,
) -> impl Stream<Item = LiveEvent> + Send + 'static {
    futures::stream::unfold(events, |mut events| async move {
        loop {
            match events.recv().await {
                Ok(event) => return Some((event, events)),
                Err(broadcast::error::RecvError::Lagged(missed)) => {
                    tracing::debug!(missed, "dashboard: a viewer missed events");
                }
                Err(broadcast::error::RecvError::Closed) => return None,
            }
        }
    })
}

async fn events(State(api): State<DashboardApi>) -> impl IntoResponse {
    let live = live_events(api.live.events()).map(|e| Ok::<_, Infallible>(sse_event(&e)));
    let ticks = futures::stream::unfold(
        tokio::time::interval(Duration::from_millis(500)),
        move |mut every| {
            let api = api.clone();
            async move {
                every.tick().await;
                let data = status_json(&api).to_string();
                Some((
                    Ok::<_, Infallible>(Event::default().event("status").data(data)),
                    every,
                ))
            }
        },
    );
    Sse::new(futures::stream::select(ticks, live)).keep_alive(KeepAlive::default())
}

fn new_request_id() -> String {
    use rand::RngCore;
    let mut bytes = [0u8; 8];
    rand::rng().fill_bytes(&mut bytes);
    let hex: String = bytes.iter().map(|b| format!("{b:02x}")).collect();
    format!("web-{hex}")
}

/// Longest chat text accepted, characters.
const MAX_CHAT_CHARS: usize = 4000;

async fn chat(State(api): State<DashboardApi>, body: Bytes) -> Response {
    let text = match serde_json::from_slice::<Value>(&body) {
        Ok(value) => value.get("text").and_then(Value::as_str).map(str::to_owned),
        Err(error) => {
            return refuse(
                StatusCode::BAD_REQUEST,
                format!("the body must be JSON {{\"text\": \"…\"}}: {error}"),
            )
        }
    };
    let Some(text) = text.filter(|t| !t.trim().is_empty()) else {
        return refuse(
            StatusCode::BAD_REQUEST,
            "\"text\" must be a non-empty string",
        );
    };
    if text.chars().count() > MAX_CHAT_CHARS {
        return refuse(
            StatusCode::PAYLOAD_TOO_LARGE,
            format!("\"text\" is limited to {MAX_CHAT_CHARS} characters"),
        );
    }
    let requests = match api.agent.as_ref() {
        AgentLink::Available { requests, .. } => requests,
        AgentLink::Off(reason) => {
            return refuse(
                StatusCode::SERVICE_UNAVAILABLE,
                format!("no LLM agent is running: {reason}"),
            )
        }
    };
    let request_id = new_request_id();
    // Listen before asking, so that no event of this request can be missed.
    let events = api.live.events();
    let request = AgentRequest {
        request_id: request_id.clone(),
        text,
    };
    let sent = requests
        .lock()
        .unwrap_or_else(|e| e.into_inner())
        .publish(&request);
    match sent {
        Ok(0) => refuse(
            StatusCode::SERVICE_UNAVAILABLE,
            "the agent is not listening on the bus (is it restarting?)",
        ),
        Ok(_) => request_events(events, request_id).into_response(),
        Err(error) => refuse(
            StatusCode::SERVICE_UNAVAILABLE,
            format!("the request could not be sent to the agent: {error}"),
        ),
    }
}

/// The SSE answer of a chat request: its id, then its agent events up to the last one.
fn request_events(
    events: broadcast::Receiver<LiveEvent>,
    id: String,
) -> Sse<impl Stream<Item = Result<Event, Infallible>> + Send + 'static> {
    let first = Event::default()
        .event("request")
        .data(json!({"request_id": id}).to_string());
    let mine = Box::pin(live_events(events).filter_map(move |event| {
        let mine = event.request_id() == Some(id.as_str());
        futures::future::ready(mine.then_some(event))
    }));
    // Up to and including the request's terminal event; the stream (and the response) ends
    // right after it, without waiting for anything else.
    let agent = futures::stream::unfold((mine, false), |(mut mine, ended)| async move {
        if ended {
            return None;
        }
        let event = mine.next().await?;
        let terminal = event.is_terminal();
        Some((Ok::<_, Infallible>(sse_event(&event)), (mine, terminal)))
    });
    let stream = futures::stream::once(async move { Ok(first) }).chain(agent);
    Sse::new(stream).keep_alive(KeepAlive::default())
}

async fn cancel(State(api): State<DashboardApi>, Path(id): Path<String>) -> Response {
    let AgentLink::Available { cancels, .. } = api.agent.as_ref() else {
        return refuse(StatusCode::SERVICE_UNAVAILABLE, "no LLM agent is running");
    };
    let sent = cancels
        .lock()
        .unwrap_or_else(|e| e.into_inner())
        .publish(&AgentCancel {
            request_id: id.clone(),
        });
    match sent {
        Ok(_) => Json(json!({"cancelled": id})).into_response(),
        Err(error) => refuse(
            StatusCode::SERVICE_UNAVAILABLE,
            format!("the cancel could not be sent: {error}"),
        ),
    }
}
