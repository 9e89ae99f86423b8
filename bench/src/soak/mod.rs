//! `robotd bench soak --minutes N`: the service under a realistic mix for N minutes, watched
//! for leaks and for faults it does not recover from.
//!
//! It starts its own world ([`service`]): `robotd serve` on the simulator with the agent (on a
//! mock LLM speaking the OpenAI wire format), the Redis edge (on a redis-server of its own), a
//! simulated gripper that fails every 15th command (supervision restarts it) and a supervised
//! external actor process. The [`workload`] then runs until the time is up: MCP clients come
//! and go on SSE and streamable HTTP, one a second (one in ten leaves without closing its session),
//! each looking at the workspace, moving the pencil 1 cm and asking cheap questions; one
//! session stays for the whole run asking ten times a second; the agent gets a request every
//! 15 s; the external actor is killed every 40 s and Redis stopped for 5 s every minute.
//!
//! [`sampler`] reads the process every 5 s (RSS, descriptors, threads) and times every call.
//! **Pass** when, after the first third of the run (at least one minute) as warm-up:
//! - resident memory grows by at most [`rss_slope_limit`] (least-squares slope of the samples:
//!   2 MB/min for runs under 30 minutes, which can only catch a fast leak, and
//!   [`LONG_RUN_RSS_SLOPE_LIMIT_MB_PER_MIN`] for longer ones);
//! - descriptors and threads end within [`FD_DRIFT_LIMIT`] / [`THREAD_DRIFT_LIMIT`] of where
//!   they were after warm-up;
//! - every injected fault was recovered from (the actor back, Redis reconnected, no actor left
//!   down or out of restart budget);
//! - no call was lost (every call got exactly one answer, `✓` or `❌`), and none ran twice:
//!   the service's own count of the MCP tool calls it answered (`robotd_tool_calls_total`)
//!   matches the calls the clients sent, and no agent request got a second final answer;
//! - the robot never stayed stuck: no stretch of [`MOTION_GAP_LIMIT_S`] without one of the
//!   pencil's moves succeeding (an injected fault may fail a move, never all later ones).

mod sampler;
mod service;
mod workload;

use anyhow::{Context, Result};
use robotd_agent::mock::MockLlm;
use sampler::{slope, CallLog, Outcome, ProcessSample};
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::Path;
use std::sync::atomic::Ordering;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use workload::{AgentTally, InjectedFault, Workload};

/// Largest resident-memory growth after warm-up that a run of 30 minutes or more passes, MB
/// per minute (0.25 MB/min is 360 MB a day).
pub const LONG_RUN_RSS_SLOPE_LIMIT_MB_PER_MIN: f64 = 0.25;
/// The same for shorter runs, whose slope is mostly noise and warming caches.
pub const SHORT_RUN_RSS_SLOPE_LIMIT_MB_PER_MIN: f64 = 2.0;
/// Largest growth of open descriptors after warm-up that passes.
pub const FD_DRIFT_LIMIT: i64 = 16;

/// The RSS slope limit of a run of `minutes`.
pub fn rss_slope_limit(minutes: f64) -> f64 {
    if minutes >= 30.0 {
        LONG_RUN_RSS_SLOPE_LIMIT_MB_PER_MIN
    } else {
        SHORT_RUN_RSS_SLOPE_LIMIT_MB_PER_MIN
    }
}
/// Longest stretch without a successful move of the pencil that passes, seconds (a visitor
/// tries one a second; a quarter of them fail on the injected gripper faults).
pub const MOTION_GAP_LIMIT_S: f64 = 60.0;
/// Largest growth of threads after warm-up that passes.
pub const THREAD_DRIFT_LIMIT: i64 = 4;

/// One minute of the soak.
#[derive(Debug, Clone, Serialize)]
pub struct MinuteRow {
    /// Minute (0-based).
    pub minute: u64,
    /// Resident memory at the minute's last sample, MB.
    pub rss_mb: f64,
    /// Open descriptors at the minute's last sample.
    pub fds: usize,
    /// Threads at the minute's last sample.
    pub threads: usize,
    /// Actor restarts so far (all actors).
    pub restarts: u64,
    /// Tool calls this minute.
    pub calls: u64,
    /// Calls by outcome this minute.
    pub outcomes: BTreeMap<Outcome, u64>,
    /// Tool latency p50 / p99 this minute, ms.
    pub p50_ms: f64,
    /// See `p50_ms`.
    pub p99_ms: f64,
}

/// Everything the soak found.
#[derive(Debug, Clone, Serialize)]
pub struct SoakReport {
    /// Minutes run.
    pub minutes: f64,
    /// The table.
    pub per_minute: Vec<MinuteRow>,
    /// RSS slope after warm-up, MB per minute.
    pub rss_slope_mb_per_min: f64,
    /// The slope that passes for this run's length.
    pub rss_slope_limit_mb_per_min: f64,
    /// Samples (after warm-up) the slope is computed from.
    pub samples_after_warm_up: usize,
    /// Descriptors after warm-up and at the end.
    pub fds_after_warm_up: usize,
    /// See `fds_after_warm_up`.
    pub fds_at_end: usize,
    /// Threads after warm-up and at the end.
    pub threads_after_warm_up: usize,
    /// See `threads_after_warm_up`.
    pub threads_at_end: usize,
    /// Calls by outcome over the run.
    pub calls: BTreeMap<Outcome, u64>,
    /// Moves of the pencil that succeeded / failed.
    pub motions_ok: u64,
    /// See `motions_ok`.
    pub motions_failed: u64,
    /// The longest stretch without a successful move, and when it began, s.
    pub longest_motion_gap_s: f64,
    /// See `longest_motion_gap_s`.
    pub longest_motion_gap_from_s: f64,
    /// The first replies (or errors) of each kind but `ok`.
    pub examples: BTreeMap<Outcome, Vec<String>>,
    /// MCP sessions opened by visiting clients.
    pub sessions: u64,
    /// MCP tool calls the clients sent.
    pub tool_calls_sent: u64,
    /// MCP tool calls the service says it answered (`robotd_tool_calls_total`), when it could
    /// be read.
    pub tool_calls_served: Option<u64>,
    /// Agent requests that got a final event after their first.
    pub agent_answered_twice: u64,
    /// Agent requests sent / answered / failed.
    pub agent_sent: u64,
    /// See `agent_sent`.
    pub agent_answered: u64,
    /// See `agent_sent`.
    pub agent_failed: u64,
    /// Faults injected from outside and their recovery.
    pub faults: Vec<InjectedFault>,
    /// Actor restarts over the run (the gripper's injected failures, the killed actor).
    pub restarts: u64,
    /// Actors not running at the end, or out of restart budget.
    pub actors_down_at_end: Vec<String>,
    /// Descriptor kinds whose count changed between the end of warm-up and the end.
    pub fd_kind_changes: BTreeMap<String, i64>,
    /// Whether every check passed.
    pub passed: bool,
    /// The checks that failed, in words.
    pub failures: Vec<String>,
}

impl SoakReport {
    /// The per-minute table and the verdict.
    pub fn table(&self) -> String {
        let mut out = format!(
            "robotd bench soak: {:.1} min, {} sessions, agent {}/{} answered, {} restarts\n\
             min  rss MB   fds  thr  restarts  calls   ok  fault  tool-err  lost   p50 ms   p99 ms\n",
            self.minutes, self.sessions, self.agent_answered, self.agent_sent, self.restarts
        );
        for row in &self.per_minute {
            let n = |o: Outcome| row.outcomes.get(&o).copied().unwrap_or(0);
            out.push_str(&format!(
                "{:>3}  {:>6.1}  {:>4}  {:>3}  {:>8}  {:>5}  {:>4}  {:>5}  {:>8}  {:>4}  {:>7.1}  {:>7.1}\n",
                row.minute,
                row.rss_mb,
                row.fds,
                row.threads,
                row.restarts,
                row.calls,
                n(Outcome::Ok),
                n(Outcome::InjectedFault),
                n(Outcome::ToolError),
                n(Outcome::Lost),
                row.p50_ms,
                row.p99_ms
            ));
        }
        for (outcome, examples) in &self.examples {
            for example in examples {
                out.push_str(&format!("  e.g. {outcome:?}: {example}\n"));
            }
        }
        if !self.fd_kind_changes.is_empty() {
            out.push_str(&format!(
                "descriptor kinds changed after warm-up: {:?}\n",
                self.fd_kind_changes
            ));
        }
        let recovered = self
            .faults
            .iter()
            .filter(|f| f.recovered_after_s.is_some())
            .count();
        out.push_str(&format!(
            "tool calls sent {}, answered by the service {}; agent requests answered twice {}\n",
            self.tool_calls_sent,
            self.tool_calls_served
                .map_or("(unknown)".to_owned(), |n| n.to_string()),
            self.agent_answered_twice
        ));
        out.push_str(&format!(
            "moves of the pencil: {} ok, {} failed; longest stretch without one {:.0} s (from \
             {:.0} s; limit {MOTION_GAP_LIMIT_S:.0})\n",
            self.motions_ok,
            self.motions_failed,
            self.longest_motion_gap_s,
            self.longest_motion_gap_from_s
        ));
        out.push_str(&format!(
            "RSS slope after warm-up {:+.2} MB/min (limit {}); fds {} -> {}; \
             threads {} -> {}; injected faults recovered {}/{}\n{}\n",
            self.rss_slope_mb_per_min,
            self.rss_slope_limit_mb_per_min,
            self.fds_after_warm_up,
            self.fds_at_end,
            self.threads_after_warm_up,
            self.threads_at_end,
            recovered,
            self.faults.len(),
            if self.passed {
                "PASS".to_owned()
            } else {
                format!("FAIL: {}", self.failures.join("; "))
            }
        ));
        out
    }
}

/// Runs the soak for `minutes` with the robotd binary `exe`.
pub fn run(exe: &Path, minutes: f64) -> Result<SoakReport> {
    anyhow::ensure!(
        minutes.is_finite() && (2.0..=60.0 * 24.0 * 7.0).contains(&minutes),
        "--minutes must be 2 … 10080 (a shorter run is all start-up), got {minutes}"
    );
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()?;
    runtime.block_on(soak(exe, minutes))
}

async fn soak(exe: &Path, minutes: f64) -> Result<SoakReport> {
    // reqwest (health checks) and the MCP client need rustls's provider.
    robotd_runtime::telemetry::install_tls_provider();
    let dir = tempfile::tempdir().context("a temporary directory")?;
    let namespace = format!("soak-{}", std::process::id());
    let redis_port = service::free_port()?;
    let redis = Arc::new(Mutex::new(Some(service::start_redis(redis_port)?)));
    let mock = Arc::new(MockLlm::start(Vec::new()).await?);
    let port = service::free_port()?;
    let robotd = service::start_robotd(&service::ServiceSetup {
        exe,
        namespace: &namespace,
        port,
        redis_url: &format!("redis://127.0.0.1:{redis_port}/0"),
        llm_base_url: &mock.openai_base_url(),
        dir: dir.path(),
    })?;
    let pid = robotd.0.id();
    let start = Instant::now();
    let work = Arc::new(Workload {
        start,
        end: start + Duration::from_secs_f64(minutes * 60.0),
        port,
        calls: CallLog::default(),
        tool_calls_sent: Default::default(),
        sessions: Default::default(),
        motions: Default::default(),
    });
    let tally = Arc::new(AgentTally::default());
    let faults = Arc::new(Mutex::new(Vec::new()));
    let mut tasks = vec![
        tokio::spawn(work.clone().visiting_clients()),
        tokio::spawn(work.clone().resident_client()),
        tokio::spawn(workload::inject_faults(
            work.clone(),
            pid,
            redis_port,
            redis.clone(),
            faults.clone(),
        )),
    ];
    let agent = tokio::spawn(workload::agent_requests(
        work.clone(),
        namespace.clone(),
        mock.clone(),
        tally.clone(),
    ));
    // Sample until the end.
    let mut samples: Vec<(ProcessSample, u64)> = Vec::new();
    let warm_up = warm_up_s(minutes);
    let mut kinds_after_warm_up = None;
    while Instant::now() < work.end {
        let process = sampler::sample(pid, start.elapsed())?;
        if kinds_after_warm_up.is_none() && process.at_s >= warm_up {
            kinds_after_warm_up = Some(sampler::fd_kinds(pid));
        }
        let restarts = restarts(port).await.unwrap_or(0);
        samples.push((process, restarts));
        tokio::time::sleep(Duration::from_secs(5)).await;
    }
    for task in tasks.drain(..) {
        let _ = task.await;
    }
    if let Ok(Err(error)) = agent.await {
        tracing::warn!(%error, "the soak's agent client failed");
    }
    // Let the last restarts settle, then the final look.
    tokio::time::sleep(Duration::from_secs(2)).await;
    let end_sample = sampler::sample(pid, start.elapsed())?;
    let health = workload::health(port).await;
    let served = workload::tool_calls_served(port).await;
    samples.push((end_sample, restarts(port).await.unwrap_or(0)));
    let kinds_at_end = sampler::fd_kinds(pid);
    let mut fd_kind_changes = BTreeMap::new();
    if let Some(before) = kinds_after_warm_up {
        for kind in before.keys().chain(kinds_at_end.keys()) {
            let change = *kinds_at_end.get(kind).unwrap_or(&0) as i64
                - *before.get(kind).unwrap_or(&0) as i64;
            if change != 0 {
                fd_kind_changes.insert(kind.clone(), change);
            }
        }
    }
    drop(robotd);
    drop(redis);
    let injected = faults.lock().unwrap_or_else(|e| e.into_inner()).clone();
    let mut report = verdict(minutes, &samples, &work, &tally, injected, health, served);
    report.fd_kind_changes = fd_kind_changes;
    Ok(report)
}

/// Why the service's count of answered tool calls (`served`) does not fit the `sent` calls of
/// which `lost` got no answer: more answered than sent means a call ran twice; with nothing
/// lost, every call sent must have been answered exactly once.
fn served_count_problem(sent: u64, served: u64, lost: u64) -> Option<String> {
    if served > sent {
        Some(format!(
            "the service answered {served} tool calls but only {sent} were sent: {} ran twice",
            served - sent
        ))
    } else if lost == 0 && served != sent {
        Some(format!(
            "{sent} tool calls were sent and all answered, but the service counted {served}"
        ))
    } else {
        None
    }
}

/// Seconds of warm-up: the first third of the run, at least a minute, at most half of it.
fn warm_up_s(minutes: f64) -> f64 {
    (minutes * 60.0 / 3.0).max(60.0).min(minutes * 60.0 / 2.0)
}

async fn restarts(port: u16) -> Option<u64> {
    let health = workload::health(port).await?;
    Some(
        health["actors"]
            .as_array()?
            .iter()
            .map(|a| a["restarts"].as_u64().unwrap_or(0))
            .sum(),
    )
}

fn verdict(
    minutes: f64,
    samples: &[(ProcessSample, u64)],
    work: &Workload,
    tally: &AgentTally,
    faults: Vec<InjectedFault>,
    health: Option<serde_json::Value>,
    served: Option<u64>,
) -> SoakReport {
    let warm_up_s = warm_up_s(minutes);
    let after: Vec<&(ProcessSample, u64)> = samples
        .iter()
        .filter(|(s, _)| s.at_s >= warm_up_s)
        .collect();
    let points: Vec<(f64, f64)> = after
        .iter()
        .map(|(s, _)| (s.at_s / 60.0, s.rss_mb))
        .collect();
    let rss_slope = slope(&points);
    let first = after.first().map(|(s, _)| *s);
    let last = samples.last().map(|(s, _)| *s);
    let calls = work.calls.totals();
    let summary = work.calls.summary();
    let per_minute = summary
        .iter()
        .map(|m| {
            let at = samples
                .iter()
                .rfind(|(s, _)| (s.at_s / 60.0) < (m.minute + 1) as f64)
                .or(samples.last());
            MinuteRow {
                minute: m.minute,
                rss_mb: at.map_or(f64::NAN, |(s, _)| s.rss_mb),
                fds: at.map_or(0, |(s, _)| s.fds),
                threads: at.map_or(0, |(s, _)| s.threads),
                restarts: at.map_or(0, |(_, r)| *r),
                calls: m.calls,
                outcomes: m.outcomes.clone(),
                p50_ms: m.p50_ms,
                p99_ms: m.p99_ms,
            }
        })
        .collect();
    let mut actors_down = Vec::new();
    match &health {
        Some(h) => {
            for actor in h["actors"].as_array().cloned().unwrap_or_default() {
                if actor["state"] != "running" {
                    actors_down.push(format!(
                        "{} ({})",
                        actor["actor"].as_str().unwrap_or("?"),
                        actor["state"]
                    ));
                }
            }
        }
        None => actors_down.push("robotd did not answer /health at the end".into()),
    }
    let mut failures = Vec::new();
    let limit = rss_slope_limit(minutes);
    if rss_slope.is_nan() || rss_slope > limit {
        failures.push(format!(
            "RSS grew {rss_slope:+.2} MB/min after warm-up (limit {limit})"
        ));
    }
    let (fds_w, fds_e, thr_w, thr_e) = match (first, last) {
        (Some(f), Some(l)) => (f.fds, l.fds, f.threads, l.threads),
        _ => (0, 0, 0, 0),
    };
    if fds_e as i64 - fds_w as i64 > FD_DRIFT_LIMIT {
        failures.push(format!("descriptors grew {fds_w} -> {fds_e}"));
    }
    if thr_e as i64 - thr_w as i64 > THREAD_DRIFT_LIMIT {
        failures.push(format!("threads grew {thr_w} -> {thr_e}"));
    }
    for fault in &faults {
        if fault.recovered_after_s.is_none() {
            failures.push(format!(
                "not recovered from '{}' at {:.0} s",
                fault.what, fault.at_s
            ));
        }
    }
    if !actors_down.is_empty() {
        failures.push(format!(
            "actors down at the end: {}",
            actors_down.join(", ")
        ));
    }
    let lost = calls.get(&Outcome::Lost).copied().unwrap_or(0);
    if lost > 0 {
        failures.push(format!("{lost} calls got no answer"));
    }
    let calls_sent = work.tool_calls_sent.load(Ordering::Relaxed);
    match served {
        Some(served) => failures.extend(served_count_problem(calls_sent, served, lost)),
        None => failures.push("the service's count of tool calls could not be read".into()),
    }
    let answered_twice = tally.answered_twice.load(Ordering::Relaxed);
    if answered_twice > 0 {
        failures.push(format!(
            "{answered_twice} agent requests got a second final answer"
        ));
    }
    let (sent, answered, agent_failed) = (
        tally.sent.load(Ordering::Relaxed),
        tally.answered.load(Ordering::Relaxed),
        tally.failed.load(Ordering::Relaxed),
    );
    if sent > 0 && answered == 0 {
        failures.push("the agent answered no request".into());
    }
    let (motions_ok, motions_failed) = work.motions.counts();
    let run_s = work.start.elapsed().as_secs_f64().min(minutes * 60.0);
    let (gap_s, gap_from_s) = work.motions.longest_gap_s(run_s);
    if gap_s > MOTION_GAP_LIMIT_S {
        failures.push(format!(
            "no move of the pencil succeeded for {gap_s:.0} s from {gap_from_s:.0} s into the \
             run: the robot was stuck (limit {MOTION_GAP_LIMIT_S:.0} s)"
        ));
    }
    let restarts = samples.last().map_or(0, |(_, r)| *r);
    SoakReport {
        minutes,
        per_minute,
        rss_slope_mb_per_min: rss_slope,
        rss_slope_limit_mb_per_min: limit,
        samples_after_warm_up: points.len(),
        fds_after_warm_up: fds_w,
        fds_at_end: fds_e,
        threads_after_warm_up: thr_w,
        threads_at_end: thr_e,
        calls,
        motions_ok,
        motions_failed,
        longest_motion_gap_s: gap_s,
        longest_motion_gap_from_s: gap_from_s,
        examples: work.calls.examples(),
        sessions: work.sessions.load(Ordering::Relaxed),
        tool_calls_sent: calls_sent,
        tool_calls_served: served,
        agent_answered_twice: answered_twice,
        agent_sent: sent,
        agent_answered: answered,
        agent_failed,
        faults,
        restarts,
        actors_down_at_end: actors_down,
        fd_kind_changes: BTreeMap::new(),
        passed: failures.is_empty(),
        failures,
    }
}

#[cfg(test)]
mod tests {
    use super::served_count_problem;

    #[test]
    fn a_call_served_twice_or_never_fails_the_run() {
        assert_eq!(served_count_problem(100, 100, 0), None);
        // Lost calls may or may not have run on the service.
        assert_eq!(served_count_problem(100, 98, 3), None);
        let twice = served_count_problem(100, 101, 0).unwrap();
        assert!(twice.contains("1 ran twice"), "{twice}");
        assert!(served_count_problem(100, 101, 5).is_some());
        let missing = served_count_problem(100, 99, 0).unwrap();
        assert!(missing.contains("counted 99"), "{missing}");
    }
}
