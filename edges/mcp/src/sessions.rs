//! Stopping what a client started when the client goes away.
//!
//! A motion tool call must not outlive its caller. Besides `notifications/cancelled`
//! (handled by rmcp through the call's own cancellation token), a call is cancelled when:
//!
//! - its **session closes**: the legacy SSE stream is dropped, or a streamable-HTTP client
//!   sends `DELETE /mcp`;
//! - its **HTTP connection drops** before the answer was sent (streamable HTTP answers each
//!   `POST /mcp` on its own response stream; dropping that stream early is a cancel).
//!
//! [`CallScopes`] keeps one cancellation token per open session and per running request;
//! the MCP service cancels a tool call when any of them fires. [`ClosingSessions`] wraps rmcp's
//! in-memory session manager to fire them for streamable HTTP; the SSE transport fires its
//! session's token when its event stream is dropped.

use crate::gate::{InitGate, TOUCH_METHOD};
use crate::owner::SessionOwner;
use futures::Stream;
use rmcp::model::{
    ClientJsonRpcMessage, ClientNotification, CustomNotification, JsonRpcMessage,
    ServerJsonRpcMessage,
};
use rmcp::transport::streamable_http_server::session::local::LocalSessionManager;
use rmcp::transport::streamable_http_server::session::ServerSseMessage;
use rmcp::transport::streamable_http_server::{SessionId, SessionManager};
use std::collections::HashMap;
use std::pin::Pin;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::task::{Context, Poll};
use std::time::{Duration, Instant};
use tokio_util::sync::CancellationToken;

/// Cancellation tokens of open sessions and running requests.
#[derive(Debug, Default)]
pub struct CallScopes {
    sessions: Mutex<HashMap<String, CancellationToken>>,
    requests: Mutex<HashMap<(String, String), CancellationToken>>,
    owners: Mutex<HashMap<String, SessionOwner>>,
}

impl CallScopes {
    /// The token of session `id`, cancelled when the session closes.
    pub fn session(&self, id: &str) -> CancellationToken {
        lock(&self.sessions)
            .entry(id.to_owned())
            .or_default()
            .clone()
    }

    /// The token of session `id` while it is open.
    pub fn find_session(&self, id: &str) -> Option<CancellationToken> {
        lock(&self.sessions).get(id).cloned()
    }

    /// The token of a running `request` of `session`, if its response stream is open.
    pub fn find_request(&self, session: &str, request: &str) -> Option<CancellationToken> {
        lock(&self.requests)
            .get(&(session.to_owned(), request.to_owned()))
            .cloned()
    }

    /// Binds session `id` to the client that opened it ([`crate::owner`]).
    pub fn bind_owner(&self, id: &str, owner: SessionOwner) {
        lock(&self.owners).insert(id.to_owned(), owner);
    }

    /// Whether `owner` may use session `id`: false when the session is bound to another
    /// client. Unbound sessions are left to the transport (which answers unknown ones 404).
    pub fn owned_by(&self, id: &str, owner: &SessionOwner) -> bool {
        lock(&self.owners).get(id).is_none_or(|o| o == owner)
    }

    /// The session closed: cancel everything it started, and give the memory it used back to
    /// the system soon (once for a burst of sessions closing).
    pub fn close_session(&self, id: &str) {
        robotd_runtime::heap::release_soon();
        lock(&self.owners).remove(id);
        if let Some(token) = lock(&self.sessions).remove(id) {
            token.cancel();
        }
        lock(&self.requests).retain(|(session, _), token| {
            if session == id {
                token.cancel();
                false
            } else {
                true
            }
        });
    }

    /// The token of `request` in `session`, cancelled when its connection drops early.
    pub fn request(&self, session: &str, request: &str) -> CancellationToken {
        lock(&self.requests)
            .entry((session.to_owned(), request.to_owned()))
            .or_default()
            .clone()
    }

    /// `request` was answered (or abandoned, with `cancel`): forget its token.
    pub(crate) fn end_request(&self, session: &str, request: &str, cancel: bool) {
        if let Some(token) = lock(&self.requests).remove(&(session.to_owned(), request.to_owned()))
        {
            if cancel {
                token.cancel();
            }
        }
    }

    /// Open sessions and running requests tracked (for tests and metrics).
    pub fn len(&self) -> (usize, usize) {
        (lock(&self.sessions).len(), lock(&self.requests).len())
    }
}

fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

/// rmcp's in-memory session manager, firing [`CallScopes`] when a session closes or a
/// request's response stream is dropped before its answer.
pub struct ClosingSessions {
    inner: LocalSessionManager,
    scopes: Arc<CallScopes>,
    /// The streamable-HTTP sessions this manager opened (`scopes` also holds SSE sessions).
    opened: Mutex<HashMap<String, OpenSession>>,
    idle_timeout: Duration,
}

/// What the direct call path needs to know of an open streamable-HTTP session.
struct OpenSession {
    /// Set by the session's [`InitGate`] at `notifications/initialized`.
    initialized: Arc<AtomicBool>,
    /// When the direct path last told rmcp's worker the session is in use.
    touched: Instant,
}

impl ClosingSessions {
    /// Sessions tracked in `scopes`, closed after `idle_timeout` without a request.
    pub fn new(scopes: Arc<CallScopes>, idle_timeout: Duration) -> Self {
        let mut inner = LocalSessionManager::default();
        inner.session_config.keep_alive = Some(idle_timeout);
        Self {
            inner,
            scopes,
            opened: Mutex::default(),
            idle_timeout,
        }
    }

    /// Whether session `id` is open and initialized, so a `tools/call` in it may be answered
    /// without rmcp's session worker. False for a session rmcp already ended (idle).
    pub(crate) async fn takes_direct_calls(&self, id: &str) -> bool {
        let initialized = lock(&self.opened)
            .get(id)
            .is_some_and(|s| s.initialized.load(Ordering::Acquire));
        initialized
            && self
                .inner
                .has_session(&SessionId::from(id))
                .await
                .unwrap_or(false)
    }

    /// A direct call was served in session `id`: keeps rmcp's idle timer of the session from
    /// closing it, as a request through rmcp would. rmcp's worker restarts its timer at any
    /// message, so this sends it a [`TOUCH_METHOD`] notification (dropped by the session's
    /// gate), at most once per eighth of the idle timeout.
    pub(crate) async fn keep_open(&self, id: &str) {
        let now = Instant::now();
        let due = match lock(&self.opened).get_mut(id) {
            Some(session) if now.duration_since(session.touched) >= self.idle_timeout / 8 => {
                session.touched = now;
                true
            }
            _ => false,
        };
        if due {
            let touch = ClientJsonRpcMessage::notification(ClientNotification::CustomNotification(
                CustomNotification::new(TOUCH_METHOD, None),
            ));
            if let Err(error) = self.inner.accept_message(&SessionId::from(id), touch).await {
                tracing::debug!(session = %id, %error, "MCP session not kept open: it ended");
            }
        }
    }

    /// Sessions open now (rmcp's count: idle ones it closed are gone).
    pub async fn open_sessions(&self) -> usize {
        self.inner.sessions.read().await.len()
    }

    /// Closes the tokens of this manager's sessions that rmcp ended without a `DELETE`
    /// (idle timeout). SSE sessions in the same scopes are not this manager's to judge.
    async fn forget_ended(&self) -> Result<(), <LocalSessionManager as SessionManager>::Error> {
        let opened: Vec<String> = lock(&self.opened).keys().cloned().collect();
        for id in opened {
            if !self
                .inner
                .has_session(&SessionId::from(id.as_str()))
                .await?
            {
                lock(&self.opened).remove(&id);
                self.scopes.close_session(&id);
            }
        }
        Ok(())
    }
}

impl SessionManager for ClosingSessions {
    type Error = <LocalSessionManager as SessionManager>::Error;
    type Transport = InitGate<<LocalSessionManager as SessionManager>::Transport>;

    async fn create_session(&self) -> Result<(SessionId, Self::Transport), Self::Error> {
        // Sessions that ended without DELETE (timed out) leave tokens behind: drop them here.
        self.forget_ended().await?;
        let (id, transport) = self.inner.create_session().await?;
        self.scopes.session(&id);
        let gate = InitGate::new(transport);
        let session = OpenSession {
            initialized: gate.initialized_flag(),
            touched: Instant::now(),
        };
        lock(&self.opened).insert(id.to_string(), session);
        Ok((id, gate))
    }

    async fn initialize_session(
        &self,
        id: &SessionId,
        message: ClientJsonRpcMessage,
    ) -> Result<ServerJsonRpcMessage, Self::Error> {
        self.inner.initialize_session(id, message).await
    }

    async fn has_session(&self, id: &SessionId) -> Result<bool, Self::Error> {
        self.inner.has_session(id).await
    }

    async fn close_session(&self, id: &SessionId) -> Result<(), Self::Error> {
        tracing::debug!(session = %id, "MCP session closed by the client: cancelling its calls");
        lock(&self.opened).remove(id.as_ref());
        self.scopes.close_session(id);
        self.inner.close_session(id).await
    }

    async fn create_stream(
        &self,
        id: &SessionId,
        message: ClientJsonRpcMessage,
    ) -> Result<impl Stream<Item = ServerSseMessage> + Send + Sync + 'static, Self::Error> {
        let request = match &message {
            JsonRpcMessage::Request(r) => Some(r.id.to_string()),
            _ => None,
        };
        if let Some(request) = &request {
            // Created before the request reaches the handler, which looks it up.
            self.scopes.request(id, request);
        }
        let inner = self.inner.create_stream(id, message).await?;
        Ok(AnswerStream {
            inner: Box::pin(inner),
            scopes: self.scopes.clone(),
            session: id.to_string(),
            request,
            answered: false,
        })
    }

    async fn accept_message(
        &self,
        id: &SessionId,
        message: ClientJsonRpcMessage,
    ) -> Result<(), Self::Error> {
        self.inner.accept_message(id, message).await
    }

    async fn create_standalone_stream(
        &self,
        id: &SessionId,
    ) -> Result<impl Stream<Item = ServerSseMessage> + Send + Sync + 'static, Self::Error> {
        self.inner.create_standalone_stream(id).await
    }

    async fn resume(
        &self,
        id: &SessionId,
        last_event_id: String,
    ) -> Result<impl Stream<Item = ServerSseMessage> + Send + Sync + 'static, Self::Error> {
        self.inner.resume(id, last_event_id).await
    }
}

type BoxedSse = Pin<Box<dyn Stream<Item = ServerSseMessage> + Send + Sync>>;

/// The response stream of one request: dropped before the answer went through, it cancels
/// the request.
struct AnswerStream {
    inner: BoxedSse,
    scopes: Arc<CallScopes>,
    session: String,
    request: Option<String>,
    answered: bool,
}

impl Stream for AnswerStream {
    type Item = ServerSseMessage;

    fn poll_next(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<Option<Self::Item>> {
        let polled = self.inner.as_mut().poll_next(cx);
        match &polled {
            Poll::Ready(Some(item)) => {
                let answers = item.message.as_deref().and_then(|m| match m {
                    JsonRpcMessage::Response(r) => Some(r.id.to_string()),
                    JsonRpcMessage::Error(e) => e.id.as_ref().map(|id| id.to_string()),
                    _ => None,
                });
                if answers.is_some() && answers == self.request {
                    self.answered = true;
                }
            }
            Poll::Ready(None) => self.answered = true,
            Poll::Pending => {}
        }
        polled
    }
}

impl Drop for AnswerStream {
    fn drop(&mut self) {
        if let Some(request) = &self.request {
            if !self.answered {
                tracing::info!(session = %self.session, %request, "MCP client dropped the connection before the answer: cancelling the call");
            }
            self.scopes
                .end_request(&self.session, request, !self.answered);
        }
    }
}
