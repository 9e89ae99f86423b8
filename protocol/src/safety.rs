//! Who asked for a motion: the [`Origin`] every bus request carries.
//!
//! robotd's motion policy (the `robotd-safety` crate) decides per origin: motions from an LLM
//! (the MCP edge, the agent) get lower speed caps than a script's; rate limits are counted per
//! origin; the audit log records who asked. Edges set the origin of the work they start (an
//! MCP session and call, an agent request, a Redis command) and the bus carries it with every
//! request made on that work's behalf, through the skills actor down to the arm.
//!
//! A process on the bus can claim any origin: the origin picks rate buckets and caps, it is
//! not an authentication. A request without one is [`OriginKind::Bus`], which the policy treats
//! as strictly as an LLM.
//!
//! ```
//! use robotd_protocol::safety::{Origin, OriginKind};
//!
//! let origin = Origin::new(OriginKind::Mcp).session("3f2a").request("7");
//! assert!(origin.is_llm());
//! assert_eq!(origin.to_string(), "mcp session 3f2a request 7");
//! assert!(!Origin::new(OriginKind::Cli).is_llm());
//! ```

use serde::{Deserialize, Serialize};
use std::fmt;

/// Which kind of client started the work.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum OriginKind {
    /// A bus client that did not say who it is (an external actor, a test).
    #[default]
    Bus,
    /// A tool call over MCP (an LLM host such as a chat client).
    Mcp,
    /// robotd's own LLM agent (`robotd chat`, the dashboard's chat).
    Agent,
    /// A command through the Redis edge.
    Redis,
    /// A person at the command line (`robotd call`, `robotd estop`).
    Cli,
    /// A person through robotd's HTTP API or dashboard.
    Http,
    /// robotd itself (start-up moves, recovery, supervision).
    Internal,
}

impl OriginKind {
    /// Wire name, e.g. `"mcp"`.
    pub const fn as_str(self) -> &'static str {
        match self {
            Self::Bus => "bus",
            Self::Mcp => "mcp",
            Self::Agent => "agent",
            Self::Redis => "redis",
            Self::Cli => "cli",
            Self::Http => "http",
            Self::Internal => "internal",
        }
    }

    /// Every kind, for configuration checks and docs.
    pub const ALL: [OriginKind; 7] = [
        Self::Bus,
        Self::Mcp,
        Self::Agent,
        Self::Redis,
        Self::Cli,
        Self::Http,
        Self::Internal,
    ];

    /// The kind named `name`, if any.
    pub fn parse(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|k| k.as_str() == name)
    }
}

impl fmt::Display for OriginKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// Who asked: the kind of client, its session and request, and the human approval (if any)
/// the work was granted.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Origin {
    /// The kind of client.
    pub kind: OriginKind,
    /// The client's session (MCP session id, agent session), empty when none.
    #[serde(default)]
    pub session: String,
    /// The request within the session (JSON-RPC id, agent request id), empty when none.
    #[serde(default)]
    pub request: String,
    /// The approval a human granted this work (0 = none), checked by the policy.
    #[serde(default)]
    pub approval_id: u64,
    /// A lower tool speed cap this work asks for, mm/s (0 = none): the policy keeps the lower
    /// of it and the origin's configured cap, so it can slow a client's motions, never speed
    /// them up (`robotd commission` attached to a running robotd moves at its own low cap).
    #[serde(default)]
    pub speed_cap_mm_s: u32,
}

impl Origin {
    /// An origin of `kind` with no session or request.
    pub fn new(kind: OriginKind) -> Self {
        Self {
            kind,
            ..Self::default()
        }
    }

    /// Sets the session (builder style).
    pub fn session(mut self, session: impl Into<String>) -> Self {
        self.session = session.into();
        self
    }

    /// Sets the request (builder style).
    pub fn request(mut self, request: impl Into<String>) -> Self {
        self.request = request.into();
        self
    }

    /// Asks for a tool speed cap of `mm_s` for this work (builder style); see
    /// [`Origin::speed_cap_mm_s`].
    pub fn speed_cap(mut self, mm_s: u32) -> Self {
        self.speed_cap_mm_s = mm_s;
        self
    }

    /// Whether an LLM decides what this origin asks (MCP clients, the agent), or nobody said
    /// (a bare bus client): these get the LLM caps.
    pub fn is_llm(&self) -> bool {
        matches!(
            self.kind,
            OriginKind::Mcp | OriginKind::Agent | OriginKind::Bus
        )
    }
}

impl fmt::Display for Origin {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.kind.as_str())?;
        if !self.session.is_empty() {
            write!(f, " session {}", self.session)?;
        }
        if !self.request.is_empty() {
            write!(f, " request {}", self.request)?;
        }
        Ok(())
    }
}

/// `text` without control characters (CR, LF, ESC… would forge log lines), at most `max`
/// characters: for the reasons and names people give the e-stop and approvals.
pub fn printable(text: &str, max: usize) -> String {
    text.chars().filter(|c| !c.is_control()).take(max).collect()
}

#[cfg(test)]
mod tests {
    #[test]
    fn printable_text_has_no_control_characters() {
        assert_eq!(super::printable("a\r\nb\u{1b}[31mc\0", 4), "ab[3");
    }

    use super::*;

    #[test]
    fn kinds_round_trip_by_name() {
        for kind in OriginKind::ALL {
            assert_eq!(OriginKind::parse(kind.as_str()), Some(kind));
        }
        assert_eq!(OriginKind::parse("robot"), None);
    }

    #[test]
    fn missing_fields_decode_as_an_unnamed_bus_client() {
        let origin: Origin = serde_json::from_value(serde_json::json!({"kind": "redis"})).unwrap();
        assert_eq!(origin, Origin::new(OriginKind::Redis));
        assert!(!origin.is_llm());
        assert!(Origin::default().is_llm());
    }
}
