//! Rate limits: at most N motions per minute from one client.
//!
//! A client is an origin kind plus its session (`mcp` session `3f2a`, the `agent`, an unnamed
//! bus client). Each keeps the times of its motions in the last minute; a motion beyond the
//! limit is refused with the limit and when the next one will be accepted. The table of
//! clients is bounded: the oldest idle client is forgotten first.

use robotd_protocol::safety::{Origin, OriginKind};
use std::collections::{HashMap, VecDeque};
use std::time::{Duration, Instant};

/// The window the limits count over.
pub const WINDOW: Duration = Duration::from_secs(60);

/// Most clients tracked at once.
const MAX_CLIENTS: usize = 4096;

/// Motion times per client.
#[derive(Debug, Default)]
pub struct RateLimiter {
    clients: HashMap<(OriginKind, String), VecDeque<Instant>>,
}

impl RateLimiter {
    /// Counts a motion of `origin` at `now` if fewer than `per_minute` happened in the last
    /// minute (0 = no limit); otherwise refuses, saying when the next is accepted.
    pub fn admit(&mut self, origin: &Origin, per_minute: u32, now: Instant) -> Result<(), String> {
        if per_minute == 0 {
            return Ok(());
        }
        if self.clients.len() >= MAX_CLIENTS {
            self.forget_idle(now);
        }
        let times = self
            .clients
            .entry((origin.kind, origin.session.clone()))
            .or_default();
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
                "rate limit: {per_minute} motions per minute for {} clients reached; the next is accepted in {:.1} s",
                origin.kind,
                wait.as_secs_f64()
            ));
        }
        times.push_back(now);
        Ok(())
    }

    fn forget_idle(&mut self, now: Instant) {
        self.clients.retain(|_, times| {
            times
                .back()
                .is_some_and(|t| now.saturating_duration_since(*t) < WINDOW)
        });
        if self.clients.len() >= MAX_CLIENTS {
            // Every client is active: drop the one whose last motion is oldest.
            if let Some(key) = self
                .clients
                .iter()
                .min_by_key(|(_, times)| times.back().copied())
                .map(|(key, _)| key.clone())
            {
                self.clients.remove(&key);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn limits_per_client_over_a_sliding_minute() {
        let mut limiter = RateLimiter::default();
        let start = Instant::now();
        let a = Origin::new(OriginKind::Mcp).session("a");
        let b = Origin::new(OriginKind::Mcp).session("b");
        for i in 0..3 {
            assert!(limiter.admit(&a, 3, start + Duration::from_secs(i)).is_ok());
        }
        let refused = limiter
            .admit(&a, 3, start + Duration::from_secs(10))
            .unwrap_err();
        assert_eq!(
            refused,
            "rate limit: 3 motions per minute for mcp clients reached; the next is accepted in 50.0 s"
        );
        assert!(limiter
            .admit(&b, 3, start + Duration::from_secs(10))
            .is_ok());
        assert!(limiter
            .admit(&a, 3, start + Duration::from_secs(60))
            .is_ok());
        assert!(limiter.admit(&a, 0, start).is_ok());
    }

    #[test]
    fn the_client_table_stays_bounded() {
        let mut limiter = RateLimiter::default();
        let now = Instant::now();
        for i in 0..(MAX_CLIENTS + 10) {
            let origin = Origin::new(OriginKind::Bus).session(i.to_string());
            limiter.admit(&origin, 5, now).unwrap();
        }
        assert!(limiter.clients.len() <= MAX_CLIENTS);
    }
}
