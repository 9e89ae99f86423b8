//! Talking to an LLM: the conversation's messages, and the two wire formats that carry them
//! with tool calling — OpenAI chat completions (`tools` / `tool_calls`; used for OpenAI, Groq,
//! Gemini and any OpenAI-compatible server) and Ollama's `/api/chat` (`tools`, not streamed).
//!
//! [`LlmClient::complete`] sends the conversation and the tool list and returns the model's
//! reply: text, tool calls, or both. It retries on HTTP 429 and 5xx with exponential backoff
//! (honouring `Retry-After`, capped), bounds every request with a timeout, and turns a 401/403
//! into an error naming the key variable to fix. Each call is a `llm.call` tracing span with
//! the provider, model and — when the provider reports them — prompt and completion tokens.
//!
//! ```no_run
//! # async fn demo() -> Result<(), robotd_agent::llm::LlmError> {
//! use robotd_agent::llm::{LlmClient, Message, RetryPolicy};
//! use robotd_agent::providers::{resolve, Env};
//!
//! let env = Env::from_process(None).expect("environment");
//! let settings = resolve("auto", None, &env).expect("a provider");
//! let client = LlmClient::new(settings, RetryPolicy::default())?;
//! let reply = client.complete(&[Message::user("Say hello")], &[]).await?;
//! println!("{}", reply.content.unwrap_or_default());
//! # Ok(()) }
//! ```

use crate::providers::{ProviderSettings, Wire};
use crate::vision::ImagePart;
use robotd_runtime::backoff::Backoff;
use serde_json::{json, Value};
use std::time::Duration;

/// One message of a conversation.
#[derive(Debug, Clone, PartialEq)]
pub enum Message {
    /// Instructions for the model.
    System(String),
    /// What the user said (or a nudge from the agent).
    User(String),
    /// The model's reply: text and/or tool calls.
    Assistant {
        /// The text, if any.
        content: Option<String>,
        /// The tool calls, in order.
        tool_calls: Vec<ToolCall>,
    },
    /// The result of one tool call.
    Tool {
        /// The call's id.
        call_id: String,
        /// The tool's name.
        name: String,
        /// The result text.
        content: String,
    },
    /// A picture a tool returned, shown to a model that takes images: sent as a user message
    /// after the tool results of its round (tool messages carry text only).
    Picture {
        /// The call that returned it.
        call_id: String,
        /// The tool's name.
        name: String,
        /// The picture.
        image: ImagePart,
    },
}

/// What a picture counts for in the history's size, in estimated tokens (about what the
/// providers bill for a 640×480 picture).
pub const PICTURE_TOKENS: usize = 800;

impl Message {
    /// A user message.
    pub fn user(text: impl Into<String>) -> Message {
        Message::User(text.into())
    }

    /// A rough token count: characters / 4, plus a little per message.
    pub fn estimated_tokens(&self) -> usize {
        let chars = match self {
            Message::System(t) | Message::User(t) => t.len(),
            Message::Assistant {
                content,
                tool_calls,
            } => {
                content.as_deref().map_or(0, str::len)
                    + tool_calls
                        .iter()
                        .map(|c| c.name.len() + c.arguments.len() + c.id.len())
                        .sum::<usize>()
            }
            Message::Tool { content, name, .. } => content.len() + name.len(),
            Message::Picture { name, .. } => return PICTURE_TOKENS + name.len() / 4,
        };
        chars / 4 + 4
    }
}

/// A tool call the model asked for.
#[derive(Debug, Clone, PartialEq)]
pub struct ToolCall {
    /// The call's id (made up when the provider gives none).
    pub id: String,
    /// The tool's name.
    pub name: String,
    /// The arguments as JSON text, verbatim (may be malformed: the model wrote it).
    pub arguments: String,
}

/// A tool as the model sees it (defined with the tool backends in `robotd_tools::backend`).
pub use robotd_tools::backend::ToolSpec;

/// Token counts a provider reported.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Usage {
    /// Tokens of the prompt.
    pub prompt_tokens: u64,
    /// Tokens of the reply.
    pub completion_tokens: u64,
}

/// The model's reply.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Completion {
    /// Text, if any (empty text is `None`).
    pub content: Option<String>,
    /// Tool calls, in order.
    pub tool_calls: Vec<ToolCall>,
    /// Token counts, when reported.
    pub usage: Option<Usage>,
}

/// How hard to try.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RetryPolicy {
    /// Retries after the first attempt (429 and 5xx only).
    pub max_retries: u32,
    /// First backoff; doubled on each retry.
    pub initial_backoff: Duration,
    /// Longest wait between attempts, also the cap of `Retry-After`.
    pub max_backoff: Duration,
    /// Longest one request may take (connect, send, reply).
    pub request_timeout: Duration,
    /// Largest reply body read, bytes; a larger one is an error, never read whole.
    pub max_reply_bytes: usize,
}

/// The default of [`RetryPolicy::max_reply_bytes`]: 8 MiB (a long completion is well under
/// 1 MiB).
pub const DEFAULT_MAX_REPLY_BYTES: usize = 8 * 1024 * 1024;

/// The body of `response`, or why it was not read: larger than `max` bytes (by its
/// `Content-Length` or as it streams in), or the connection failed.
async fn read_limited(mut response: reqwest::Response, max: usize) -> Result<String, String> {
    let too_large = || format!("the reply is larger than {max} bytes ([agent] max_reply_bytes)");
    if response.content_length().is_some_and(|n| n > max as u64) {
        return Err(too_large());
    }
    let mut body = Vec::new();
    while let Some(chunk) = response
        .chunk()
        .await
        .map_err(|e| format!("reading the reply: {}", error_chain(&e)))?
    {
        if body.len() + chunk.len() > max {
            return Err(too_large());
        }
        body.extend_from_slice(&chunk);
    }
    Ok(String::from_utf8_lossy(&body).into_owned())
}

impl Default for RetryPolicy {
    fn default() -> Self {
        Self {
            max_retries: 4,
            initial_backoff: Duration::from_millis(1000),
            max_backoff: Duration::from_secs(30),
            request_timeout: Duration::from_secs(120),
            max_reply_bytes: DEFAULT_MAX_REPLY_BYTES,
        }
    }
}

/// Why a completion failed.
#[derive(Debug, thiserror::Error)]
pub enum LlmError {
    /// The provider refused the key.
    #[error("{provider} rejected the API key (HTTP {status}): check {variable}{detail}")]
    RejectedKey {
        /// Provider name.
        provider: String,
        /// HTTP status (401 or 403).
        status: u16,
        /// The variable to fix.
        variable: String,
        /// The provider's message, prefixed with ": " (may be empty).
        detail: String,
    },
    /// Still rate-limited or failing after every retry.
    #[error("{provider} at {url} kept failing (HTTP {status}) after {attempts} attempts: {body}")]
    Exhausted {
        /// Provider name.
        provider: String,
        /// Endpoint.
        url: String,
        /// The last status.
        status: u16,
        /// Attempts made.
        attempts: u32,
        /// The last reply body (shortened).
        body: String,
    },
    /// Any other HTTP error (bad model name, bad request …).
    #[error("{provider} at {url} refused the request (HTTP {status}): {body}")]
    Refused {
        /// Provider name.
        provider: String,
        /// Endpoint.
        url: String,
        /// Status.
        status: u16,
        /// The reply body (shortened).
        body: String,
    },
    /// The server could not be reached or did not answer in time.
    #[error("cannot reach {provider} at {url}: {reason}")]
    Unreachable {
        /// Provider name.
        provider: String,
        /// Endpoint.
        url: String,
        /// Why.
        reason: String,
    },
    /// The reply is not what the wire format promises.
    #[error("{provider} sent a reply robotd cannot read: {reason}")]
    BadReply {
        /// Provider name.
        provider: String,
        /// What is wrong.
        reason: String,
    },
    /// The HTTP client could not be built.
    #[error("cannot set up the HTTP client: {0}")]
    Client(String),
}

/// A client of one provider and model.
#[derive(Debug, Clone)]
pub struct LlmClient {
    settings: ProviderSettings,
    retry: RetryPolicy,
    http: reqwest::Client,
}

fn shorten(text: &str, max: usize) -> String {
    let text = text.trim();
    if text.chars().count() <= max {
        text.to_owned()
    } else {
        let cut: String = text.chars().take(max).collect();
        format!("{cut}…")
    }
}

/// Parses `Retry-After` (seconds; an HTTP date is not worth a date parser here).
fn retry_after(headers: &reqwest::header::HeaderMap) -> Option<Duration> {
    let value = headers.get(reqwest::header::RETRY_AFTER)?.to_str().ok()?;
    let secs: f64 = value.trim().parse().ok()?;
    (secs.is_finite() && secs >= 0.0).then(|| Duration::from_secs_f64(secs.min(3600.0)))
}

impl LlmClient {
    /// A client for `settings`.
    pub fn new(settings: ProviderSettings, retry: RetryPolicy) -> Result<LlmClient, LlmError> {
        robotd_runtime::telemetry::install_tls_provider();
        let http = reqwest::Client::builder()
            .connect_timeout(Duration::from_secs(10).min(retry.request_timeout))
            .timeout(retry.request_timeout)
            .build()
            .map_err(|e| LlmError::Client(e.to_string()))?;
        Ok(LlmClient {
            settings,
            retry,
            http,
        })
    }

    /// The provider and model this client talks to.
    pub fn settings(&self) -> &ProviderSettings {
        &self.settings
    }

    /// The endpoint requests go to.
    pub fn endpoint(&self) -> String {
        let base = self.settings.base_url.trim_end_matches('/');
        match self.settings.provider.wire() {
            Wire::OpenAi => format!("{base}/chat/completions"),
            Wire::Ollama => format!("{base}/api/chat"),
        }
    }

    /// The request body for `messages` and `tools` in this provider's wire format.
    pub fn request_body(&self, messages: &[Message], tools: &[ToolSpec]) -> Value {
        match self.settings.provider.wire() {
            Wire::OpenAi => openai_body(&self.settings.model, messages, tools),
            Wire::Ollama => ollama_body(&self.settings.model, messages, tools),
        }
    }

    /// Sends the conversation and returns the model's reply (see the module docs).
    pub async fn complete(
        &self,
        messages: &[Message],
        tools: &[ToolSpec],
    ) -> Result<Completion, LlmError> {
        let span = tracing::info_span!(
            "llm.call",
            provider = self.settings.provider.name(),
            model = %self.settings.model,
            prompt_tokens = tracing::field::Empty,
            completion_tokens = tracing::field::Empty,
            attempts = tracing::field::Empty,
        );
        let result =
            tracing::Instrument::instrument(self.complete_inner(messages, tools), span.clone())
                .await;
        match &result {
            Ok((completion, attempts)) => {
                span.record("attempts", attempts);
                if let Some(u) = completion.usage {
                    span.record("prompt_tokens", u.prompt_tokens);
                    span.record("completion_tokens", u.completion_tokens);
                }
                span.in_scope(|| {
                    tracing::info!(
                        tool_calls = completion.tool_calls.len(),
                        prompt_tokens = completion.usage.map(|u| u.prompt_tokens),
                        completion_tokens = completion.usage.map(|u| u.completion_tokens),
                        "LLM replied"
                    )
                });
            }
            Err(error) => span.in_scope(|| tracing::warn!(%error, "LLM call failed")),
        }
        result.map(|(c, _)| c)
    }

    async fn complete_inner(
        &self,
        messages: &[Message],
        tools: &[ToolSpec],
    ) -> Result<(Completion, u32), LlmError> {
        let url = self.endpoint();
        let body = self.request_body(messages, tools);
        let provider = self.settings.provider.name().to_owned();
        let mut backoff = Backoff::new(self.retry.initial_backoff, self.retry.max_backoff);
        let mut attempt = 0u32;
        loop {
            attempt += 1;
            let mut request = self.http.post(&url).json(&body);
            if let Some(key) = &self.settings.api_key {
                request = request.bearer_auth(key);
            }
            let response = match request.send().await {
                Ok(r) => r,
                Err(e) => {
                    let reason = if e.is_timeout() {
                        format!("no reply within {:?}", self.retry.request_timeout)
                    } else {
                        error_chain(&e)
                    };
                    // A connection refused is not worth retrying; a timeout is, a little.
                    if e.is_timeout() && attempt <= self.retry.max_retries {
                        tracing::warn!(attempt, %reason, "LLM request timed out; retrying");
                        continue;
                    }
                    return Err(LlmError::Unreachable {
                        provider,
                        url,
                        reason,
                    });
                }
            };
            let status = response.status().as_u16();
            let wait_hint = retry_after(response.headers());
            let text = match read_limited(response, self.retry.max_reply_bytes).await {
                Ok(t) => t,
                Err(reason) => {
                    return Err(LlmError::Unreachable {
                        provider,
                        url,
                        reason,
                    })
                }
            };
            if (200..300).contains(&status) {
                let completion = match self.settings.provider.wire() {
                    Wire::OpenAi => parse_openai(&text),
                    Wire::Ollama => parse_ollama(&text),
                }
                .map_err(|reason| LlmError::BadReply {
                    provider: provider.clone(),
                    reason,
                })?;
                return Ok((completion, attempt));
            }
            if status == 401 || status == 403 {
                let variable = self
                    .settings
                    .key_variable
                    .unwrap_or("the provider's API key variable")
                    .to_owned();
                let detail = shorten(&error_message(&text), 200);
                return Err(LlmError::RejectedKey {
                    provider,
                    status,
                    variable,
                    detail: if detail.is_empty() {
                        String::new()
                    } else {
                        format!(": {detail}")
                    },
                });
            }
            let retryable = status == 429 || (500..600).contains(&status);
            if !retryable {
                return Err(LlmError::Refused {
                    provider,
                    url,
                    status,
                    body: shorten(&error_message(&text), 300),
                });
            }
            if attempt > self.retry.max_retries {
                return Err(LlmError::Exhausted {
                    provider,
                    url,
                    status,
                    attempts: attempt,
                    body: shorten(&error_message(&text), 300),
                });
            }
            // The doubling goes on under a Retry-After, which replaces only this wait.
            let next = backoff.next_delay();
            let wait = wait_hint.unwrap_or(next).min(self.retry.max_backoff);
            tracing::warn!(
                status,
                attempt,
                wait_ms = wait.as_millis() as u64,
                "LLM busy or failing; retrying"
            );
            tokio::time::sleep(wait).await;
        }
    }
}

fn error_chain(e: &dyn std::error::Error) -> String {
    let mut text = e.to_string();
    let mut source = e.source();
    while let Some(s) = source {
        text.push_str(": ");
        text.push_str(&s.to_string());
        source = s.source();
    }
    text
}

/// The `error.message` of an error body when it is JSON, else the body.
fn error_message(body: &str) -> String {
    serde_json::from_str::<Value>(body)
        .ok()
        .and_then(|v| {
            let e = v.get("error")?;
            e.get("message")
                .and_then(Value::as_str)
                .or_else(|| e.as_str())
                .map(str::to_owned)
        })
        .unwrap_or_else(|| body.to_owned())
}

fn tools_json(tools: &[ToolSpec]) -> Vec<Value> {
    tools
        .iter()
        .map(|t| {
            json!({
                "type": "function",
                "function": {
                    "name": t.name,
                    "description": t.description,
                    "parameters": Value::Object(t.parameters.clone()),
                }
            })
        })
        .collect()
}

/// OpenAI chat-completions request body.
pub fn openai_body(model: &str, messages: &[Message], tools: &[ToolSpec]) -> Value {
    let messages: Vec<Value> = messages
        .iter()
        .map(|m| match m {
            Message::System(t) => json!({"role": "system", "content": t}),
            Message::User(t) => json!({"role": "user", "content": t}),
            Message::Assistant {
                content,
                tool_calls,
            } => {
                let mut v = json!({"role": "assistant", "content": content});
                if !tool_calls.is_empty() {
                    v["tool_calls"] = tool_calls
                        .iter()
                        .map(|c| {
                            json!({
                                "id": c.id,
                                "type": "function",
                                "function": {"name": c.name, "arguments": c.arguments}
                            })
                        })
                        .collect();
                }
                v
            }
            Message::Tool {
                call_id,
                name,
                content,
            } => json!({"role": "tool", "tool_call_id": call_id, "name": name, "content": content}),
            Message::Picture {
                call_id,
                name,
                image,
            } => json!({"role": "user", "content": [
                {"type": "text", "text": picture_caption(name, call_id)},
                {"type": "image_url", "image_url": {"url": image.data_url()}},
            ]}),
        })
        .collect();
    let mut body = json!({"model": model, "messages": messages});
    if !tools.is_empty() {
        body["tools"] = Value::Array(tools_json(tools));
        body["tool_choice"] = json!("auto");
    }
    body
}

/// Ollama `/api/chat` request body (not streamed).
pub fn ollama_body(model: &str, messages: &[Message], tools: &[ToolSpec]) -> Value {
    let messages: Vec<Value> = messages
        .iter()
        .map(|m| match m {
            Message::System(t) => json!({"role": "system", "content": t}),
            Message::User(t) => json!({"role": "user", "content": t}),
            Message::Assistant {
                content,
                tool_calls,
            } => {
                let mut v =
                    json!({"role": "assistant", "content": content.clone().unwrap_or_default()});
                if !tool_calls.is_empty() {
                    v["tool_calls"] = tool_calls
                        .iter()
                        .map(|c| {
                            // Ollama wants the arguments as an object.
                            let args = serde_json::from_str::<Value>(&c.arguments)
                                .ok()
                                .filter(Value::is_object)
                                .unwrap_or_else(|| json!({}));
                            json!({"function": {"name": c.name, "arguments": args}})
                        })
                        .collect();
                }
                v
            }
            Message::Tool { name, content, .. } => {
                json!({"role": "tool", "tool_name": name, "content": content})
            }
            Message::Picture {
                call_id,
                name,
                image,
            } => json!({
                "role": "user",
                "content": picture_caption(name, call_id),
                "images": [image.data_base64],
            }),
        })
        .collect();
    let mut body = json!({"model": model, "messages": messages, "stream": false});
    if !tools.is_empty() {
        body["tools"] = Value::Array(tools_json(tools));
    }
    body
}

/// The words that come with a picture.
fn picture_caption(name: &str, call_id: &str) -> String {
    format!(
        "The picture {name} returned (call {call_id}); the ids drawn on it are the objects' ids."
    )
}

fn non_empty(text: Option<&str>) -> Option<String> {
    text.map(str::trim)
        .filter(|t| !t.is_empty())
        .map(str::to_owned)
}

/// The `tool_calls` of a reply message (the same shape in both wire formats; `arguments` a JSON
/// string or an object). `id_of` names a call from its JSON and index.
fn parse_tool_calls(
    message: &Value,
    id_of: impl Fn(&Value, usize) -> String,
) -> Result<Vec<ToolCall>, String> {
    let mut tool_calls = Vec::new();
    let Some(calls) = message.get("tool_calls").and_then(Value::as_array) else {
        return Ok(tool_calls);
    };
    for (i, call) in calls.iter().enumerate() {
        let function = call
            .get("function")
            .ok_or_else(|| format!("tool call {i} has no function"))?;
        let name = function
            .get("name")
            .and_then(Value::as_str)
            .filter(|n| !n.is_empty())
            .ok_or_else(|| format!("tool call {i} has no function name"))?;
        let arguments = match function.get("arguments") {
            Some(Value::String(s)) => s.clone(),
            Some(Value::Null) | None => "{}".to_owned(),
            Some(other) => other.to_string(),
        };
        tool_calls.push(ToolCall {
            id: id_of(call, i),
            name: name.to_owned(),
            arguments,
        });
    }
    Ok(tool_calls)
}

/// Reads an OpenAI chat-completions reply.
pub fn parse_openai(text: &str) -> Result<Completion, String> {
    let v: Value = serde_json::from_str(text)
        .map_err(|e| format!("not JSON ({e}): {}", shorten(text, 200)))?;
    let message = v
        .get("choices")
        .and_then(|c| c.get(0))
        .and_then(|c| c.get("message"))
        .ok_or_else(|| format!("no choices[0].message in {}", shorten(text, 200)))?;
    let tool_calls = parse_tool_calls(message, |call, i| {
        call.get("id")
            .and_then(Value::as_str)
            .filter(|s| !s.is_empty())
            .map(str::to_owned)
            .unwrap_or_else(|| format!("call_{i}"))
    })?;
    let usage = v.get("usage").map(|u| Usage {
        prompt_tokens: u.get("prompt_tokens").and_then(Value::as_u64).unwrap_or(0),
        completion_tokens: u
            .get("completion_tokens")
            .and_then(Value::as_u64)
            .unwrap_or(0),
    });
    Ok(Completion {
        content: non_empty(message.get("content").and_then(Value::as_str)),
        tool_calls,
        usage,
    })
}

/// Reads an Ollama `/api/chat` reply.
pub fn parse_ollama(text: &str) -> Result<Completion, String> {
    let v: Value = serde_json::from_str(text)
        .map_err(|e| format!("not JSON ({e}): {}", shorten(text, 200)))?;
    if let Some(error) = v.get("error").and_then(Value::as_str) {
        return Err(error.to_owned());
    }
    let message = v
        .get("message")
        .ok_or_else(|| format!("no message in {}", shorten(text, 200)))?;
    let tool_calls = parse_tool_calls(message, |_, i| format!("ollama_{i}"))?;
    let usage = match (
        v.get("prompt_eval_count").and_then(Value::as_u64),
        v.get("eval_count").and_then(Value::as_u64),
    ) {
        (None, None) => None,
        (p, c) => Some(Usage {
            prompt_tokens: p.unwrap_or(0),
            completion_tokens: c.unwrap_or(0),
        }),
    };
    Ok(Completion {
        content: non_empty(message.get("content").and_then(Value::as_str)),
        tool_calls,
        usage,
    })
}

#[cfg(test)]
#[path = "llm/tests.rs"]
mod tests;
