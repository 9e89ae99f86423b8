//! `[redis]`: the Redis edge to the Python tools (detector, viewer, recorder): where Redis
//! is, how often each stream is written, which detector to trust.

use robotd_runtime::config::{check_url, lenient, Checks, Section};
use serde::{Deserialize, Serialize};

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

mod defaults {
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
}

impl Section for RedisConfig {
    fn check(&self, checks: &mut Checks) {
        if let Some(url) = &self.url {
            if let Err(reason) = check_url(url, &["redis", "rediss", "redis+unix", "unix"]) {
                checks.problem(
                    "url",
                    format!("{reason}; expected a URL such as \"redis://localhost:6379/0\""),
                );
            }
        }
        for (key, fps) in [
            ("camera_fps", self.camera_fps),
            ("annotated_fps", self.annotated_fps),
            ("objects_fps", self.objects_fps),
        ] {
            if !(0.0..=60.0).contains(&fps) {
                checks.problem(key, format!("{fps} is not a frame rate from 0 (off) to 60"));
            }
        }
        if !["builtin", "external", "both"]
            .contains(&self.trust.trim().to_ascii_lowercase().as_str())
        {
            checks.problem(
                "trust",
                format!(
                    "'{}' is not a detector to trust; use builtin, external or both",
                    self.trust
                ),
            );
        }
        if !(1024..=512 * 1024 * 1024).contains(&self.max_entry_bytes) {
            checks.problem(
                "max_entry_bytes",
                format!(
                    "{} is not a size from 1024 to 536870912 bytes",
                    self.max_entry_bytes
                ),
            );
        }
    }
}
