//! What is wrong with a configuration, said so a user can act on it: each [`Problem`] has
//! its dotted key, the reason, and the layer that set the value ([`Origin`]).

use figment::error::Kind;
use figment::{Figment, Metadata, Profile, Source};
use std::fmt;
use std::path::PathBuf;

// Names of the layers' metadata; `origin_of` maps them back to an `Origin`.
pub(super) const DEFAULTS_NAME: &str = "built-in defaults";
pub(super) const FILE_NAME: &str = "config file";
pub(super) const ENV_NAME: &str = "environment variable";
pub(super) const OVERRIDE_NAME: &str = "command-line override";

/// A [`Problem`] from a figment error; `prefix` is the dotted key the error's path is
/// relative to.
pub(super) fn problem_from_figment(
    figment: &Figment,
    prefix: &str,
    error: figment::Error,
) -> Problem {
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
pub(super) fn origin_of(
    figment: &Figment,
    key: &str,
    fallback: Option<&Metadata>,
) -> Option<Origin> {
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
