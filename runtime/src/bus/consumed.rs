//! Waiting for room on a back-pressure topic: the handler a publisher gives iceoryx2 for the
//! moment a subscriber's queue is full. It sleeps in the kernel on the topic's `consumed`
//! event (raised by subscribers after they take messages), retries on every wake-up, and
//! gives up with "not delivered" after the topic's `max_wait`.

use super::{Bus, BusError};
use iceoryx2::port::{BackpressureAction, BackpressureInfo};
use std::sync::Arc;
use std::time::Duration;

/// Blocks a back-pressured sender until a subscriber consumed something, or gives up.
///
/// Its listener on the topic's `consumed` event exists only once needed: during the
/// publisher's handshake (dropped after it), and from the first time a subscriber's queue is
/// full (kept from then on: a publisher that met a slow subscriber once is likely to again).
/// A publisher whose subscribers keep up — most of them, most of the time — holds none: a
/// socket, a port and a shared-memory segment fewer each.
#[derive(Clone)]
pub(crate) struct ConsumedWaiter {
    name: String,
    listener: Arc<std::sync::Mutex<Option<Arc<super::wake::PlainListener>>>>,
    bus: Bus,
    last_cleanup: Arc<std::sync::Mutex<std::time::Instant>>,
}

/// How long a sender waits on a full subscriber before it checks for dead subscribers.
const DEAD_SUBSCRIBER_CHECK: Duration = Duration::from_millis(100);

/// How long a full sender sleeps between retries when it cannot make its listener.
const RETRY_WITHOUT_LISTENER: Duration = Duration::from_millis(1);

impl ConsumedWaiter {
    pub(crate) fn new(bus: &Bus, name: &str) -> Self {
        Self {
            name: name.to_owned(),
            listener: Arc::default(),
            bus: bus.clone(),
            last_cleanup: Arc::new(std::sync::Mutex::new(std::time::Instant::now())),
        }
    }

    /// The listener, if one exists now.
    fn current(&self) -> Option<Arc<super::wake::PlainListener>> {
        self.listener
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .clone()
    }

    /// Starts listening (if not yet); notifications from then on are kept for the next wait.
    pub(crate) fn listen(&self) -> Result<Arc<super::wake::PlainListener>, BusError> {
        let mut slot = self.listener.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(listener) = &*slot {
            return Ok(listener.clone());
        }
        let listener = Arc::new(super::wake::listener(&self.bus, &self.name)?);
        *slot = Some(listener.clone());
        Ok(listener)
    }

    /// Stops listening.
    pub(crate) fn stop_listening(&self) {
        *self.listener.lock().unwrap_or_else(|e| e.into_inner()) = None;
    }

    pub(crate) fn on_full(
        &self,
        info: &BackpressureInfo,
        max_wait: Duration,
    ) -> BackpressureAction {
        if info.elapsed_time >= DEAD_SUBSCRIBER_CHECK {
            // Still full after a while: a subscriber whose process died never makes room.
            // Remove such leftovers (a scan of the nodes, so not on every full buffer).
            let mut last = self.last_cleanup.lock().unwrap_or_else(|e| e.into_inner());
            if last.elapsed() >= DEAD_SUBSCRIBER_CHECK {
                *last = std::time::Instant::now();
                drop(last);
                self.bus.cleanup_dead_nodes();
            }
        }
        let Some(left) = max_wait.checked_sub(info.elapsed_time) else {
            return BackpressureAction::DiscardDataAndFail;
        };
        if left.is_zero() {
            return BackpressureAction::DiscardDataAndFail;
        }
        let listener = match self.current() {
            Some(listener) => listener,
            // The first full queue: listen, then retry at once rather than wait. Room made
            // before the listener existed is seen by that retry; room made after it wakes
            // the next wait.
            None => {
                if let Err(error) = self.listen() {
                    tracing::warn!(%error, "a full sender cannot wait for room; retrying");
                    std::thread::sleep(left.min(RETRY_WITHOUT_LISTENER));
                }
                return BackpressureAction::Retry;
            }
        };
        // Sleeps in the kernel until a subscriber reports progress (or the time is up).
        let _ = listener.timed_wait(|_| {}, left);
        BackpressureAction::Retry
    }
}

#[cfg(test)]
mod tests {
    use crate::bus::pubsub::tests::{listeners, ping};
    use crate::bus::wake::consumed_event;
    use crate::bus::{Bus, BusOptions, Overflow, Topic};
    use robotd_protocol::diagnostics::Ping;
    use std::time::Duration;

    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn a_sender_listens_for_room_only_once_a_queue_was_full() {
        const SLOW: Topic<Ping> = Topic::new(
            "slow",
            Overflow::BackPressure {
                depth: 2,
                max_wait: Duration::from_millis(500),
            },
        );
        let namespace = format!("test-room-{}", std::process::id());
        let bus = Bus::open(BusOptions::new(&namespace, "room")).unwrap();
        let mut subscriber = bus.subscriber(&SLOW).unwrap();
        let publisher = bus.publisher(&SLOW).unwrap();
        let consumed = consumed_event("slow");
        assert_eq!(listeners(&bus, &consumed), 0, "none after the handshake");
        publisher.publish(&ping(0)).unwrap();
        publisher.publish(&ping(1)).unwrap();
        assert_eq!(listeners(&bus, &consumed), 0, "none while there is room");

        // The queue is full: the third message waits for room, which a reader makes later.
        let reader = tokio::spawn(async move {
            tokio::time::sleep(Duration::from_millis(100)).await;
            for expected in 0..3 {
                let message = subscriber.recv().await.unwrap();
                assert_eq!(message.body.seq, expected);
            }
        });
        let started = std::time::Instant::now();
        let sent = tokio::task::spawn_blocking(move || {
            let result = publisher.publish(&ping(2));
            (result, publisher)
        });
        let (result, _publisher) = sent.await.unwrap();
        assert_eq!(result.unwrap(), 1, "delivered once room was made");
        assert!(started.elapsed() >= Duration::from_millis(50), "it waited");
        assert_eq!(listeners(&bus, &consumed), 1, "kept after a full queue");
        tokio::time::timeout(Duration::from_secs(2), reader)
            .await
            .unwrap()
            .unwrap();
    }
}
