//! How long the latest tool calls took, for the dashboard's latency plot.
//!
//! Every [`crate::Registry::call`] in this process (MCP clients, the agent) is recorded here:
//! tool, duration, success, time. The last [`KEPT`] are kept (a few kilobytes).

use serde::Serialize;
use std::collections::VecDeque;
use std::sync::Mutex;
use std::time::{Duration, SystemTime, UNIX_EPOCH};

/// Calls kept.
pub const KEPT: usize = 500;

/// One finished call.
#[derive(Debug, Clone, Serialize)]
pub struct CallTiming {
    /// The tool.
    pub tool: String,
    /// How long it took, milliseconds.
    pub ms: f64,
    /// Whether it succeeded (`✓`).
    pub ok: bool,
    /// When it finished, seconds since the Unix epoch.
    pub at_unix_s: f64,
}

static RECENT: Mutex<VecDeque<CallTiming>> = Mutex::new(VecDeque::new());

/// Records a call of `tool` that took `duration`.
pub fn record(tool: &str, duration: Duration, ok: bool) {
    let at_unix_s = SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0.0, |d| d.as_secs_f64());
    let mut recent = RECENT.lock().unwrap_or_else(|e| e.into_inner());
    if recent.len() == KEPT {
        recent.pop_front();
    }
    recent.push_back(CallTiming {
        tool: tool.to_owned(),
        ms: duration.as_secs_f64() * 1e3,
        ok,
        at_unix_s,
    });
}

/// The calls that finished in the last `within`, oldest first.
pub fn recent(within: Duration) -> Vec<CallTiming> {
    let now = SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0.0, |d| d.as_secs_f64());
    let since = now - within.as_secs_f64();
    let recent = RECENT.lock().unwrap_or_else(|e| e.into_inner());
    recent
        .iter()
        .filter(|c| c.at_unix_s >= since)
        .cloned()
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn calls_are_kept_newest_last_and_bounded() {
        for i in 0..KEPT + 10 {
            record("speak", Duration::from_millis(i as u64), true);
        }
        let calls = recent(Duration::from_secs(60));
        assert!(calls.len() <= KEPT);
        let last = calls.last().unwrap();
        assert_eq!(last.tool, "speak");
        assert!((last.ms - (KEPT + 9) as f64).abs() < 1e-9);
    }
}
