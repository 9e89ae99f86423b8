//! What the soak watches: the service process's memory, descriptors and threads, and the
//! outcome and latency of every call, by minute.

use anyhow::{Context, Result};
use serde::Serialize;
use std::collections::BTreeMap;
use std::sync::Mutex;
use std::time::Duration;

/// One look at the robotd process.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct ProcessSample {
    /// Seconds since the soak started.
    pub at_s: f64,
    /// Resident memory, MB.
    pub rss_mb: f64,
    /// Open file descriptors.
    pub fds: usize,
    /// Threads.
    pub threads: usize,
}

/// Reads `/proc/<pid>`.
pub fn sample(pid: u32, at: Duration) -> Result<ProcessSample> {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status"))
        .with_context(|| format!("robotd (pid {pid}) is gone"))?;
    let field = |name: &str| -> Option<f64> {
        status
            .lines()
            .find_map(|l| l.strip_prefix(name))
            .and_then(|v| v.split_whitespace().next())
            .and_then(|v| v.parse().ok())
    };
    let fds = std::fs::read_dir(format!("/proc/{pid}/fd"))
        .map(|d| d.count())
        .unwrap_or(0);
    Ok(ProcessSample {
        at_s: at.as_secs_f64(),
        rss_mb: field("VmRSS:").context("VmRSS")? / 1024.0,
        fds,
        threads: field("Threads:").unwrap_or(0.0) as usize,
    })
}

/// Open descriptors of `pid` by kind: `socket`, `pipe`, `anon_inode:…`, or for files the
/// extension iceoryx2 gives each kind of resource (`dynamic`, `event_mgmt`, `connection`, …).
pub fn fd_kinds(pid: u32) -> BTreeMap<String, usize> {
    let mut kinds = BTreeMap::new();
    let Ok(entries) = std::fs::read_dir(format!("/proc/{pid}/fd")) else {
        return kinds;
    };
    for entry in entries.flatten() {
        let Ok(target) = std::fs::read_link(entry.path()) else {
            continue;
        };
        let target = target.to_string_lossy();
        let kind = if let Some((kind, _)) = target.split_once(':') {
            if kind.starts_with('/') {
                target.rsplit('.').next().unwrap_or("file").to_owned()
            } else {
                kind.to_owned()
            }
        } else {
            target
                .rsplit_once('.')
                .map_or("file", |(_, ext)| ext)
                .to_owned()
        };
        *kinds.entry(kind).or_default() += 1;
    }
    kinds
}

/// How a call ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Outcome {
    /// `✓ …`.
    Ok,
    /// `❌ …` caused by an injected fault (the actor failed and was restarted).
    InjectedFault,
    /// Any other `❌ …` (e.g. the object was not where it was looked for).
    ToolError,
    /// No answer: a transport error or a timeout. A soak passes only without these.
    Lost,
}

impl Outcome {
    /// Classifies a tool's reply text.
    pub fn of_reply(text: &str) -> Outcome {
        if !text.starts_with('❌') {
            // `✓ …`, or a tool that answers with data (get_system_status: JSON).
            Outcome::Ok
        } else if text.contains("not retried")
            || text.contains("actor failed")
            || text.contains("restarting")
            || text.contains("injected")
        {
            Outcome::InjectedFault
        } else {
            Outcome::ToolError
        }
    }
}

/// One minute's calls.
#[derive(Debug, Clone)]
pub struct MinuteSummary {
    /// Minute (0-based).
    pub minute: u64,
    /// Calls that started in it.
    pub calls: u64,
    /// By outcome.
    pub outcomes: BTreeMap<Outcome, u64>,
    /// Latency p50 / p99 of the answered ones, ms.
    pub p50_ms: f64,
    /// See `p50_ms`.
    pub p99_ms: f64,
}

/// Calls, by minute.
#[derive(Debug, Default)]
pub struct CallLog {
    minutes: Mutex<BTreeMap<u64, MinuteCalls>>,
    examples: Mutex<BTreeMap<Outcome, Vec<String>>>,
}

#[derive(Debug, Default, Clone)]
struct MinuteCalls {
    latencies_ms: Vec<f64>,
    outcomes: BTreeMap<Outcome, u64>,
}

impl CallLog {
    /// Keeps the first few replies (or errors) of each kind but `Ok`, for the report.
    pub fn example(&self, outcome: Outcome, tool: &str, text: &str) {
        if outcome == Outcome::Ok {
            return;
        }
        let mut examples = self.examples.lock().unwrap_or_else(|e| e.into_inner());
        let list = examples.entry(outcome).or_default();
        if list.len() < 3 {
            list.push(format!(
                "{tool}: {}",
                text.chars().take(200).collect::<String>()
            ));
        }
    }

    /// The examples kept.
    pub fn examples(&self) -> BTreeMap<Outcome, Vec<String>> {
        self.examples
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .clone()
    }

    /// Records one call that started `since_start` into the soak.
    pub fn record(&self, since_start: Duration, took: Duration, outcome: Outcome) {
        let minute = since_start.as_secs() / 60;
        let mut minutes = self.minutes.lock().unwrap_or_else(|e| e.into_inner());
        let row = minutes.entry(minute).or_default();
        if outcome != Outcome::Lost {
            row.latencies_ms.push(took.as_secs_f64() * 1e3);
        }
        *row.outcomes.entry(outcome).or_default() += 1;
    }

    /// Each minute's calls.
    pub fn summary(&self) -> Vec<MinuteSummary> {
        let minutes = self.minutes.lock().unwrap_or_else(|e| e.into_inner());
        minutes
            .iter()
            .map(|(minute, row)| {
                let mut l = row.latencies_ms.clone();
                l.sort_by(f64::total_cmp);
                let pick = |p: f64| {
                    if l.is_empty() {
                        f64::NAN
                    } else {
                        l[((p / 100.0) * (l.len() - 1) as f64).round() as usize]
                    }
                };
                MinuteSummary {
                    minute: *minute,
                    calls: row.outcomes.values().sum(),
                    outcomes: row.outcomes.clone(),
                    p50_ms: pick(50.0),
                    p99_ms: pick(99.0),
                }
            })
            .collect()
    }

    /// Calls by outcome over the whole soak.
    pub fn totals(&self) -> BTreeMap<Outcome, u64> {
        let mut totals = BTreeMap::new();
        for minute in self.summary() {
            for (outcome, n) in minute.outcomes {
                *totals.entry(outcome).or_default() += n;
            }
        }
        totals
    }
}

/// When the pencil's moves succeeded: a robot stuck after a fault shows as a long gap.
#[derive(Debug, Default)]
pub struct MotionLog {
    ok_at_s: Mutex<Vec<f64>>,
    failed: std::sync::atomic::AtomicU64,
}

impl MotionLog {
    /// One motion that started `at_s` seconds into the soak, and whether it succeeded.
    pub fn record(&self, at_s: f64, ok: bool) {
        if ok {
            self.ok_at_s
                .lock()
                .unwrap_or_else(|e| e.into_inner())
                .push(at_s);
        } else {
            self.failed
                .fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        }
    }

    /// Motions that succeeded and failed.
    pub fn counts(&self) -> (u64, u64) {
        let ok = self.ok_at_s.lock().unwrap_or_else(|e| e.into_inner()).len();
        (
            ok as u64,
            self.failed.load(std::sync::atomic::Ordering::Relaxed),
        )
    }

    /// The longest stretch of `[0, end_s]` without a successful motion: (length, start), s.
    pub fn longest_gap_s(&self, end_s: f64) -> (f64, f64) {
        let mut times = self
            .ok_at_s
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .clone();
        times.sort_by(f64::total_cmp);
        let mut longest = (0.0, 0.0);
        let mut from = 0.0;
        for t in times.into_iter().chain([end_s]) {
            if t - from > longest.0 {
                longest = (t - from, from);
            }
            from = from.max(t);
        }
        longest
    }
}

/// Least-squares slope of `y` over `x` (per unit of x); NaN with fewer than two points.
pub fn slope(points: &[(f64, f64)]) -> f64 {
    let n = points.len() as f64;
    if points.len() < 2 {
        return f64::NAN;
    }
    let (mx, my) = points
        .iter()
        .fold((0.0, 0.0), |(a, b), (x, y)| (a + x / n, b + y / n));
    let (num, den) = points.iter().fold((0.0, 0.0), |(num, den), (x, y)| {
        (num + (x - mx) * (y - my), den + (x - mx).powi(2))
    });
    if den == 0.0 {
        f64::NAN
    } else {
        num / den
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn slope_of_a_line_and_replies_by_kind() {
        let line: Vec<(f64, f64)> = (0..10).map(|i| (i as f64, 3.0 + 0.5 * i as f64)).collect();
        assert!((slope(&line) - 0.5).abs() < 1e-9);
        assert!(slope(&line[..1]).is_nan());
        assert_eq!(Outcome::of_reply("✓ Done"), Outcome::Ok);
        assert_eq!(
            Outcome::of_reply(
                "❌ the gripper actor failed while handling the request; it was not retried"
            ),
            Outcome::InjectedFault
        );
        assert_eq!(Outcome::of_reply("❌ no pencil near"), Outcome::ToolError);
    }

    #[test]
    fn the_longest_stretch_without_a_motion_counts_the_start_and_the_end() {
        let log = MotionLog::default();
        assert_eq!(log.longest_gap_s(100.0), (100.0, 0.0));
        for (t, ok) in [(10.0, true), (20.0, false), (15.0, true), (70.0, true)] {
            log.record(t, ok);
        }
        assert_eq!(log.counts(), (3, 1));
        assert_eq!(log.longest_gap_s(100.0), (55.0, 15.0));
        assert_eq!(log.longest_gap_s(200.0), (130.0, 70.0));
    }
}
