//! Logs and traces: where robotd's `tracing` output goes, and how one trace follows a request
//! across the bus.
//!
//! Everything in robotd reports through [`tracing`] spans and events. [`init`] installs the
//! process-wide subscriber once, at start-up, and returns a [`TelemetryGuard`] to keep until
//! `main` returns:
//!
//! - **filter**: `RUST_LOG` when set, else [`TelemetryConfig::filter`] (an env-filter);
//! - **terminal**: human-readable lines on **stderr** — never stdout, which belongs to the
//!   MCP stdio transport;
//! - **log file** (not in [`Mode::Command`]): `<log_dir>/<service>.<YYYY-MM-DD>.log` (UTC date,
//!   a new file each day), written by a background thread, as text or JSON
//!   ([`TelemetryConfig::log_format`]);
//! - **OpenTelemetry**: spans get W3C trace and span ids. When an OTLP endpoint is configured
//!   ([`TelemetryConfig::otlp_endpoint`], else `OTEL_EXPORTER_OTLP_TRACES_ENDPOINT` /
//!   `OTEL_EXPORTER_OTLP_ENDPOINT`), finished spans are batched and exported over OTLP
//!   HTTP/protobuf.
//!
//! Dropping the guard flushes the log file and shuts the exporter down; an unreachable
//! collector delays exit by at most [`SHUTDOWN_BUDGET`].
//!
//! ```no_run
//! use robotd_runtime::config::{LogFormat, TelemetryConfig};
//! use robotd_runtime::telemetry::{self, Mode};
//!
//! let config = TelemetryConfig {
//!     log_dir: "log".into(),
//!     filter: "info".into(),
//!     log_format: LogFormat::Text,
//!     otlp_endpoint: None,
//!     service_name: Some("robotd".into()),
//!     max_event_bytes: TelemetryConfig::default_max_event_bytes(),
//!     keep_log_days: TelemetryConfig::default_keep_log_days(),
//! };
//! let _telemetry = telemetry::init(&config, Mode::Service)?;
//! tracing::info!("robotd starting");
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! # Traces across the bus
//!
//! A sender stamps each envelope with [`current_trace_context()`] (the W3C `traceparent` of the
//! current span); the receiver opens its span and calls [`set_parent_from`] before entering
//! it, so the receiving span joins the sender's trace — in this process or another one:
//!
//! ```
//! use robotd_runtime::telemetry::{current_trace_context, set_parent_from};
//!
//! // Sender (e.g. the MCP edge), inside its request span:
//! let trace = current_trace_context(); // goes into the envelope
//!
//! // Receiver (e.g. the arm actor), for the request it took off the bus:
//! let span = tracing::info_span!("arm.move");
//! set_parent_from(&span, &trace);
//! let _entered = span.enter();
//! ```
//!
//! # Cost when nothing is exported
//!
//! Without an OTLP endpoint the OpenTelemetry layer still runs, so trace ids exist and
//! propagate across processes (and an exporting process downstream would see one trace), but
//! it is made cheap: spans are never sampled (the SDK creates non-recording spans: ids only,
//! no attributes or events kept), the layer ignores events, and records no code locations,
//! thread names or busy/idle timings. What remains is a small allocation per span for its
//! builder plus two id draws: measured in a release build, about 0.4 µs more per span
//! (create, enter, exit, close) and 0.3 µs per [`current_trace_context()`] — small next to a
//! bus hop or a formatted log line, so propagation is always on. Because unsampled contexts carry the flag `00`, a downstream process that
//! does export drops those spans too: configure export on every process of a deployment, or
//! on none.
//!
//! Spans below the log filter are not created at all, so they are neither logged, exported
//! nor propagated (keep the filter at `info` or finer to trace bus requests).

pub mod escape;
mod files;
pub mod retention;
pub mod rotating;

pub use files::{file_stamp, utc_fields};
use files::{log_file_writer, session_file_writer};

use crate::config::{LogFormat, TelemetryConfig};
use opentelemetry::propagation::{Extractor, Injector, TextMapPropagator};
use opentelemetry::trace::{TraceContextExt, TracerProvider as _};
use opentelemetry_otlp::{Protocol, WithExportConfig};
use opentelemetry_sdk::propagation::TraceContextPropagator;
use opentelemetry_sdk::trace::{
    BatchConfigBuilder, BatchSpanProcessor, Sampler, SdkTracerProvider,
};
use opentelemetry_sdk::Resource;
use robotd_protocol::envelope::TraceContext;
use std::io::IsTerminal;
use std::path::PathBuf;
use std::sync::mpsc;
use std::sync::OnceLock;
use std::time::{Duration, Instant};
use tracing::Dispatch;
use tracing_appender::non_blocking::WorkerGuard;
use tracing_opentelemetry::OpenTelemetrySpanExt;
use tracing_subscriber::filter::{filter_fn, EnvFilter};
use tracing_subscriber::layer::{Layer, Layered, SubscriberExt};
use tracing_subscriber::util::SubscriberInitExt;
use tracing_subscriber::Registry;

/// Longest time dropping a [`TelemetryGuard`] waits for the exporter to flush and stop.
pub const SHUTDOWN_BUDGET: Duration = Duration::from_millis(900);

/// Timeout of one OTLP export request (retries included). Longer than [`SHUTDOWN_BUDGET`]:
/// at run time a slow collector may take its time; at exit the budget cuts it short.
pub const EXPORT_TIMEOUT: Duration = Duration::from_secs(3);

/// How often the batch processor sends finished spans.
pub const EXPORT_INTERVAL: Duration = Duration::from_secs(1);

/// The instrumentation scope name of robotd's spans.
pub const TRACER_NAME: &str = "robotd";

/// What kind of process is starting, which decides where its telemetry goes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mode {
    /// The long-running service (or an out-of-process actor): stderr, the daily log file and,
    /// when configured, OTLP export. Colours on stderr when it is a terminal.
    Service,
    /// The service serving MCP over stdio: as [`Mode::Service`], but stderr never gets colour
    /// codes (the desktop apps that spawn it save stderr to their own log files). No mode ever
    /// writes to stdout.
    Stdio,
    /// A short command (`robotd config check` and the like): stderr only; no log file and no
    /// export. Trace ids are still created so bus calls made by the command carry them.
    Command,
    /// An interactive session (`robotd chat`): the terminal belongs to the conversation, so
    /// stderr gets warnings only; everything else goes to one file per session,
    /// `<log_dir>/mcp_client_YYYYmmdd_HHMMSS.log` (the Python client's name), and spans are
    /// exported as in [`Mode::Service`].
    Chat,
}

/// Setting up telemetry failed.
#[derive(Debug, thiserror::Error)]
pub enum TelemetryError {
    /// The log filter does not parse.
    #[error("invalid log filter {filter:?} (from {origin}): {source}; use a tracing env-filter such as \"info\" or \"info,robotd_runtime::bus=debug\"")]
    Filter {
        /// `"RUST_LOG"` or `"telemetry.filter"`.
        origin: &'static str,
        /// The filter text.
        filter: String,
        /// What the parser said.
        #[source]
        source: tracing_subscriber::filter::ParseError,
    },
    /// The log directory or file cannot be created.
    #[error("cannot write log files in {}: {source}; fix the permissions or set telemetry.log_dir (ROBOTD_TELEMETRY__LOG_DIR) to a writable directory", path.display())]
    LogFile {
        /// The log directory.
        path: PathBuf,
        /// What failed.
        #[source]
        source: Box<dyn std::error::Error + Send + Sync>,
    },
    /// The OTLP exporter cannot be built (e.g. a malformed endpoint).
    #[error("cannot set up OTLP trace export to {endpoint:?}: {source}; check telemetry.otlp_endpoint or OTEL_EXPORTER_OTLP_ENDPOINT")]
    Otlp {
        /// The endpoint URL.
        endpoint: String,
        /// What the exporter said.
        #[source]
        source: opentelemetry_otlp::ExporterBuildError,
    },
    /// [`init`] ran before in this process (or another global subscriber was installed).
    #[error("a global tracing subscriber is already installed; call telemetry::init once per process, at start-up")]
    AlreadyInitialised(#[source] tracing_subscriber::util::TryInitError),
}

/// Keeps telemetry running; dropping it flushes the log file and shuts trace export down,
/// waiting at most [`SHUTDOWN_BUDGET`] for the collector.
#[must_use = "telemetry stops when the guard is dropped: keep it until main returns"]
pub struct TelemetryGuard {
    provider: Option<SdkTracerProvider>,
    file: Option<WorkerGuard>,
    log_dir: Option<PathBuf>,
    session_file: Option<PathBuf>,
    otlp_endpoint: Option<String>,
}

impl std::fmt::Debug for TelemetryGuard {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("TelemetryGuard")
            .field("log_dir", &self.log_dir)
            .field("otlp_endpoint", &self.otlp_endpoint)
            .finish_non_exhaustive()
    }
}

impl TelemetryGuard {
    /// The directory log files go to (`None` in [`Mode::Command`]).
    pub fn log_dir(&self) -> Option<&std::path::Path> {
        self.log_dir.as_deref()
    }

    /// The session's log file ([`Mode::Chat`] only).
    pub fn session_file(&self) -> Option<&std::path::Path> {
        self.session_file.as_deref()
    }

    /// The OTLP/HTTP traces URL spans are exported to, if any.
    pub fn otlp_endpoint(&self) -> Option<&str> {
        self.otlp_endpoint.as_deref()
    }
}

impl Drop for TelemetryGuard {
    fn drop(&mut self) {
        let started = Instant::now();
        // Shut the tracer provider down on its own thread: a hanging export must not hold
        // up the process beyond the budget.
        let stopped = self.provider.take().and_then(|provider| {
            let (done, wait) = mpsc::channel();
            std::thread::Builder::new()
                .name("robotd-otel-shutdown".into())
                .spawn(move || {
                    let _ = done.send(provider.shutdown_with_timeout(SHUTDOWN_BUDGET));
                })
                .ok()
                .map(|_| wait)
        });
        // Meanwhile flush the log file (local disk: fast).
        drop(self.file.take());
        if let Some(wait) = stopped {
            let left = SHUTDOWN_BUDGET.saturating_sub(started.elapsed());
            match wait.recv_timeout(left) {
                Ok(Ok(())) | Err(mpsc::RecvTimeoutError::Disconnected) => {}
                Ok(Err(error)) => {
                    eprintln!("robotd: trace export did not shut down cleanly: {error}")
                }
                Err(mpsc::RecvTimeoutError::Timeout) => eprintln!(
                    "robotd: gave up flushing traces to {} after {} ms; unsent spans are lost",
                    self.otlp_endpoint.as_deref().unwrap_or("the collector"),
                    SHUTDOWN_BUDGET.as_millis()
                ),
            }
        }
    }
}

/// Installs robotd's subscriber as the process-wide default (see the module docs), sets the
/// global OpenTelemetry propagator to W3C TraceContext, and routes `log` records into
/// `tracing`. Call once, at start-up.
pub fn init(config: &TelemetryConfig, mode: Mode) -> Result<TelemetryGuard, TelemetryError> {
    let (dispatch, guard) = build(config, mode)?;
    opentelemetry::global::set_text_map_propagator(TraceContextPropagator::new());
    if let Some(provider) = &guard.provider {
        opentelemetry::global::set_tracer_provider(provider.clone());
    }
    dispatch
        .try_init()
        .map_err(TelemetryError::AlreadyInitialised)?;
    if let Some(endpoint) = &guard.otlp_endpoint {
        tracing::info!(endpoint = %endpoint, "exporting traces over OTLP/HTTP");
    }
    Ok(guard)
}

/// Builds everything [`init`] installs, without installing it: a [`Dispatch`] to use with
/// [`tracing::dispatcher::with_default`] (tests, embedding) plus its guard.
pub fn build(
    config: &TelemetryConfig,
    mode: Mode,
) -> Result<(Dispatch, TelemetryGuard), TelemetryError> {
    let rust_log = std::env::var("RUST_LOG").ok();
    let filter = env_filter(&config.filter, rust_log.as_deref())?;
    let env = |name: &str| std::env::var(name).ok();
    let endpoint = match mode {
        Mode::Command => None,
        Mode::Service | Mode::Stdio | Mode::Chat => otlp_endpoint(config, env),
    };

    let mut layers: Vec<Box<dyn Layer<Base> + Send + Sync>> = Vec::new();

    let ansi = mode == Mode::Service && std::io::stderr().is_terminal();
    // Without colours, escape control characters (outside text cannot forge a line); with
    // colours (a person at a terminal) the formatter's own escapes must pass.
    use tracing_subscriber::fmt::writer::BoxMakeWriter;
    let stderr_writer = if ansi {
        BoxMakeWriter::new(std::io::stderr)
    } else {
        BoxMakeWriter::new(escape::EscapingMakeWriter::new(
            std::io::stderr,
            config.max_event_bytes,
        ))
    };
    let stderr = tracing_subscriber::fmt::layer()
        .with_writer(stderr_writer)
        .with_ansi(ansi);
    layers.push(if mode == Mode::Chat {
        Box::new(stderr.with_filter(tracing_subscriber::filter::LevelFilter::WARN))
    } else {
        Box::new(stderr)
    });

    let mut file_guard = None;
    let mut log_dir = None;
    let mut session_file = None;
    if mode != Mode::Command {
        let (writer, guard) = if mode == Mode::Chat {
            let (writer, guard, path) = session_file_writer(config)?;
            session_file = Some(path);
            (writer, guard)
        } else {
            log_file_writer(config)?
        };
        file_guard = Some(guard);
        log_dir = Some(config.log_dir.clone());
        let file_layer = tracing_subscriber::fmt::layer()
            .with_writer(escape::EscapingMakeWriter::new(
                writer,
                config.max_event_bytes,
            ))
            .with_ansi(false);
        layers.push(match config.log_format {
            LogFormat::Text => Box::new(file_layer),
            LogFormat::Json => Box::new(file_layer.json().with_current_span(true)),
        });
    }

    let provider = tracer_provider(config, endpoint.as_deref())?;
    let tracer = provider.tracer(TRACER_NAME);
    let otel = tracing_opentelemetry::layer().with_tracer(tracer);
    layers.push(if endpoint.is_some() {
        Box::new(otel)
    } else {
        // Ids only: no events, locations, thread names or timings to collect.
        Box::new(
            otel.with_location(false)
                .with_threads(false)
                .with_tracked_inactivity(false)
                .with_filter(filter_fn(|metadata| metadata.is_span())),
        )
    });

    let subscriber = tracing_subscriber::registry().with(filter).with(layers);
    let guard = TelemetryGuard {
        provider: Some(provider),
        file: file_guard,
        log_dir,
        session_file,
        otlp_endpoint: endpoint,
    };
    Ok((Dispatch::new(subscriber), guard))
}

type Base = Layered<EnvFilter, Registry>;

/// `RUST_LOG` (when set and not blank) wins over the configured filter.
fn env_filter(configured: &str, rust_log: Option<&str>) -> Result<EnvFilter, TelemetryError> {
    let (origin, text) = match rust_log.filter(|v| !v.trim().is_empty()) {
        Some(value) => ("RUST_LOG", value),
        None => ("telemetry.filter", configured),
    };
    let filter = EnvFilter::builder()
        .parse(text)
        .map_err(|source| TelemetryError::Filter {
            origin,
            filter: text.to_owned(),
            source,
        })?;
    // The URDF loader (`k`) logs every link at INFO when the kinematics are built: keep it to
    // warnings unless the filter names it.
    let names_k = text
        .split(',')
        .any(|directive| directive.trim().starts_with("k=") || directive.trim().starts_with("k::"));
    Ok(match QUIET_URDF_LOADER.parse() {
        Ok(directive) if !names_k => filter.add_directive(directive),
        _ => filter,
    })
}

/// The directive that keeps the URDF loader's per-link INFO lines out of the logs.
const QUIET_URDF_LOADER: &str = "k=warn";

/// The OTLP/HTTP traces URL: the configured base URL, else the standard OTel variables.
fn otlp_endpoint(config: &TelemetryConfig, env: impl Fn(&str) -> Option<String>) -> Option<String> {
    let set = |v: Option<String>| v.filter(|v| !v.trim().is_empty());
    if let Some(base) = set(config.otlp_endpoint.clone()) {
        return Some(traces_url(&base));
    }
    if let Some(full) = set(env(opentelemetry_otlp::OTEL_EXPORTER_OTLP_TRACES_ENDPOINT)) {
        return Some(full);
    }
    set(env(opentelemetry_otlp::OTEL_EXPORTER_OTLP_ENDPOINT)).map(|base| traces_url(&base))
}

/// `<base>/v1/traces`, unless `base` already ends with it.
fn traces_url(base: &str) -> String {
    let base = base.trim().trim_end_matches('/');
    if base.ends_with("/v1/traces") {
        base.to_owned()
    } else {
        format!("{base}/v1/traces")
    }
}

/// With an endpoint: sample everything (following remote parents) and batch-export.
/// Without: a provider that never samples — ids only, nothing recorded.
fn tracer_provider(
    config: &TelemetryConfig,
    endpoint: Option<&str>,
) -> Result<SdkTracerProvider, TelemetryError> {
    let resource = Resource::builder()
        .with_service_name(config.service_name().to_owned())
        .build();
    let builder = SdkTracerProvider::builder().with_resource(resource);
    let Some(endpoint) = endpoint else {
        return Ok(builder.with_sampler(Sampler::AlwaysOff).build());
    };
    install_tls_provider();
    let exporter = opentelemetry_otlp::SpanExporter::builder()
        .with_http()
        .with_protocol(Protocol::HttpBinary)
        .with_endpoint(endpoint)
        .with_timeout(EXPORT_TIMEOUT)
        .build()
        .map_err(|source| TelemetryError::Otlp {
            endpoint: endpoint.to_owned(),
            source,
        })?;
    let processor = BatchSpanProcessor::builder(exporter)
        .with_batch_config(
            BatchConfigBuilder::default()
                .with_scheduled_delay(EXPORT_INTERVAL)
                .build(),
        )
        .build();
    Ok(builder
        .with_sampler(Sampler::ParentBased(Box::new(Sampler::AlwaysOn)))
        .with_span_processor(processor)
        .build())
}

// ---------------------------------------------------------------------------------------------
// Trace context on the bus

/// The W3C propagator of the bus. The envelope's fields are W3C `traceparent`/`tracestate` by
/// definition, so this does not depend on (or wait for) the global propagator `init` sets.
fn propagator() -> &'static TraceContextPropagator {
    static PROPAGATOR: OnceLock<TraceContextPropagator> = OnceLock::new();
    PROPAGATOR.get_or_init(TraceContextPropagator::new)
}

/// The W3C trace context of the current `tracing` span, to put into an outgoing envelope.
///
/// Empty (both fields `None`) when there is no current span or no OpenTelemetry layer
/// (telemetry not initialised, or a test subscriber).
pub fn current_trace_context() -> TraceContext {
    let span = tracing::Span::current();
    if span.is_none() {
        return TraceContext::default();
    }
    let context = span.context();
    if !context.span().span_context().is_valid() {
        return TraceContext::default();
    }
    let mut carrier = TraceContext::default();
    propagator().inject_context(&context, &mut ContextCarrier(&mut carrier));
    carrier
}

/// Makes `span` continue the remote trace in `trace` (from an incoming envelope): it becomes
/// a child of the sender's span. Call it before the span is first entered; afterwards the
/// parent is fixed. An empty or malformed context leaves `span` as it is (a new trace).
pub fn set_parent_from(span: &tracing::Span, trace: &TraceContext) {
    if trace.traceparent.is_none() || span.is_none() {
        return;
    }
    let parent = propagator().extract(&ContextReader(trace));
    if !parent.span().span_context().is_valid() {
        tracing::debug!(traceparent = ?trace.traceparent, "ignoring a malformed trace context");
        return;
    }
    // Fails only without an OTel layer or when the span already started: nothing to join then.
    let _ = span.set_parent(parent);
}

struct ContextCarrier<'a>(&'a mut TraceContext);

impl Injector for ContextCarrier<'_> {
    fn set(&mut self, key: &str, value: String) {
        match key {
            "traceparent" => self.0.traceparent = Some(value),
            "tracestate" if !value.is_empty() => self.0.tracestate = Some(value),
            _ => {}
        }
    }
}

struct ContextReader<'a>(&'a TraceContext);

impl Extractor for ContextReader<'_> {
    fn get(&self, key: &str) -> Option<&str> {
        match key {
            "traceparent" => self.0.traceparent.as_deref(),
            "tracestate" => self.0.tracestate.as_deref(),
            _ => None,
        }
    }

    fn keys(&self) -> Vec<&str> {
        let mut keys = Vec::with_capacity(2);
        if self.0.traceparent.is_some() {
            keys.push("traceparent");
        }
        if self.0.tracestate.is_some() {
            keys.push("tracestate");
        }
        keys
    }
}

/// Makes rustls (the TLS of every HTTPS client in robotd: the OTLP exporter, the ElevenLabs
/// engine) use the `ring` crypto provider. An HTTP client built before any provider is
/// installed panics, so each place that builds one calls this first; calling it again does
/// nothing.
pub fn install_tls_provider() {
    let _ = rustls::crypto::ring::default_provider().install_default();
}

#[cfg(test)]
mod tests {
    use super::files::file_prefix;
    use super::*;
    use std::sync::atomic::{AtomicU32, Ordering};

    /// A fresh, empty directory for log files.
    fn temp_log_dir() -> PathBuf {
        static NEXT: AtomicU32 = AtomicU32::new(0);
        let dir = std::env::temp_dir().join(format!(
            "robotd-telemetry-test-{}-{}",
            std::process::id(),
            NEXT.fetch_add(1, Ordering::Relaxed)
        ));
        let _ = std::fs::remove_dir_all(&dir);
        dir
    }

    fn config(log_dir: PathBuf, otlp_endpoint: Option<&str>) -> TelemetryConfig {
        TelemetryConfig {
            log_dir,
            filter: "info".into(),
            log_format: LogFormat::Text,
            otlp_endpoint: otlp_endpoint.map(str::to_owned),
            service_name: Some("robotd-test".into()),
            max_event_bytes: TelemetryConfig::default_max_event_bytes(),
            keep_log_days: TelemetryConfig::default_keep_log_days(),
        }
    }

    fn trace_id(trace: &TraceContext) -> &str {
        trace
            .traceparent
            .as_deref()
            .and_then(|tp| tp.split('-').nth(1))
            .expect("a traceparent")
    }

    #[test]
    fn trace_context_round_trips_between_processes() {
        // Two independent subscribers (own tracer providers) stand for two processes.
        let edge_dir = temp_log_dir();
        let actor_dir = temp_log_dir();
        let (edge, edge_guard) = build(&config(edge_dir.clone(), None), Mode::Command).unwrap();
        let (actor, actor_guard) = build(&config(actor_dir.clone(), None), Mode::Command).unwrap();

        let sent = tracing::dispatcher::with_default(&edge, || {
            let span = tracing::info_span!("mcp.tool_call");
            let _entered = span.enter();
            current_trace_context()
        });
        let traceparent = sent
            .traceparent
            .clone()
            .expect("a traceparent in the edge span");
        assert_eq!(traceparent.len(), 55, "{traceparent}");
        assert!(traceparent.starts_with("00-"), "{traceparent}");

        let (received, child) = tracing::dispatcher::with_default(&actor, || {
            let span = tracing::info_span!("arm.move");
            set_parent_from(&span, &sent);
            let _entered = span.enter();
            let received = current_trace_context();
            let grandchild = tracing::info_span!("arm.driver");
            let _entered = grandchild.enter();
            (received, current_trace_context())
        });
        assert_eq!(trace_id(&received), trace_id(&sent));
        assert_ne!(received.traceparent, sent.traceparent, "a new span id");
        assert_eq!(
            trace_id(&child),
            trace_id(&sent),
            "children stay in the trace"
        );
        drop((edge_guard, actor_guard));
    }

    #[test]
    fn no_context_without_an_otel_layer_or_span() {
        assert_eq!(current_trace_context(), TraceContext::default());
        let subscriber = tracing_subscriber::registry();
        tracing::subscriber::with_default(subscriber, || {
            let span = tracing::info_span!("plain");
            let _entered = span.enter();
            assert_eq!(current_trace_context(), TraceContext::default());
            // Harmless without an OTel layer, and with garbage.
            set_parent_from(
                &span,
                &TraceContext {
                    traceparent: Some("00-xyz".into()),
                    tracestate: None,
                },
            );
        });
    }

    #[test]
    fn malformed_or_empty_context_starts_a_new_trace() {
        let (dispatch, _guard) = build(&config(temp_log_dir(), None), Mode::Command).unwrap();
        tracing::dispatcher::with_default(&dispatch, || {
            for bad in [
                None,
                Some("garbage"),
                Some("00-00000000000000000000000000000000-0000000000000000-01"),
            ] {
                let span = tracing::info_span!("handler");
                set_parent_from(
                    &span,
                    &TraceContext {
                        traceparent: bad.map(str::to_owned),
                        tracestate: None,
                    },
                );
                let _entered = span.enter();
                let trace = current_trace_context();
                assert_ne!(trace_id(&trace), "00000000000000000000000000000000");
            }
        });
    }

    #[test]
    fn unreachable_collector_does_not_delay_shutdown() {
        let dir = temp_log_dir();
        let (dispatch, guard) = build(
            &config(dir.clone(), Some("http://127.0.0.1:9")),
            Mode::Service,
        )
        .unwrap();
        assert_eq!(guard.otlp_endpoint(), Some("http://127.0.0.1:9/v1/traces"));
        tracing::dispatcher::with_default(&dispatch, || {
            for i in 0..200 {
                let span = tracing::info_span!("work", i);
                let _entered = span.enter();
                tracing::debug!("inside a span (below the filter: spans only, quiet test output)");
            }
        });
        // Let the batch processor start an export against the dead endpoint.
        std::thread::sleep(EXPORT_INTERVAL + Duration::from_millis(100));
        tracing::dispatcher::with_default(&dispatch, || {
            let _span = tracing::info_span!("late").entered();
        });
        let started = Instant::now();
        drop(guard);
        let took = started.elapsed();
        assert!(took < Duration::from_secs(1), "shutdown took {took:?}");
        let _ = std::fs::remove_dir_all(dir);
    }

    #[test]
    fn log_file_is_date_stamped_and_written() {
        let dir = temp_log_dir();
        let mut config = config(dir.clone(), None);
        config.log_format = LogFormat::Json;
        let (dispatch, guard) = build(&config, Mode::Service).unwrap();
        tracing::dispatcher::with_default(&dispatch, || {
            let _span = tracing::info_span!("startup").entered();
            tracing::info!(answer = 42, "hello from the test");
        });
        assert_eq!(guard.log_dir(), Some(dir.as_path()));
        drop(guard); // flushes
        let files: Vec<String> = std::fs::read_dir(&dir)
            .unwrap()
            .map(|entry| entry.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        assert_eq!(files.len(), 1, "{files:?}");
        let name = &files[0];
        // robotd-test.YYYY-MM-DD.log
        let date = name
            .strip_prefix("robotd-test.")
            .and_then(|rest| rest.strip_suffix(".log"))
            .unwrap_or_else(|| panic!("unexpected log file name {name}"));
        assert_eq!(date.len(), 10, "{name}");
        assert!(
            date.chars().all(|c| c.is_ascii_digit() || c == '-'),
            "{name}"
        );
        let text = std::fs::read_to_string(dir.join(name)).unwrap();
        let line = text
            .lines()
            .find(|l| l.contains("hello from the test"))
            .expect(&text);
        assert!(
            line.starts_with('{') && line.contains("\"answer\":42"),
            "{line}"
        );
        let _ = std::fs::remove_dir_all(dir);
    }

    #[test]
    fn command_mode_writes_no_file() {
        let dir = temp_log_dir();
        let (_dispatch, guard) = build(
            &config(dir.clone(), Some("http://127.0.0.1:9")),
            Mode::Command,
        )
        .unwrap();
        assert_eq!(guard.log_dir(), None);
        assert_eq!(guard.otlp_endpoint(), None);
        assert!(!dir.exists());
    }

    #[test]
    fn rust_log_wins_over_config_and_bad_filters_are_reported() {
        // The filter's directives, sorted (its display orders them by specificity).
        fn directives(filter: &EnvFilter) -> Vec<String> {
            let mut all: Vec<String> = filter.to_string().split(',').map(str::to_owned).collect();
            all.sort();
            all
        }
        let filter = env_filter("info", Some("robotd=trace")).unwrap();
        assert_eq!(directives(&filter), ["k=warn", "robotd=trace"]);
        let filter = env_filter("warn", Some("  ")).unwrap();
        assert_eq!(directives(&filter), ["k=warn", "warn"]);
        // A filter that names the URDF loader keeps its own level for it.
        let filter = env_filter("info,k=debug", None).unwrap();
        assert_eq!(directives(&filter), ["info", "k=debug"]);
        let error = env_filter("info", Some("[=nope")).unwrap_err();
        assert!(error.to_string().contains("RUST_LOG"), "{error}");
        let error = env_filter("[=nope", None).unwrap_err();
        assert!(error.to_string().contains("telemetry.filter"), "{error}");
    }

    #[test]
    fn endpoint_resolution() {
        let mut c = config(PathBuf::from("log"), None);
        let none = |_: &str| None;
        assert_eq!(otlp_endpoint(&c, none), None);
        let base = |name: &str| {
            (name == "OTEL_EXPORTER_OTLP_ENDPOINT").then(|| "http://collector:4318/".to_owned())
        };
        assert_eq!(
            otlp_endpoint(&c, base).as_deref(),
            Some("http://collector:4318/v1/traces")
        );
        let full = |name: &str| {
            (name == "OTEL_EXPORTER_OTLP_TRACES_ENDPOINT").then(|| "http://x:1/custom".to_owned())
        };
        assert_eq!(
            otlp_endpoint(&c, full).as_deref(),
            Some("http://x:1/custom")
        );
        c.otlp_endpoint = Some("http://config:4318/v1/traces".into());
        assert_eq!(
            otlp_endpoint(&c, base).as_deref(),
            Some("http://config:4318/v1/traces")
        );
    }

    #[test]
    fn file_prefix_is_file_name_safe() {
        assert_eq!(file_prefix("robotd"), "robotd");
        assert_eq!(file_prefix("lab 2/arm"), "lab_2_arm");
        assert_eq!(file_prefix(""), "robotd");
        assert_eq!(file_prefix(".."), "robotd..");
    }
}
