//! The runtime's own sections: `[service]`, `[bus]`, `[telemetry]`, `[supervision]` and
//! `[actors.<name>]` — what every robotd process needs, whatever robot it drives.

use super::checks::{check_name, check_url};
use super::lenient;
use super::{Checks, Section};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::PathBuf;
use std::time::Duration;

/// Longest accepted [`BusConfig::namespace`].
pub const MAX_NAMESPACE_LEN: usize = 64;

/// Largest accepted [`BusConfig::frame_subscriber_buffer`] (each slot holds a whole frame in
/// shared memory).
pub const MAX_FRAME_SUBSCRIBER_BUFFER: usize = 64;

/// `[service]`
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ServiceConfig {
    /// Name of this instance, shown in logs, health and the dashboard.
    #[serde(deserialize_with = "lenient::string")]
    pub name: String,
    /// Threads of the async runtime that runs the edges and the light actors (1 to
    /// `MAX_WORKER_THREADS`); perception, the writers and the live views have threads of
    /// their own. See `config/default.toml` for the default and the trade-off.
    pub worker_threads: usize,
}

/// Largest accepted [`ServiceConfig::worker_threads`].
pub const MAX_WORKER_THREADS: usize = 64;

/// `[bus]`
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BusConfig {
    /// Prefix of this instance's iceoryx2 service names (`[A-Za-z0-9_-]`, at most
    /// [`MAX_NAMESPACE_LEN`]), so two instances on one host do not collide.
    #[serde(deserialize_with = "lenient::string")]
    pub namespace: String,
    /// How long a bus request waits for its reply, in ms (> 0).
    pub request_timeout_ms: u64,
    /// Camera frames each subscriber keeps (1 to [`MAX_FRAME_SUBSCRIBER_BUFFER`]).
    pub frame_subscriber_buffer: usize,
}

impl BusConfig {
    /// [`Self::request_timeout_ms`] as a duration.
    pub fn request_timeout(&self) -> Duration {
        Duration::from_millis(self.request_timeout_ms)
    }
}

/// Format of the log file.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum LogFormat {
    /// One human-readable line per event.
    #[default]
    Text,
    /// One JSON object per line.
    Json,
}

/// `[telemetry]`
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TelemetryConfig {
    /// Directory of the daily log files (created if missing).
    pub log_dir: PathBuf,
    /// A tracing env-filter (`"info"`, `"info,robotd_runtime::bus=debug"`); `RUST_LOG`
    /// overrides it when set.
    #[serde(deserialize_with = "lenient::string")]
    pub filter: String,
    /// Format of the log file (the terminal always gets text).
    pub log_format: LogFormat,
    /// Base URL of an OTLP/HTTP collector (`http://localhost:4318`); when `None`, the
    /// `OTEL_EXPORTER_OTLP_*ENDPOINT` variables decide, and without them nothing is exported.
    #[serde(
        default,
        deserialize_with = "lenient::opt_string",
        skip_serializing_if = "Option::is_none"
    )]
    pub otlp_endpoint: Option<String>,
    /// Service name of exported spans and prefix of the log file names. `Config::load`
    /// fills it with `[service] name` when not set.
    #[serde(
        default,
        deserialize_with = "lenient::opt_string",
        skip_serializing_if = "Option::is_none"
    )]
    pub service_name: Option<String>,
    /// Longest log event written, bytes (1 KiB … 1 MiB); the rest of a longer one is cut and
    /// the line ends with `… [N bytes cut]`.
    #[serde(default = "TelemetryConfig::default_max_event_bytes")]
    pub max_event_bytes: usize,
    /// Daily log files kept (1 … 3,650); older ones are deleted.
    #[serde(default = "TelemetryConfig::default_keep_log_days")]
    pub keep_log_days: usize,
}

impl TelemetryConfig {
    /// 16 KiB.
    pub const fn default_max_event_bytes() -> usize {
        16 * 1024
    }

    /// 30 days.
    pub const fn default_keep_log_days() -> usize {
        30
    }

    /// The service name: [`Self::service_name`], or `"robotd"` when unset.
    pub fn service_name(&self) -> &str {
        self.service_name.as_deref().unwrap_or("robotd")
    }
}

/// `[supervision]`: a restart policy.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SupervisionConfig {
    /// At most this many restarts (>= 1) within [`Self::window_s`].
    pub max_restarts: u32,
    /// The sliding window of the restart budget, in seconds (> 0).
    pub window_s: u64,
    /// Delay before the first restart, in ms (> 0).
    pub backoff_initial_ms: u64,
    /// Longest delay between restarts, in ms (>= `backoff_initial_ms`).
    pub backoff_max_ms: u64,
    /// Growth of the delay per further restart (finite, >= 1.0).
    pub backoff_multiplier: f64,
}

impl SupervisionConfig {
    /// The restart policy these settings describe (permanent: restarted after any failure).
    pub fn policy(&self) -> crate::supervision::SupervisionPolicy {
        crate::supervision::SupervisionPolicy {
            max_restarts: self.max_restarts,
            window: self.window(),
            backoff_initial: self.backoff_initial(),
            backoff_max: self.backoff_max(),
            backoff_multiplier: self.backoff_multiplier,
            restart: crate::supervision::RestartPolicy::Permanent,
        }
    }

    /// [`Self::window_s`] as a duration.
    pub fn window(&self) -> Duration {
        Duration::from_secs(self.window_s)
    }

    /// [`Self::backoff_initial_ms`] as a duration.
    pub fn backoff_initial(&self) -> Duration {
        Duration::from_millis(self.backoff_initial_ms)
    }

    /// [`Self::backoff_max_ms`] as a duration.
    pub fn backoff_max(&self) -> Duration {
        Duration::from_millis(self.backoff_max_ms)
    }

    /// This policy with the keys set in `overrides` replaced.
    pub fn with_overrides(&self, overrides: &SupervisionOverrides) -> SupervisionConfig {
        SupervisionConfig {
            max_restarts: overrides.max_restarts.unwrap_or(self.max_restarts),
            window_s: overrides.window_s.unwrap_or(self.window_s),
            backoff_initial_ms: overrides
                .backoff_initial_ms
                .unwrap_or(self.backoff_initial_ms),
            backoff_max_ms: overrides.backoff_max_ms.unwrap_or(self.backoff_max_ms),
            backoff_multiplier: overrides
                .backoff_multiplier
                .unwrap_or(self.backoff_multiplier),
        }
    }

    /// Problems of this policy as `(key under prefix, reason)`.
    fn problems(&self, prefix: &str, out: &mut Vec<(String, String)>) {
        let mut problem = |key: &str, reason: String| out.push((format!("{prefix}.{key}"), reason));
        if self.max_restarts < 1 {
            problem(
                "max_restarts",
                "must be at least 1 (an actor that may never restart is not supervised)".into(),
            );
        }
        if self.window_s == 0 {
            problem("window_s", "must be greater than 0 seconds".into());
        }
        if self.backoff_initial_ms == 0 {
            problem("backoff_initial_ms", "must be greater than 0 ms".into());
        }
        if self.backoff_max_ms < self.backoff_initial_ms {
            problem(
                "backoff_max_ms",
                format!(
                    "must be at least backoff_initial_ms ({} ms), got {} ms",
                    self.backoff_initial_ms, self.backoff_max_ms
                ),
            );
        }
        if !self.backoff_multiplier.is_finite() || self.backoff_multiplier < 1.0 {
            problem(
                "backoff_multiplier",
                format!(
                    "must be a number of at least 1.0 (delays never shrink), got {}",
                    self.backoff_multiplier
                ),
            );
        }
    }
}

/// Where an actor runs.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ActorMode {
    /// A task inside robotd (the default).
    #[default]
    InProcess,
    /// A child process robotd starts from [`ActorConfig::command`], supervises and restarts.
    Process,
}

/// `[actors.<name>]`: settings of one actor.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ActorConfig {
    /// Where the actor runs.
    #[serde(default)]
    pub mode: ActorMode,
    /// Program and arguments of the child process; required with [`ActorMode::Process`],
    /// refused otherwise.
    #[serde(
        default,
        deserialize_with = "lenient::strings",
        skip_serializing_if = "Vec::is_empty"
    )]
    pub command: Vec<String>,
    /// Keys of `[supervision]` that differ for this actor.
    #[serde(default)]
    pub supervision: SupervisionOverrides,
}

/// Per-actor replacements of `[supervision]` keys; `None` keeps the default.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SupervisionOverrides {
    /// See [`SupervisionConfig::max_restarts`].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_restarts: Option<u32>,
    /// See [`SupervisionConfig::window_s`].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub window_s: Option<u64>,
    /// See [`SupervisionConfig::backoff_initial_ms`].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub backoff_initial_ms: Option<u64>,
    /// See [`SupervisionConfig::backoff_max_ms`].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub backoff_max_ms: Option<u64>,
    /// See [`SupervisionConfig::backoff_multiplier`].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub backoff_multiplier: Option<f64>,
}

// ---------------------------------------------------------------------------------------------
// Loading

impl Section for ServiceConfig {
    fn check(&self, checks: &mut Checks) {
        if self.name.trim().is_empty() {
            checks.problem("name", "must not be empty");
        } else if self.name.chars().any(char::is_control) {
            checks.problem("name", "must not contain control characters");
        }
        if !(1..=MAX_WORKER_THREADS).contains(&self.worker_threads) {
            checks.problem(
                "worker_threads",
                format!(
                    "must be from 1 to {MAX_WORKER_THREADS}, got {}",
                    self.worker_threads
                ),
            );
        }
    }
}

impl Section for BusConfig {
    fn check(&self, checks: &mut Checks) {
        if let Err(reason) = check_name(&self.namespace, MAX_NAMESPACE_LEN) {
            checks.problem(
                "namespace",
                format!("{reason} (it prefixes iceoryx2 service names)"),
            );
        }
        if self.request_timeout_ms == 0 {
            checks.problem("request_timeout_ms", "must be greater than 0 ms");
        }
        if !(1..=MAX_FRAME_SUBSCRIBER_BUFFER).contains(&self.frame_subscriber_buffer) {
            checks.problem(
                "frame_subscriber_buffer",
                format!(
                    "must be from 1 to {MAX_FRAME_SUBSCRIBER_BUFFER} frames, got {}",
                    self.frame_subscriber_buffer
                ),
            );
        }
    }
}

impl Section for TelemetryConfig {
    fn check(&self, checks: &mut Checks) {
        if self.log_dir.as_os_str().is_empty() {
            checks.problem(
                "log_dir",
                "must not be empty (use \".\" for the working directory)",
            );
        }
        if let Err(error) = tracing_subscriber::EnvFilter::builder().parse(&self.filter) {
            checks.problem(
                "filter",
                format!("{error}; expected a tracing env-filter such as \"info\" or \"info,robotd_runtime=debug\""),
            );
        }
        if let Some(endpoint) = &self.otlp_endpoint {
            if let Err(reason) = check_url(endpoint, &["http", "https"]) {
                checks.problem(
                    "otlp_endpoint",
                    format!("{reason}; expected the collector's base URL such as \"http://localhost:4318\""),
                );
            }
        }
        if let Some(name) = &self.service_name {
            if name.trim().is_empty() {
                checks.problem("service_name", "must not be empty");
            }
        }
        checks.range_u64(
            "max_event_bytes",
            self.max_event_bytes as u64,
            1024..=1024 * 1024,
            "",
        );
        checks.range_u64("keep_log_days", self.keep_log_days as u64, 1..=3650, "");
    }
}

impl Section for SupervisionConfig {
    fn check(&self, checks: &mut Checks) {
        let mut found = Vec::new();
        self.problems("", &mut found);
        for (key, reason) in found {
            checks.problem(key.trim_start_matches('.'), reason);
        }
    }
}

/// `[actors]`: one table per actor, each read on its own so every actor's problem is listed.
pub type ActorsConfig = BTreeMap<String, ActorConfig>;

impl Section for ActorsConfig {
    /// Names and modes; the per-actor supervision overrides are checked against
    /// `[supervision]` by [`check_actors`], which the composed configuration calls.
    fn check(&self, checks: &mut Checks) {
        for (name, actor) in self {
            if let Err(reason) = check_name(name, MAX_NAMESPACE_LEN) {
                checks.problem(name, format!("bad actor name: {reason}"));
            }
            match actor.mode {
                ActorMode::Process if actor.command.first().is_none_or(|p| p.trim().is_empty()) => {
                    checks.problem(
                        &format!("{name}.command"),
                        "mode = \"process\" needs the program to start, e.g. command = [\"robotd-camera\", \"--device\", \"0\"]",
                    )
                }
                ActorMode::InProcess if !actor.command.is_empty() => checks.problem(
                    &format!("{name}.command"),
                    "is only used with mode = \"process\"; set the mode or remove the command",
                ),
                _ => {}
            }
        }
    }

    fn read_problems(reader: &mut super::SectionReader<'_>, key: &str) {
        reader.read_each::<ActorConfig>(key);
    }
}

/// Problems the actors' supervision overrides cause (those of `[supervision]` itself are
/// reported once, under `supervision.*`), as `(dotted key, reason)`.
pub fn check_actors(
    actors: &ActorsConfig,
    supervision: &SupervisionConfig,
    out: &mut Vec<(String, String)>,
) {
    let mut inherited = Vec::new();
    supervision.problems("", &mut inherited);
    for (name, actor) in actors {
        let mut own = Vec::new();
        supervision
            .with_overrides(&actor.supervision)
            .problems(&format!("actors.{name}.supervision"), &mut own);
        out.extend(own.into_iter().filter(|(key, _)| {
            let field = key.rsplit('.').next().unwrap_or_default();
            !inherited
                .iter()
                .any(|(k, _)| k.rsplit('.').next() == Some(field))
        }));
    }
}
