//! Rate limits: at most N motions per minute from one origin kind.
//!
//! The count is per origin kind (`mcp`, `agent`, `bus`, `redis`, …), all its sessions
//! together: a client that opens a new MCP session, or claims another session id on the bus,
//! does not start a new count. Each kind keeps the times of its motions in the last minute; a
//! motion beyond the limit is refused with the limit and when the next one will be accepted.

use robotd_protocol::safety::{Origin, OriginKind};
use std::collections::{HashMap, VecDeque};
use std::time::{Duration, Instant};

/// The window the limits count over.
pub const WINDOW: Duration = Duration::from_secs(60);

/// Motion times per origin kind.
#[derive(Debug, Default)]
pub struct RateLimiter {
    kinds: HashMap<OriginKind, VecDeque<Instant>>,
}

impl RateLimiter {
    /// Counts a motion of `origin` at `now` if fewer than `per_minute` happened in the last
    /// minute (0 = no limit); otherwise refuses, saying when the next is accepted.
    pub fn admit(&mut self, origin: &Origin, per_minute: u32, now: Instant) -> Result<(), String> {
        if per_minute == 0 {
            return Ok(());
        }
        let times = self.kinds.entry(origin.kind).or_default();
        while times
            .front()
            .is_some_and(|t| now.saturating_duration_since(*t) >= WINDOW)
        {
            times.pop_front();
        }
        if times.len() >= per_minute as usize {
            let wait = times
                .front()
                .map(|t| WINDOW.saturating_sub(now.saturating_duration_since(*t)))
                .unwrap_or_default();
            return Err(format!(
                "rate limit: {per_minute} motions per minute for {} clients (all sessions together) reached; the next is accepted in {:.1} s",
                origin.kind,
                wait.as_secs_f64()
            ));
        }
        times.push_back(now);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn limits_per_origin_kind_over_a_sliding_minute_whatever_the_session() {
        let mut limiter = RateLimiter::default();
        let start = Instant::now();
        let a = Origin::new(OriginKind::Mcp).session("a");
        let b = Origin::new(OriginKind::Mcp).session("b");
        let agent = Origin::new(OriginKind::Agent);
        for i in 0..3 {
            assert!(limiter.admit(&a, 3, start + Duration::from_secs(i)).is_ok());
        }
        let refused = limiter
            .admit(&a, 3, start + Duration::from_secs(10))
            .unwrap_err();
        assert_eq!(
            refused,
            "rate limit: 3 motions per minute for mcp clients (all sessions together) reached; the next is accepted in 50.0 s"
        );
        // A new session of the same kind does not start a new count.
        assert!(limiter
            .admit(&b, 3, start + Duration::from_secs(10))
            .is_err());
        // Another kind has its own.
        assert!(limiter
            .admit(&agent, 3, start + Duration::from_secs(10))
            .is_ok());
        assert!(limiter
            .admit(&b, 3, start + Duration::from_secs(60))
            .is_ok());
        assert!(limiter.admit(&a, 0, start).is_ok());
    }
}
