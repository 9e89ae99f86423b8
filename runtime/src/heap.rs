//! Giving freed heap memory back to the system after a burst.
//!
//! glibc's allocator keeps what a burst of work freed (64 MCP clients' sessions, buffers and
//! replies) inside its per-thread arenas for reuse, so a service's resident memory stays at
//! its peak long after the clients left: `robotd bench mcp` measured ~25 MB held this way.
//! [`release_soon`] asks for that memory to be returned (`malloc_trim`) once a second has
//! passed without another request, so a burst (64 sessions closing together, thousands of
//! tool calls) makes one trim after its end and none while it lasts. Callers are the places
//! a burst is made of: an MCP tool call, an MCP session closing.
//!
//! On other C libraries this does nothing: their allocators have their own policies.

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::OnceLock;
use std::time::Duration;
use tokio::time::Instant;

/// How long without a request before the trim runs: the burst is over.
const QUIET: Duration = Duration::from_secs(1);

static PENDING: AtomicBool = AtomicBool::new(false);
static TRIMS: AtomicU64 = AtomicU64::new(0);
/// When the last request came, in microseconds after [`clock_base`].
static LAST_REQUEST_US: AtomicU64 = AtomicU64::new(0);

fn clock_base() -> Instant {
    static BASE: OnceLock<Instant> = OnceLock::new();
    *BASE.get_or_init(Instant::now)
}

fn now_us() -> u64 {
    u64::try_from(clock_base().elapsed().as_micros()).unwrap_or(u64::MAX)
}

/// Returns freed heap memory to the system once a second has passed without another call
/// (one trim per burst, after it). Costs a clock read and two atomics; does nothing outside a
/// tokio runtime.
pub fn release_soon() {
    let Ok(runtime) = tokio::runtime::Handle::try_current() else {
        return;
    };
    LAST_REQUEST_US.store(now_us(), Ordering::Release);
    if PENDING.swap(true, Ordering::AcqRel) {
        return;
    }
    runtime.spawn(async {
        loop {
            let quiet_from = LAST_REQUEST_US
                .load(Ordering::Acquire)
                .saturating_add(QUIET.as_micros() as u64);
            let now = now_us();
            if now >= quiet_from {
                break;
            }
            tokio::time::sleep(Duration::from_micros(quiet_from - now)).await;
        }
        // Cleared before trimming: a request from here on schedules another trim.
        PENDING.store(false, Ordering::Release);
        let _ = tokio::task::spawn_blocking(release_now).await;
    });
}

/// Returns freed heap memory to the system now; true when the allocator returned some.
pub fn release_now() -> bool {
    TRIMS.fetch_add(1, Ordering::Relaxed);
    trim()
}

/// How many trims ran in this process (for tests and diagnostics).
pub fn trims() -> u64 {
    TRIMS.load(Ordering::Relaxed)
}

#[cfg(all(target_os = "linux", target_env = "gnu"))]
fn trim() -> bool {
    // SAFETY: malloc_trim only walks the allocator's own free lists; any thread may call it.
    unsafe { libc::malloc_trim(0) == 1 }
}

#[cfg(not(all(target_os = "linux", target_env = "gnu")))]
fn trim() -> bool {
    false
}

#[cfg(test)]
mod tests {
    use super::*;

    #[tokio::test(start_paused = true)]
    async fn a_burst_of_requests_makes_one_trim_a_second_after_its_end() {
        let before = trims();
        // A burst of 3 s: a request every 100 ms.
        for _ in 0..30 {
            release_soon();
            tokio::time::sleep(Duration::from_millis(100)).await;
        }
        assert_eq!(trims(), before, "no trim while the burst lasts");
        tokio::time::sleep(Duration::from_millis(800)).await;
        assert_eq!(trims(), before, "no trim before a quiet second");
        tokio::time::sleep(Duration::from_millis(200)).await;
        // The trim runs on the blocking pool: wait for it without a fixed sleep.
        while trims() == before {
            tokio::task::yield_now().await;
        }
        tokio::time::sleep(Duration::from_secs(5)).await;
        assert_eq!(trims(), before + 1, "one trim for the whole burst");
        release_soon();
        tokio::time::sleep(Duration::from_secs(2)).await;
        while trims() == before + 1 {
            tokio::task::yield_now().await;
        }
        assert_eq!(trims(), before + 2, "a later request makes its own trim");
    }

    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    #[test]
    fn freed_memory_goes_back_to_the_system() {
        fn rss_kb() -> u64 {
            let status = std::fs::read_to_string("/proc/self/status").unwrap();
            status
                .lines()
                .find_map(|l| l.strip_prefix("VmRSS:"))
                .and_then(|v| v.split_whitespace().next())
                .and_then(|v| v.parse().ok())
                .unwrap()
        }
        // Many small blocks (below the allocator's mmap threshold, so they live in the heap),
        // touched, then all freed except the last one, which pins the heap's top.
        let blocks: Vec<Vec<u8>> = (0..4096).map(|_| vec![1u8; 16 * 1024]).collect();
        let pin = vec![1u8; 1024];
        drop(blocks);
        let held = rss_kb();
        trim();
        let after = rss_kb();
        drop(pin);
        assert!(
            held.saturating_sub(after) > 32 * 1024,
            "trim returned {} KB of ~64 MB freed",
            held.saturating_sub(after)
        );
    }
}
