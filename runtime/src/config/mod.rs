//! robotd's configuration machinery: typed sections, loaded in layers and checked at start-up.
//!
//! Each crate owns its section — the struct, its serde defaults and its checks
//! ([`Section`]) — and one composing crate (`robotd-config`) lists the sections with
//! [`compose_config!`](crate::compose_config). This module owns what all sections share:
//! the layers, the error reports, the text helpers, and the runtime's own sections
//! ([`ServiceConfig`], [`BusConfig`], [`TelemetryConfig`], [`SupervisionConfig`],
//! [`ActorConfig`]).
//!
//! Each layer only names the keys it changes; later layers win:
//!
//! 1. the built-in defaults (`config/default.toml`, compiled in, every key documented), so
//!    robotd runs with no file at all;
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
//! every value reads, every section's [`Section::check`] is run and all is reported together:
//!
//! ```text
//! invalid configuration:
//!   - http.bind: invalid socket address syntax; expected an IP address and port such as "127.0.0.1:8000" (set in environment variable ROBOTD_HTTP__BIND)
//!   - supervision.max_restart: unknown key; [supervision] accepts max_restarts, window_s, backoff_initial_ms, backoff_max_ms, backoff_multiplier (set in config file robotd.toml)
//!   - robot.driver: unknown value "ned3"; expected one of "sim-ned2", "sim-widowx", "niryo", "widowx" (set in command-line override robot.driver=…)
//! ```
//!
//! A section of a new crate:
//!
//! ```
//! use robotd_runtime::config::{Checks, Section};
//! use serde::{Deserialize, Serialize};
//!
//! /// `[gripper_cam]`: a second camera.
//! #[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
//! #[serde(deny_unknown_fields)]
//! pub struct GripperCamConfig {
//!     pub fps: f64,
//! }
//!
//! impl Section for GripperCamConfig {
//!     fn check(&self, checks: &mut Checks) {
//!         if !(0.1..=60.0).contains(&self.fps) {
//!             checks.problem("fps", format!("must be from 0.1 to 60, got {}", self.fps));
//!         }
//!     }
//! }
//! ```
//!
//! It then takes one line in `robotd-config`'s `compose_config!` and its documented keys in
//! `config/default.toml`.

mod checks;
mod compose;
mod core;
mod layers;
pub mod lenient;
mod problems;

pub use self::checks::{check_name, check_url};
pub use self::compose::{load, validate, Composed, SectionReader};
pub use self::core::{
    check_actors, ActorConfig, ActorMode, ActorsConfig, BusConfig, LogFormat, ServiceConfig,
    SupervisionConfig, SupervisionOverrides, TelemetryConfig, MAX_FRAME_SUBSCRIBER_BUFFER,
    MAX_NAMESPACE_LEN,
};
pub use self::problems::{ConfigError, Origin, Problem};

use serde::de::DeserializeOwned;
use std::path::PathBuf;

/// Prefix of the environment variables that set configuration keys.
pub const ENV_PREFIX: &str = "ROBOTD_";

/// The environment variable naming the configuration file; the only `ROBOTD_` variable that
/// is not read as a key (the binary passes its value as [`LoadOptions::file`]).
pub const ENV_CONFIG_FILE: &str = "ROBOTD_CONFIG";

/// Separator of nesting levels in environment variable names (`ROBOTD_HTTP__BIND`).
pub const ENV_SEPARATOR: &str = "__";

/// One table of the configuration, owned by the crate that uses it.
///
/// serde reads it (unknown keys refused with `#[serde(deny_unknown_fields)]`, defaults with
/// `#[serde(default = …)]`); [`Section::check`] then finds what serde cannot express: ranges,
/// formats, combinations of keys.
pub trait Section: DeserializeOwned {
    /// Adds a problem for each value that is out of range or malformed; keys are relative to
    /// the section (`"time_scale"`, `"camera.fps"`).
    fn check(&self, checks: &mut Checks);

    /// Reads the section's table on its own after the whole configuration failed to read, so
    /// each section reports its own first problem. Tables of many entries (`[actors]`)
    /// override it to read each entry.
    fn read_problems(reader: &mut SectionReader<'_>, key: &str) {
        reader.read::<Self>(key);
    }
}

/// Collects the problems of one section under its key.
#[derive(Debug)]
pub struct Checks<'a> {
    prefix: &'a str,
    out: &'a mut Vec<(String, String)>,
}

impl<'a> Checks<'a> {
    /// Problems of the section at `prefix` (a dotted key) go to `out` as `(dotted key, reason)`.
    pub fn new(prefix: &'a str, out: &'a mut Vec<(String, String)>) -> Self {
        Checks { prefix, out }
    }

    /// `key` (relative to the section; empty for the section itself) is wrong because `reason`.
    pub fn problem(&mut self, key: &str, reason: impl Into<String>) {
        let key = match (self.prefix.is_empty(), key.is_empty()) {
            (true, _) => key.to_owned(),
            (false, true) => self.prefix.to_owned(),
            (false, false) => format!("{}.{key}", self.prefix),
        };
        self.out.push((key, reason.into()));
    }

    /// A problem when `value` is not a finite number in `range`, worded "must be from … to …
    /// {unit}, got …".
    pub fn range_f64(
        &mut self,
        key: &str,
        value: f64,
        range: std::ops::RangeInclusive<f64>,
        unit: &str,
    ) {
        if !(value.is_finite() && range.contains(&value)) {
            self.problem(
                key,
                format!(
                    "must be from {} to {}{unit}, got {value}",
                    range.start(),
                    range.end()
                ),
            );
        }
    }

    /// The two keys of a camera stream a viewer gets (`camera_fps`, `jpeg_quality`): 0.5 … 30
    /// frames a second, quality 10 … 100.
    pub fn camera_stream(&mut self, camera_fps: f64, jpeg_quality: u8) {
        if !(0.5..=30.0).contains(&camera_fps) {
            self.problem(
                "camera_fps",
                format!("must be 0.5 … 30 frames per second, got {camera_fps}"),
            );
        }
        self.range_u64("jpeg_quality", u64::from(jpeg_quality), 10..=100, "");
    }

    /// A problem when `value` is not in `range`, worded "must be from … to …{unit}, got …".
    pub fn range_u64(
        &mut self,
        key: &str,
        value: u64,
        range: std::ops::RangeInclusive<u64>,
        unit: &str,
    ) {
        if !range.contains(&value) {
            self.problem(
                key,
                format!(
                    "must be from {} to {}{unit}, got {value}",
                    range.start(),
                    range.end()
                ),
            );
        }
    }
}

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
