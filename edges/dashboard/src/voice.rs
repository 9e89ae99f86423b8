//! `POST /api/voice`: talk to the robot. The body is a recording (the page's push-to-talk
//! button sends what the browser's MediaRecorder made: WebM or Ogg; a WAV file or raw 16 kHz
//! 16-bit PCM as `Content-Type: audio/pcm;rate=16000` work too), transcribed by the STT actor
//! over the bus service `stt/transcribe`, then:
//!
//! - **a stop word** (`[voice] stop_phrases`, "stop" and "emergency stop" by default) at the
//!   start of the transcript engages the e-stop at once, on `safety/estop` as `POST /estop`
//!   does, and nothing goes to the LLM (`[voice] stop_words = false` turns this off);
//! - anything else is handed to the agent as if typed in the chat (`agent/request`).
//!
//! The answer is JSON (`transcript`, `action`, and `request_id` or `estop`), or, when the
//! request accepts `text/event-stream`, the events the chat gets: `transcript`, then `estop`,
//! or `request` and that request's `agent` events up to its answer. The route sits behind the
//! port's guard like every other (token, Origin); 503 says so when no STT actor runs.

use crate::api::AgentLink;
use crate::live::{Live, LiveEvent};
use axum::body::Bytes;
use axum::extract::State;
use axum::http::{header, HeaderMap, StatusCode};
use axum::response::sse::{Event, KeepAlive, Sse};
use axum::response::{IntoResponse, Response};
use axum::routing::post;
use axum::{Json, Router};
use futures::{Stream, StreamExt};
use robotd_protocol::agent::AgentRequest;
use robotd_protocol::health::EmergencyStop;
use robotd_protocol::stt::{
    SttErrorKind, TranscribeReply, TranscribeRequest, Transcript, MAX_AUDIO_BYTES,
};
use robotd_runtime::bus::{BusError, Client, Publisher};
use robotd_runtime::config::{Checks, Section};
use serde::{Deserialize, Serialize};
use serde_json::{json, Value};
use std::convert::Infallible;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use tokio::sync::broadcast;

/// `[voice]`: spoken commands through `POST /api/voice`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct VoiceConfig {
    /// A transcript that starts with one of `stop_phrases` engages the e-stop directly.
    pub stop_words: bool,
    /// The stop phrases, lower-case words (punctuation in the transcript is ignored).
    pub stop_phrases: Vec<String>,
    /// Largest recording accepted, bytes (1,000 … 1,000,000: what one bus request carries).
    pub max_audio_bytes: usize,
    /// Longest wait for the transcript, seconds (1 … 120).
    pub timeout_s: f64,
}

impl Default for VoiceConfig {
    fn default() -> Self {
        Self {
            stop_words: true,
            stop_phrases: vec!["stop".into(), "emergency stop".into()],
            max_audio_bytes: MAX_AUDIO_BYTES,
            timeout_s: 20.0,
        }
    }
}

impl Section for VoiceConfig {
    fn check(&self, checks: &mut Checks) {
        checks.range_u64(
            "max_audio_bytes",
            self.max_audio_bytes as u64,
            1000..=MAX_AUDIO_BYTES as u64,
            " bytes",
        );
        checks.range_f64("timeout_s", self.timeout_s, 1.0..=120.0, " s");
        if self.stop_words && self.stop_phrases.is_empty() {
            checks.problem(
                "stop_phrases",
                "is empty while stop_words = true: list at least one phrase",
            );
        }
        for phrase in &self.stop_phrases {
            if normalize(phrase) != *phrase || phrase.is_empty() || phrase.len() > 40 {
                checks.problem(
                    "stop_phrases",
                    format!(
                        "{phrase:?}: a phrase is 1-40 characters of lower-case words separated \
                         by single spaces, without punctuation"
                    ),
                );
            }
        }
    }
}

/// What `/api/voice` works with.
#[derive(Clone)]
pub struct VoiceApi {
    /// A client of `stt/transcribe`.
    pub stt: Arc<Client<TranscribeRequest, TranscribeReply>>,
    /// `safety/estop`.
    pub estop: Arc<Mutex<Publisher<EmergencyStop>>>,
    /// The agent (the chat's link).
    pub agent: Arc<AgentLink>,
    /// The live state: the agent's events.
    pub live: Arc<Live>,
    /// `[voice]`.
    pub config: VoiceConfig,
}

/// The route.
pub fn routes(api: VoiceApi) -> Router {
    Router::new()
        .route("/api/voice", post(voice))
        .with_state(api)
}

fn refuse(status: StatusCode, kind: &str, message: impl Into<String>) -> Response {
    (status, Json(json!({"error": message.into(), "kind": kind}))).into_response()
}

/// Lower-case words of `text`, punctuation dropped, single spaces.
pub fn normalize(text: &str) -> String {
    let cleaned: String = text
        .chars()
        .map(|c| {
            if c.is_alphanumeric() || c == '\'' {
                c.to_ascii_lowercase()
            } else {
                ' '
            }
        })
        .collect();
    cleaned.split_whitespace().collect::<Vec<_>>().join(" ")
}

/// The stop phrase `text` starts with, if any.
pub fn stop_phrase<'a>(text: &str, phrases: &'a [String]) -> Option<&'a str> {
    let words = normalize(text);
    phrases
        .iter()
        .find(|p| words == **p || words.starts_with(&format!("{p} ")))
        .map(String::as_str)
}

/// A refusal: status, kind, message.
type Refusal = (StatusCode, &'static str, String);

/// The request for `body` as its `Content-Type` says: raw PCM (`audio/pcm`, `audio/l16`, with
/// `rate=`), or a file's bytes (anything else audio, or `application/octet-stream`).
fn stt_request(headers: &HeaderMap, body: Vec<u8>) -> Result<TranscribeRequest, Refusal> {
    let content_type = headers
        .get(header::CONTENT_TYPE)
        .and_then(|v| v.to_str().ok())
        .unwrap_or("application/octet-stream")
        .to_ascii_lowercase();
    let mut parts = content_type.split(';').map(str::trim);
    let mime = parts.next().unwrap_or_default();
    match mime {
        "audio/pcm" | "audio/l16" => {
            let rate = parts
                .find_map(|p| p.strip_prefix("rate="))
                .and_then(|r| r.parse::<u32>().ok());
            let Some(rate) = rate else {
                return Err((
                    StatusCode::BAD_REQUEST,
                    "wrong_sample_rate",
                    format!("{mime} needs its rate: Content-Type: {mime};rate=16000"),
                ));
            };
            let mut request = TranscribeRequest::pcm16k(body, "dashboard");
            request.sample_rate_hz = rate;
            Ok(request)
        }
        m if m.starts_with("audio/")
            || m.starts_with("video/webm")
            || m == "application/octet-stream"
            || m == "application/ogg" =>
        {
            Ok(TranscribeRequest::file(body, "dashboard"))
        }
        other => Err((
            StatusCode::UNSUPPORTED_MEDIA_TYPE,
            "not_audio",
            format!(
                "the body must be a recording (audio/webm, audio/ogg, audio/wav, or audio/pcm;\
                 rate=16000), not {other}"
            ),
        )),
    }
}

async fn voice(State(api): State<VoiceApi>, headers: HeaderMap, body: Bytes) -> Response {
    if body.is_empty() {
        return refuse(
            StatusCode::BAD_REQUEST,
            "empty",
            "no audio: the body is empty (send the recording's bytes)",
        );
    }
    if body.len() > api.config.max_audio_bytes {
        return refuse(
            StatusCode::PAYLOAD_TOO_LARGE,
            "too_large",
            format!(
                "a recording of {} bytes is larger than [voice] max_audio_bytes ({}): speak for \
                 a shorter time",
                body.len(),
                api.config.max_audio_bytes
            ),
        );
    }
    let request = match stt_request(&headers, body.to_vec()) {
        Ok(r) => r,
        Err((status, kind, message)) => return refuse(status, kind, message),
    };
    let timeout = Duration::from_secs_f64(api.config.timeout_s);
    let transcript = match api.stt.request(&request, timeout).await {
        Ok(TranscribeReply::Transcript { transcript }) => transcript,
        Ok(TranscribeReply::Error { error }) => {
            let status = match error.kind {
                SttErrorKind::TooLarge => StatusCode::PAYLOAD_TOO_LARGE,
                SttErrorKind::Failed => StatusCode::INTERNAL_SERVER_ERROR,
                _ => StatusCode::UNPROCESSABLE_ENTITY,
            };
            let kind = serde_json::to_value(error.kind).unwrap_or_default();
            return refuse(status, kind.as_str().unwrap_or("failed"), error.message);
        }
        Err(BusError::NoServer { .. }) => {
            return refuse(
                StatusCode::SERVICE_UNAVAILABLE,
                "no_stt",
                "no speech-to-text actor is running: add [actors.stt] (mode = \"process\", \
                 command = [\"python3\", \"-m\", \"robotd.stt\"]) to the configuration \
                 (docs/speech.md)",
            )
        }
        Err(BusError::Timeout { .. }) => {
            return refuse(
                StatusCode::GATEWAY_TIMEOUT,
                "timeout",
                format!(
                    "the speech-to-text actor did not answer within {} s",
                    api.config.timeout_s
                ),
            )
        }
        Err(error) => {
            return refuse(
                StatusCode::SERVICE_UNAVAILABLE,
                "no_stt",
                format!("the speech-to-text actor could not be asked: {error}"),
            )
        }
    };
    let heard_at = Instant::now();
    let stream = headers
        .get(header::ACCEPT)
        .and_then(|v| v.to_str().ok())
        .is_some_and(|v| v.contains("text/event-stream"));
    let outcome = act(&api, &transcript, heard_at);
    if stream {
        return events(transcript, outcome).into_response();
    }
    let mut answer = json!({"transcript": transcript, "action": outcome.action()});
    match &outcome {
        Outcome::Estop { reason, ms, .. } => {
            answer["estop"] = json!({"engaged": true, "reason": reason, "ms": ms})
        }
        Outcome::Agent { request_id, .. } => answer["request_id"] = json!(request_id),
        Outcome::Nothing { note } => answer["note"] = json!(note),
    }
    if let Outcome::Estop {
        error: Some(error), ..
    } = &outcome
    {
        answer["estop"]["engaged"] = json!(false);
        answer["estop"]["error"] = json!(error);
        return (StatusCode::SERVICE_UNAVAILABLE, Json(answer)).into_response();
    }
    Json(answer).into_response()
}

/// What a transcript led to.
enum Outcome {
    /// A stop word: the e-stop was published (`ms` after the transcript), or could not be.
    Estop {
        reason: String,
        ms: f64,
        error: Option<String>,
    },
    /// Handed to the agent; its events follow on `events`.
    Agent {
        request_id: String,
        events: broadcast::Receiver<LiveEvent>,
    },
    /// Nothing was sent anywhere, because `note`.
    Nothing { note: String },
}

impl Outcome {
    fn action(&self) -> &'static str {
        match self {
            Outcome::Estop { .. } => "estop",
            Outcome::Agent { .. } => "agent",
            Outcome::Nothing { .. } => "none",
        }
    }
}

fn act(api: &VoiceApi, transcript: &Transcript, heard_at: Instant) -> Outcome {
    if api.config.stop_words {
        if let Some(phrase) = stop_phrase(&transcript.text, &api.config.stop_phrases) {
            let estop = EmergencyStop {
                engaged: true,
                reason: format!("voice: heard \"{phrase}\" ({:?})", transcript.text),
                source: "voice".into(),
            };
            let sent = api
                .estop
                .lock()
                .unwrap_or_else(|e| e.into_inner())
                .publish(&estop);
            let ms = heard_at.elapsed().as_secs_f64() * 1000.0;
            let error = match sent {
                Ok(0) => {
                    Some("no arm is listening on safety/estop (is the arm actor running?)".into())
                }
                Ok(_) => None,
                Err(e) => Some(format!("the e-stop could not be sent: {e}")),
            };
            tracing::warn!(text = %transcript.text, ms, ?error, "emergency stop engaged by voice");
            return Outcome::Estop {
                reason: estop.reason,
                ms,
                error,
            };
        }
    }
    let text = transcript.text.trim();
    if text.is_empty() {
        return Outcome::Nothing {
            note: "nothing was heard; nothing was sent to the agent".into(),
        };
    }
    let requests = match api.agent.as_ref() {
        AgentLink::Available { requests, .. } => requests,
        AgentLink::Off(reason) => {
            return Outcome::Nothing {
                note: format!("no LLM agent is running: {reason}"),
            }
        }
    };
    let request_id = crate_request_id();
    // Listen before asking, so that no event of this request can be missed.
    let events = api.live.events();
    let sent = requests
        .lock()
        .unwrap_or_else(|e| e.into_inner())
        .publish(&AgentRequest {
            request_id: request_id.clone(),
            text: text.chars().take(4000).collect(),
        });
    match sent {
        Ok(0) => Outcome::Nothing {
            note: "the agent is not listening on the bus (is it restarting?)".into(),
        },
        Ok(_) => Outcome::Agent { request_id, events },
        Err(e) => Outcome::Nothing {
            note: format!("the request could not be sent to the agent: {e}"),
        },
    }
}

fn crate_request_id() -> String {
    use rand::RngCore;
    let mut bytes = [0u8; 8];
    rand::rng().fill_bytes(&mut bytes);
    let hex: String = bytes.iter().map(|b| format!("{b:02x}")).collect();
    format!("voice-{hex}")
}

/// The SSE answer: `transcript`, then `estop`, `note`, or `request` and the agent's events of
/// that request up to its terminal one.
fn events(
    transcript: Transcript,
    outcome: Outcome,
) -> Sse<impl Stream<Item = Result<Event, Infallible>> + Send + 'static> {
    let event = |name: &str, data: Value| {
        Ok::<_, Infallible>(Event::default().event(name).data(data.to_string()))
    };
    let mut first = vec![event("transcript", json!(transcript))];
    let follow = match outcome {
        Outcome::Estop { reason, ms, error } => {
            first.push(event(
                "estop",
                json!({"engaged": error.is_none(), "reason": reason, "ms": ms, "error": error}),
            ));
            None
        }
        Outcome::Nothing { note } => {
            first.push(event("note", json!({"note": note})));
            None
        }
        Outcome::Agent { request_id, events } => {
            first.push(event("request", json!({"request_id": request_id})));
            Some((request_id, events))
        }
    };
    let agent = futures::stream::unfold(follow, |state| async move {
        let (id, mut events) = state?;
        loop {
            match events.recv().await {
                Ok(LiveEvent::Agent(e)) if e.request_id == id => {
                    let terminal = e.event.is_terminal();
                    let data =
                        serde_json::to_string(&LiveEvent::Agent(e)).unwrap_or_else(|_| "{}".into());
                    let item = Ok(Event::default().event("agent").data(data));
                    return Some((item, (!terminal).then_some((id, events))));
                }
                Ok(_) | Err(broadcast::error::RecvError::Lagged(_)) => continue,
                Err(broadcast::error::RecvError::Closed) => return None,
            }
        }
    });
    // A terminal event is sent with a `None` state: the stream ends right after it.
    Sse::new(futures::stream::iter(first).chain(agent)).keep_alive(KeepAlive::default())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stop_words_are_whole_words_at_the_start() {
        let phrases = VoiceConfig::default().stop_phrases;
        assert_eq!(stop_phrase("Stop.", &phrases), Some("stop"));
        assert_eq!(stop_phrase(" STOP! now", &phrases), Some("stop"));
        assert_eq!(
            stop_phrase("Emergency stop!", &phrases),
            Some("emergency stop")
        );
        assert_eq!(stop_phrase("Stopping is hard", &phrases), None);
        assert_eq!(stop_phrase("please stop", &phrases), None);
        assert_eq!(stop_phrase("pick up the pencil", &phrases), None);
        assert_eq!(stop_phrase("", &phrases), None);
    }

    #[test]
    fn the_section_checks_its_keys() {
        let mut problems = Vec::new();
        let bad = VoiceConfig {
            stop_phrases: vec!["Stop!".into()],
            max_audio_bytes: 2_000_000,
            timeout_s: 0.0,
            ..VoiceConfig::default()
        };
        bad.check(&mut Checks::new("voice", &mut problems));
        let keys: Vec<&str> = problems.iter().map(|(k, _)| k.as_str()).collect();
        assert_eq!(
            keys,
            [
                "voice.max_audio_bytes",
                "voice.timeout_s",
                "voice.stop_phrases"
            ]
        );
        let mut none = Vec::new();
        VoiceConfig::default().check(&mut Checks::new("voice", &mut none));
        assert!(none.is_empty(), "{none:?}");
    }
}
