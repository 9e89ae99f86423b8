//! The one task that writes to Redis, and the queue in front of it.
//!
//! Producers (the camera thread, the detection and label relays) hand entries to an
//! [`EntrySender`], which never waits: when the queue is full — Redis slow, or away — the entry
//! is dropped and counted (`dropped_queue_full`). The writer appends what is queued with
//! `XADD … MAXLEN ~ n` in one pipeline per batch. When Redis fails it marks the edge down,
//! drops what is queued (counted `dropped_disconnected`: a stale frame is worth nothing later),
//! and reconnects with backoff from 100 ms doubling to 1 s, so it resumes within about a second
//! of Redis coming back.

use crate::status::EdgeStatus;
use crate::wire::{maxlen, Entry};
use redis::aio::{ConnectionManager, ConnectionManagerConfig};
use robotd_runtime::backoff::Backoff;
use std::sync::Arc;
use std::time::Duration;
use tokio::sync::mpsc;
use tokio_util::sync::CancellationToken;

/// Entries waiting for the writer, at most.
pub const QUEUE_CAPACITY: usize = 32;
/// Entries appended per pipeline, at most.
const BATCH: usize = 16;
/// First reconnect delay (also the connection manager's).
const BACKOFF_MIN: Duration = robotd_runtime::backoff::FIRST_DELAY;
/// Longest reconnect delay (the writer's and the consumer's).
pub(crate) const BACKOFF_MAX: Duration = Duration::from_secs(1);
/// A command that takes longer than this fails (Redis is taken to be unresponsive).
pub const RESPONSE_TIMEOUT: Duration = Duration::from_secs(2);
/// A connection attempt that takes longer than this fails.
pub const CONNECT_TIMEOUT: Duration = Duration::from_secs(1);

/// Hands entries to the writer without ever waiting.
#[derive(Clone, Debug)]
pub struct EntrySender {
    tx: mpsc::Sender<Entry>,
    status: Arc<EdgeStatus>,
}

impl EntrySender {
    /// Queues `entry`; drops and counts it when the queue is full. Returns whether it was
    /// queued.
    pub fn offer(&self, entry: Entry) -> bool {
        let stream = entry.stream;
        match self.tx.try_send(entry) {
            Ok(()) => true,
            Err(mpsc::error::TrySendError::Full(_)) => {
                self.status.count(stream, "dropped_queue_full");
                false
            }
            Err(mpsc::error::TrySendError::Closed(_)) => false,
        }
    }
}

/// Opens a connection manager to `client` (one attempt, bounded by the timeouts).
pub async fn connect(client: &redis::Client) -> redis::RedisResult<ConnectionManager> {
    let config = ConnectionManagerConfig::new()
        .set_number_of_retries(1)
        .set_min_delay(BACKOFF_MIN)
        .set_max_delay(BACKOFF_MAX)
        .set_connection_timeout(Some(CONNECT_TIMEOUT))
        .set_response_timeout(Some(RESPONSE_TIMEOUT));
    let mut manager = ConnectionManager::new_with_config(client.clone(), config).await?;
    // The manager connects lazily inside; a PING makes the first failure show here.
    redis::cmd("PING")
        .query_async::<()>(&mut manager)
        .await
        .map(|()| manager)
}

/// Starts the writer on the current tokio runtime; returns the sender producers use.
pub fn start(
    client: redis::Client,
    status: Arc<EdgeStatus>,
    stop: CancellationToken,
) -> (EntrySender, tokio::task::JoinHandle<()>) {
    let (tx, rx) = mpsc::channel(QUEUE_CAPACITY);
    let sender = EntrySender {
        tx,
        status: status.clone(),
    };
    let task = tokio::spawn(run(client, rx, status, stop));
    (sender, task)
}

async fn run(
    client: redis::Client,
    mut rx: mpsc::Receiver<Entry>,
    status: Arc<EdgeStatus>,
    stop: CancellationToken,
) {
    let mut connection: Option<ConnectionManager> = None;
    let mut backoff = Backoff::new(BACKOFF_MIN, BACKOFF_MAX);
    loop {
        if connection.is_none() {
            let attempt = tokio::select! {
                _ = stop.cancelled() => return,
                attempt = connect(&client) => attempt,
            };
            match attempt {
                Ok(c) => {
                    connection = Some(c);
                    backoff.reset();
                    status.connected();
                }
                Err(error) => {
                    status.down(&error.to_string());
                    // Drop what waits while the backoff runs: stale frames help no one.
                    let sleep = tokio::time::sleep(backoff.next_delay());
                    tokio::pin!(sleep);
                    loop {
                        tokio::select! {
                            _ = stop.cancelled() => return,
                            _ = &mut sleep => break,
                            entry = rx.recv() => match entry {
                                Some(e) => status.count(e.stream, "dropped_disconnected"),
                                None => return,
                            },
                        }
                    }
                    continue;
                }
            }
        }
        let first = tokio::select! {
            _ = stop.cancelled() => return,
            entry = rx.recv() => match entry {
                Some(e) => e,
                None => return,
            },
        };
        let mut batch = vec![first];
        while batch.len() < BATCH {
            match rx.try_recv() {
                Ok(e) => batch.push(e),
                Err(_) => break,
            }
        }
        let mut pipe = redis::pipe();
        for entry in &batch {
            let cmd = pipe
                .cmd("XADD")
                .arg(entry.stream)
                .arg("MAXLEN")
                .arg("~")
                .arg(maxlen(entry.stream))
                .arg("*");
            for (name, value) in &entry.fields {
                cmd.arg(*name).arg(value.as_bytes());
            }
            cmd.ignore();
        }
        let Some(conn) = connection.as_mut() else {
            continue;
        };
        let result = tokio::time::timeout(RESPONSE_TIMEOUT, pipe.query_async::<()>(conn)).await;
        match result {
            Ok(Ok(())) => {
                for entry in &batch {
                    status.count(entry.stream, "published");
                }
            }
            Ok(Err(error)) => {
                for entry in &batch {
                    status.count(entry.stream, "dropped_disconnected");
                }
                status.down(&error.to_string());
                connection = None;
            }
            Err(_) => {
                for entry in &batch {
                    status.count(entry.stream, "dropped_disconnected");
                }
                status.down("Redis did not answer within 2 s");
                connection = None;
            }
        }
    }
}
