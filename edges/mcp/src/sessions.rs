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
//! the MCP service cancels a tool call when any of them fires. A `notifications/cancelled`
//! that arrives before the request it names was seen (the client sent both at once) is kept,
//! and the request starts cancelled. [`ClosingSessions`] wraps rmcp's in-memory session
//! manager to fire them for streamable HTTP and gives the session's place back
//! (`crate::http::places`), which also decides when an idle or unused session is closed; the
//! SSE transport fires its session's token when its event stream is dropped.

use crate::gate::InitGate;
use crate::http::places::SessionPlaces;
use crate::owner::SessionOwner;
use futures::Stream;
use rmcp::model::{ClientJsonRpcMessage, JsonRpcMessage, ServerJsonRpcMessage};
use rmcp::transport::streamable_http_server::session::local::LocalSessionManager;
use rmcp::transport::streamable_http_server::session::ServerSseMessage;
use rmcp::transport::streamable_http_server::{SessionId, SessionManager};
use std::collections::{HashMap, VecDeque};
use std::pin::Pin;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::task::{Context, Poll};
use tokio_util::sync::CancellationToken;

/// Most cancellations of requests not seen yet kept per session (the oldest are forgotten).
const MAX_EARLY_CANCELS: usize = 64;

/// Cancellation tokens of open sessions and running requests.
#[derive(Debug, Default)]
pub struct CallScopes {
    sessions: Mutex<HashMap<String, CancellationToken>>,
    requests: Mutex<HashMap<(String, String), CancellationToken>>,
    owners: Mutex<HashMap<String, SessionOwner>>,
    /// Per session, the requests cancelled before they were seen, oldest first.
    early_cancels: Mutex<HashMap<String, VecDeque<String>>>,
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
        lock(&self.early_cancels).remove(id);
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

    /// The token of `request` in `session`, cancelled when its connection drops early; born
    /// cancelled when the client cancelled it before it was seen ([`Self::cancel_request`]).
    pub fn request(&self, session: &str, request: &str) -> CancellationToken {
        let token = lock(&self.requests)
            .entry((session.to_owned(), request.to_owned()))
            .or_default()
            .clone();
        let mut early = lock(&self.early_cancels);
        if let Some(cancelled) = early.get_mut(session) {
            if let Some(at) = cancelled.iter().position(|r| r == request) {
                cancelled.remove(at);
                token.cancel();
            }
        }
        token
    }

    /// The client cancelled `request` of `session` (`notifications/cancelled`): cancels it, or,
    /// when it was not seen yet (a cancellation can overtake its request), makes it start
    /// cancelled. Only for open sessions; at most [`MAX_EARLY_CANCELS`] are kept per session.
    /// True when a running request was cancelled.
    pub fn cancel_request(&self, session: &str, request: &str) -> bool {
        let key = (session.to_owned(), request.to_owned());
        if let Some(token) = lock(&self.requests).get(&key) {
            token.cancel();
            return true;
        }
        if !lock(&self.sessions).contains_key(session) {
            return false;
        }
        let mut early = lock(&self.early_cancels);
        let cancelled = early.entry(session.to_owned()).or_default();
        if cancelled.len() >= MAX_EARLY_CANCELS {
            cancelled.pop_front();
        }
        cancelled.push_back(request.to_owned());
        false
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
/// request's response stream is dropped before its answer, and giving the session's place
/// back.
pub struct ClosingSessions {
    inner: LocalSessionManager,
    scopes: Arc<CallScopes>,
    places: Arc<SessionPlaces>,
    /// The streamable-HTTP sessions this manager opened (`scopes` also holds SSE sessions).
    opened: Mutex<HashMap<String, OpenSession>>,
}

/// What the direct call path needs to know of an open streamable-HTTP session.
struct OpenSession {
    /// Set by the session's [`InitGate`] at `notifications/initialized`.
    initialized: Arc<AtomicBool>,
}

impl ClosingSessions {
    /// Sessions tracked in `scopes`, holding `places`. rmcp's own idle timer is off: `places`
    /// says when a session expires, and the `/mcp` checks close it then.
    pub(crate) fn new(scopes: Arc<CallScopes>, places: Arc<SessionPlaces>) -> Self {
        let mut inner = LocalSessionManager::default();
        inner.session_config.keep_alive = None;
        Self {
            inner,
            scopes,
            places,
            opened: Mutex::default(),
        }
    }

    /// Closes session `id` if this manager still holds it (it expired, or its client opened
    /// another at its share).
    pub(crate) async fn close_if_open(&self, id: &str) {
        if lock(&self.opened).contains_key(id) {
            tracing::debug!(session = %id, "MCP session closed by robotd: cancelling its calls");
            if let Err(error) = self.close_session(&SessionId::from(id)).await {
                tracing::debug!(session = %id, %error, "MCP session already gone");
            }
        }
    }

    /// Whether session `id` is open and initialized, so a `tools/call` in it may be answered
    /// without rmcp's session worker. False for a session rmcp already ended.
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

    /// Closes the tokens and places of this manager's sessions that rmcp ended without a
    /// `DELETE` (a worker that failed). SSE sessions in the same scopes are not this manager's
    /// to judge.
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
                self.places.release(&id);
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
        self.places.release(id);
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
        // Created before the request reaches the handler, which looks it up.
        let cancelled = request.as_ref().map(|request| {
            let token = self.scopes.request(id, request);
            Box::pin(token.cancelled_owned()) as Cancelled
        });
        let inner = self.inner.create_stream(id, message).await?;
        Ok(AnswerStream {
            inner: Box::pin(inner),
            scopes: self.scopes.clone(),
            session: id.to_string(),
            request,
            answered: false,
            cancelled: cancelled.map(std::sync::Mutex::new),
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

/// Resolves when a request is cancelled.
type Cancelled = Pin<Box<dyn std::future::Future<Output = ()> + Send>>;

/// The response stream of one request: dropped before the answer went through, it cancels
/// the request. Once the request is cancelled (`notifications/cancelled`, or its session
/// closed) the stream ends unanswered: rmcp sends no answer to a cancelled request, and the
/// client's POST would otherwise wait for one until the session ends.
struct AnswerStream {
    inner: BoxedSse,
    scopes: Arc<CallScopes>,
    session: String,
    request: Option<String>,
    answered: bool,
    /// The request's cancellation (a mutex only to make the stream `Sync`, as rmcp asks).
    cancelled: Option<std::sync::Mutex<Cancelled>>,
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
            Poll::Pending => {
                let cancelled = self.cancelled.as_mut().is_some_and(|c| {
                    c.get_mut()
                        .unwrap_or_else(|e| e.into_inner())
                        .as_mut()
                        .poll(cx)
                        .is_ready()
                });
                if cancelled && !self.answered {
                    tracing::debug!(session = %self.session, request = ?self.request, "MCP request cancelled: its stream ends unanswered");
                    self.answered = true;
                    return Poll::Ready(None);
                }
            }
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
