//! How robotd waits between attempts to reach something that is down: the Redis server, a
//! camera, a robot's socket or servo bus, an LLM that is busy.
//!
//! Every reconnect and retry loop in robotd uses this one policy: the first wait is short
//! (100 ms by default, so a blip costs nothing), each failed attempt doubles it, it never
//! exceeds a ceiling (so a device that comes back is found within that time), and a success
//! starts again from the first wait. No jitter: each loop talks to one peer of its own, so
//! there is no herd of clients to spread out.
//!
//! A [`Backoff`] only computes the waits (with [`backon`]'s exponential backoff); the loop
//! waits its own way — `tokio::time::sleep` in a `select!` with its cancellation,
//! `std::thread::sleep` in a device thread — so the same helper serves both, and tests that
//! pause tokio's clock see the same waits as production:
//!
//! ```
//! use robotd_runtime::backoff::Backoff;
//! use std::time::Duration;
//!
//! let mut backoff = Backoff::new(Duration::from_millis(100), Duration::from_millis(500));
//! let waits: Vec<u64> = (0..5).map(|_| backoff.next_delay().as_millis() as u64).collect();
//! assert_eq!(waits, [100, 200, 400, 500, 500]); // doubled, then held at the ceiling
//! backoff.reset(); // connected: the next failure waits the first delay again
//! assert_eq!(backoff.next_delay(), Duration::from_millis(100));
//! ```

use backon::{BackoffBuilder, ExponentialBackoff, ExponentialBuilder};
use std::time::Duration;

/// The first wait of robotd's reconnect loops.
pub const FIRST_DELAY: Duration = Duration::from_millis(100);

/// Exponential waits between attempts: `first`, twice that, … up to `max`, forever; see the
/// [module docs](self).
#[derive(Debug)]
pub struct Backoff {
    builder: ExponentialBuilder,
    delays: ExponentialBackoff,
    max: Duration,
}

impl Backoff {
    /// Waits from `first`, doubling, held at `max` (a `max` below `first` is raised to it).
    pub fn new(first: Duration, max: Duration) -> Self {
        let max = max.max(first);
        let builder = ExponentialBuilder::new()
            .with_min_delay(first)
            .with_max_delay(max)
            .with_factor(2.0)
            .without_max_times();
        Backoff {
            builder,
            delays: builder.build(),
            max,
        }
    }

    /// Waits from [`FIRST_DELAY`] (100 ms) up to `max`.
    pub fn up_to(max: Duration) -> Self {
        Self::new(FIRST_DELAY, max)
    }

    /// How long to wait before the next attempt; the wait after it is twice as long (at most
    /// the ceiling).
    pub fn next_delay(&mut self) -> Duration {
        self.delays.next().unwrap_or(self.max)
    }

    /// An attempt succeeded: the next failure waits the first delay again.
    pub fn reset(&mut self) {
        self.delays = self.builder.build();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn doubles_up_to_the_ceiling_and_starts_again_after_a_reset() {
        let ms = |b: &mut Backoff| b.next_delay().as_millis();
        let mut b = Backoff::up_to(Duration::from_secs(1));
        let waits: Vec<_> = (0..7).map(|_| ms(&mut b)).collect();
        assert_eq!(waits, [100, 200, 400, 800, 1000, 1000, 1000]);
        b.reset();
        assert_eq!(ms(&mut b), 100);
        // Thousands of failures later the wait is still the ceiling (no overflow, no end).
        for _ in 0..10_000 {
            b.next_delay();
        }
        assert_eq!(ms(&mut b), 1000);
        // A ceiling below the first wait holds the first wait.
        let mut low = Backoff::new(Duration::from_millis(100), Duration::from_millis(10));
        assert_eq!((ms(&mut low), ms(&mut low)), (100, 100));
    }
}
