//! The liveness watchdog: proof, from inside the supervision loops, that they still turn.
//!
//! A service manager such as systemd can restart a service that has hung, if the service
//! sends it a "still alive" ping at a steady rate (`WATCHDOG=1`). A ping from a separate timer
//! task proves little: that timer keeps ticking while the loops that matter are stuck. So here
//! the pings come from the supervision loops themselves.
//!
//! Once [`install`] has been called with an interval and a `ping` function, every supervisor
//! that starts afterwards joins the watchdog and, while it waits for its actor or process to
//! end, beats once per interval. A *round* is complete when every supervisor still supervising
//! has beaten since the previous round; the supervisor whose beat completes it calls `ping`.
//! With every loop turning, that is one ping per interval. If any one loop hangs (a blocking
//! call, an await that never returns), rounds stop completing and the pings stop, though the
//! rest of the process may still answer: exactly what the service manager must learn.
//!
//! A supervisor leaves the watchdog when its loop ends (shut down, or its restart budget is
//! exhausted and it gave up): an actor that is down for good is reported by health, not by the
//! watchdog. Should every supervisor have ended, nothing pings any more, and a service manager
//! restarts the whole service, which is what an operator would do.
//!
//! Between two beats a loop may be busy restarting its actor: the safe-state hook, the cleanup
//! hook and the backoff (at most `backoff_max`, 5 s by default) are each bounded, and the
//! loop beats during the backoff too. The interval must be longer than the slowest of those
//! steps, or a restart looks like a hang (systemd's `WatchdogSec=` of 30 s or more is plenty).
//!
//! Without [`install`] nothing of this runs: supervisors do not beat.
//!
//! For tests, [`test_hooks::hang_one_loop`] makes the next supervision loop that beats hang
//! for good, and in a process started with `TEST_ROBOTD_HOOKS=1` whose watchdog is installed,
//! `SIGUSR1` calls it, so a test can watch the pings stop. The hooks are compiled into debug
//! builds (the ones tests run) and with the crate's `test-hooks` feature, never into a
//! `release` or `dist` build.

use std::collections::BTreeMap;
use std::sync::{Arc, Mutex, OnceLock};
use std::time::Duration;

/// What a complete round calls: typically sends `WATCHDOG=1` to the service manager.
pub type PingFn = dyn Fn() + Send + Sync + 'static;

struct Watchdog {
    interval: Duration,
    ping: Box<PingFn>,
    members: Mutex<Members>,
}

#[derive(Default)]
struct Members {
    next_id: u64,
    /// Each member, by id: its name and whether it beat in the current round.
    beaten: BTreeMap<u64, (String, bool)>,
}

static WATCHDOG: OnceLock<Arc<Watchdog>> = OnceLock::new();

/// `install` was called twice in one process.
#[derive(Debug, thiserror::Error)]
#[error("the supervision watchdog is already installed in this process")]
pub struct AlreadyInstalled;

/// Makes every supervisor started from now on beat every `interval`, and calls `ping` once
/// per complete round (every live supervisor beat). Once per process.
pub fn install(
    interval: Duration,
    ping: impl Fn() + Send + Sync + 'static,
) -> Result<(), AlreadyInstalled> {
    let watchdog = Arc::new(Watchdog {
        interval: interval.max(Duration::from_millis(1)),
        ping: Box::new(ping),
        members: Mutex::new(Members::default()),
    });
    WATCHDOG.set(watchdog).map_err(|_| AlreadyInstalled)?;
    #[cfg(any(feature = "test-hooks", debug_assertions))]
    test_hooks::listen_for_sigusr1();
    Ok(())
}

/// The installed watchdog's beat interval, if one is installed.
pub fn interval() -> Option<Duration> {
    WATCHDOG.get().map(|w| w.interval)
}

/// Names of the supervisors that have not beaten in the current round (what a stuck watchdog
/// waits for); empty without a watchdog.
pub fn waiting_for() -> Vec<String> {
    let Some(watchdog) = WATCHDOG.get() else {
        return Vec::new();
    };
    let members = watchdog.members.lock().unwrap_or_else(|e| e.into_inner());
    members
        .beaten
        .values()
        .filter(|(_, beat)| !beat)
        .map(|(name, _)| name.clone())
        .collect()
}

/// One supervision loop's membership; leaves the watchdog when dropped.
pub(crate) struct Member {
    watchdog: Arc<Watchdog>,
    id: u64,
}

/// Joins the installed watchdog, if there is one.
pub(crate) fn join(name: &str) -> Option<Member> {
    let watchdog = WATCHDOG.get()?.clone();
    let id = {
        let mut members = watchdog.members.lock().unwrap_or_else(|e| e.into_inner());
        let id = members.next_id;
        members.next_id += 1;
        members.beaten.insert(id, (name.to_owned(), false));
        id
    };
    Some(Member { watchdog, id })
}

impl Member {
    /// How often this member must beat.
    pub(crate) fn interval(&self) -> Duration {
        self.watchdog.interval
    }

    /// This loop is alive; pings when that completes the round.
    pub(crate) fn beat(&self) {
        let complete = {
            let mut members = self
                .watchdog
                .members
                .lock()
                .unwrap_or_else(|e| e.into_inner());
            if let Some(entry) = members.beaten.get_mut(&self.id) {
                entry.1 = true;
            }
            let complete = members.beaten.values().all(|(_, beat)| *beat);
            if complete {
                members
                    .beaten
                    .values_mut()
                    .for_each(|entry| entry.1 = false);
            }
            complete
        };
        // Outside the lock: the ping does I/O.
        if complete {
            (self.watchdog.ping)();
        }
    }
}

impl Drop for Member {
    fn drop(&mut self) {
        let mut members = self
            .watchdog
            .members
            .lock()
            .unwrap_or_else(|e| e.into_inner());
        members.beaten.remove(&self.id);
    }
}

/// A ticker for an optional member: ticks every interval with a member, never without one.
pub(crate) async fn next_beat(ticker: &mut Option<(Member, tokio::time::Interval)>) {
    match ticker {
        Some((_, interval)) => {
            interval.tick().await;
        }
        None => std::future::pending().await,
    }
}

/// The member and its ticker for a loop named `name`, when a watchdog is installed.
pub(crate) fn ticker(name: &str) -> Option<(Member, tokio::time::Interval)> {
    let member = join(name)?;
    let mut interval = tokio::time::interval(member.interval());
    interval.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    Some((member, interval))
}

/// Beats for the loop that owns `ticker` (after [`next_beat`] returned).
pub(crate) async fn beat(ticker: &Option<(Member, tokio::time::Interval)>) {
    #[cfg(any(feature = "test-hooks", debug_assertions))]
    if test_hooks::take_hang() {
        tracing::warn!("test hook: this supervision loop now hangs for good");
        std::future::pending::<()>().await;
    }
    if let Some((member, _)) = ticker {
        member.beat();
    }
}

/// Test-only controls (debug builds and the `test-hooks` feature): never part of a release
/// build.
#[cfg(any(feature = "test-hooks", debug_assertions))]
pub mod test_hooks {
    use std::sync::atomic::{AtomicBool, Ordering};

    static HANG: AtomicBool = AtomicBool::new(false);

    /// The next supervision loop that beats hangs for good (one loop, once).
    pub fn hang_one_loop() {
        HANG.store(true, Ordering::SeqCst);
    }

    pub(super) fn take_hang() -> bool {
        HANG.swap(false, Ordering::SeqCst)
    }

    /// The environment variable that arms the hooks in a process.
    pub const ENV: &str = "TEST_ROBOTD_HOOKS";

    /// With `TEST_ROBOTD_HOOKS=1`, in a tokio runtime: `SIGUSR1` calls [`hang_one_loop`], so a
    /// test can block a running robotd's supervision from outside.
    pub(super) fn listen_for_sigusr1() {
        if std::env::var(ENV).as_deref() != Ok("1") {
            return;
        }
        let Ok(runtime) = tokio::runtime::Handle::try_current() else {
            return;
        };
        runtime.spawn(async {
            use tokio::signal::unix::{signal, SignalKind};
            let Ok(mut usr1) = signal(SignalKind::user_defined1()) else {
                return;
            };
            while usr1.recv().await.is_some() {
                hang_one_loop();
            }
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::atomic::{AtomicU32, Ordering};

    fn watchdog(pings: Arc<AtomicU32>) -> Arc<Watchdog> {
        Arc::new(Watchdog {
            interval: Duration::from_millis(10),
            ping: Box::new(move || {
                pings.fetch_add(1, Ordering::SeqCst);
            }),
            members: Mutex::new(Members::default()),
        })
    }

    fn member(watchdog: &Arc<Watchdog>, name: &str) -> Member {
        let mut members = watchdog.members.lock().unwrap();
        let id = members.next_id;
        members.next_id += 1;
        members.beaten.insert(id, (name.into(), false));
        Member {
            watchdog: watchdog.clone(),
            id,
        }
    }

    #[test]
    fn a_round_pings_once_every_member_has_beaten() {
        let pings = Arc::new(AtomicU32::new(0));
        let dog = watchdog(pings.clone());
        let arm = member(&dog, "arm");
        let camera = member(&dog, "camera");
        arm.beat();
        arm.beat();
        assert_eq!(pings.load(Ordering::SeqCst), 0, "the camera has not beaten");
        camera.beat();
        assert_eq!(pings.load(Ordering::SeqCst), 1);
        camera.beat();
        assert_eq!(
            pings.load(Ordering::SeqCst),
            1,
            "a new round waits for the arm"
        );
        arm.beat();
        assert_eq!(pings.load(Ordering::SeqCst), 2);
    }

    #[test]
    fn a_silent_member_stops_the_pings_until_it_leaves() {
        let pings = Arc::new(AtomicU32::new(0));
        let dog = watchdog(pings.clone());
        let arm = member(&dog, "arm");
        let stuck = member(&dog, "stuck");
        for _ in 0..5 {
            arm.beat();
        }
        assert_eq!(pings.load(Ordering::SeqCst), 0);
        drop(stuck);
        arm.beat();
        assert_eq!(
            pings.load(Ordering::SeqCst),
            1,
            "a finished loop no longer counts"
        );
    }
}
