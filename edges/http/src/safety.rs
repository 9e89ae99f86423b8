//! The safety API on the HTTP port: the emergency stop and the approval queue.
//!
//! | route | does |
//! |---|---|
//! | `GET /estop` | `{"engaged": bool, "reason": …}` |
//! | `POST /estop` | engages the e-stop whatever the body (optional: `{"reason": "…"}`; a body that is not that is ignored and the reply's `notes` say what was wrong); the arm halts within one control tick |
//! | `POST /estop/release` | releases it; the body must be `{"confirm": "release"}` (a deliberate act, never a side effect), optionally with `"by"` |
//! | `GET /approvals` | motions waiting for a human's yes, oldest first |
//! | `POST /approvals/{id}` | `{"approve": true\|false, "by": "name"}` answers one |
//!
//! Engaging goes through the bus topic `safety/estop`, like every other entry point (MCP
//! tools, `robotd estop`, bus clients); releasing is a request to the safety policy's own
//! service `safety/release` (with origin `http`), like the MCP tool's and the CLI's, so all of
//! them act the same way. The
//! routes sit behind the same guard as the MCP edge (`Host` and `Origin` checks, and the
//! bearer token whenever one is configured, which it must be off loopback): a request the
//! guard refuses engages nothing. Past the guard, engaging never fails on the request's
//! form; only a bus with no arm listening makes it fail (503).

use axum::body::Bytes;
use axum::extract::{Path, State};
use axum::http::StatusCode;
use axum::response::{IntoResponse, Response};
use axum::routing::{get, post};
use axum::{Json, Router};
use robotd_protocol::health::{EStopRelease, EStopState, EmergencyStop};
use robotd_protocol::safety::{printable, Origin, OriginKind};
use robotd_runtime::bus::{BusError, Client, FaultKind, Publisher};
use robotd_safety::Safety;
use serde::Deserialize;
use std::sync::{Arc, Mutex};

/// What the safety routes need.
#[derive(Clone)]
pub struct SafetyApi {
    /// The motion policy (e-stop state, approvals).
    pub safety: Safety,
    /// `safety/estop` publisher.
    pub estop: Arc<Mutex<Publisher<EmergencyStop>>>,
    /// `safety/release` client: the policy's own release service.
    pub release: Arc<Client<EStopRelease, EStopState>>,
}

/// How long the policy may take to answer a release.
const RELEASE_TIMEOUT: std::time::Duration = std::time::Duration::from_secs(5);

/// The routes above, over `api`.
pub fn router(api: SafetyApi) -> Router {
    Router::new()
        .route("/estop", get(estop_state).post(engage))
        .route("/estop/release", post(release))
        .route("/approvals", get(approvals))
        .route("/approvals/{id}", post(answer))
        .with_state(api)
}

/// A refusal: the status and a message a user can act on, as `{"error": …}`.
struct ApiError(StatusCode, String);

impl IntoResponse for ApiError {
    fn into_response(self) -> Response {
        (self.0, Json(serde_json::json!({"error": self.1}))).into_response()
    }
}

fn error(status: StatusCode, message: impl Into<String>) -> ApiError {
    ApiError(status, message.into())
}

/// Reads an optional JSON body of type `T` (empty = `T::default()`).
fn body<T: for<'de> Deserialize<'de> + Default>(bytes: &Bytes) -> Result<T, ApiError> {
    if bytes.iter().all(u8::is_ascii_whitespace) {
        return Ok(T::default());
    }
    serde_json::from_slice(bytes).map_err(|e| {
        error(
            StatusCode::BAD_REQUEST,
            format!("the body is not the expected JSON: {e}"),
        )
    })
}

fn state(api: &SafetyApi) -> serde_json::Value {
    let reason = api.safety.estop();
    serde_json::json!({"engaged": reason.is_some(), "reason": reason})
}

async fn estop_state(State(api): State<SafetyApi>) -> Response {
    Json(state(&api)).into_response()
}

/// At most this many characters of a bad body or value are quoted back.
const QUOTE_MAX: usize = 60;

fn quote(text: &str) -> String {
    if text.chars().count() <= QUOTE_MAX {
        printable(text, QUOTE_MAX)
    } else {
        format!("{}…", printable(text, QUOTE_MAX))
    }
}

/// The reason an engage body gives, and what was wrong with the body (ignored). Never fails:
/// a request to stop is not refused for its form.
fn engage_body(bytes: &Bytes) -> (Option<String>, Vec<String>) {
    if bytes.iter().all(u8::is_ascii_whitespace) {
        return (None, Vec::new());
    }
    let value = match serde_json::from_slice::<serde_json::Value>(bytes) {
        Ok(value) => value,
        Err(e) => {
            return (
                None,
                vec![format!(
                    "the body is not JSON ({e}): {}",
                    quote(&String::from_utf8_lossy(bytes))
                )],
            )
        }
    };
    let serde_json::Value::Object(fields) = value else {
        return (
            None,
            vec![format!(
                "the body must be a JSON object such as {{\"reason\": \"…\"}}, got {}",
                quote(&value.to_string())
            )],
        );
    };
    let mut notes = Vec::new();
    let mut reason = None;
    for (name, value) in &fields {
        match (name.as_str(), value) {
            ("reason", serde_json::Value::String(text)) => reason = Some(text.clone()),
            ("reason", serde_json::Value::Null) => {}
            ("reason", other) => notes.push(format!(
                "field 'reason' must be a string, got {}",
                quote(&other.to_string())
            )),
            (other, _) => notes.push(format!("unknown field '{}'", quote(other))),
        }
    }
    (reason, notes)
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct ReleaseBody {
    confirm: Option<String>,
    by: Option<String>,
}

/// Publishes `estop`; how many receivers (arms) took it.
fn publish(api: &SafetyApi, estop: &EmergencyStop) -> Result<usize, ApiError> {
    let publisher = api.estop.lock().unwrap_or_else(|e| e.into_inner());
    match publisher.publish(estop) {
        Ok(0) => Err(error(
            StatusCode::SERVICE_UNAVAILABLE,
            "no arm is listening on safety/estop (is the arm actor running?)",
        )),
        Ok(n) => Ok(n),
        Err(e) => Err(error(
            StatusCode::SERVICE_UNAVAILABLE,
            format!("the e-stop could not be sent: {e}"),
        )),
    }
}

/// The most of an engage body that is read; the rest is ignored (and said so).
const ENGAGE_BODY_MAX: usize = 16 * 1024;

async fn engage(State(api): State<SafetyApi>, body: axum::body::Body) -> Response {
    let (reason, notes) = match axum::body::to_bytes(body, ENGAGE_BODY_MAX).await {
        Ok(bytes) => engage_body(&bytes),
        Err(error) => (
            None,
            vec![format!(
                "the body could not be read ({}); a reason is at most {ENGAGE_BODY_MAX} bytes of JSON",
                quote(&error.to_string())
            )],
        ),
    };
    let reason = printable(reason.as_deref().unwrap_or_default(), 500);
    let reason = match reason.trim() {
        "" => "engaged over HTTP".to_owned(),
        text => text.to_owned(),
    };
    let estop = EmergencyStop {
        engaged: true,
        reason: reason.clone(),
        source: "http".into(),
    };
    if let Err(r) = publish(&api, &estop) {
        return r.into_response();
    }
    tracing::warn!(%reason, ?notes, "emergency stop engaged over HTTP");
    let mut reply = serde_json::json!({"engaged": true, "reason": estop.reason});
    if !notes.is_empty() {
        reply["note"] = format!(
            "the request was not well formed, and this was ignored: {}",
            notes.join("; ")
        )
        .into();
        reply["notes"] = notes.into();
    }
    Json(reply).into_response()
}

async fn release(State(api): State<SafetyApi>, bytes: Bytes) -> Response {
    let body: ReleaseBody = match body(&bytes) {
        Ok(b) => b,
        Err(r) => return r.into_response(),
    };
    if body.confirm.as_deref() != Some("release") {
        return error(
            StatusCode::BAD_REQUEST,
            "releasing the emergency stop is a deliberate act: send {\"confirm\": \"release\"}",
        )
        .into_response();
    }
    let by = printable(body.by.as_deref().unwrap_or("http"), 100);
    let request = EStopRelease {
        confirm: "release".into(),
        by,
        only_if_reason: None,
    };
    // A request to the policy's own service, like every release: it records the release with
    // this origin and answers with the new state.
    let asked = robotd_runtime::origin::with_origin(
        Origin::new(OriginKind::Http),
        api.release.request(&request, RELEASE_TIMEOUT),
    )
    .await;
    match asked {
        Ok(state) => {
            tracing::warn!(reason = %state.reason, "emergency stop released over HTTP");
            Json(serde_json::json!({"engaged": state.engaged, "reason": state.reason}))
                .into_response()
        }
        Err(BusError::Remote { fault, .. }) if fault.kind == FaultKind::Refused => {
            error(StatusCode::BAD_REQUEST, fault.message).into_response()
        }
        Err(e) => error(
            StatusCode::SERVICE_UNAVAILABLE,
            format!("the release could not be sent to the safety policy: {e}"),
        )
        .into_response(),
    }
}

async fn approvals(State(api): State<SafetyApi>) -> Response {
    Json(api.safety.approvals().pending()).into_response()
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct AnswerBody {
    approve: Option<bool>,
    by: Option<String>,
}

async fn answer(State(api): State<SafetyApi>, Path(id): Path<String>, bytes: Bytes) -> Response {
    let Ok(id) = id.parse::<u64>() else {
        return error(
            StatusCode::BAD_REQUEST,
            format!("'{id}' is not an approval id (a number from GET /approvals)"),
        )
        .into_response();
    };
    let body: AnswerBody = match body(&bytes) {
        Ok(b) => b,
        Err(r) => return r.into_response(),
    };
    let Some(approve) = body.approve else {
        return error(
            StatusCode::BAD_REQUEST,
            "say {\"approve\": true} or {\"approve\": false}",
        )
        .into_response();
    };
    let by = printable(body.by.as_deref().unwrap_or("http"), 100);
    match api.safety.approvals().answer(id, approve, &by) {
        Ok(()) => {
            Json(serde_json::json!({"id": id, "approved": approve, "by": by})).into_response()
        }
        Err(e) => error(StatusCode::NOT_FOUND, e.to_string()).into_response(),
    }
}
