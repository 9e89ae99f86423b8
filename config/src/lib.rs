//! robotd's whole configuration: one [`Config`] made of the sections each crate owns.
//!
//! A section — its struct, serde defaults and checks — lives in the crate that uses it
//! (`[robot]` in `drivers/api`, `[tts]` in `actors/speech`, `[mcp]` in `edges/mcp`, …); the
//! runtime owns `[service]`, `[bus]`, `[telemetry]`, `[supervision]` and `[actors]`. This crate
//! only lists them, holds the documented built-in defaults (`config/default.toml`, beside
//! this crate) and the checks that span sections. How layers, errors and checks work:
//! [`robotd_runtime::config`].
//!
//! ```
//! use robotd_config::{Config, LoadOptions, RobotDriver};
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
//!
//! A new section is one line in [`Config`] below and its documented keys in
//! `config/default.toml`.

pub use robotd_agent::AgentSection;
pub use robotd_dashboard::voice::VoiceConfig;
pub use robotd_dashboard::DashboardConfig;
pub use robotd_driver::{CameraConfig, FaultConfig, FaultsConfig, RobotConfig, RobotDriver};
pub use robotd_foxglove::{FoxgloveConfig, RecordConfig};
pub use robotd_http::HttpConfig;
pub use robotd_mcp::McpConfig;
pub use robotd_perception::PerceptionConfig;
pub use robotd_redis::RedisConfig;
pub use robotd_runtime::config::{
    ActorConfig, ActorMode, ActorsConfig, BusConfig, ConfigError, LoadOptions, LogFormat, Origin,
    Problem, ServiceConfig, SupervisionConfig, SupervisionOverrides, TelemetryConfig,
    ENV_CONFIG_FILE, ENV_PREFIX, ENV_SEPARATOR, MAX_FRAME_SUBSCRIBER_BUFFER, MAX_NAMESPACE_LEN,
};
pub use robotd_safety::SafetyConfig;
pub use robotd_speech::TtsConfig;
pub use robotd_workspace_model::WorkspaceConfig;

/// The built-in defaults (`config/default.toml`), the first layer of every configuration.
pub const DEFAULT_TOML: &str = include_str!("../default.toml");

robotd_runtime::compose_config! {
    /// The whole robotd configuration. See the crate docs for how it is loaded, and
    /// `config/default.toml` for every key with its meaning and default.
    pub struct Config {
        /// `[service]`: this instance.
        service: ServiceConfig,
        /// `[http]`: the HTTP edge.
        http: HttpConfig,
        /// `[bus]`: the iceoryx2 bus.
        bus: BusConfig,
        /// `[telemetry]`: logs and trace export.
        telemetry: TelemetryConfig,
        /// `[supervision]`: the default restart policy of supervised actors.
        supervision: SupervisionConfig,
        /// `[robot]`: which arm robotd drives.
        robot: RobotConfig,
        /// `[redis]`: the Redis edge to the Python tools.
        #[serde(default)]
        redis: RedisConfig,
        /// `[perception]`: the built-in detector.
        #[serde(default)]
        perception: PerceptionConfig,
        /// `[workspace]`: the scene memory the detection tools answer from.
        #[serde(default)]
        workspace: WorkspaceConfig,
        /// `[tts]`: text to speech.
        #[serde(default)]
        tts: TtsConfig,
        /// `[mcp]`: the MCP edge (served on the `[http]` port).
        #[serde(default)]
        mcp: McpConfig,
        /// `[dashboard]`: the web page at `/` and its API.
        #[serde(default)]
        dashboard: DashboardConfig,
        /// `[voice]`: spoken commands (`POST /api/voice`): stop words, limits.
        #[serde(default)]
        voice: VoiceConfig,
        /// `[foxglove]`: the live view for the Foxglove app.
        #[serde(default)]
        foxglove: FoxgloveConfig,
        /// `[record]`: always-on recording of the bus into MCAP files.
        #[serde(default)]
        record: RecordConfig,
        /// `[agent]`: the LLM agent (`robotd chat`, and the agent actor of `robotd serve`).
        #[serde(default)]
        agent: AgentSection,
        /// `[safety]`: the motion policy (geofence, caps, rate limits, approval, audit log).
        #[serde(default)]
        safety: SafetyConfig,
        /// `[actors.<name>]`: per-actor settings; actors without an entry run in-process with
        /// the `[supervision]` policy.
        #[serde(default)]
        actors: ActorsConfig,
    }
    defaults = DEFAULT_TOML;
    finish = finish;
}

/// Values derived from others, and the checks that span sections.
fn finish(config: &mut Config, problems: &mut Vec<(String, String)>) {
    if config.telemetry.service_name.is_none() {
        config.telemetry.service_name = Some(config.service.name.clone());
    }
    problems.extend(config.mcp.bind_problem(config.http.bind));
    robotd_runtime::config::check_actors(&config.actors, &config.supervision, problems);
}

impl Config {
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

    /// The sections the robot reads (`[robot]`, `[safety]`, `[telemetry] log_dir`, the restart
    /// policies of its actors), for [`robotd_robot::Hardware::start`].
    pub fn robot_sections(&self) -> robotd_robot::RobotSections {
        robotd_robot::RobotSections {
            robot: self.robot.clone(),
            safety: self.safety.clone(),
            log_dir: self.telemetry.log_dir.clone(),
            supervision: self.supervision.clone(),
            actor_supervision: robotd_robot::ACTORS
                .iter()
                .filter(|actor| self.actors.contains_key(**actor))
                .map(|actor| (actor.to_string(), self.supervision_for(actor)))
                .collect(),
            commissioning: false,
        }
    }
}

#[cfg(test)]
mod tests;
