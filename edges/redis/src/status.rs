//! The edge's state and counters, shared by its tasks and read by `get_system_status`,
//! `/health` and `/metrics`.
//!
//! Every count also goes to the process's Prometheus registry
//! (`robotd_redis_entries_total{stream, outcome}`, `robotd_redis_up`), so a dashboard sees
//! frames dropped while Redis was away and bad entries skipped from a misbehaving detector.

use robotd_runtime::metrics::Metrics;
use std::collections::BTreeMap;
use std::sync::Mutex;
use std::time::{SystemTime, UNIX_EPOCH};

/// Where the connection stands.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LinkState {
    /// Not connected yet.
    Connecting,
    /// Commands succeed.
    Connected,
    /// The last attempt failed; the edge retries with backoff.
    Down,
}

impl LinkState {
    /// A word for status texts.
    pub fn as_str(self) -> &'static str {
        match self {
            LinkState::Connecting => "connecting",
            LinkState::Connected => "connected",
            LinkState::Down => "down",
        }
    }
}

#[derive(Debug)]
struct Inner {
    state: LinkState,
    since_unix_s: f64,
    last_error: Option<String>,
    reconnects: u64,
    counts: BTreeMap<(String, String), u64>,
}

/// State and counters of the running edge.
#[derive(Debug)]
pub struct EdgeStatus {
    target: String,
    trust: &'static str,
    inner: Mutex<Inner>,
}

fn now_s() -> f64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map(|d| d.as_secs_f64())
        .unwrap_or(0.0)
}

impl EdgeStatus {
    /// A fresh status for the edge connecting to `target` (display form, no password).
    pub fn new(target: &str, trust: &'static str) -> EdgeStatus {
        Metrics::global().redis_up(false);
        EdgeStatus {
            target: target.to_owned(),
            trust,
            inner: Mutex::new(Inner {
                state: LinkState::Connecting,
                since_unix_s: now_s(),
                last_error: None,
                reconnects: 0,
                counts: BTreeMap::new(),
            }),
        }
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, Inner> {
        self.inner
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
    }

    /// The connection state.
    pub fn state(&self) -> LinkState {
        self.lock().state
    }

    /// Commands succeed again (or for the first time).
    pub fn connected(&self) {
        let mut inner = self.lock();
        if inner.state != LinkState::Connected {
            if inner.state == LinkState::Down {
                inner.reconnects += 1;
                tracing::info!(target = %self.target, "redis edge: connected again");
            } else {
                tracing::info!(target = %self.target, "redis edge: connected");
            }
            inner.state = LinkState::Connected;
            inner.since_unix_s = now_s();
        }
        Metrics::global().redis_up(true);
    }

    /// A command or connection attempt failed with `error`.
    pub fn down(&self, error: &str) {
        let mut inner = self.lock();
        if inner.state != LinkState::Down {
            tracing::warn!(
                target = %self.target,
                %error,
                "redis edge: Redis is unreachable; the robot carries on, the edge retries"
            );
            inner.state = LinkState::Down;
            inner.since_unix_s = now_s();
        }
        inner.last_error = Some(error.to_owned());
        Metrics::global().redis_up(false);
    }

    /// Counts one entry of `stream` with `outcome`.
    pub fn count(&self, stream: &str, outcome: &str) {
        *self
            .lock()
            .counts
            .entry((stream.to_owned(), outcome.to_owned()))
            .or_default() += 1;
        Metrics::global().redis_entry(stream, outcome);
    }

    /// How many entries of `stream` had `outcome`.
    pub fn counted(&self, stream: &str, outcome: &str) -> u64 {
        self.lock()
            .counts
            .get(&(stream.to_owned(), outcome.to_owned()))
            .copied()
            .unwrap_or(0)
    }

    /// Everything, as JSON (for `get_system_status` and `/health`).
    pub fn to_json(&self) -> serde_json::Value {
        let inner = self.lock();
        let mut streams = serde_json::Map::new();
        for ((stream, outcome), n) in &inner.counts {
            let entry = streams
                .entry(stream.clone())
                .or_insert_with(|| serde_json::json!({}));
            entry[outcome] = serde_json::json!(n);
        }
        serde_json::json!({
            "state": inner.state.as_str(),
            "target": self.target,
            "trust": self.trust,
            "since_unix_s": inner.since_unix_s,
            "reconnects": inner.reconnects,
            "last_error": inner.last_error,
            "streams": streams,
        })
    }
}
