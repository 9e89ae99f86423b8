//! robotd's configuration: one typed [`Config`], loaded in layers and checked at start-up.
//!
//! Each layer only names the keys it changes; later layers win:
//!
//! 1. the built-in defaults, [`DEFAULT_TOML`] (`config/default.toml`, compiled in, every key
//!    documented), so robotd runs with no file at all;
//! 2. a TOML file given with `--config path` ([`LoadOptions::file`]);
//! 3. environment variables `ROBOTD_<SECTION>__<KEY>`: `__` separates levels and names are
//!    case-insensitive, e.g. `ROBOTD_HTTP__BIND=0.0.0.0:8000` or
//!    `ROBOTD_ACTORS__CAMERA__COMMAND='["robotd-camera", "--device", "0"]'`
//!    (`ROBOTD_CONFIG`, the file of layer 2, is the one `ROBOTD_` variable that is not a key);
//! 4. command-line overrides `key=value` ([`LoadOptions::overrides`]), e.g. `http.bind=0.0.0.0:8000`.
//!
//! Values from the environment and overrides are read like TOML values (`8000` is a number,
//! `true` a boolean, `[a, b]` a list) and may also be written as text.
//!
//! Nothing wrong is ignored: an unknown key (a typo) or an invalid value anywhere refuses the
//! whole configuration with a [`ConfigError::Invalid`] listing each problem with its key, the
//! reason and where it was set (file, environment variable or override). Problems of types
//! and unknown keys are found one per section (serde stops at the first in a table); once
//! every value reads, [`Config::validate`]'s range checks are all reported together:
//!
//! ```text
//! invalid configuration:
//!   - http.bind: invalid socket address syntax; expected an IP address and port such as "127.0.0.1:8000" (set in environment variable ROBOTD_HTTP__BIND)
//!   - supervision.max_restart: unknown key; [supervision] accepts max_restarts, window_s, backoff_initial_ms, backoff_max_ms, backoff_multiplier (set in config file robotd.toml)
//!   - robot.driver: unknown value "ned3"; expected one of "sim-ned2", "sim-widowx", "niryo", "widowx" (set in command-line override robot.driver=…)
//! ```
//!
//! ```
//! use robotd_runtime::config::{Config, LoadOptions, RobotDriver};
//!
//! // What the binary does: `robotd --config lab.toml http.bind=0.0.0.0:8000` (serving the
//! // network needs the MCP bearer token, usually from ROBOTD_MCP__TOKEN).
//! let options = LoadOptions {
//!     file: None,
//!     overrides: vec![
//!         ("http.bind".into(), "0.0.0.0:8000".into()),
//!         ("mcp.token".into(), "a-long-random-token".into()),
//!     ],
//! };
//! // `load` reads the process environment; `load_with_env` takes it explicitly (tests).
//! let config = Config::load_with_env(options, Vec::<(String, String)>::new()).unwrap();
//! assert_eq!(config.http.bind.port(), 8000);
//! assert_eq!(config.robot.driver, RobotDriver::SimNed2);
//! assert_eq!(config.supervision_for("camera").max_restarts, 5);
//!
//! // A typo is refused, not ignored.
//! let typo = LoadOptions { file: None, overrides: vec![("http.bnid".into(), "x".into())] };
//! let error = Config::load_with_env(typo, Vec::<(String, String)>::new()).unwrap_err();
//! assert!(error.to_string().contains("http.bnid: unknown key"));
//! ```

use figment::error::Kind;
use figment::value::{Dict, Map, Value};
use figment::{Figment, Metadata, Profile, Provider, Source};
use serde::{Deserialize, Deserializer, Serialize};
use std::collections::BTreeMap;
use std::fmt;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::OnceLock;
use std::time::Duration;

/// The built-in defaults (`config/default.toml`), the first layer of every configuration.
pub const DEFAULT_TOML: &str = include_str!("../../config/default.toml");

/// Prefix of the environment variables that set configuration keys.
pub const ENV_PREFIX: &str = "ROBOTD_";

/// The environment variable naming the configuration file; the only `ROBOTD_` variable that
/// is not read as a key (the binary passes its value as [`LoadOptions::file`]).
pub const ENV_CONFIG_FILE: &str = "ROBOTD_CONFIG";

/// Separator of nesting levels in environment variable names (`ROBOTD_HTTP__BIND`).
pub const ENV_SEPARATOR: &str = "__";

/// Longest accepted [`BusConfig::namespace`].
pub const MAX_NAMESPACE_LEN: usize = 64;

/// Largest accepted [`BusConfig::frame_subscriber_buffer`] (each slot holds a whole frame in
/// shared memory).
pub const MAX_FRAME_SUBSCRIBER_BUFFER: usize = 64;

// Names of the layers' metadata; `origin_of` maps them back to an `Origin`.
const DEFAULTS_NAME: &str = "built-in defaults";
const FILE_NAME: &str = "config file";
const ENV_NAME: &str = "environment variable";
const OVERRIDE_NAME: &str = "command-line override";

// ---------------------------------------------------------------------------------------------
// The configuration

/// The whole robotd configuration. See the module docs for how it is loaded, and
/// `config/default.toml` for every key with its meaning and default.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Config {
    /// `[service]`: this instance.
    pub service: ServiceConfig,
    /// `[http]`: the HTTP edge.
    pub http: HttpConfig,
    /// `[bus]`: the iceoryx2 bus.
    pub bus: BusConfig,
    /// `[telemetry]`: logs and trace export.
    pub telemetry: TelemetryConfig,
    /// `[supervision]`: the default restart policy of supervised actors.
    pub supervision: SupervisionConfig,
    /// `[robot]`: which arm robotd drives.
    pub robot: RobotConfig,
    /// `[redis]`: the Redis edge to the Python tools.
    #[serde(default)]
    pub redis: RedisConfig,
    /// `[perception]`: the built-in detector.
    #[serde(default)]
    pub perception: PerceptionConfig,
    /// `[workspace]`: the scene memory the detection tools answer from.
    #[serde(default)]
    pub workspace: WorkspaceConfig,
    /// `[tts]`: text to speech.
    #[serde(default)]
    pub tts: TtsConfig,
    /// `[mcp]`: the MCP edge (served on the `[http]` port).
    #[serde(default)]
    pub mcp: McpConfig,
    /// `[agent]`: the LLM agent (`robotd chat`, and the agent actor of `robotd serve`).
    #[serde(default)]
    pub agent: AgentConfig,
    /// `[actors.<name>]`: per-actor settings; actors without an entry run in-process with
    /// the `[supervision]` policy.
    #[serde(default)]
    pub actors: BTreeMap<String, ActorConfig>,
}

/// `[service]`
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ServiceConfig {
    /// Name of this instance, shown in logs, health and the dashboard.
    #[serde(deserialize_with = "lenient::string")]
    pub name: String,
}

/// `[http]`
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HttpConfig {
    /// Address of the HTTP edge; port 0 picks a free port.
    pub bind: SocketAddr,
}

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
    /// Service name of exported spans and prefix of the log file names. [`Config::load`]
    /// fills it with `[service] name` when not set.
    #[serde(
        default,
        deserialize_with = "lenient::opt_string",
        skip_serializing_if = "Option::is_none"
    )]
    pub service_name: Option<String>,
}

impl TelemetryConfig {
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

/// Which arm robotd drives.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum RobotDriver {
    /// Simulated Niryo Ned2 (the default; no hardware).
    SimNed2,
    /// Simulated WidowX.
    SimWidowx,
    /// A real Niryo Ned2 over its TCP protocol.
    Niryo,
    /// A real WidowX over Dynamixel Protocol 2.0.
    Widowx,
}

impl RobotDriver {
    /// Whether this driver is a simulator (needs no hardware).
    pub fn is_simulated(self) -> bool {
        matches!(self, RobotDriver::SimNed2 | RobotDriver::SimWidowx)
    }
}

/// `[robot]`
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RobotConfig {
    /// The arm driver.
    pub driver: RobotDriver,
    /// Scene file of the simulator (objects, workspaces); `None` = the built-in default scene
    /// of the simulated model.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub scene: Option<PathBuf>,
    /// Simulated motion time relative to the real robot (1.0 = realistic, 0.1 = ten times
    /// faster). Finite, from 0.001 to 100.
    #[serde(default = "defaults::time_scale")]
    pub time_scale: f64,
    /// Control ticks per second of the arm: how often a motion is advanced, checked for a stop
    /// and published on `arm/state` (1 to 1000).
    #[serde(default = "defaults::control_rate_hz")]
    pub control_rate_hz: u32,
    /// `[robot.camera]`: the wrist camera.
    #[serde(default)]
    pub camera: CameraConfig,
    /// `[robot.faults.<arm|gripper|camera>]`: faults the simulated drivers inject on purpose.
    #[serde(default)]
    pub faults: FaultsConfig,
}

impl RobotConfig {
    /// [`Self::control_rate_hz`] as the period of one control tick.
    pub fn control_period(&self) -> Duration {
        Duration::from_secs_f64(1.0 / f64::from(self.control_rate_hz.max(1)))
    }
}

/// `[robot.camera]`
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraConfig {
    /// Frames per second published on `camera/frames` (0.1 to 60).
    #[serde(default = "defaults::camera_fps")]
    pub fps: f64,
    /// Standard deviation of the simulated sensor noise, in 0–255 pixel units (0 to 50).
    #[serde(default = "defaults::noise_stddev")]
    pub noise_stddev: f64,
    /// Whether the simulated camera applies the lens distortion of its intrinsics.
    #[serde(default)]
    pub lens_distortion: bool,
}

impl Default for CameraConfig {
    fn default() -> Self {
        Self {
            fps: defaults::camera_fps(),
            noise_stddev: defaults::noise_stddev(),
            lens_distortion: false,
        }
    }
}

/// `[robot.faults]`: fault injection per simulated hardware actor.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FaultsConfig {
    /// Faults of the arm driver.
    #[serde(default)]
    pub arm: FaultConfig,
    /// Faults of the gripper driver.
    #[serde(default)]
    pub gripper: FaultConfig,
    /// Faults of the camera driver.
    #[serde(default)]
    pub camera: FaultConfig,
}

/// Faults one simulated driver injects: a failing command crashes the driver (as a driver bug
/// would), so supervision brings the actor to its safe state and restarts it.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FaultConfig {
    /// Fail every Nth command (0 = never).
    #[serde(default)]
    pub fail_every_n: u32,
    /// Fail each command with this probability (0.0 to 1.0).
    #[serde(default)]
    pub fail_probability: f64,
    /// Seed of the random failures, so a run can be repeated.
    #[serde(default)]
    pub seed: u64,
    /// A failing command first hangs this long, in ms (0 = fails at once).
    #[serde(default)]
    pub hang_ms: u64,
}

impl FaultConfig {
    /// Whether any fault is configured.
    pub fn is_active(&self) -> bool {
        self.fail_every_n > 0 || self.fail_probability > 0.0
    }
}

mod defaults {
    pub fn agent_api() -> String {
        "auto".into()
    }
    pub fn yes() -> bool {
        true
    }
    pub fn redis_camera_fps() -> f64 {
        10.0
    }
    pub fn redis_objects_fps() -> f64 {
        5.0
    }
    pub fn redis_annotated_fps() -> f64 {
        2.0
    }
    pub fn redis_trust() -> String {
        "both".into()
    }
    pub fn redis_max_entry_bytes() -> u64 {
        16 * 1024 * 1024
    }
    pub fn time_scale() -> f64 {
        1.0
    }
    pub fn control_rate_hz() -> u32 {
        50
    }
    pub fn camera_fps() -> f64 {
        15.0
    }
    pub fn noise_stddev() -> f64 {
        2.0
    }
}

/// `[redis]`
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RedisConfig {
    /// `redis://[:password@]host:port/db` (or `rediss://` for TLS) of the Python tools' Redis.
    /// `None`: `REDIS_HOST`/`REDIS_PORT` decide, and without them the Redis edge is off.
    #[serde(
        default,
        deserialize_with = "lenient::opt_string",
        skip_serializing_if = "Option::is_none"
    )]
    pub url: Option<String>,
    /// Camera frames per second to `robot_camera` (0 = none; at most 60).
    #[serde(default = "defaults::redis_camera_fps")]
    pub camera_fps: f64,
    /// Annotated frames per second to `annotated_camera` (0 = none; at most 60).
    #[serde(default = "defaults::redis_annotated_fps")]
    pub annotated_fps: f64,
    /// Entries per second of robotd's own detections to `detected_objects` (0 = none; at
    /// most 60).
    #[serde(default = "defaults::redis_objects_fps")]
    pub objects_fps: f64,
    /// Which detector the workspace model believes: `builtin`, `external` (over Redis; the
    /// built-in detector then does not run) or `both`.
    #[serde(
        default = "defaults::redis_trust",
        deserialize_with = "lenient::string"
    )]
    pub trust: String,
    /// Largest entry read from Redis, bytes of its values (bigger ones are skipped).
    #[serde(default = "defaults::redis_max_entry_bytes")]
    pub max_entry_bytes: u64,
}

impl Default for RedisConfig {
    fn default() -> Self {
        Self {
            url: None,
            camera_fps: defaults::redis_camera_fps(),
            annotated_fps: defaults::redis_annotated_fps(),
            objects_fps: defaults::redis_objects_fps(),
            trust: defaults::redis_trust(),
            max_entry_bytes: defaults::redis_max_entry_bytes(),
        }
    }
}

/// `[agent]`. Keys and base URLs set in the environment (or `secrets.env`) win over the base
/// URLs here.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AgentConfig {
    /// The provider: `auto` (the first whose key is set: openai, groq, gemini, ollama,
    /// openai-compatible), or one of those names.
    #[serde(default = "defaults::agent_api", deserialize_with = "lenient::string")]
    pub api: String,
    /// The model; `None` = the provider's default.
    #[serde(
        default,
        deserialize_with = "lenient::opt_string",
        skip_serializing_if = "Option::is_none"
    )]
    pub model: Option<String>,
    /// Run the agent actor on the bus in `robotd serve` when a provider is usable.
    #[serde(default = "defaults::yes")]
    pub serve: bool,
    /// Base URL of OpenAI (as `OPENAI_BASE_URL`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub openai_base_url: Option<String>,
    /// Base URL of Groq (as `GROQ_BASE_URL`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub groq_base_url: Option<String>,
    /// Base URL of Gemini's OpenAI-compatible API (as `GEMINI_BASE_URL`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gemini_base_url: Option<String>,
    /// The Ollama server (as `OLLAMA_HOST`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ollama_host: Option<String>,
    /// Any OpenAI-compatible server (as `LLM_BASE_URL`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub llm_base_url: Option<String>,
}

impl Default for AgentConfig {
    fn default() -> Self {
        Self {
            api: defaults::agent_api(),
            model: None,
            serve: true,
            openai_base_url: None,
            groq_base_url: None,
            gemini_base_url: None,
            ollama_host: None,
            llm_base_url: None,
        }
    }
}

impl AgentConfig {
    /// The base URLs set here, under the names of their environment variables.
    pub fn base_url_variables(&self) -> Vec<(&'static str, String)> {
        [
            ("OPENAI_BASE_URL", &self.openai_base_url),
            ("GROQ_BASE_URL", &self.groq_base_url),
            ("GEMINI_BASE_URL", &self.gemini_base_url),
            ("OLLAMA_HOST", &self.ollama_host),
            ("LLM_BASE_URL", &self.llm_base_url),
        ]
        .into_iter()
        .filter_map(|(k, v)| v.clone().map(|v| (k, v)))
        .collect()
    }
}

/// `[perception]`
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PerceptionConfig {
    /// Label table of the built-in colour/shape detector (see `config/labels.toml`); `None`
    /// uses the built-in table.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub labels: Option<PathBuf>,
}

/// `[workspace]`
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WorkspaceConfig {
    /// Margin kept free around every object when looking for free space, metres (0 … 0.1).
    #[serde(default = "WorkspaceConfig::free_space_margin_m")]
    pub free_space_margin_m: f64,
    /// An object not seen in this many steady frames of its workspace in a row is forgotten
    /// (1 … 1000).
    #[serde(default = "WorkspaceConfig::expire_after_frames")]
    pub expire_after_frames: u32,
    /// Longest a detection tool waits for a fresh view of the workspace, ms (1 … 60000).
    #[serde(default = "WorkspaceConfig::fresh_wait_ms")]
    pub fresh_wait_ms: u64,
}

impl Default for WorkspaceConfig {
    fn default() -> Self {
        Self {
            free_space_margin_m: Self::free_space_margin_m(),
            expire_after_frames: Self::expire_after_frames(),
            fresh_wait_ms: Self::fresh_wait_ms(),
        }
    }
}

impl WorkspaceConfig {
    fn free_space_margin_m() -> f64 {
        0.01
    }
    fn expire_after_frames() -> u32 {
        3
    }
    fn fresh_wait_ms() -> u64 {
        3000
    }
}

/// `[mcp]`: the MCP edge, served on the `[http]` port (`/sse`, `/messages/`, `/mcp`).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct McpConfig {
    /// Serve the MCP routes at all.
    pub enabled: bool,
    /// Bearer token every MCP request must carry (`Authorization: Bearer …`). Required when
    /// `http.bind` is not a loopback address. Prefer the `ROBOTD_MCP__TOKEN` environment
    /// variable to writing it in a file.
    pub token: Option<String>,
    /// Largest request body, bytes (1 KiB … 64 MiB).
    pub max_body_bytes: usize,
    /// Browser origins allowed besides local ones, e.g. "https://lab.example.org".
    pub allowed_origins: Vec<String>,
    /// Set `isError: true` on failure replies (the Python server never did).
    pub strict_errors: bool,
    /// Longest a motion tool (pick, place, push …) may take, seconds.
    pub skill_timeout_s: u64,
}

impl Default for McpConfig {
    fn default() -> Self {
        Self {
            enabled: true,
            token: None,
            max_body_bytes: 1024 * 1024,
            allowed_origins: Vec::new(),
            strict_errors: false,
            skill_timeout_s: 180,
        }
    }
}

/// `[tts]`
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct TtsConfig {
    /// "auto", "espeak-ng", "elevenlabs" or "none".
    pub engine: String,
    /// espeak-ng voice.
    pub voice: String,
    /// espeak-ng speed, words per minute (80 … 450).
    pub rate_wpm: u32,
    /// "auto" (the audio device when there is one, else the spool), "device" or "spool".
    pub output: String,
    /// Directory of the WAV spool.
    pub spool_dir: PathBuf,
    /// Largest size of the spool, MB (oldest files are deleted first).
    pub spool_max_mb: u64,
    /// Texts that may wait (1 … 1000).
    pub queue_capacity: usize,
    /// The same text within this many ms is spoken once.
    pub duplicate_window_ms: u64,
    /// Base URL of the ElevenLabs API.
    pub elevenlabs_base_url: String,
    /// ElevenLabs voice id.
    pub elevenlabs_voice_id: String,
    /// ElevenLabs model id.
    pub elevenlabs_model_id: String,
}

impl Default for TtsConfig {
    fn default() -> Self {
        Self {
            engine: "auto".into(),
            voice: "en".into(),
            rate_wpm: 160,
            output: "auto".into(),
            spool_dir: PathBuf::from("log/speech"),
            spool_max_mb: 50,
            queue_capacity: 50,
            duplicate_window_ms: 2000,
            elevenlabs_base_url: "https://api.elevenlabs.io".into(),
            elevenlabs_voice_id: "21m00Tcm4TlvDq8ikWAM".into(),
            elevenlabs_model_id: "eleven_multilingual_v2".into(),
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

/// What the binary passes to [`Config::load`]: the user's file and command-line overrides.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct LoadOptions {
    /// A TOML file layered over the defaults (`--config path`); it must exist.
    pub file: Option<PathBuf>,
    /// `(key, value)` pairs applied last, e.g. `("http.bind", "0.0.0.0:8000")`; keys are dotted
    /// paths, values are read like environment values.
    pub overrides: Vec<(String, String)>,
}

impl LoadOptions {
    /// Splits a command-line `key=value` argument into an override pair.
    ///
    /// ```
    /// # use robotd_runtime::config::LoadOptions;
    /// let pair = LoadOptions::parse_override("http.bind=0.0.0.0:8000").unwrap();
    /// assert_eq!(pair, ("http.bind".to_string(), "0.0.0.0:8000".to_string()));
    /// assert!(LoadOptions::parse_override("http.bind").is_err());
    /// ```
    pub fn parse_override(argument: &str) -> Result<(String, String), ConfigError> {
        match argument.split_once('=') {
            Some((key, value)) if !key.trim().is_empty() => {
                Ok((key.trim().to_owned(), value.to_owned()))
            }
            _ => Err(ConfigError::BadOverride {
                argument: argument.to_owned(),
            }),
        }
    }
}

impl Default for Config {
    /// The built-in defaults ([`DEFAULT_TOML`]) alone: no file, environment or overrides.
    fn default() -> Self {
        static DEFAULT: OnceLock<Config> = OnceLock::new();
        DEFAULT
            .get_or_init(|| {
                let figment = Figment::new().merge(defaults_layer());
                match extract(&figment) {
                    Ok(config) => config,
                    // Checked by the `defaults_load` test; cannot depend on outside input.
                    Err(error) => panic!("the built-in config/default.toml is invalid: {error}"),
                }
            })
            .clone()
    }
}

impl Config {
    /// Loads the configuration: defaults, then `options.file`, then the process's `ROBOTD_*`
    /// environment variables, then `options.overrides`; then checks it ([`Config::validate`]).
    pub fn load(options: LoadOptions) -> Result<Config, ConfigError> {
        Self::load_with_env(
            options,
            std::env::vars_os()
                .filter_map(|(k, v)| Some((k.into_string().ok()?, v.into_string().ok()?))),
        )
    }

    /// As [`Config::load`], with the environment given explicitly instead of read from the
    /// process (tests use this so they never touch, or race on, the real environment).
    /// Pairs whose name does not start with [`ENV_PREFIX`] are ignored.
    pub fn load_with_env<I, K, V>(options: LoadOptions, env: I) -> Result<Config, ConfigError>
    where
        I: IntoIterator<Item = (K, V)>,
        K: Into<String>,
        V: Into<String>,
    {
        let mut figment = Figment::new().merge(defaults_layer());
        if let Some(path) = &options.file {
            let text = std::fs::read_to_string(path).map_err(|source| ConfigError::ReadFile {
                path: path.clone(),
                source,
            })?;
            figment = figment.merge(Layer::toml(
                text,
                Metadata::from(FILE_NAME, Source::File(path.clone())),
            ));
        }
        let env = EnvLayer::new(env.into_iter().map(|(k, v)| (k.into(), v.into())));
        figment = figment.merge(env).merge(OverrideLayer(options.overrides));
        extract(&figment)
    }

    /// Checks ranges and formats serde cannot express (ports and addresses are checked while
    /// reading). [`Config::load`] already does this; call it after changing a config in code.
    pub fn validate(&self) -> Result<(), ConfigError> {
        let problems: Vec<Problem> = self
            .problems()
            .into_iter()
            .map(|(key, reason)| Problem {
                key,
                reason,
                origin: None,
            })
            .collect();
        if problems.is_empty() {
            Ok(())
        } else {
            Err(ConfigError::Invalid { problems })
        }
    }

    /// The effective restart policy of `actor`: `[supervision]` with its overrides applied.
    pub fn supervision_for(&self, actor: &str) -> SupervisionConfig {
        match self.actors.get(actor) {
            Some(settings) => self.supervision.with_overrides(&settings.supervision),
            None => self.supervision.clone(),
        }
    }

    /// Settings of `actor` (the defaults, in-process, when it has no `[actors.<name>]`).
    pub fn actor(&self, actor: &str) -> ActorConfig {
        self.actors.get(actor).cloned().unwrap_or_default()
    }

    /// Every problem as `(dotted key, reason)`.
    fn problems(&self) -> Vec<(String, String)> {
        let mut out = Vec::new();
        let mut problem = |key: &str, reason: String| out.push((key.to_owned(), reason));

        if self.service.name.trim().is_empty() {
            problem("service.name", "must not be empty".into());
        } else if self.service.name.chars().any(char::is_control) {
            problem("service.name", "must not contain control characters".into());
        }

        if let Err(reason) = check_name(&self.bus.namespace, MAX_NAMESPACE_LEN) {
            problem(
                "bus.namespace",
                format!("{reason} (it prefixes iceoryx2 service names)"),
            );
        }
        if self.bus.request_timeout_ms == 0 {
            problem("bus.request_timeout_ms", "must be greater than 0 ms".into());
        }
        if !(1..=MAX_FRAME_SUBSCRIBER_BUFFER).contains(&self.bus.frame_subscriber_buffer) {
            problem(
                "bus.frame_subscriber_buffer",
                format!(
                    "must be from 1 to {MAX_FRAME_SUBSCRIBER_BUFFER} frames, got {}",
                    self.bus.frame_subscriber_buffer
                ),
            );
        }

        if self.telemetry.log_dir.as_os_str().is_empty() {
            problem(
                "telemetry.log_dir",
                "must not be empty (use \".\" for the working directory)".into(),
            );
        }
        if let Err(error) = tracing_subscriber::EnvFilter::builder().parse(&self.telemetry.filter) {
            problem(
                "telemetry.filter",
                format!("{error}; expected a tracing env-filter such as \"info\" or \"info,robotd_runtime=debug\""),
            );
        }
        if let Some(endpoint) = &self.telemetry.otlp_endpoint {
            if let Err(reason) = check_url(endpoint, &["http", "https"]) {
                problem(
                    "telemetry.otlp_endpoint",
                    format!("{reason}; expected the collector's base URL such as \"http://localhost:4318\""),
                );
            }
        }
        if let Some(name) = &self.telemetry.service_name {
            if name.trim().is_empty() {
                problem("telemetry.service_name", "must not be empty".into());
            }
        }

        self.supervision.problems("supervision", &mut out);

        let robot = &self.robot;
        if !(robot.time_scale.is_finite() && (0.001..=100.0).contains(&robot.time_scale)) {
            out.push((
                "robot.time_scale".into(),
                format!("must be from 0.001 to 100, got {}", robot.time_scale),
            ));
        }
        if !(1..=1000).contains(&robot.control_rate_hz) {
            out.push((
                "robot.control_rate_hz".into(),
                format!("must be from 1 to 1000, got {}", robot.control_rate_hz),
            ));
        }
        if let Some(scene) = &robot.scene {
            if scene.as_os_str().is_empty() {
                out.push((
                    "robot.scene".into(),
                    "must not be empty (leave it out for the built-in scene)".into(),
                ));
            }
        }
        if !(robot.camera.fps.is_finite() && (0.1..=60.0).contains(&robot.camera.fps)) {
            out.push((
                "robot.camera.fps".into(),
                format!("must be from 0.1 to 60, got {}", robot.camera.fps),
            ));
        }
        if !(robot.camera.noise_stddev.is_finite()
            && (0.0..=50.0).contains(&robot.camera.noise_stddev))
        {
            out.push((
                "robot.camera.noise_stddev".into(),
                format!("must be from 0 to 50, got {}", robot.camera.noise_stddev),
            ));
        }
        for (name, fault) in [
            ("arm", &robot.faults.arm),
            ("gripper", &robot.faults.gripper),
            ("camera", &robot.faults.camera),
        ] {
            if !(fault.fail_probability.is_finite()
                && (0.0..=1.0).contains(&fault.fail_probability))
            {
                out.push((
                    format!("robot.faults.{name}.fail_probability"),
                    format!("must be from 0.0 to 1.0, got {}", fault.fail_probability),
                ));
            }
            if fault.hang_ms > 600_000 {
                out.push((
                    format!("robot.faults.{name}.hang_ms"),
                    format!("must be at most 600000 ms, got {}", fault.hang_ms),
                ));
            }
        }

        let ws = &self.workspace;
        if !(ws.free_space_margin_m.is_finite() && (0.0..=0.1).contains(&ws.free_space_margin_m)) {
            out.push((
                "workspace.free_space_margin_m".into(),
                format!("must be from 0 to 0.1 m, got {}", ws.free_space_margin_m),
            ));
        }
        if !(1..=1000).contains(&ws.expire_after_frames) {
            out.push((
                "workspace.expire_after_frames".into(),
                format!("must be from 1 to 1000, got {}", ws.expire_after_frames),
            ));
        }
        if !(1..=60_000).contains(&ws.fresh_wait_ms) {
            out.push((
                "workspace.fresh_wait_ms".into(),
                format!("must be from 1 to 60000 ms, got {}", ws.fresh_wait_ms),
            ));
        }
        let tts = &self.tts;
        if !["auto", "espeak-ng", "elevenlabs", "none"].contains(&tts.engine.as_str()) {
            out.push((
                "tts.engine".into(),
                format!(
                    "unknown value \"{}\"; expected one of \"auto\", \"espeak-ng\", \"elevenlabs\", \"none\"",
                    tts.engine
                ),
            ));
        }
        if !["auto", "device", "spool"].contains(&tts.output.as_str()) {
            out.push((
                "tts.output".into(),
                format!(
                    "unknown value \"{}\"; expected one of \"auto\", \"device\", \"spool\"",
                    tts.output
                ),
            ));
        }
        if !(80..=450).contains(&tts.rate_wpm) {
            out.push((
                "tts.rate_wpm".into(),
                format!("must be from 80 to 450, got {}", tts.rate_wpm),
            ));
        }
        if !(1..=1000).contains(&tts.queue_capacity) {
            out.push((
                "tts.queue_capacity".into(),
                format!("must be from 1 to 1000, got {}", tts.queue_capacity),
            ));
        }
        if tts.duplicate_window_ms > 600_000 {
            out.push((
                "tts.duplicate_window_ms".into(),
                format!("must be at most 600000 ms, got {}", tts.duplicate_window_ms),
            ));
        }
        if !(1..=100_000).contains(&tts.spool_max_mb) {
            out.push((
                "tts.spool_max_mb".into(),
                format!("must be from 1 to 100000, got {}", tts.spool_max_mb),
            ));
        }
        if tts.voice.trim().is_empty() || tts.voice.starts_with('-') {
            out.push((
                "tts.voice".into(),
                format!(
                    "must be an espeak-ng voice name such as \"en\", got \"{}\"",
                    tts.voice
                ),
            ));
        }
        if let Some(path) = &self.perception.labels {
            if path.as_os_str().is_empty() {
                out.push((
                    "perception.labels".into(),
                    "must name a label table file (or be left out for the built-in one)".into(),
                ));
            }
        }

        let mcp = &self.mcp;
        if !(1024..=64 * 1024 * 1024).contains(&mcp.max_body_bytes) {
            out.push((
                "mcp.max_body_bytes".into(),
                format!("must be from 1024 to 67108864, got {}", mcp.max_body_bytes),
            ));
        }
        if !(1..=3600).contains(&mcp.skill_timeout_s) {
            out.push((
                "mcp.skill_timeout_s".into(),
                format!("must be from 1 to 3600 s, got {}", mcp.skill_timeout_s),
            ));
        }
        if let Some(token) = &mcp.token {
            if token.trim().len() < 8 {
                out.push((
                    "mcp.token".into(),
                    "must be at least 8 characters (a random string; leave it out for no token)"
                        .into(),
                ));
            }
        }
        for origin in &mcp.allowed_origins {
            if let Err(reason) = check_url(origin, &["http", "https"]) {
                out.push((
                    "mcp.allowed_origins".into(),
                    format!("{reason}; expected an origin such as \"https://lab.example.org\""),
                ));
            }
        }
        if mcp.enabled
            && !self.http.bind.ip().is_loopback()
            && mcp.token.as_deref().is_none_or(|t| t.trim().is_empty())
        {
            out.push((
                "mcp.token".into(),
                format!(
                    "is required because http.bind {} is not a loopback address: without it \
                     anyone on the network could move the robot (set ROBOTD_MCP__TOKEN, or bind \
                     127.0.0.1)",
                    self.http.bind
                ),
            ));
        }

        if let Some(url) = &self.redis.url {
            if let Err(reason) = check_url(url, &["redis", "rediss", "redis+unix", "unix"]) {
                out.push((
                    "redis.url".into(),
                    format!("{reason}; expected a URL such as \"redis://localhost:6379/0\""),
                ));
            }
        }
        for (key, url) in [
            ("agent.openai_base_url", &self.agent.openai_base_url),
            ("agent.groq_base_url", &self.agent.groq_base_url),
            ("agent.gemini_base_url", &self.agent.gemini_base_url),
            ("agent.ollama_host", &self.agent.ollama_host),
            ("agent.llm_base_url", &self.agent.llm_base_url),
        ] {
            if let Some(url) = url {
                if let Err(reason) = check_url(url, &["http", "https"]) {
                    out.push((key.into(), reason));
                }
            }
        }
        if ![
            "auto",
            "openai",
            "groq",
            "gemini",
            "ollama",
            "openai-compatible",
            "compatible",
            "llm",
        ]
        .contains(&self.agent.api.trim().to_ascii_lowercase().as_str())
        {
            out.push((
                "agent.api".into(),
                format!(
                    "'{}' is not a provider; use auto, openai, groq, gemini, ollama or \
                     openai-compatible",
                    self.agent.api
                ),
            ));
        }
        for (key, fps) in [
            ("redis.camera_fps", self.redis.camera_fps),
            ("redis.annotated_fps", self.redis.annotated_fps),
            ("redis.objects_fps", self.redis.objects_fps),
        ] {
            if !(0.0..=60.0).contains(&fps) {
                out.push((
                    key.into(),
                    format!("{fps} is not a frame rate from 0 (off) to 60"),
                ));
            }
        }
        if !["builtin", "external", "both"]
            .contains(&self.redis.trust.trim().to_ascii_lowercase().as_str())
        {
            out.push((
                "redis.trust".into(),
                format!(
                    "'{}' is not a detector to trust; use builtin, external or both",
                    self.redis.trust
                ),
            ));
        }
        if !(1024..=512 * 1024 * 1024).contains(&self.redis.max_entry_bytes) {
            out.push((
                "redis.max_entry_bytes".into(),
                format!(
                    "{} is not a size from 1024 to 536870912 bytes",
                    self.redis.max_entry_bytes
                ),
            ));
        }

        for (name, actor) in &self.actors {
            let prefix = format!("actors.{name}");
            if let Err(reason) = check_name(name, MAX_NAMESPACE_LEN) {
                out.push((prefix.clone(), format!("bad actor name: {reason}")));
            }
            match actor.mode {
                ActorMode::Process if actor.command.first().is_none_or(|p| p.trim().is_empty()) => {
                    out.push((
                        format!("{prefix}.command"),
                        "mode = \"process\" needs the program to start, e.g. command = [\"robotd-camera\", \"--device\", \"0\"]".into(),
                    ))
                }
                ActorMode::InProcess if !actor.command.is_empty() => out.push((
                    format!("{prefix}.command"),
                    "is only used with mode = \"process\"; set the mode or remove the command".into(),
                )),
                _ => {}
            }
            // Problems the actor's overrides cause (those of [supervision] itself are already
            // reported once, above).
            let mut inherited = Vec::new();
            self.supervision.problems("", &mut inherited);
            let mut own = Vec::new();
            self.supervision
                .with_overrides(&actor.supervision)
                .problems(&format!("{prefix}.supervision"), &mut own);
            out.extend(own.into_iter().filter(|(key, _)| {
                let field = key.rsplit('.').next().unwrap_or_default();
                !inherited
                    .iter()
                    .any(|(k, _)| k.rsplit('.').next() == Some(field))
            }));
        }
        out
    }
}

/// `Ok` when `name` is 1 to `max` characters of `[A-Za-z0-9_-]`.
fn check_name(name: &str, max: usize) -> Result<(), String> {
    if name.is_empty() {
        return Err("must not be empty".into());
    }
    if name.len() > max {
        return Err(format!(
            "must be at most {max} characters, got {}",
            name.len()
        ));
    }
    if let Some(bad) = name
        .chars()
        .find(|c| !(c.is_ascii_alphanumeric() || *c == '_' || *c == '-'))
    {
        return Err(format!(
            "{name:?} contains {bad:?}; only letters, digits, '_' and '-' are allowed"
        ));
    }
    Ok(())
}

/// `Ok` when `url` is `<scheme>://<something>` with one of `schemes`.
fn check_url(url: &str, schemes: &[&str]) -> Result<(), String> {
    match url.split_once("://") {
        Some((scheme, rest)) if schemes.contains(&scheme) && !rest.is_empty() => Ok(()),
        Some((scheme, _)) if !schemes.contains(&scheme) => Err(format!(
            "{url:?} has scheme {scheme:?}, not one of {}",
            schemes.join(", ")
        )),
        _ => Err(format!("{url:?} is not a URL")),
    }
}

/// Extracts and validates, turning every error into a [`Problem`] with its origin.
fn extract(figment: &Figment) -> Result<Config, ConfigError> {
    let mut config: Config = figment.extract().map_err(|error| ConfigError::Invalid {
        problems: deserialization_problems(figment, error),
    })?;
    if config.telemetry.service_name.is_none() {
        config.telemetry.service_name = Some(config.service.name.clone());
    }
    let problems: Vec<Problem> = config
        .problems()
        .into_iter()
        .map(|(key, reason)| {
            let origin = origin_of(figment, &key, None);
            Problem {
                key,
                reason,
                origin,
            }
        })
        .collect();
    if problems.is_empty() {
        Ok(config)
    } else {
        Err(ConfigError::Invalid { problems })
    }
}

/// The sections of [`Config`], in file order.
const SECTIONS: [&str; 13] = [
    "service",
    "http",
    "bus",
    "telemetry",
    "supervision",
    "robot",
    "redis",
    "perception",
    "workspace",
    "tts",
    "mcp",
    "agent",
    "actors",
];

/// serde stops at the first error of a struct, so after a failed extraction each section
/// (and each actor) is read again on its own: the user learns about one problem per section
/// instead of one per start-up.
fn deserialization_problems(figment: &Figment, first: figment::Error) -> Vec<Problem> {
    let top: Dict = match figment.extract() {
        Ok(top) => top,
        // A layer that does not parse (TOML syntax) is reported alone.
        Err(error) => {
            return error
                .into_iter()
                .map(|error| problem_from_figment(figment, "", error))
                .collect()
        }
    };
    let mut problems = Vec::new();
    for key in top.keys().filter(|key| !SECTIONS.contains(&key.as_str())) {
        problems.push(Problem {
            key: key.clone(),
            reason: format!(
                "unknown section; the top level accepts {}",
                SECTIONS.join(", ")
            ),
            origin: origin_of(figment, key, None),
        });
    }
    /// Reads the table at `key` (if present) alone as a `T`, adding its problems.
    fn read<T: serde::de::DeserializeOwned>(
        figment: &Figment,
        top: &Dict,
        key: &str,
        problems: &mut Vec<Problem>,
    ) {
        if !key.contains('.') && !top.contains_key(key) {
            return;
        }
        if let Err(error) = figment.focus(key).extract::<T>() {
            problems.extend(
                error
                    .into_iter()
                    .map(|error| problem_from_figment(figment, key, error)),
            );
        }
    }
    let p = &mut problems;
    read::<ServiceConfig>(figment, &top, "service", p);
    read::<HttpConfig>(figment, &top, "http", p);
    read::<BusConfig>(figment, &top, "bus", p);
    read::<TelemetryConfig>(figment, &top, "telemetry", p);
    read::<SupervisionConfig>(figment, &top, "supervision", p);
    read::<RobotConfig>(figment, &top, "robot", p);
    read::<RedisConfig>(figment, &top, "redis", p);
    read::<PerceptionConfig>(figment, &top, "perception", p);
    read::<WorkspaceConfig>(figment, &top, "workspace", p);
    read::<TtsConfig>(figment, &top, "tts", p);
    read::<AgentConfig>(figment, &top, "agent", p);
    read::<McpConfig>(figment, &top, "mcp", p);
    match top.get("actors").map(|actors| actors.as_dict()) {
        Some(Some(actors)) => {
            for name in actors.keys().filter(|name| !name.contains('.')) {
                read::<ActorConfig>(figment, &top, &format!("actors.{name}"), p);
            }
        }
        Some(None) => read::<BTreeMap<String, ActorConfig>>(figment, &top, "actors", p),
        None => {}
    }
    if problems.is_empty() {
        // Not found section by section (e.g. a missing section): report what serde said.
        problems = first
            .into_iter()
            .map(|error| problem_from_figment(figment, "", error))
            .collect();
    }
    problems
}

/// A [`Problem`] from a figment error; `prefix` is the dotted key the error's path is
/// relative to.
fn problem_from_figment(figment: &Figment, prefix: &str, error: figment::Error) -> Problem {
    let mut path: Vec<String> = prefix
        .split('.')
        .filter(|s| !s.is_empty())
        .map(str::to_owned)
        .chain(error.path.iter().cloned())
        .collect();
    let reason = match &error.kind {
        Kind::UnknownField(field, expected) => {
            // figment usually has the field in the path already; make sure it is there once.
            if path.last() != Some(field) {
                path.push(field.clone());
            }
            let parent = &path[..path.len() - 1];
            let section = if parent.is_empty() {
                "the top level".to_owned()
            } else {
                format!("[{}]", parent.join("."))
            };
            format!("unknown key; {section} accepts {}", expected.join(", "))
        }
        Kind::MissingField(field) => {
            path.push(field.to_string());
            "missing (config/default.toml should set every key; is this build's default file incomplete?)".to_owned()
        }
        Kind::UnknownVariant(found, expected) => format!(
            "unknown value {found:?}; expected one of {}",
            expected
                .iter()
                .map(|v| format!("{v:?}"))
                .collect::<Vec<_>>()
                .join(", ")
        ),
        other => {
            let key = path.last().map(String::as_str).unwrap_or("");
            match (expectation(key), other) {
                (Some(expected), Kind::InvalidValue(found, _) | Kind::InvalidType(found, _)) => {
                    format!("found {found}; expected {expected}")
                }
                (Some(expected), other) => format!("{other}; expected {expected}"),
                (None, other) => other.to_string(),
            }
        }
    };
    let key = path.join(".");
    // An error of a whole layer (TOML syntax, a malformed variable name) names its place itself.
    let origin = if key.is_empty() {
        None
    } else {
        origin_of(figment, &key, error.metadata.as_ref())
    };
    Problem {
        key,
        reason,
        origin,
    }
}

/// What a key holds, in words, to complete terse serde messages.
fn expectation(key: &str) -> Option<&'static str> {
    Some(match key {
        "bind" => "an IP address and port such as \"127.0.0.1:8000\"",
        "max_restarts" => "a whole number of at least 1",
        "window_s" => "a whole number of seconds greater than 0",
        "request_timeout_ms" | "backoff_initial_ms" | "backoff_max_ms" => {
            "a whole number of milliseconds greater than 0"
        }
        "frame_subscriber_buffer" => "a whole number of frames from 1 to 64",
        "backoff_multiplier" => "a number of at least 1.0",
        "log_dir" => "a directory path",
        "command" => "a list of strings such as [\"robotd-camera\", \"--device\", \"0\"]",
        _ => return None,
    })
}

/// Which layer set `key` (a dotted path), from the figment's metadata. A key that is not set
/// (a missing value) is attributed to the layer of its nearest enclosing table.
fn origin_of(figment: &Figment, key: &str, fallback: Option<&Metadata>) -> Option<Origin> {
    let segments: Vec<&str> = key.split('.').filter(|s| !s.is_empty()).collect();
    let found = (1..=segments.len()).rev().find_map(|len| {
        let path = &segments[..len];
        figment
            .find_metadata(&path.join("."))
            .map(|metadata| (metadata, path))
    });
    let (metadata, path) = match found {
        Some(found) => found,
        None => (fallback?, &segments[..]),
    };
    Some(match metadata.name.as_ref() {
        DEFAULTS_NAME => Origin::Defaults,
        FILE_NAME => match metadata.source.as_ref().and_then(Source::file_path) {
            Some(path) => Origin::File(path.to_path_buf()),
            None => Origin::Defaults,
        },
        ENV_NAME => Origin::Env(metadata.interpolate(&Profile::Default, path)),
        OVERRIDE_NAME => Origin::Override(path.join(".")),
        _ => return None,
    })
}

// ---------------------------------------------------------------------------------------------
// Errors

/// Loading the configuration failed.
#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    /// The `--config` file could not be read.
    #[error("cannot read config file {}: {source}; check the path given with --config (or ROBOTD_CONFIG)", path.display())]
    ReadFile {
        /// The file.
        path: PathBuf,
        /// What the OS said.
        #[source]
        source: std::io::Error,
    },
    /// A command-line override is not `key=value`.
    #[error("override {argument:?} is not key=value; write e.g. http.bind=0.0.0.0:8000")]
    BadOverride {
        /// The argument as given.
        argument: String,
    },
    /// The layers do not form a valid configuration: unknown keys, unreadable or out-of-range
    /// values, TOML syntax errors. Every problem found is listed.
    #[error("invalid configuration:{}", Problems(problems))]
    Invalid {
        /// Each problem, with its key, reason and origin.
        problems: Vec<Problem>,
    },
}

struct Problems<'a>(&'a [Problem]);

impl fmt::Display for Problems<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for problem in self.0 {
            let text = problem.to_string();
            write!(f, "\n  - {}", text.trim_end().replace('\n', "\n    "))?;
        }
        Ok(())
    }
}

/// One thing wrong with the configuration.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Problem {
    /// Dotted key, e.g. `http.bind` (empty for a whole layer, such as a TOML syntax error).
    pub key: String,
    /// What is wrong and what is expected.
    pub reason: String,
    /// Where the offending value was set, when known.
    pub origin: Option<Origin>,
}

impl fmt::Display for Problem {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.key.is_empty() {
            write!(f, "{}", self.reason)?;
        } else {
            write!(f, "{}: {}", self.key, self.reason)?;
        }
        if let Some(origin) = &self.origin {
            write!(f, " (set in {origin})")?;
        }
        Ok(())
    }
}

/// The layer a configuration value came from.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Origin {
    /// The built-in `config/default.toml`.
    Defaults,
    /// A `--config` file.
    File(PathBuf),
    /// An environment variable (its name, e.g. `ROBOTD_HTTP__BIND`).
    Env(String),
    /// A command-line override (its dotted key).
    Override(String),
}

impl fmt::Display for Origin {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Origin::Defaults => f.write_str("the built-in defaults (config/default.toml)"),
            Origin::File(path) => write!(f, "config file {}", path.display()),
            Origin::Env(name) => write!(f, "environment variable {name}"),
            Origin::Override(key) => write!(f, "command-line override {key}=…"),
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Layers (figment providers)

fn defaults_layer() -> Layer {
    Layer::toml(DEFAULT_TOML.to_owned(), Metadata::named(DEFAULTS_NAME))
}

/// A TOML text with the metadata we want errors to show.
struct Layer {
    text: String,
    metadata: Metadata,
}

impl Layer {
    fn toml(text: String, metadata: Metadata) -> Self {
        Layer { text, metadata }
    }
}

impl Provider for Layer {
    fn metadata(&self) -> Metadata {
        self.metadata.clone()
    }

    fn data(&self) -> Result<Map<Profile, Dict>, figment::Error> {
        use figment::providers::{Format, Toml};
        Toml::string(&self.text).data().map_err(|error| {
            let place = match self.metadata.source.as_ref().and_then(Source::file_path) {
                Some(path) => format!("config file {}", path.display()),
                None => self.metadata.name.to_string(),
            };
            figment::Error::from(format!("{place} is not valid TOML: {}", error.kind))
        })
    }
}

/// `ROBOTD_*` variables, nested on `__`.
struct EnvLayer {
    vars: Vec<(String, String)>,
}

impl EnvLayer {
    fn new(vars: impl Iterator<Item = (String, String)>) -> Self {
        let vars = vars
            .filter(|(name, _)| {
                name.len() > ENV_PREFIX.len()
                    && name.is_char_boundary(ENV_PREFIX.len())
                    && name[..ENV_PREFIX.len()].eq_ignore_ascii_case(ENV_PREFIX)
                    && !name.eq_ignore_ascii_case(ENV_CONFIG_FILE)
            })
            .collect();
        EnvLayer { vars }
    }
}

impl Provider for EnvLayer {
    fn metadata(&self) -> Metadata {
        Metadata::named(ENV_NAME).interpolater(|_: &Profile, keys: &[&str]| {
            let keys: Vec<String> = keys.iter().map(|k| k.to_ascii_uppercase()).collect();
            format!("{ENV_PREFIX}{}", keys.join(ENV_SEPARATOR))
        })
    }

    fn data(&self) -> Result<Map<Profile, Dict>, figment::Error> {
        let mut dict = Dict::new();
        for (name, value) in &self.vars {
            let segments: Vec<String> = name[ENV_PREFIX.len()..]
                .split(ENV_SEPARATOR)
                .map(|s| s.to_ascii_lowercase())
                .collect();
            if segments.iter().any(|s| s.is_empty() || s.contains('.')) {
                return Err(figment::Error::from(format!(
                    "environment variable {name} does not name a key: write ROBOTD_<SECTION>__<KEY>, e.g. ROBOTD_HTTP__BIND"
                )));
            }
            insert(&mut dict, &segments, parse_value(value));
        }
        Ok(Profile::Default.collect(dict))
    }
}

/// Command-line `key=value` overrides.
struct OverrideLayer(Vec<(String, String)>);

impl Provider for OverrideLayer {
    fn metadata(&self) -> Metadata {
        Metadata::named(OVERRIDE_NAME)
    }

    fn data(&self) -> Result<Map<Profile, Dict>, figment::Error> {
        let mut dict = Dict::new();
        for (key, value) in &self.0 {
            let segments: Vec<String> = key.trim().split('.').map(str::to_owned).collect();
            if segments.iter().any(String::is_empty) {
                return Err(figment::Error::from(format!(
                    "override {key:?}={value:?} does not name a key: write e.g. http.bind=0.0.0.0:8000"
                )));
            }
            insert(&mut dict, &segments, parse_value(value));
        }
        Ok(Profile::Default.collect(dict))
    }
}

/// Reads an environment/override value like a TOML value (number, bool, list, table), else
/// as text.
fn parse_value(value: &str) -> Value {
    match value.parse::<Value>() {
        Ok(value) => value,
        Err(never) => match never {},
    }
}

/// Sets `segments` (a key path) in `dict` to `value`, merging with what is already there.
fn insert(dict: &mut Dict, segments: &[String], value: Value) {
    match segments {
        [] => {}
        [last] => {
            dict.insert(last.clone(), value);
        }
        [first, rest @ ..] => {
            let child = dict
                .entry(first.clone())
                .or_insert_with(|| Value::from(Dict::new()));
            if child.as_dict().is_none() {
                *child = Value::from(Dict::new());
            }
            if let Value::Dict(_, child) = child {
                insert(child, rest, value);
            }
        }
    }
}

/// Deserializers that accept numbers and booleans where text is expected, since
/// `ROBOTD_SERVICE__NAME=42` reads `42` as a number.
mod lenient {
    use super::*;
    use serde::de::{self, SeqAccess, Visitor};

    struct Text;

    impl<'de> Visitor<'de> for Text {
        type Value = String;

        fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
            f.write_str("a string")
        }
        fn visit_str<E: de::Error>(self, v: &str) -> Result<String, E> {
            Ok(v.to_owned())
        }
        fn visit_string<E: de::Error>(self, v: String) -> Result<String, E> {
            Ok(v)
        }
        fn visit_bool<E: de::Error>(self, v: bool) -> Result<String, E> {
            Ok(v.to_string())
        }
        fn visit_i64<E: de::Error>(self, v: i64) -> Result<String, E> {
            Ok(v.to_string())
        }
        fn visit_u64<E: de::Error>(self, v: u64) -> Result<String, E> {
            Ok(v.to_string())
        }
        fn visit_i128<E: de::Error>(self, v: i128) -> Result<String, E> {
            Ok(v.to_string())
        }
        fn visit_u128<E: de::Error>(self, v: u128) -> Result<String, E> {
            Ok(v.to_string())
        }
        fn visit_f64<E: de::Error>(self, v: f64) -> Result<String, E> {
            Ok(v.to_string())
        }
        fn visit_char<E: de::Error>(self, v: char) -> Result<String, E> {
            Ok(v.to_string())
        }
    }

    pub fn string<'de, D: Deserializer<'de>>(d: D) -> Result<String, D::Error> {
        d.deserialize_any(Text)
    }

    /// Text, with the empty string meaning "not set".
    pub fn opt_string<'de, D: Deserializer<'de>>(d: D) -> Result<Option<String>, D::Error> {
        let text = d.deserialize_any(Text)?;
        Ok((!text.is_empty()).then_some(text))
    }

    struct Item(String);

    impl<'de> Deserialize<'de> for Item {
        fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
            string(d).map(Item)
        }
    }

    struct List;

    impl<'de> Visitor<'de> for List {
        type Value = Vec<String>;

        fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
            f.write_str("a list of strings")
        }
        fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Vec<String>, A::Error> {
            let mut out = Vec::with_capacity(seq.size_hint().unwrap_or(0));
            while let Some(Item(item)) = seq.next_element()? {
                out.push(item);
            }
            Ok(out)
        }
    }

    pub fn strings<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<String>, D::Error> {
        d.deserialize_seq(List)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::atomic::{AtomicU32, Ordering};

    fn no_env() -> Vec<(String, String)> {
        Vec::new()
    }

    fn env(pairs: &[(&str, &str)]) -> Vec<(String, String)> {
        pairs
            .iter()
            .map(|(k, v)| (k.to_string(), v.to_string()))
            .collect()
    }

    /// A uniquely named file holding `text`, removed on drop.
    struct TempFile(PathBuf);

    impl TempFile {
        fn new(text: &str) -> Self {
            static NEXT: AtomicU32 = AtomicU32::new(0);
            let path = std::env::temp_dir().join(format!(
                "robotd-config-test-{}-{}.toml",
                std::process::id(),
                NEXT.fetch_add(1, Ordering::Relaxed)
            ));
            std::fs::write(&path, text).expect("write temp config");
            TempFile(path)
        }
    }

    impl Drop for TempFile {
        fn drop(&mut self) {
            let _ = std::fs::remove_file(&self.0);
        }
    }

    fn with_file(file: &TempFile) -> LoadOptions {
        LoadOptions {
            file: Some(file.0.clone()),
            overrides: Vec::new(),
        }
    }

    fn problems_of(error: ConfigError) -> Vec<Problem> {
        match error {
            ConfigError::Invalid { problems } => problems,
            other => panic!("expected Invalid, got {other}"),
        }
    }

    #[test]
    fn defaults_load() {
        let config = Config::load_with_env(LoadOptions::default(), no_env()).unwrap();
        assert_eq!(config, Config::default());
        assert_eq!(config.service.name, "robotd");
        assert_eq!(config.http.bind, "127.0.0.1:8000".parse().unwrap());
        assert_eq!(config.bus.namespace, "robotd");
        assert_eq!(config.bus.request_timeout(), Duration::from_secs(30));
        assert_eq!(config.bus.frame_subscriber_buffer, 2);
        assert_eq!(config.telemetry.log_dir, PathBuf::from("log"));
        assert_eq!(config.telemetry.filter, "info");
        assert_eq!(config.telemetry.log_format, LogFormat::Text);
        assert_eq!(config.telemetry.otlp_endpoint, None);
        assert_eq!(config.telemetry.service_name.as_deref(), Some("robotd"));
        assert_eq!(
            config.supervision,
            SupervisionConfig {
                max_restarts: 5,
                window_s: 60,
                backoff_initial_ms: 10,
                backoff_max_ms: 5000,
                backoff_multiplier: 2.0,
            }
        );
        assert_eq!(config.robot.driver, RobotDriver::SimNed2);
        assert_eq!(config.redis.url, None);
        assert!(config.actors.is_empty());
        config.validate().unwrap();
    }

    #[test]
    fn file_layers_over_defaults() {
        let file = TempFile::new(
            r#"
            [service]
            name = "lab-2"
            [robot]
            driver = "niryo"
            [redis]
            url = "redis://localhost:6379/0"
            [actors.camera]
            mode = "process"
            command = ["robotd-camera", "--device", "0"]
            supervision = { max_restarts = 10 }
            "#,
        );
        let config = Config::load_with_env(with_file(&file), no_env()).unwrap();
        assert_eq!(config.service.name, "lab-2");
        // Untouched keys keep their defaults.
        assert_eq!(config.http.bind.port(), 8000);
        assert_eq!(config.telemetry.service_name.as_deref(), Some("lab-2"));
        assert_eq!(config.robot.driver, RobotDriver::Niryo);
        assert_eq!(
            config.redis.url.as_deref(),
            Some("redis://localhost:6379/0")
        );
        let camera = config.actor("camera");
        assert_eq!(camera.mode, ActorMode::Process);
        assert_eq!(camera.command, ["robotd-camera", "--device", "0"]);
        assert_eq!(config.supervision_for("camera").max_restarts, 10);
        assert_eq!(config.supervision_for("camera").window_s, 60);
        assert_eq!(config.supervision_for("arm"), config.supervision);
        assert_eq!(config.actor("arm").mode, ActorMode::InProcess);
    }

    #[test]
    fn env_overrides_file() {
        let file =
            TempFile::new("[http]\nbind = \"127.0.0.1:9000\"\n[bus]\nnamespace = \"from-file\"\n");
        let config = Config::load_with_env(
            with_file(&file),
            env(&[
                ("ROBOTD_HTTP__BIND", "0.0.0.0:8001"),
                ("ROBOTD_MCP__TOKEN", "a-long-random-token"),
                ("robotd_supervision__max_restarts", "7"),
                ("ROBOTD_SERVICE__NAME", "42"),
                ("ROBOTD_ACTORS__CAMERA__MODE", "process"),
                ("ROBOTD_ACTORS__CAMERA__COMMAND", "[robotd-camera, 0]"),
                ("ROBOTD_CONFIG", "/ignored/here.toml"),
                ("PATH", "/usr/bin"),
            ]),
        )
        .unwrap();
        assert_eq!(config.http.bind, "0.0.0.0:8001".parse().unwrap());
        assert_eq!(config.mcp.token.as_deref(), Some("a-long-random-token"));
        assert_eq!(config.bus.namespace, "from-file");
        assert_eq!(config.supervision.max_restarts, 7);
        assert_eq!(config.service.name, "42");
        assert_eq!(config.actor("camera").command, ["robotd-camera", "0"]);
    }

    #[test]
    fn overrides_beat_env() {
        let options = LoadOptions {
            file: None,
            overrides: vec![
                ("http.bind".into(), "127.0.0.1:9100".into()),
                ("telemetry.log_format".into(), "json".into()),
            ],
        };
        let config = Config::load_with_env(
            options,
            env(&[
                ("ROBOTD_HTTP__BIND", "0.0.0.0:8001"),
                ("ROBOTD_TELEMETRY__FILTER", "debug"),
            ]),
        )
        .unwrap();
        assert_eq!(config.http.bind, "127.0.0.1:9100".parse().unwrap());
        assert_eq!(config.telemetry.log_format, LogFormat::Json);
        assert_eq!(config.telemetry.filter, "debug");
    }

    #[test]
    fn unknown_key_in_file_is_refused_naming_file_and_key() {
        let file = TempFile::new("[http]\nbind = \"127.0.0.1:8000\"\nbnid = \"oops\"\n");
        let error = Config::load_with_env(with_file(&file), no_env()).unwrap_err();
        let message = error.to_string();
        let problems = problems_of(error);
        assert_eq!(problems.len(), 1, "{message}");
        assert_eq!(problems[0].key, "http.bnid");
        assert_eq!(problems[0].origin, Some(Origin::File(file.0.clone())));
        assert!(problems[0].reason.contains("unknown key"), "{message}");
        assert!(problems[0].reason.contains("bind"), "{message}");
        assert!(message.contains(&file.0.display().to_string()), "{message}");
        assert!(message.contains("http.bnid"), "{message}");
    }

    #[test]
    fn unknown_section_and_actor_key_are_refused() {
        let file = TempFile::new("[htp]\nbind = 1\n[actors.arm]\nmod = \"process\"\n");
        let problems = problems_of(Config::load_with_env(with_file(&file), no_env()).unwrap_err());
        let keys: Vec<&str> = problems.iter().map(|p| p.key.as_str()).collect();
        assert!(keys.contains(&"htp"), "{problems:?}");
        assert!(keys.contains(&"actors.arm.mod"), "{problems:?}");
    }

    #[test]
    fn invalid_values_are_refused_naming_key_and_reason() {
        let file = TempFile::new(
            r#"
            [http]
            bind = "nope"
            [supervision]
            max_restarts = -1
            "#,
        );
        let error = Config::load_with_env(with_file(&file), no_env()).unwrap_err();
        let message = error.to_string();
        let problems = problems_of(error);
        let bind = problems
            .iter()
            .find(|p| p.key == "http.bind")
            .expect(&message);
        assert!(bind.reason.contains("IP address and port"), "{message}");
        assert_eq!(bind.origin, Some(Origin::File(file.0.clone())));
        let restarts = problems
            .iter()
            .find(|p| p.key == "supervision.max_restarts")
            .expect(&message);
        assert!(restarts.reason.contains("-1"), "{message}");
        assert!(restarts.reason.contains("at least 1"), "{message}");
    }

    #[test]
    fn out_of_range_values_are_refused_by_validation() {
        let file = TempFile::new(
            r#"
            [bus]
            namespace = "robot d/1"
            request_timeout_ms = 0
            frame_subscriber_buffer = 0
            [supervision]
            max_restarts = 0
            backoff_initial_ms = 100
            backoff_max_ms = 50
            backoff_multiplier = 0.5
            [telemetry]
            filter = "info,[=bad"
            otlp_endpoint = "localhost:4318"
            [robot]
            driver = "ned3"
            "#,
        );
        let error = Config::load_with_env(with_file(&file), no_env()).unwrap_err();
        let message = error.to_string();
        let problems = problems_of(error);
        // The driver is a type error, reported before range checks run.
        let driver = problems
            .iter()
            .find(|p| p.key == "robot.driver")
            .expect(&message);
        assert!(driver.reason.contains("\"sim-ned2\""), "{message}");

        let file = TempFile::new(
            r#"
            [bus]
            namespace = "robot d/1"
            request_timeout_ms = 0
            frame_subscriber_buffer = 0
            [supervision]
            max_restarts = 0
            backoff_initial_ms = 100
            backoff_max_ms = 50
            backoff_multiplier = 0.5
            [telemetry]
            filter = "info,[=bad"
            otlp_endpoint = "localhost:4318"
            [actors.camera]
            mode = "process"
            [actors.arm]
            command = ["x"]
            "#,
        );
        let error = Config::load_with_env(with_file(&file), no_env()).unwrap_err();
        let message = error.to_string();
        let problems = problems_of(error);
        for key in [
            "bus.namespace",
            "bus.request_timeout_ms",
            "bus.frame_subscriber_buffer",
            "supervision.max_restarts",
            "supervision.backoff_max_ms",
            "supervision.backoff_multiplier",
            "telemetry.filter",
            "telemetry.otlp_endpoint",
            "actors.camera.command",
            "actors.arm.command",
        ] {
            let problem = problems
                .iter()
                .find(|p| p.key == key)
                .unwrap_or_else(|| panic!("no problem for {key}:\n{message}"));
            assert_eq!(problem.origin, Some(Origin::File(file.0.clone())), "{key}");
        }
        let namespace = problems.iter().find(|p| p.key == "bus.namespace").unwrap();
        assert!(namespace.reason.contains("' '"), "{message}");
    }

    #[test]
    fn bad_namespace_from_env_names_the_variable() {
        let error = Config::load_with_env(
            LoadOptions::default(),
            env(&[("ROBOTD_BUS__NAMESPACE", "a.b")]),
        )
        .unwrap_err();
        let message = error.to_string();
        assert!(message.contains("bus.namespace"), "{message}");
        assert!(message.contains("ROBOTD_BUS__NAMESPACE"), "{message}");
    }

    #[test]
    fn env_var_with_unknown_key_is_refused() {
        let error = Config::load_with_env(
            LoadOptions::default(),
            env(&[("ROBOTD_HTTP__BINDD", "0.0.0.0:1"), ("ROBOTD_NOPE", "1")]),
        )
        .unwrap_err();
        let message = error.to_string();
        let problems = problems_of(error);
        let bindd = problems
            .iter()
            .find(|p| p.key == "http.bindd")
            .expect(&message);
        assert_eq!(bindd.origin, Some(Origin::Env("ROBOTD_HTTP__BINDD".into())));
        let nope = problems.iter().find(|p| p.key == "nope").expect(&message);
        assert_eq!(nope.origin, Some(Origin::Env("ROBOTD_NOPE".into())));
        assert!(
            message.contains("environment variable ROBOTD_HTTP__BINDD"),
            "{message}"
        );
    }

    #[test]
    fn invalid_env_value_names_the_variable() {
        let error = Config::load_with_env(
            LoadOptions::default(),
            env(&[("ROBOTD_HTTP__BIND", "nope")]),
        )
        .unwrap_err();
        let problems = problems_of(error);
        assert_eq!(problems.len(), 1);
        assert_eq!(problems[0].key, "http.bind");
        assert_eq!(
            problems[0].origin,
            Some(Origin::Env("ROBOTD_HTTP__BIND".into()))
        );
    }

    #[test]
    fn invalid_override_names_the_override() {
        let options = LoadOptions {
            file: None,
            overrides: vec![("supervision.window_s".into(), "soon".into())],
        };
        let problems = problems_of(Config::load_with_env(options, no_env()).unwrap_err());
        assert_eq!(problems[0].key, "supervision.window_s");
        assert_eq!(
            problems[0].origin,
            Some(Origin::Override("supervision.window_s".into()))
        );
    }

    #[test]
    fn missing_file_and_bad_toml_are_reported() {
        let missing = LoadOptions {
            file: Some(PathBuf::from("/definitely/not/here/robotd.toml")),
            overrides: Vec::new(),
        };
        let error = Config::load_with_env(missing, no_env()).unwrap_err();
        assert!(matches!(error, ConfigError::ReadFile { .. }), "{error}");
        assert!(error
            .to_string()
            .contains("/definitely/not/here/robotd.toml"));

        let file = TempFile::new("[http\nbind = 1\n");
        let message = Config::load_with_env(with_file(&file), no_env())
            .unwrap_err()
            .to_string();
        assert!(message.contains("not valid TOML"), "{message}");
        assert!(message.contains(&file.0.display().to_string()), "{message}");
    }

    #[test]
    fn parse_override_splits_on_the_first_equals() {
        assert_eq!(
            LoadOptions::parse_override("telemetry.filter=info,a=debug").unwrap(),
            ("telemetry.filter".into(), "info,a=debug".into())
        );
        assert!(matches!(
            LoadOptions::parse_override("=x"),
            Err(ConfigError::BadOverride { .. })
        ));
    }

    #[test]
    fn filter_with_commas_from_env_stays_text() {
        let config = Config::load_with_env(
            LoadOptions::default(),
            env(&[("ROBOTD_TELEMETRY__FILTER", "info,robotd_runtime::bus=debug")]),
        )
        .unwrap();
        assert_eq!(config.telemetry.filter, "info,robotd_runtime::bus=debug");
    }
}
