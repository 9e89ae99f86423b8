//! `[http]`: the address of robotd's one HTTP port.

use robotd_runtime::config::{Checks, Section};
use serde::{Deserialize, Serialize};
use std::net::SocketAddr;

/// `[http]`
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HttpConfig {
    /// Address of the HTTP edge; port 0 picks a free port.
    pub bind: SocketAddr,
}

impl Section for HttpConfig {
    /// The address is checked while it is read (serde parses it).
    fn check(&self, _checks: &mut Checks) {}
}
