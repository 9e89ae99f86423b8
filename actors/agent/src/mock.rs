//! A scripted LLM server for tests: real OpenAI chat-completions (`/v1/chat/completions` and
//! `/chat/completions`) and Ollama (`/api/chat`) JSON on 127.0.0.1, answering from a queue of
//! [`MockReply`]s and recording every request it receives.
//!
//! It is the only stand-in robotd's agent tests use: everything else (the agent, the HTTP
//! client, the tools, the robot) is real. A reply can be a tool call, text, an HTTP error
//! (429 with `Retry-After`, 500 …), a malformed body, or computed from the request (to answer
//! with coordinates the tools reported, as a real model would).
//!
//! ```no_run
//! # async fn demo() -> std::io::Result<()> {
//! use robotd_agent::mock::{MockLlm, MockReply};
//! use serde_json::json;
//!
//! let mock = MockLlm::start(vec![
//!     MockReply::status(429),
//!     MockReply::tool_call("get_detected_objects", json!({})),
//!     MockReply::text("I see three objects."),
//! ])
//! .await?;
//! // Point the agent at it: OPENAI_BASE_URL = mock.openai_base_url(), or
//! // OLLAMA_HOST = mock.base_url().
//! # let _ = mock.requests();
//! # Ok(()) }
//! ```

use axum::body::Bytes;
use axum::extract::State;
use axum::http::{HeaderMap, StatusCode, Uri};
use axum::response::{IntoResponse, Response};
use axum::routing::post;
use axum::Router;
use serde_json::{json, Value};
use std::collections::VecDeque;
use std::net::SocketAddr;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};

/// A function computing a reply from the request body.
pub type ReplyFn = Arc<dyn Fn(&Value) -> MockReply + Send + Sync>;

/// One scripted reply.
#[derive(Clone)]
pub enum MockReply {
    /// Tool calls (name, arguments), with optional text (the plan).
    ToolCalls {
        /// Text beside the calls.
        content: Option<String>,
        /// The calls.
        calls: Vec<(String, Value)>,
    },
    /// A plain text reply.
    Text(String),
    /// An HTTP error.
    Status {
        /// The status code.
        status: u16,
        /// `Retry-After` seconds, if any.
        retry_after: Option<u64>,
        /// The body.
        body: String,
    },
    /// HTTP 200 with this body verbatim (e.g. malformed JSON).
    Raw(String),
    /// Computed from the request body when it arrives.
    Dynamic(ReplyFn),
}

impl std::fmt::Debug for MockReply {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            MockReply::ToolCalls { content, calls } => f
                .debug_struct("ToolCalls")
                .field("content", content)
                .field("calls", calls)
                .finish(),
            MockReply::Text(t) => f.debug_tuple("Text").field(t).finish(),
            MockReply::Status { status, .. } => f.debug_tuple("Status").field(status).finish(),
            MockReply::Raw(b) => f.debug_tuple("Raw").field(b).finish(),
            MockReply::Dynamic(_) => f.write_str("Dynamic"),
        }
    }
}

impl MockReply {
    /// One tool call.
    pub fn tool_call(name: &str, arguments: Value) -> MockReply {
        MockReply::ToolCalls {
            content: None,
            calls: vec![(name.to_owned(), arguments)],
        }
    }

    /// One tool call with the plan text beside it.
    pub fn plan_and_call(plan: &str, name: &str, arguments: Value) -> MockReply {
        MockReply::ToolCalls {
            content: Some(plan.to_owned()),
            calls: vec![(name.to_owned(), arguments)],
        }
    }

    /// A text reply.
    pub fn text(text: &str) -> MockReply {
        MockReply::Text(text.to_owned())
    }

    /// An HTTP error status with a JSON error body.
    pub fn status(status: u16) -> MockReply {
        MockReply::Status {
            status,
            retry_after: None,
            body: json!({"error": {"message": format!("mock status {status}")}}).to_string(),
        }
    }

    /// A reply computed from the request body.
    pub fn dynamic(f: impl Fn(&Value) -> MockReply + Send + Sync + 'static) -> MockReply {
        MockReply::Dynamic(Arc::new(f))
    }
}

/// A request the mock received.
#[derive(Debug, Clone)]
pub struct RecordedRequest {
    /// The path, e.g. `/v1/chat/completions`.
    pub path: String,
    /// The `Authorization` header, if any.
    pub authorization: Option<String>,
    /// The JSON body (`null` if it was not JSON).
    pub body: Value,
}

#[derive(Default)]
struct Shared {
    replies: Mutex<VecDeque<MockReply>>,
    requests: Mutex<Vec<RecordedRequest>>,
    next_id: AtomicU64,
}

/// The running mock server; stops when dropped.
pub struct MockLlm {
    addr: SocketAddr,
    shared: Arc<Shared>,
    task: tokio::task::JoinHandle<()>,
}

impl Drop for MockLlm {
    fn drop(&mut self) {
        self.task.abort();
    }
}

impl MockLlm {
    /// Starts the server on 127.0.0.1 (a free port) with these replies queued.
    pub async fn start(replies: Vec<MockReply>) -> std::io::Result<MockLlm> {
        let shared = Arc::new(Shared::default());
        shared
            .replies
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .extend(replies);
        let app = Router::new()
            .route("/v1/chat/completions", post(openai))
            .route("/chat/completions", post(openai))
            .route("/api/chat", post(ollama))
            .with_state(shared.clone());
        let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await?;
        let addr = listener.local_addr()?;
        let task = tokio::spawn(async move {
            if let Err(error) = axum::serve(listener, app).await {
                tracing::warn!(%error, "the mock LLM server stopped");
            }
        });
        Ok(MockLlm { addr, shared, task })
    }

    /// `http://127.0.0.1:PORT` (for `OLLAMA_HOST`).
    pub fn base_url(&self) -> String {
        format!("http://{}", self.addr)
    }

    /// `http://127.0.0.1:PORT/v1` (for `OPENAI_BASE_URL` and the like).
    pub fn openai_base_url(&self) -> String {
        format!("http://{}/v1", self.addr)
    }

    /// Queues more replies.
    pub fn push(&self, reply: MockReply) {
        self.shared
            .replies
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .push_back(reply);
    }

    /// Replies not used yet.
    pub fn remaining(&self) -> usize {
        self.shared
            .replies
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .len()
    }

    /// Every request received so far.
    pub fn requests(&self) -> Vec<RecordedRequest> {
        self.shared
            .requests
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .clone()
    }
}

#[derive(Clone, Copy)]
enum Format {
    OpenAi,
    Ollama,
}

fn next_reply(shared: &Shared, headers: &HeaderMap, uri: &Uri, body: &[u8]) -> (MockReply, Value) {
    let body: Value = serde_json::from_slice(body).unwrap_or(Value::Null);
    shared
        .requests
        .lock()
        .unwrap_or_else(|e| e.into_inner())
        .push(RecordedRequest {
            path: uri.path().to_owned(),
            authorization: headers
                .get("authorization")
                .and_then(|v| v.to_str().ok())
                .map(str::to_owned),
            body: body.clone(),
        });
    let reply = shared
        .replies
        .lock()
        .unwrap_or_else(|e| e.into_inner())
        .pop_front();
    let reply = reply.unwrap_or_else(|| MockReply::Status {
        status: 500,
        retry_after: None,
        body: json!({"error": {"message": "mock LLM: no scripted reply left"}}).to_string(),
    });
    (reply, body)
}

fn respond(shared: &Shared, format: Format, reply: MockReply, request: &Value) -> Response {
    let reply = match reply {
        MockReply::Dynamic(f) => f(request),
        other => other,
    };
    let (content, calls) = match reply {
        MockReply::Status {
            status,
            retry_after,
            body,
        } => {
            let code = StatusCode::from_u16(status).unwrap_or(StatusCode::INTERNAL_SERVER_ERROR);
            let mut response = (code, body).into_response();
            if let Some(secs) = retry_after {
                if let Ok(v) = secs.to_string().parse() {
                    response.headers_mut().insert("retry-after", v);
                }
            }
            return response;
        }
        MockReply::Raw(body) => return (StatusCode::OK, body).into_response(),
        MockReply::Text(t) => (Some(t), Vec::new()),
        MockReply::ToolCalls { content, calls } => (content, calls),
        MockReply::Dynamic(_) => {
            return (
                StatusCode::INTERNAL_SERVER_ERROR,
                "mock LLM: nested dynamic reply",
            )
                .into_response()
        }
    };
    let model = request.get("model").cloned().unwrap_or(Value::Null);
    let body = match format {
        Format::OpenAi => {
            let mut message = json!({"role": "assistant", "content": content});
            if !calls.is_empty() {
                message["tool_calls"] = calls
                    .iter()
                    .map(|(name, args)| {
                        let id = shared.next_id.fetch_add(1, Ordering::Relaxed);
                        json!({
                            "id": format!("call_{id}"),
                            "type": "function",
                            "function": {"name": name, "arguments": args.to_string()}
                        })
                    })
                    .collect();
            }
            json!({
                "id": "chatcmpl-mock",
                "object": "chat.completion",
                "model": model,
                "choices": [{
                    "index": 0,
                    "message": message,
                    "finish_reason": if calls.is_empty() { "stop" } else { "tool_calls" }
                }],
                "usage": {"prompt_tokens": 100, "completion_tokens": 20, "total_tokens": 120}
            })
        }
        Format::Ollama => {
            let mut message = json!({"role": "assistant", "content": content.unwrap_or_default()});
            if !calls.is_empty() {
                message["tool_calls"] = calls
                    .iter()
                    .map(|(name, args)| json!({"function": {"name": name, "arguments": args}}))
                    .collect();
            }
            json!({
                "model": model,
                "created_at": "2026-01-01T00:00:00Z",
                "message": message,
                "done": true,
                "done_reason": "stop",
                "prompt_eval_count": 100,
                "eval_count": 20
            })
        }
    };
    (
        StatusCode::OK,
        [("content-type", "application/json")],
        body.to_string(),
    )
        .into_response()
}

async fn openai(
    State(shared): State<Arc<Shared>>,
    headers: HeaderMap,
    uri: Uri,
    body: Bytes,
) -> Response {
    let (reply, request) = next_reply(&shared, &headers, &uri, &body);
    respond(&shared, Format::OpenAi, reply, &request)
}

async fn ollama(
    State(shared): State<Arc<Shared>>,
    headers: HeaderMap,
    uri: Uri,
    body: Bytes,
) -> Response {
    let (reply, request) = next_reply(&shared, &headers, &uri, &body);
    respond(&shared, Format::Ollama, reply, &request)
}
