//! robotd and systemd: readiness, status, the watchdog and shutdown, over `sd_notify`.
//!
//! Run by systemd as a `Type=notify` service (packaging/robotd.service), `robotd serve` finds
//! `NOTIFY_SOCKET` in its environment and tells systemd, one datagram at a time:
//!
//! - `READY=1` once the HTTP edge is bound and the robot is connected or known to be absent
//!   (the hardware actors have started and the driver has answered whether its link is up):
//!   `systemctl start robotd` returns then, and units ordered after robotd start;
//! - `STATUS=…`, one line that `systemctl status robotd` shows, saying what robotd waits for
//!   (the robot not connected, the e-stop engaged, an actor degraded, the disk nearly full)
//!   or that all is well;
//!   checked every second and sent when it changes;
//! - `WATCHDOG=1` at half of `WATCHDOG_USEC` (systemd sets it from `WatchdogSec=`), sent by
//!   the supervision loops themselves through the runtime's watchdog
//!   (`robotd_runtime::supervision::watchdog`): when one of them hangs the pings stop, and
//!   systemd kills and restarts robotd;
//! - `STOPPING=1` when a shutdown begins.
//!
//! Without `NOTIFY_SOCKET` (run by hand, in a container, in tests) every call here does
//! nothing; a failed send is logged, never fatal. Actor processes robotd starts do not inherit
//! the variables: the unit's `NotifyAccess=main` would ignore them anyway.

use std::time::Duration;

use robotd_http::HealthSource;
use sd_notify::NotifyState;

/// The environment variables of the protocol, removed from actor processes' environments.
pub const NOTIFY_VARS: [&str; 3] = ["NOTIFY_SOCKET", "WATCHDOG_USEC", "WATCHDOG_PID"];

/// How often the status line is recomputed.
const STATUS_EVERY: Duration = Duration::from_secs(1);

/// Whether a service manager listens (`NOTIFY_SOCKET` is set).
pub fn enabled() -> bool {
    std::env::var_os("NOTIFY_SOCKET").is_some_and(|socket| !socket.is_empty())
}

fn send(states: &[NotifyState<'_>]) {
    if !enabled() {
        return;
    }
    if let Err(error) = sd_notify::notify(states) {
        tracing::warn!(%error, "telling systemd (NOTIFY_SOCKET)");
    }
}

/// When systemd asks for a watchdog (`WATCHDOG_USEC`, for this process), installs the
/// runtime's supervision watchdog at half that period, pinging `WATCHDOG=1`. Must run before
/// the first supervisor starts. Returns the ping interval.
pub fn install_watchdog() -> Option<Duration> {
    if !enabled() {
        return None;
    }
    let period = sd_notify::watchdog_enabled()?;
    let interval = period / 2;
    match robotd_runtime::supervision::watchdog::install(interval, || {
        send(&[NotifyState::Watchdog])
    }) {
        Ok(()) => {
            tracing::info!(
                ?period,
                ?interval,
                "systemd watchdog: the supervision loops ping it"
            );
            Some(interval)
        }
        Err(error) => {
            tracing::warn!(%error, "systemd watchdog");
            None
        }
    }
}

/// `READY=1` with the first status line.
pub fn ready(status: &str) {
    send(&[NotifyState::Ready, NotifyState::Status(status)]);
}

/// `STOPPING=1`: the shutdown has begun.
pub fn stopping() {
    send(&[NotifyState::Stopping, NotifyState::Status("shutting down")]);
}

/// Keeps systemd's status line current from the health report until the task is aborted.
pub fn spawn_status_updates(
    health: HealthSource,
    address: String,
    first: String,
) -> Option<tokio::task::JoinHandle<()>> {
    if !enabled() {
        return None;
    }
    Some(tokio::spawn(async move {
        let mut last = first;
        let mut every = tokio::time::interval(STATUS_EVERY);
        every.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
        loop {
            every.tick().await;
            let report = health();
            let line = status_line(&report, &address);
            if line != last {
                send(&[NotifyState::Status(&line)]);
                last = line;
            }
        }
    }))
}

/// The status line for a `/health` report: what robotd waits for, or that it serves.
pub fn status_line(report: &serde_json::Value, address: &str) -> String {
    let mut waiting = Vec::new();
    if report["robot"]["connected"] == false {
        let reason = report["robot"]["reason"]
            .as_str()
            .unwrap_or("robot not connected");
        waiting.push(one_line(reason));
    }
    if report["safety"]["estop"]["engaged"] == true {
        let reason = report["safety"]["estop"]["reason"]
            .as_str()
            .unwrap_or("no reason given");
        waiting.push(format!(
            "e-stop engaged ({}): motions refused until released",
            one_line(reason)
        ));
    }
    let degraded: Vec<String> = report["actors"]
        .as_array()
        .into_iter()
        .flatten()
        .filter(|actor| actor["state"] != "running")
        .map(|actor| {
            format!(
                "{} {}",
                actor["actor"].as_str().unwrap_or("?"),
                actor["state"].as_str().unwrap_or("?")
            )
        })
        .collect();
    if !degraded.is_empty() {
        waiting.push(format!("degraded actor: {}", degraded.join(", ")));
    }
    if report["disk"]["low"] == true {
        let reason = report["disk"]["reason"].as_str().unwrap_or("");
        waiting.push(format!("disk low: {}", one_line(reason)));
    }
    if waiting.is_empty() {
        format!(
            "serving on http://{address}; robot {} connected",
            report["robot"]["model"].as_str().unwrap_or("")
        )
    } else {
        format!(
            "serving on http://{address}; waiting: {}",
            waiting.join("; ")
        )
    }
}

/// A reason on one line, at most 200 characters (systemd shows one line).
fn one_line(text: &str) -> String {
    let flat: String = text
        .chars()
        .map(|c| if c.is_control() { ' ' } else { c })
        .collect();
    match flat.char_indices().nth(200) {
        Some((cut, _)) => format!("{}…", &flat[..cut]),
        None => flat,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    fn report() -> serde_json::Value {
        json!({
            "robot": {"connected": true, "model": "Niryo Ned2"},
            "safety": {"estop": {"engaged": false, "reason": null}},
            "actors": [{"actor": "arm", "state": "running"}, {"actor": "tts", "state": "running"}],
        })
    }

    #[test]
    fn all_well_says_where_it_serves() {
        assert_eq!(
            status_line(&report(), "127.0.0.1:8000"),
            "serving on http://127.0.0.1:8000; robot Niryo Ned2 connected"
        );
    }

    #[test]
    fn says_what_it_waits_for() {
        let mut report = report();
        report["robot"]["connected"] = false.into();
        report["robot"]["reason"] = "robot not connected: 10.10.10.10:40001 refused".into();
        report["safety"]["estop"] = json!({"engaged": true, "reason": "operator\npressed"});
        report["actors"][1]["state"] = "restarting".into();
        report["disk"] = json!({"low": true, "reason": "log /var/log/robotd has 100.0 MiB free"});
        assert_eq!(
            status_line(&report, "0.0.0.0:8000"),
            "serving on http://0.0.0.0:8000; waiting: robot not connected: 10.10.10.10:40001 \
             refused; e-stop engaged (operator pressed): motions refused until released; \
             degraded actor: tts restarting; disk low: log /var/log/robotd has 100.0 MiB free"
        );
    }

    #[test]
    fn a_long_reason_is_cut() {
        let line = one_line(&"x".repeat(500));
        assert_eq!(line.chars().count(), 201);
    }
}
