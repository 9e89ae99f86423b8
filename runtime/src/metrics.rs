//! Process metrics in the Prometheus / OpenMetrics text format.
//!
//! robotd counts what an operator needs to see on a dashboard: how many messages each bus topic
//! carries and how long they take, how many were dropped and why, and how the supervised actors
//! are doing (up or down, restarts, exhausted restart budgets). The bus and the supervisors
//! record into [`Metrics::global()`]; the HTTP edge serves [`Metrics::render`] at
//! `GET /metrics` with the [`CONTENT_TYPE`] header, where Prometheus scrapes it.
//!
//! | metric | type | labels |
//! |---|---|---|
//! | `robotd_bus_messages_total` | counter | `topic`, `direction` (`sent`/`received`) |
//! | `robotd_bus_latency_seconds` | histogram (5 µs … 1 s) | `topic` |
//! | `robotd_bus_dropped_total` | counter | `topic`, `reason` |
//! | `robotd_actor_restarts_total` | counter | `actor` |
//! | `robotd_actor_up` | gauge (1 = running, 0 = down) | `actor` |
//! | `robotd_actor_budget_exhausted_total` | counter | `actor` |
//! | `robotd_tool_calls_total` | counter | `transport` (`sse`, `streamable_http`, `stdio`), `status` (`ok`, `failed`, `protocol_error`) |
//! | `robotd_stt_model_loaded` | gauge (1 = the STT actor's model is loaded) | – |
//! | `robotd_stt_utterances_total` | counter (requests transcribed) | – |
//! | `robotd_stt_errors_total` | counter (requests refused or failed) | – |
//! | `robotd_stt_audio_seconds_total` | counter (seconds of audio transcribed) | – |
//! | `robotd_stt_processing_seconds_total` | counter (seconds spent transcribing) | – |
//! | `robotd_stt_real_time_factor` | gauge (processing ÷ audio time of the last utterance) | – |
//!
//! Recording is cheap enough for every bus message: after the first message on a topic, a
//! call is a shared read lock, one hash lookup by `&str` (no allocation) and an atomic add
//! (a short mutex for the histogram).
//!
//! ```
//! use robotd_runtime::metrics::{Direction, Metrics};
//!
//! let metrics = Metrics::new(); // tests use their own; the runtime uses Metrics::global()
//! metrics.bus_message("arm.command", Direction::Sent);
//! metrics.bus_latency("arm.command", 0.000_120);
//! metrics.actor_up("arm", true);
//!
//! let text = metrics.render();
//! assert!(text.contains(r#"robotd_bus_messages_total{topic="arm.command",direction="sent"} 1"#));
//! assert!(text.contains(r#"robotd_actor_up{actor="arm"} 1"#));
//! ```

use prometheus_client::encoding::text::encode;
use prometheus_client::encoding::{EncodeLabelValue, LabelValueEncoder};
use prometheus_client::metrics::counter::Counter;
use prometheus_client::metrics::family::Family;
use prometheus_client::metrics::gauge::Gauge;
use prometheus_client::metrics::histogram::Histogram;
use prometheus_client::registry::{Registry, Unit};
use std::collections::HashMap;
use std::fmt;
use std::sync::atomic::AtomicU64;
use std::sync::{Arc, OnceLock, PoisonError, RwLock};

/// The `Content-Type` of [`Metrics::render`]'s output (OpenMetrics text 1.0.0), for the HTTP
/// edge's `GET /metrics` response. Prometheus negotiates and parses it natively.
pub const CONTENT_TYPE: &str = "application/openmetrics-text; version=1.0.0; charset=utf-8";

/// Upper bounds (seconds) of the bus latency histogram buckets: 5 µs to 1 s, roughly ×2–2.5
/// per step, so both shared-memory hand-offs (µs) and slow request/replies (100s of ms) resolve.
pub const LATENCY_BUCKETS: [f64; 17] = [
    0.000_005, 0.000_01, 0.000_025, 0.000_05, 0.000_1, 0.000_25, 0.000_5, 0.001, 0.002_5, 0.005,
    0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1.0,
];

/// Which way a bus message went, from the point of view of the process that counts it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Direction {
    /// Published or sent (publisher, client request, server reply).
    Sent,
    /// Taken from the bus (subscriber, server request, client reply).
    Received,
}

impl Direction {
    /// The label value: `"sent"` or `"received"`.
    pub fn as_str(self) -> &'static str {
        match self {
            Direction::Sent => "sent",
            Direction::Received => "received",
        }
    }
}

impl EncodeLabelValue for Direction {
    fn encode(&self, encoder: &mut LabelValueEncoder) -> Result<(), fmt::Error> {
        EncodeLabelValue::encode(&self.as_str(), encoder)
    }
}

type TopicLabels = [(&'static str, Arc<str>); 1];
type TopicDirectionLabels = (
    [(&'static str, Arc<str>); 1],
    [(&'static str, Direction); 1],
);
type TopicReasonLabels = [(&'static str, Arc<str>); 2];
type ActorLabels = [(&'static str, Arc<str>); 1];

fn latency_histogram() -> Histogram {
    Histogram::new(LATENCY_BUCKETS)
}

/// Handles of one topic's metrics, cached so the hot path never builds label sets.
struct TopicHandles {
    /// The interned topic name, shared by every label set of this topic.
    topic: Arc<str>,
    sent: Counter,
    received: Counter,
    latency: Histogram,
    /// Drop counters by reason; a topic sees only a handful of reasons.
    dropped: RwLock<Vec<(Box<str>, Counter)>>,
}

struct Inner {
    registry: Registry,
    messages: Family<TopicDirectionLabels, Counter>,
    latency: Family<TopicLabels, Histogram, fn() -> Histogram>,
    dropped: Family<TopicReasonLabels, Counter>,
    restarts: Family<ActorLabels, Counter>,
    up: Family<ActorLabels, Gauge>,
    budget_exhausted: Family<ActorLabels, Counter>,
    redis_up: Gauge,
    redis_entries: Family<TopicReasonLabels, Counter>,
    tool_calls: Family<TopicReasonLabels, Counter>,
    stt: SttMetrics,
    topics: RwLock<HashMap<Arc<str>, Arc<TopicHandles>>>,
}

/// robotd's metrics registry. Cheap to clone (an `Arc` inside); every clone records into the
/// same series.
///
/// The runtime records into [`Metrics::global()`]; a [`Metrics::new()`] instance is
/// independent of it (handy in tests).
#[derive(Clone)]
pub struct Metrics {
    inner: Arc<Inner>,
}

impl fmt::Debug for Metrics {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Metrics").finish_non_exhaustive()
    }
}

impl Default for Metrics {
    fn default() -> Self {
        Self::new()
    }
}

impl Metrics {
    /// A fresh registry with every robotd metric family registered (and no series yet).
    pub fn new() -> Self {
        let mut registry = Registry::with_prefix("robotd");
        let messages = Family::<TopicDirectionLabels, Counter>::default();
        let latency: Family<TopicLabels, Histogram, fn() -> Histogram> =
            Family::new_with_constructor(latency_histogram);
        let dropped = Family::<TopicReasonLabels, Counter>::default();
        let restarts = Family::<ActorLabels, Counter>::default();
        let up = Family::<ActorLabels, Gauge>::default();
        let budget_exhausted = Family::<ActorLabels, Counter>::default();
        let redis_up = Gauge::default();
        let redis_entries = Family::<TopicReasonLabels, Counter>::default();
        let tool_calls = Family::<TopicReasonLabels, Counter>::default();
        registry.register(
            "bus_messages",
            "Messages sent to or received from the bus, by topic and direction",
            messages.clone(),
        );
        registry.register_with_unit(
            "bus_latency",
            "Bus latency by topic: send-to-receive time of published messages, round-trip time of requests",
            Unit::Seconds,
            latency.clone(),
        );
        registry.register(
            "bus_dropped",
            "Messages that did not reach a receiver, by topic and reason",
            dropped.clone(),
        );
        registry.register(
            "actor_restarts",
            "Restarts of a supervised actor",
            restarts.clone(),
        );
        registry.register(
            "actor_up",
            "Whether a supervised actor is running (1) or down (0)",
            up.clone(),
        );
        registry.register(
            "actor_budget_exhausted",
            "Times an actor used up its restart budget and was left stopped",
            budget_exhausted.clone(),
        );
        registry.register(
            "redis_up",
            "Whether the Redis edge is connected (1) or not (0; also 0 when the edge is off)",
            redis_up.clone(),
        );
        registry.register(
            "redis_entries",
            "Redis stream entries by stream and outcome (published, dropped_*, consumed, skipped_*)",
            redis_entries.clone(),
        );
        registry.register(
            "tool_calls",
            "Tool calls served to MCP clients, by transport and status (each call counted once, when answered)",
            tool_calls.clone(),
        );
        let stt = SttMetrics::register(&mut registry);
        Self {
            inner: Arc::new(Inner {
                registry,
                messages,
                latency,
                dropped,
                restarts,
                up,
                budget_exhausted,
                redis_up,
                redis_entries,
                tool_calls,
                stt,
                topics: RwLock::new(HashMap::new()),
            }),
        }
    }

    /// The process-wide instance the bus, the supervisors and `GET /metrics` share.
    pub fn global() -> &'static Metrics {
        static GLOBAL: OnceLock<Metrics> = OnceLock::new();
        GLOBAL.get_or_init(Metrics::new)
    }

    /// Runs `f` with the cached handles of `topic`, creating them on the topic's first use.
    ///
    /// `f` runs with no lock of the topic table held: `std`'s `RwLock` may block a second read
    /// lock of the same thread behind a waiting writer, so holding the table while `f` takes it
    /// again would deadlock.
    fn with_topic<R>(&self, topic: &str, f: impl FnOnce(&TopicHandles) -> R) -> R {
        let cached = self
            .inner
            .topics
            .read()
            .unwrap_or_else(PoisonError::into_inner)
            .get(topic)
            .map(Arc::clone);
        if let Some(handles) = cached {
            return f(&handles);
        }
        let handles = {
            let mut topics = self
                .inner
                .topics
                .write()
                .unwrap_or_else(PoisonError::into_inner);
            let key: Arc<str> = Arc::from(topic);
            Arc::clone(topics.entry(Arc::clone(&key)).or_insert_with(|| {
                let inner = &self.inner;
                let by_direction = |direction| {
                    inner.messages.get_or_create_owned(&(
                        [("topic", Arc::clone(&key))],
                        [("direction", direction)],
                    ))
                };
                Arc::new(TopicHandles {
                    topic: Arc::clone(&key),
                    sent: by_direction(Direction::Sent),
                    received: by_direction(Direction::Received),
                    latency: inner
                        .latency
                        .get_or_create_owned(&[("topic", Arc::clone(&key))]),
                    dropped: RwLock::new(Vec::new()),
                })
            }))
        };
        f(&handles)
    }

    /// Counts one message on `topic` in `direction`.
    pub fn bus_message(&self, topic: &str, direction: Direction) {
        self.with_topic(topic, |handles| match direction {
            Direction::Sent => handles.sent.inc(),
            Direction::Received => handles.received.inc(),
        });
    }

    /// Records one latency observation for `topic`, in seconds. Negative or non-finite values
    /// (clock steps between processes) are ignored rather than skewing the histogram.
    pub fn bus_latency(&self, topic: &str, seconds: f64) {
        if !seconds.is_finite() || seconds < 0.0 {
            return;
        }
        self.with_topic(topic, |handles| handles.latency.observe(seconds));
    }

    /// Counts one message on `topic` that did not reach a receiver, with a short stable
    /// `reason` (e.g. `"subscriber_full"`, `"overwritten_latest_wins"`).
    pub fn bus_dropped(&self, topic: &str, reason: &str) {
        self.with_topic(topic, |handles| {
            {
                let dropped = handles
                    .dropped
                    .read()
                    .unwrap_or_else(PoisonError::into_inner);
                if let Some((_, counter)) = dropped.iter().find(|(r, _)| &**r == reason) {
                    counter.inc();
                    return;
                }
            }
            let mut dropped = handles
                .dropped
                .write()
                .unwrap_or_else(PoisonError::into_inner);
            if let Some((_, counter)) = dropped.iter().find(|(r, _)| &**r == reason) {
                counter.inc();
                return;
            }
            let counter = self.inner.dropped.get_or_create_owned(&[
                ("topic", Arc::clone(&handles.topic)),
                ("reason", Arc::from(reason)),
            ]);
            counter.inc();
            dropped.push((reason.into(), counter));
        });
    }

    /// Counts one restart of `actor` by its supervisor.
    pub fn actor_restart(&self, actor: &str) {
        self.inner
            .restarts
            .get_or_create(&actor_labels(actor))
            .inc();
    }

    /// Sets whether `actor` is running (`true` → 1) or down (`false` → 0).
    pub fn actor_up(&self, actor: &str, up: bool) {
        self.inner
            .up
            .get_or_create(&actor_labels(actor))
            .set(i64::from(up));
    }

    /// Counts one time `actor` used up its restart budget (its supervisor gave up on it).
    pub fn budget_exhausted(&self, actor: &str) {
        self.inner
            .budget_exhausted
            .get_or_create(&actor_labels(actor))
            .inc();
    }

    /// Sets whether the Redis edge is connected.
    pub fn redis_up(&self, up: bool) {
        self.inner.redis_up.set(i64::from(up));
    }

    /// Counts one entry of Redis stream `stream` with `outcome` (`published`,
    /// `dropped_queue_full`, `consumed`, `skipped_bad_json`, …).
    pub fn redis_entry(&self, stream: &str, outcome: &str) {
        self.inner
            .redis_entries
            .get_or_create(&[
                ("stream", Arc::from(stream)),
                ("outcome", Arc::from(outcome)),
            ])
            .inc();
    }

    /// Counts one tool call answered to an MCP client over `transport` with `status`.
    pub fn tool_call(&self, transport: &str, status: &str) {
        self.inner
            .tool_calls
            .get_or_create(&[
                ("transport", Arc::from(transport)),
                ("status", Arc::from(status)),
            ])
            .inc();
    }

    /// Sets whether the STT actor's model is loaded.
    pub fn stt_model_loaded(&self, loaded: bool) {
        self.inner.stt.model_loaded.set(i64::from(loaded));
    }

    /// Counts what the STT actor did since its last report: `utterances` transcribed,
    /// `errors` refused or failed, `audio_s` seconds of audio taking `processing_s` seconds.
    pub fn stt_served(&self, utterances: u64, errors: u64, audio_s: f64, processing_s: f64) {
        let stt = &self.inner.stt;
        stt.utterances.inc_by(utterances);
        stt.errors.inc_by(errors);
        if audio_s.is_finite() && audio_s > 0.0 {
            stt.audio_seconds.inc_by(audio_s);
        }
        if processing_s.is_finite() && processing_s > 0.0 {
            stt.processing_seconds.inc_by(processing_s);
        }
    }

    /// Sets the real-time factor of the STT actor's last utterance (processing ÷ audio time).
    pub fn stt_real_time_factor(&self, factor: f64) {
        if factor.is_finite() && factor >= 0.0 {
            self.inner.stt.real_time_factor.set(factor);
        }
    }

    /// Every series in the OpenMetrics text format (ends with `# EOF`), to be served with
    /// [`CONTENT_TYPE`].
    pub fn render(&self) -> String {
        let mut text = String::with_capacity(4096);
        if let Err(error) = encode(&mut text, &self.inner.registry) {
            // Writing into a String cannot fail; an encoder error would be a bug in a metric.
            tracing::error!(%error, "cannot encode the metrics registry");
        }
        text
    }
}

/// The speech-to-text actor's series (it reports them on `stt/status`; robotd serves them).
struct SttMetrics {
    model_loaded: Gauge,
    utterances: Counter,
    errors: Counter,
    audio_seconds: Counter<f64, AtomicU64>,
    processing_seconds: Counter<f64, AtomicU64>,
    real_time_factor: Gauge<f64, AtomicU64>,
}

impl SttMetrics {
    fn register(registry: &mut Registry) -> Self {
        let stt = Self {
            model_loaded: Gauge::default(),
            utterances: Counter::default(),
            errors: Counter::default(),
            audio_seconds: Counter::default(),
            processing_seconds: Counter::default(),
            real_time_factor: Gauge::default(),
        };
        registry.register(
            "stt_model_loaded",
            "Whether the STT actor's model is loaded and it serves (1) or not (0)",
            stt.model_loaded.clone(),
        );
        registry.register(
            "stt_utterances",
            "Requests the STT actor transcribed",
            stt.utterances.clone(),
        );
        registry.register(
            "stt_errors",
            "Requests the STT actor refused (bad audio) or failed on",
            stt.errors.clone(),
        );
        registry.register_with_unit(
            "stt_audio",
            "Seconds of audio the STT actor transcribed",
            Unit::Seconds,
            stt.audio_seconds.clone(),
        );
        registry.register_with_unit(
            "stt_processing",
            "Seconds the STT actor spent transcribing (decoding included)",
            Unit::Seconds,
            stt.processing_seconds.clone(),
        );
        registry.register(
            "stt_real_time_factor",
            "Processing time over audio length of the STT actor's last utterance",
            stt.real_time_factor.clone(),
        );
        stt
    }
}

fn actor_labels(actor: &str) -> ActorLabels {
    [("actor", Arc::from(actor))]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The value of the series whose line starts with `series ` in `text`.
    fn value(text: &str, series: &str) -> Option<f64> {
        text.lines()
            .find_map(|line| line.strip_prefix(series)?.strip_prefix(' '))
            .and_then(|v| v.split_whitespace().next()?.parse().ok())
    }

    #[test]
    fn render_reports_recorded_values() {
        let metrics = Metrics::new();
        for _ in 0..3 {
            metrics.bus_message("camera.frames", Direction::Sent);
        }
        metrics.bus_message("camera.frames", Direction::Received);
        metrics.bus_latency("camera.frames", 0.000_003);
        metrics.bus_latency("camera.frames", 0.000_2);
        metrics.bus_latency("camera.frames", 3.0);
        metrics.bus_latency("camera.frames", -1.0); // ignored
        metrics.bus_dropped("camera.frames", "subscriber_full");
        metrics.bus_dropped("camera.frames", "subscriber_full");
        metrics.bus_dropped("camera.frames", "overwritten_latest_wins");
        metrics.actor_restart("camera");
        metrics.actor_restart("camera");
        metrics.actor_up("camera", true);
        metrics.actor_up("arm", true);
        metrics.actor_up("arm", false);
        metrics.budget_exhausted("gripper");

        let text = metrics.render();
        let v = |series: &str| value(&text, series);
        assert_eq!(
            v(r#"robotd_bus_messages_total{topic="camera.frames",direction="sent"}"#),
            Some(3.0),
            "{text}"
        );
        assert_eq!(
            v(r#"robotd_bus_messages_total{topic="camera.frames",direction="received"}"#),
            Some(1.0)
        );
        assert_eq!(
            v(r#"robotd_bus_latency_seconds_count{topic="camera.frames"}"#),
            Some(3.0)
        );
        assert_eq!(
            v(r#"robotd_bus_latency_seconds_bucket{le="5e-6",topic="camera.frames"}"#).or_else(
                || v(r#"robotd_bus_latency_seconds_bucket{le="0.000005",topic="camera.frames"}"#)
            ),
            Some(1.0),
            "{text}"
        );
        assert_eq!(
            v(r#"robotd_bus_latency_seconds_bucket{le="1.0",topic="camera.frames"}"#),
            Some(2.0),
            "{text}"
        );
        assert_eq!(
            v(r#"robotd_bus_latency_seconds_bucket{le="+Inf",topic="camera.frames"}"#),
            Some(3.0)
        );
        assert_eq!(
            v(r#"robotd_bus_dropped_total{topic="camera.frames",reason="subscriber_full"}"#),
            Some(2.0)
        );
        assert_eq!(
            v(
                r#"robotd_bus_dropped_total{topic="camera.frames",reason="overwritten_latest_wins"}"#
            ),
            Some(1.0)
        );
        assert_eq!(
            v(r#"robotd_actor_restarts_total{actor="camera"}"#),
            Some(2.0)
        );
        assert_eq!(v(r#"robotd_actor_up{actor="camera"}"#), Some(1.0));
        assert_eq!(v(r#"robotd_actor_up{actor="arm"}"#), Some(0.0));
        assert_eq!(
            v(r#"robotd_actor_budget_exhausted_total{actor="gripper"}"#),
            Some(1.0)
        );
        assert!(text.contains("# TYPE robotd_bus_latency_seconds histogram"));
        assert!(text.ends_with("# EOF\n"));
    }

    #[test]
    fn clones_share_series_and_instances_are_independent() {
        let a = Metrics::new();
        let b = a.clone();
        let other = Metrics::new();
        a.bus_message("t", Direction::Sent);
        b.bus_message("t", Direction::Sent);
        let series = r#"robotd_bus_messages_total{topic="t",direction="sent"}"#;
        assert_eq!(value(&a.render(), series), Some(2.0));
        assert_eq!(value(&other.render(), series), None);
    }

    #[test]
    fn tool_calls_are_counted_by_transport_and_status() {
        let metrics = Metrics::new();
        metrics.tool_call("sse", "ok");
        metrics.tool_call("sse", "ok");
        metrics.tool_call("streamable_http", "failed");
        let text = metrics.render();
        let sse = r#"robotd_tool_calls_total{transport="sse",status="ok"}"#;
        let http = r#"robotd_tool_calls_total{transport="streamable_http",status="failed"}"#;
        assert_eq!(value(&text, sse), Some(2.0), "{text}");
        assert_eq!(value(&text, http), Some(1.0), "{text}");
    }

    #[test]
    fn stt_series_add_up_what_the_actor_reports() {
        let metrics = Metrics::new();
        let text = metrics.render();
        assert_eq!(
            value(&text, "robotd_stt_utterances_total"),
            Some(0.0),
            "{text}"
        );
        metrics.stt_model_loaded(true);
        metrics.stt_served(2, 0, 6.5, 1.5);
        metrics.stt_served(1, 1, 3.0, f64::NAN);
        metrics.stt_real_time_factor(0.25);
        metrics.stt_real_time_factor(-1.0); // ignored
        let text = metrics.render();
        assert_eq!(value(&text, "robotd_stt_model_loaded"), Some(1.0), "{text}");
        assert_eq!(value(&text, "robotd_stt_utterances_total"), Some(3.0));
        assert_eq!(value(&text, "robotd_stt_errors_total"), Some(1.0));
        assert_eq!(value(&text, "robotd_stt_audio_seconds_total"), Some(9.5));
        assert_eq!(
            value(&text, "robotd_stt_processing_seconds_total"),
            Some(1.5)
        );
        assert_eq!(value(&text, "robotd_stt_real_time_factor"), Some(0.25));
    }

    #[test]
    fn label_values_are_escaped() {
        let metrics = Metrics::new();
        metrics.actor_restart("we\"ird\nname");
        let text = metrics.render();
        assert!(
            text.contains(r#"robotd_actor_restarts_total{actor="we\"ird\nname"} 1"#),
            "{text}"
        );
    }

    #[test]
    fn recording_from_many_threads_counts_every_message() {
        let metrics = Metrics::new();
        std::thread::scope(|scope| {
            for t in 0..4 {
                let metrics = metrics.clone();
                scope.spawn(move || {
                    for i in 0..1000 {
                        let topic = if i % 2 == 0 { "even" } else { "odd" };
                        metrics.bus_message(topic, Direction::Received);
                        metrics.bus_dropped(topic, if t % 2 == 0 { "a" } else { "b" });
                    }
                });
            }
        });
        let text = metrics.render();
        assert_eq!(
            value(
                &text,
                r#"robotd_bus_messages_total{topic="even",direction="received"}"#
            ),
            Some(2000.0)
        );
        assert_eq!(
            value(&text, r#"robotd_bus_dropped_total{topic="odd",reason="b"}"#),
            Some(1000.0)
        );
    }
}
