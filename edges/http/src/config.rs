//! `[http]`: the address of robotd's one HTTP port, the host names it answers to, and how
//! many connections it holds and for how long.

use robotd_runtime::config::{Checks, Section};
use serde::{Deserialize, Serialize};
use std::net::SocketAddr;

/// `[http]`
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HttpConfig {
    /// Address of the HTTP edge; port 0 picks a free port.
    pub bind: SocketAddr,
    /// Host names accepted in the `Host` header besides `localhost`, `127.0.0.1` and `[::1]`
    /// (DNS-rebinding protection), e.g. "robot-pc.lab". On a non-loopback bind a non-empty
    /// list restricts `Host` to these names.
    #[serde(default)]
    pub allowed_hosts: Vec<String>,
    /// Connections the port holds open at once (8 … 65536); the next gets a 503 and is closed.
    #[serde(default = "default_max_connections")]
    pub max_connections: usize,
    /// Seconds an open connection may go without sending a request before it is closed
    /// (1 … 3600). Responses in progress (tool calls, SSE streams) are not cut.
    #[serde(default = "default_idle_timeout_s")]
    pub idle_timeout_s: u64,
}

fn default_max_connections() -> usize {
    crate::ConnectionLimits::default().max_connections
}

fn default_idle_timeout_s() -> u64 {
    crate::ConnectionLimits::default().idle_timeout.as_secs()
}

impl HttpConfig {
    /// The connection cap and idle timeout of this section.
    pub fn limits(&self) -> crate::ConnectionLimits {
        crate::ConnectionLimits {
            max_connections: self.max_connections,
            idle_timeout: std::time::Duration::from_secs(self.idle_timeout_s),
        }
    }
}

/// Whether `name` is a plain host name or IP address (no scheme, port, path or spaces).
fn is_host_name(name: &str) -> bool {
    if name.parse::<std::net::IpAddr>().is_ok() {
        return true;
    }
    if let Some(v6) = name.strip_prefix('[').and_then(|n| n.strip_suffix(']')) {
        return v6.parse::<std::net::Ipv6Addr>().is_ok();
    }
    !name.is_empty()
        && name.len() <= 253
        && name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || matches!(c, '.' | '-' | '_'))
}

impl Section for HttpConfig {
    /// The address is checked while it is read (serde parses it).
    fn check(&self, checks: &mut Checks) {
        checks.range_u64(
            "max_connections",
            self.max_connections as u64,
            8..=65536,
            "",
        );
        checks.range_u64("idle_timeout_s", self.idle_timeout_s, 1..=3600, " s");
        for name in &self.allowed_hosts {
            if !is_host_name(name) {
                checks.problem(
                    "allowed_hosts",
                    format!(
                        "'{name}' is not a host name; expected a name or address without \
                         scheme or port, such as \"robot-pc.lab\" or \"192.168.1.20\""
                    ),
                );
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::is_host_name;

    #[test]
    fn host_names_without_scheme_or_port() {
        for ok in [
            "robot-pc.lab",
            "192.168.1.20",
            "localhost",
            "[fe80::1]",
            "fe80::1",
        ] {
            assert!(is_host_name(ok), "{ok}");
        }
        for bad in ["", "http://robot", "robot:8000", "a b", "robot/path"] {
            assert!(!is_host_name(bad), "{bad}");
        }
    }
}
