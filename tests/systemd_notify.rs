//! robotd speaks systemd's notification protocol: this test plays systemd. It binds a Unix
//! datagram socket, starts `robotd serve` with `NOTIFY_SOCKET` pointing at it and
//! `WATCHDOG_USEC` set, and checks what arrives: `READY=1` with a status line once the port
//! serves, a `STATUS=` line when the e-stop is engaged, `WATCHDOG=1` at half the watchdog
//! period, no more pings once a supervision loop hangs (the test hook behind SIGUSR1, in debug
//! builds with `TEST_ROBOTD_HOOKS=1` only) while `/health` still answers, and `STOPPING=1` on
//! SIGTERM.

mod common;

use std::os::unix::net::UnixDatagram;
use std::sync::mpsc;
use std::time::{Duration, Instant};

/// systemd's `WatchdogSec=`, as the environment variable it sets (µs): 1 s, so pings every
/// 500 ms.
const WATCHDOG_USEC: u64 = 1_000_000;
const PING_EVERY: Duration = Duration::from_millis(500);

/// Every datagram robotd sends, with its time of arrival.
fn listen(socket: UnixDatagram) -> mpsc::Receiver<(Instant, String)> {
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        let mut buffer = vec![0u8; 4096];
        while let Ok(n) = socket.recv(&mut buffer) {
            let text = String::from_utf8_lossy(&buffer[..n]).into_owned();
            if tx.send((Instant::now(), text)).is_err() {
                return;
            }
        }
    });
    rx
}

/// Waits up to `limit` for a datagram with a line equal to `line` (or starting with it, for a
/// `STATUS=` prefix); returns that datagram.
fn until(rx: &mpsc::Receiver<(Instant, String)>, prefix: &str, limit: Duration) -> String {
    let deadline = Instant::now() + limit;
    let mut seen = Vec::new();
    while let Some(left) = deadline.checked_duration_since(Instant::now()) {
        match rx.recv_timeout(left) {
            Ok((_, text)) if text.lines().any(|l| l.starts_with(prefix)) => return text,
            Ok((_, text)) => seen.push(text),
            Err(_) => break,
        }
    }
    panic!("no '{prefix}' within {limit:?}; got {seen:?}");
}

/// The arrival times of the next `count` watchdog pings.
fn pings(rx: &mpsc::Receiver<(Instant, String)>, count: usize) -> Vec<Instant> {
    let mut times = Vec::new();
    while times.len() < count {
        let (at, text) = rx
            .recv_timeout(PING_EVERY * 6)
            .expect("a watchdog ping within three periods");
        if text.lines().any(|l| l == "WATCHDOG=1") {
            times.push(at);
        }
    }
    times
}

#[test]
fn robotd_tells_systemd_it_is_ready_what_it_waits_for_that_it_lives_and_that_it_stops() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("notify.sock");
    let socket = UnixDatagram::bind(&path).unwrap();
    let rx = listen(socket);
    let namespace = common::fresh_namespace("notify");
    let port = common::free_port();
    let robotd = common::start_robotd_with_env(
        &namespace,
        port,
        &[],
        &[
            ("NOTIFY_SOCKET", path.to_str().unwrap()),
            ("WATCHDOG_USEC", &WATCHDOG_USEC.to_string()),
            ("TEST_ROBOTD_HOOKS", "1"),
        ],
    );

    // Ready, with what it is doing, once the port serves and the robot is there.
    let ready = until(&rx, "READY=1", Duration::from_secs(10));
    assert!(
        ready.contains(&format!(
            "STATUS=serving on http://127.0.0.1:{port}; robot "
        )),
        "{ready:?}"
    );
    let (status, _) = common::http_get(port, "/health");
    assert_eq!(status, 200);

    // The pings come at half the watchdog period, from the supervision loops.
    let times = pings(&rx, 6);
    let gaps: Vec<Duration> = times.windows(2).map(|w| w[1] - w[0]).collect();
    let mean = (times[5] - times[0]) / 5;
    assert!(
        mean >= PING_EVERY * 8 / 10 && mean <= PING_EVERY * 2,
        "mean gap {mean:?} for a ping every {PING_EVERY:?}: {gaps:?}"
    );
    assert!(gaps.iter().all(|gap| *gap >= PING_EVERY / 2), "{gaps:?}");

    // The e-stop engaged: the status line says what robotd waits for.
    let (status, body) = common::http_request(
        port,
        "POST",
        "/estop",
        &[("Content-Type", "application/json")],
        br#"{"reason": "notify test"}"#,
    );
    assert_eq!(status, 200, "{body}");
    let line = until(&rx, "STATUS=", Duration::from_secs(10));
    assert!(
        line.contains("waiting: e-stop engaged (notify test): motions refused until released"),
        "{line:?}"
    );

    // One supervision loop hangs (test hook): the pings stop, the HTTP edge still serves.
    let kill = std::process::Command::new("kill")
        .args(["-USR1", &robotd.pid().to_string()])
        .status()
        .unwrap();
    assert!(kill.success());
    // At most the round already under way completes after the hang.
    let mut after = Vec::new();
    let quiet_from = Instant::now();
    while let Ok((at, text)) = rx.recv_timeout(PING_EVERY * 6) {
        if text.lines().any(|l| l == "WATCHDOG=1") {
            after.push(at - quiet_from);
        }
        assert!(
            after.len() <= 2,
            "pings went on after a loop hung: {after:?}"
        );
    }
    let (status, _) = common::http_get(port, "/health");
    assert_eq!(status, 200, "the rest of robotd still serves");

    // SIGTERM: robotd says it stops.
    let term = std::process::Command::new("kill")
        .args(["-TERM", &robotd.pid().to_string()])
        .status()
        .unwrap();
    assert!(term.success());
    until(&rx, "STOPPING=1", Duration::from_secs(10));
    drop(robotd);
}
