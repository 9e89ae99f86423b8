//! Where the Redis edge connects and what it does: resolved once at start from the command
//! line, the config file and the `REDIS_*` variables the Python tools use.
//!
//! Precedence: `robotd serve --redis URL`, then `[redis] url` of the config file, then
//! `REDIS_HOST` / `REDIS_PORT` / `REDIS_DB`. `REDIS_PASSWORD` fills in a password the URL does
//! not carry. With none of them set the edge is off. `rediss://` URLs speak TLS (rustls, the
//! system's root certificates).

use redis::{ConnectionInfo, IntoConnectionInfo};

/// Which detector's objects the workspace model believes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Trust {
    /// Only robotd's built-in detector; external detections are not consumed.
    Builtin,
    /// Only external detectors over Redis; the built-in detector does not run.
    External,
    /// Both: each confirms and ages its own objects (the default).
    #[default]
    Both,
}

impl Trust {
    /// The config words.
    pub const STRINGS: &'static [&'static str] = &["builtin", "external", "both"];

    /// Parses a config word.
    pub fn parse(word: &str) -> Result<Trust, String> {
        match word.trim().to_ascii_lowercase().as_str() {
            "builtin" | "built-in" => Ok(Trust::Builtin),
            "external" => Ok(Trust::External),
            "both" => Ok(Trust::Both),
            other => Err(format!(
                "'{other}' is not a detector to trust; use one of {}",
                Self::STRINGS.join(", ")
            )),
        }
    }

    /// Whether external detections are consumed.
    pub fn consumes_external(self) -> bool {
        self != Trust::Builtin
    }

    /// Whether the built-in detector runs.
    pub fn runs_builtin(self) -> bool {
        self != Trust::External
    }

    /// The config word.
    pub fn as_str(self) -> &'static str {
        match self {
            Trust::Builtin => "builtin",
            Trust::External => "external",
            Trust::Both => "both",
        }
    }
}

/// A Redis server to connect to. Holds the password: its `Debug` shows only [`Self::display`].
#[derive(Clone)]
pub struct RedisTarget {
    /// What redis-rs connects with.
    pub info: ConnectionInfo,
    /// `redis://host:port/db` without the password, for logs and status.
    pub display: String,
    /// Where the setting came from (`--redis`, `[redis] url`, `REDIS_HOST/REDIS_PORT`).
    pub source: &'static str,
}

impl std::fmt::Debug for RedisTarget {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "RedisTarget({} from {})", self.display, self.source)
    }
}

/// Resolves the Redis target: `cli_url`, else `config_url`, else `REDIS_HOST`/`REDIS_PORT`/
/// `REDIS_DB` from `env`; `REDIS_PASSWORD` (from `env`) is used when the URL has none.
/// `Ok(None)`: nothing is set, the edge is off.
pub fn resolve_target(
    cli_url: Option<&str>,
    config_url: Option<&str>,
    env: &dyn Fn(&str) -> Option<String>,
) -> Result<Option<RedisTarget>, String> {
    let nonempty = |v: Option<String>| v.filter(|s| !s.trim().is_empty());
    let (url, source) = if let Some(url) = cli_url {
        (url.trim().to_owned(), "--redis")
    } else if let Some(url) = config_url {
        (url.trim().to_owned(), "[redis] url")
    } else {
        let host = nonempty(env("REDIS_HOST"));
        let port = nonempty(env("REDIS_PORT"));
        if host.is_none() && port.is_none() {
            return Ok(None);
        }
        let host = host.unwrap_or_else(|| "localhost".into());
        let port = match port {
            None => 6379,
            Some(p) => p
                .trim()
                .parse::<u16>()
                .ok()
                .filter(|p| *p > 0)
                .ok_or_else(|| format!("REDIS_PORT '{p}' is not a port number (1-65535)"))?,
        };
        let db = match nonempty(env("REDIS_DB")) {
            None => 0,
            Some(d) => d
                .trim()
                .parse::<u32>()
                .map_err(|_| format!("REDIS_DB '{d}' is not a database number"))?,
        };
        let host = host.trim();
        if host.contains(['/', '@', ' ']) {
            return Err(format!("REDIS_HOST '{host}' is not a host name"));
        }
        let host = if host.contains(':') && !host.starts_with('[') {
            format!("[{host}]")
        } else {
            host.to_owned()
        };
        (
            format!("redis://{host}:{port}/{db}"),
            "REDIS_HOST/REDIS_PORT",
        )
    };
    let mut info = url.as_str().into_connection_info().map_err(|e| {
        format!(
            "Redis URL from {source} is not valid ({e}); expected redis://[:password@]host:port/db \
             or rediss:// for TLS"
        )
    })?;
    if info.redis_settings().password().is_none() {
        if let Some(password) = nonempty(env("REDIS_PASSWORD")) {
            let settings = info.redis_settings().clone().set_password(password);
            info = info.set_redis_settings(settings);
        }
    }
    Ok(Some(RedisTarget {
        display: redact(&url),
        info,
        source,
    }))
}

/// The URL without its password (`redis://:***@host:port/db`).
pub fn redact(url: &str) -> String {
    let Some((scheme, rest)) = url.split_once("://") else {
        return url.to_owned();
    };
    match rest.rsplit_once('@') {
        Some((credentials, host)) => {
            let user = credentials.split(':').next().unwrap_or("");
            format!("{scheme}://{user}:***@{host}")
        }
        None => url.to_owned(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::HashMap;

    fn env_of(pairs: &[(&str, &str)]) -> impl Fn(&str) -> Option<String> {
        let map: HashMap<String, String> = pairs
            .iter()
            .map(|(k, v)| (k.to_string(), v.to_string()))
            .collect();
        move |k| map.get(k).cloned()
    }

    #[test]
    fn nothing_set_means_off() {
        assert!(resolve_target(None, None, &env_of(&[])).unwrap().is_none());
    }

    #[test]
    fn command_line_wins_over_config_and_environment() {
        let env = env_of(&[("REDIS_HOST", "envhost")]);
        let t = resolve_target(Some("redis://cli:1234/2"), Some("redis://cfg:1/0"), &env)
            .unwrap()
            .unwrap();
        assert_eq!(t.source, "--redis");
        assert_eq!(t.info.redis_settings().db(), 2);
        let t = resolve_target(None, Some("redis://cfg:1/0"), &env)
            .unwrap()
            .unwrap();
        assert_eq!(t.source, "[redis] url");
    }

    #[test]
    fn environment_variables_of_the_python_tools() {
        let env = env_of(&[
            ("REDIS_HOST", "10.0.0.5"),
            ("REDIS_PORT", "6380"),
            ("REDIS_DB", "3"),
            ("REDIS_PASSWORD", "s3cret"),
        ]);
        let t = resolve_target(None, None, &env).unwrap().unwrap();
        assert_eq!(t.display, "redis://10.0.0.5:6380/3");
        assert_eq!(t.info.redis_settings().password(), Some("s3cret"));
        assert!(!format!("{t:?}").contains("s3cret"));
    }

    #[test]
    fn bad_values_are_named() {
        let err = resolve_target(None, None, &env_of(&[("REDIS_PORT", "http")])).unwrap_err();
        assert!(err.contains("REDIS_PORT 'http'"), "{err}");
        let err = resolve_target(Some("http://x"), None, &env_of(&[])).unwrap_err();
        assert!(err.contains("--redis"), "{err}");
    }

    #[test]
    fn passwords_never_reach_the_display_form() {
        assert_eq!(redact("redis://:pw@h:1/0"), "redis://:***@h:1/0");
        assert_eq!(redact("rediss://u:pw@h:1/0"), "rediss://u:***@h:1/0");
        assert_eq!(redact("redis://h:1/0"), "redis://h:1/0");
    }

    #[test]
    fn trust_words() {
        assert_eq!(Trust::parse("External").unwrap(), Trust::External);
        assert!(Trust::parse("gpu")
            .unwrap_err()
            .contains("builtin, external, both"));
    }
}
