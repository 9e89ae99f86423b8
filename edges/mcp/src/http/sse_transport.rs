//! rmcp's side of a legacy-SSE session, with a bound on the requests it holds unanswered.
//!
//! rmcp reads a session's next message without waiting for its earlier answers: each answer is
//! written by a task of its own. With a client that stops reading its event stream, nothing
//! would stop rmcp from taking request after request, each holding a task and its answer.
//! [`SseTransport`] hands rmcp a request only while fewer than [`MAX_UNANSWERED`] of the
//! session's requests have no answer on the stream's queue yet; beyond, the posted messages
//! wait in the session's queue, and a POST that finds that queue full long enough is refused
//! with 503 (`super::sse`).
//!
//! A request's place is given back when its answer is queued onto the stream (or the answer
//! is dropped unsent), or when the client cancels it (rmcp then sends no answer). An id the
//! client reuses while it is still unanswered gets one answer from rmcp, which gives back all
//! its places.
//!
//! While a request waits for a place, the transport reads on (up to [`MAX_READ_AHEAD`]
//! messages) so that a cancellation is not stuck behind it: a `notifications/cancelled` goes
//! to rmcp at once, and one that names a request still waiting here (or read ahead) removes
//! that request, which then never runs and gets no answer (as the MCP spec asks of a cancelled
//! request). Every other message read ahead keeps its order behind the waiting request.

use super::sse::SharedSender;
use futures::channel::mpsc;
use futures::StreamExt;
use rmcp::model::{
    ClientJsonRpcMessage, ClientNotification, JsonRpcMessage, RequestId, ServerJsonRpcMessage,
};
use rmcp::transport::Transport;
use rmcp::RoleServer;
use std::collections::{HashMap, VecDeque};
use std::future::Future;
use std::sync::{Arc, Mutex, PoisonError};
use tokio::sync::{OwnedSemaphorePermit, Semaphore};

/// Most requests of one SSE session that rmcp holds without their answer on the stream's queue.
pub(super) const MAX_UNANSWERED: usize = 64;

/// Most messages read past a request that waits for a place, looking for cancellations.
pub(super) const MAX_READ_AHEAD: usize = MAX_UNANSWERED;

/// The places of unanswered requests, by request id (a list: a client may reuse an id).
type Unanswered = Arc<Mutex<HashMap<RequestId, Vec<OwnedSemaphorePermit>>>>;

/// The messages a client posted into its SSE session, in, and the session's event stream,
/// out (see the module documentation).
pub(super) struct SseTransport {
    from_client: mpsc::Receiver<ClientJsonRpcMessage>,
    to_client: SharedSender<ServerJsonRpcMessage>,
    room: Arc<Semaphore>,
    unanswered: Unanswered,
    /// A request taken from the queue, waiting for a place.
    waiting: Option<ClientJsonRpcMessage>,
    /// Messages read past the waiting request, in the order they came.
    read_ahead: VecDeque<ClientJsonRpcMessage>,
}

impl SseTransport {
    /// rmcp reads the session's posted messages from `from_client` and writes onto its
    /// stream through `to_client`.
    pub(super) fn new(
        from_client: mpsc::Receiver<ClientJsonRpcMessage>,
        to_client: SharedSender<ServerJsonRpcMessage>,
    ) -> Self {
        Self {
            from_client,
            to_client,
            room: Arc::new(Semaphore::new(MAX_UNANSWERED)),
            unanswered: Arc::default(),
            waiting: None,
            read_ahead: VecDeque::new(),
        }
    }
}

/// Takes every place held under request `id` (rmcp answers a reused id once: one answer ends
/// all of them).
fn take_places(unanswered: &Unanswered, id: &RequestId) -> Vec<OwnedSemaphorePermit> {
    unanswered
        .lock()
        .unwrap_or_else(PoisonError::into_inner)
        .remove(id)
        .unwrap_or_default()
}

/// Queues `message` on `sender` once there is room. Unlike `SinkExt::send`, which queues the
/// message first and then waits for room (a send that times out has still queued its
/// message), this either queues it or waits; dropped while waiting, nothing was queued.
pub(super) async fn queue<T>(
    sender: &mut mpsc::Sender<T>,
    message: T,
) -> Result<(), mpsc::SendError> {
    std::future::poll_fn(|cx| sender.poll_ready(cx)).await?;
    sender.start_send(message)
}

impl Transport<RoleServer> for SseTransport {
    type Error = mpsc::SendError;

    fn send(
        &mut self,
        item: ServerJsonRpcMessage,
    ) -> impl Future<Output = Result<(), Self::Error>> + Send + 'static {
        let to_client = self.to_client.clone();
        // The answer holds its request's place until it is queued onto the stream, or dropped
        // (rmcp may drop a send the gate started inside `receive`): either way it comes back.
        let answers = match &item {
            JsonRpcMessage::Response(response) => Some(&response.id),
            JsonRpcMessage::Error(error) => error.id.as_ref(),
            _ => None,
        };
        let places = answers.map(|id| take_places(&self.unanswered, id));
        async move {
            let queued = queue(&mut *to_client.lock().await, item).await;
            drop(places);
            queued
        }
    }

    // Cancel-safe: rmcp drops this future whenever something else happened first. Every
    // message taken from the queue is kept in `self` across an await, and the next call takes
    // it up again.
    async fn receive(&mut self) -> Option<ClientJsonRpcMessage> {
        loop {
            if let Some(JsonRpcMessage::Request(request)) = &self.waiting {
                let id = request.id.clone();
                let room = Arc::clone(&self.room);
                let may_read_on = self.read_ahead.len() < MAX_READ_AHEAD;
                tokio::select! {
                    biased;
                    place = room.acquire_owned() => {
                        self.unanswered
                            .lock()
                            .unwrap_or_else(PoisonError::into_inner)
                            .entry(id)
                            .or_default()
                            .push(place.ok()?);
                        return self.waiting.take();
                    }
                    next = self.from_client.next(), if may_read_on => {
                        let message = next?;
                        match cancelled_id(&message) {
                            Some(cancelled) if cancelled == &id => self.waiting = None,
                            Some(cancelled) => {
                                let before = self.read_ahead.len();
                                self.read_ahead.retain(|m| !is_request(m, cancelled));
                                if self.read_ahead.len() == before {
                                    return Some(self.pass_on(message));
                                }
                            }
                            None => self.read_ahead.push_back(message),
                        }
                        continue;
                    }
                }
            }
            let message = match self.read_ahead.pop_front() {
                Some(message) => message,
                None => self.from_client.next().await?,
            };
            if matches!(message, JsonRpcMessage::Request(_)) {
                // Waits for a place at the top of the loop.
                self.waiting = Some(message);
                continue;
            }
            return Some(self.pass_on(message));
        }
    }

    async fn close(&mut self) -> Result<(), Self::Error> {
        Ok(())
    }
}

impl SseTransport {
    /// A message that needs no place, on its way to rmcp: a cancellation gives its request's
    /// places back (rmcp sends no answer to a cancelled request).
    fn pass_on(&self, message: ClientJsonRpcMessage) -> ClientJsonRpcMessage {
        if let Some(id) = cancelled_id(&message) {
            drop(take_places(&self.unanswered, id));
        }
        message
    }
}

/// The request a `notifications/cancelled` names.
fn cancelled_id(message: &ClientJsonRpcMessage) -> Option<&RequestId> {
    let JsonRpcMessage::Notification(notification) = message else {
        return None;
    };
    let ClientNotification::CancelledNotification(cancelled) = &notification.notification else {
        return None;
    };
    cancelled.params.request_id.as_ref()
}

/// Whether `message` is request `id`.
fn is_request(message: &ClientJsonRpcMessage, id: &RequestId) -> bool {
    matches!(message, JsonRpcMessage::Request(request) if &request.id == id)
}

#[cfg(test)]
mod tests {
    use super::*;
    use futures::SinkExt;

    fn request(id: i64) -> ClientJsonRpcMessage {
        serde_json::from_value(serde_json::json!({"jsonrpc": "2.0", "id": id, "method": "ping"}))
            .unwrap()
    }

    /// A session's transport: where the client's posts go in, and its stream's queue.
    fn session() -> (
        mpsc::Sender<ClientJsonRpcMessage>,
        SseTransport,
        mpsc::Receiver<ServerJsonRpcMessage>,
    ) {
        let (to_server, from_client) = mpsc::channel(2 * MAX_UNANSWERED);
        let (to_client, from_server) = mpsc::channel(2 * MAX_UNANSWERED);
        let transport =
            SseTransport::new(from_client, Arc::new(tokio::sync::Mutex::new(to_client)));
        (to_server, transport, from_server)
    }

    /// Posts request `id` and checks the transport takes it within 5 s (`room` names the
    /// place that must have come back).
    async fn takes_request(
        to_server: &mut mpsc::Sender<ClientJsonRpcMessage>,
        transport: &mut SseTransport,
        id: i64,
        room: &str,
    ) {
        to_server.send(request(id)).await.unwrap();
        let next = tokio::time::timeout(std::time::Duration::from_secs(5), transport.receive())
            .await
            .unwrap_or_else(|_| panic!("{room} did not come back"))
            .expect("a request");
        assert!(matches!(next, JsonRpcMessage::Request(r) if r.id == RequestId::Number(id)));
    }

    fn answer(id: i64) -> ServerJsonRpcMessage {
        ServerJsonRpcMessage::response(rmcp::model::ServerResult::empty(()), RequestId::Number(id))
    }

    #[tokio::test]
    async fn no_more_requests_are_taken_than_have_room_until_one_is_answered() {
        let (mut to_server, mut transport, mut from_server) = session();
        for id in 0..=MAX_UNANSWERED as i64 {
            to_server.send(request(id)).await.unwrap();
        }
        for _ in 0..MAX_UNANSWERED {
            assert!(transport.receive().await.is_some());
        }
        let waits = tokio::time::timeout(std::time::Duration::from_millis(50), transport.receive());
        assert!(waits.await.is_err(), "a request beyond the bound was taken");
        transport.send(answer(3)).await.unwrap();
        assert!(
            from_server.next().await.is_some(),
            "the answer is on the stream"
        );
        let next = transport.receive().await.expect("room again");
        assert!(matches!(next, JsonRpcMessage::Request(r) if r.id == RequestId::Number(64)));
    }

    #[tokio::test]
    async fn a_cancelled_request_gives_its_place_back() {
        let (mut to_server, mut transport, _from_server) = session();
        for id in 0..MAX_UNANSWERED as i64 {
            to_server.send(request(id)).await.unwrap();
            transport.receive().await.unwrap();
        }
        // A notification needs no place; a cancellation gives its request's place back (rmcp
        // sends no answer to a cancelled request).
        let cancel = serde_json::json!({"jsonrpc": "2.0", "method": "notifications/cancelled",
            "params": {"requestId": 5}});
        to_server
            .send(serde_json::from_value(cancel).unwrap())
            .await
            .unwrap();
        let next = transport.receive().await.expect("the cancellation");
        assert!(matches!(next, JsonRpcMessage::Notification(_)));
        takes_request(
            &mut to_server,
            &mut transport,
            99,
            "the cancelled request's place",
        )
        .await;
    }

    #[tokio::test]
    async fn a_queueing_that_gave_up_queued_nothing() {
        let (mut sender, mut receiver) = mpsc::channel::<u32>(1);
        // One slot of the channel, one of the sender: then it waits.
        queue(&mut sender, 1).await.unwrap();
        queue(&mut sender, 2).await.unwrap();
        let gave_up =
            tokio::time::timeout(std::time::Duration::from_millis(50), queue(&mut sender, 3));
        assert!(gave_up.await.is_err(), "there was no room");
        assert_eq!(receiver.next().await, Some(1));
        assert_eq!(receiver.next().await, Some(2));
        assert!(
            receiver.try_recv().is_err(),
            "3 was queued although refused"
        );
    }

    #[tokio::test]
    async fn one_answer_gives_back_every_place_of_a_reused_id() {
        let (mut to_server, mut transport, _from_server) = session();
        for _ in 0..MAX_UNANSWERED {
            to_server.send(request(7)).await.unwrap();
            transport.receive().await.unwrap();
        }
        // rmcp answers a reused id once.
        transport.send(answer(7)).await.unwrap();
        takes_request(&mut to_server, &mut transport, 8, "the reused id's places").await;
    }

    fn cancel(id: i64) -> ClientJsonRpcMessage {
        serde_json::from_value(serde_json::json!({"jsonrpc": "2.0",
            "method": "notifications/cancelled", "params": {"requestId": id}}))
        .unwrap()
    }

    /// Fills every place: requests 0..MAX_UNANSWERED are inside rmcp, unanswered.
    async fn full(
        to_server: &mut mpsc::Sender<ClientJsonRpcMessage>,
        transport: &mut SseTransport,
    ) {
        for id in 0..MAX_UNANSWERED as i64 {
            to_server.send(request(id)).await.unwrap();
            transport.receive().await.unwrap();
        }
    }

    #[tokio::test]
    async fn a_cancellation_is_not_held_up_by_a_request_waiting_for_a_place() {
        let (mut to_server, mut transport, _from_server) = session();
        full(&mut to_server, &mut transport).await;
        to_server.send(request(100)).await.unwrap();
        to_server.send(request(101)).await.unwrap();
        to_server.send(cancel(5)).await.unwrap();
        let next = tokio::time::timeout(std::time::Duration::from_secs(5), transport.receive())
            .await
            .expect("the cancellation went past the waiting request")
            .unwrap();
        assert_eq!(cancelled_id(&next), Some(&RequestId::Number(5)));
        // Its place came back: the waiting requests follow, in order.
        let next = transport.receive().await.unwrap();
        assert!(is_request(&next, &RequestId::Number(100)));
        transport.send(answer(6)).await.unwrap();
        let next = transport.receive().await.unwrap();
        assert!(is_request(&next, &RequestId::Number(101)));
    }

    #[tokio::test]
    async fn a_request_cancelled_while_it_waits_for_a_place_never_reaches_rmcp() {
        let (mut to_server, mut transport, _from_server) = session();
        full(&mut to_server, &mut transport).await;
        to_server.send(request(100)).await.unwrap();
        to_server.send(request(101)).await.unwrap();
        to_server.send(request(102)).await.unwrap();
        to_server.send(cancel(100)).await.unwrap();
        to_server.send(cancel(101)).await.unwrap();
        let waits = tokio::time::timeout(std::time::Duration::from_millis(50), transport.receive());
        assert!(waits.await.is_err(), "no place yet, nothing to hand on");
        transport.send(answer(0)).await.unwrap();
        let next = transport.receive().await.unwrap();
        assert!(
            is_request(&next, &RequestId::Number(102)),
            "100 (waiting) and 101 (read ahead) were cancelled: {next:?}"
        );
    }
}
