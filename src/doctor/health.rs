//! `redis-edge`: how a robotd that is already running sees its Redis edge.
//!
//! The `redis` row says whether Redis can be reached from here and now; a running service may
//! have been started with other settings, or lost its connection since. Its `/health` (on
//! `http.bind`) reports the edge's state, target, trust and per-stream counters, so this row
//! reads it and summarises. No robotd answering is not a problem — the doctor is usually run
//! before starting one.
//!
//! `/health` is fetched with reqwest (blocking), which speaks real HTTP/1.1: chunked bodies,
//! keep-alive and redirects are its business, not the doctor's. A bind address of "any"
//! (`0.0.0.0`, `[::]`) is asked on loopback, proxies from the environment are not used (the
//! service is on this machine), and the request is bounded by [`NET_TIMEOUT`] to connect and
//! twice that in all.

use super::{Check, NET_TIMEOUT};
use serde_json::Value;
use std::io::Read;
use std::net::{IpAddr, Ipv4Addr, Ipv6Addr, SocketAddr};

/// The largest `/health` body read (a real one is a few kilobytes).
const MAX_BODY: u64 = 1 << 20;

/// The Redis edge of a robotd serving on `bind`, from its `/health`.
pub(super) fn check_redis_edge(bind: Option<&str>) -> Check {
    const NAME: &str = "redis-edge";
    let Some(bind) = bind else {
        return Check::ok(NAME, "no HTTP address configured; nothing to ask");
    };
    let health = match fetch_health(bind) {
        Ok(health) => health,
        Err(_) => {
            return Check::ok(
                NAME,
                format!("no robotd answers on {bind}; start it to see its Redis edge here"),
            )
        }
    };
    let redis = &health["redis"];
    let state = redis["state"].as_str().unwrap_or("off");
    let target = redis["target"].as_str().unwrap_or("?");
    let sum = |prefix: &str| -> u64 {
        redis["streams"]
            .as_object()
            .map(|streams| {
                streams
                    .values()
                    .filter_map(|counts| counts.as_object())
                    .flat_map(|counts| counts.iter())
                    .filter(|(k, _)| k.starts_with(prefix))
                    .filter_map(|(_, v)| v.as_u64())
                    .sum()
            })
            .unwrap_or(0)
    };
    let counts = format!(
        "{} entries published, {} dropped, {} consumed, {} skipped as bad",
        sum("published"),
        sum("dropped_"),
        sum("consumed"),
        sum("skipped_")
    );
    match state {
        "connected" => Check::ok(
            NAME,
            format!(
                "the robotd on {bind} is connected to {target} (trust {}; {counts})",
                redis["trust"].as_str().unwrap_or("?")
            ),
        ),
        "off" => Check::ok(
            NAME,
            format!("the robotd on {bind} runs without a Redis edge"),
        ),
        _ => Check::problem(
            NAME,
            format!(
                "the robotd on {bind} cannot reach {target} ({state}: {}); {counts}",
                redis["last_error"].as_str().unwrap_or("no error recorded")
            ),
            "start redis-server or correct the URL; robotd reconnects by itself within a second",
        ),
    }
}

/// Where to ask a robotd bound to `bind`: "any" addresses become loopback.
fn health_url(bind: &str) -> String {
    let host = match bind.parse::<SocketAddr>() {
        Ok(addr) if addr.ip().is_unspecified() => {
            let loopback = match addr.ip() {
                IpAddr::V4(_) => IpAddr::V4(Ipv4Addr::LOCALHOST),
                IpAddr::V6(_) => IpAddr::V6(Ipv6Addr::LOCALHOST),
            };
            SocketAddr::new(loopback, addr.port()).to_string()
        }
        _ => bind.trim().to_owned(),
    };
    format!("http://{host}/health")
}

/// `GET /health` of the robotd serving on `bind`, as JSON; bounded by the timeouts.
fn fetch_health(bind: &str) -> Result<Value, String> {
    // reqwest's rustls client (built even for http://) needs robotd's crypto provider.
    robotd_runtime::telemetry::install_tls_provider();
    let client = reqwest::blocking::Client::builder()
        .connect_timeout(NET_TIMEOUT)
        .timeout(2 * NET_TIMEOUT)
        .no_proxy()
        .build()
        .map_err(|e| format!("no HTTP client: {e}"))?;
    let response = client
        .get(health_url(bind))
        .send()
        .and_then(|r| r.error_for_status())
        .map_err(|e| e.to_string())?;
    let mut body = Vec::new();
    response
        .take(MAX_BODY)
        .read_to_end(&mut body)
        .map_err(|e| format!("reading /health: {e}"))?;
    serde_json::from_slice(&body).map_err(|e| format!("/health is not JSON: {e}"))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::doctor::report::Status;
    use crate::doctor::test_support::free_port;
    use serde_json::json;
    use std::io::Write;
    use std::net::{TcpListener, TcpStream};
    use std::sync::{Arc, Mutex};
    use std::time::{Duration, Instant};

    /// A stand-in robotd: axum serving `/health` with whatever `health` holds, as a chunked
    /// body (a stream of pieces, no Content-Length), the way a streaming server answers.
    struct FakeRobotd {
        bind: String,
        health: Arc<Mutex<Value>>,
        stop: Option<tokio::sync::oneshot::Sender<()>>,
        thread: Option<std::thread::JoinHandle<()>>,
    }

    impl FakeRobotd {
        fn start(health: Value) -> Self {
            let health = Arc::new(Mutex::new(health));
            let shared = health.clone();
            let listener = TcpListener::bind("127.0.0.1:0").expect("bind");
            listener.set_nonblocking(true).expect("nonblocking");
            let bind = listener.local_addr().expect("addr").to_string();
            let (stop, stopped) = tokio::sync::oneshot::channel::<()>();
            let thread = std::thread::spawn(move || {
                let runtime = tokio::runtime::Builder::new_current_thread()
                    .enable_all()
                    .build()
                    .expect("runtime");
                runtime.block_on(async move {
                    let app = axum::Router::new().route(
                        "/health",
                        axum::routing::get(move || {
                            let text = shared.lock().expect("health").to_string();
                            async move {
                                // Three pieces, each sent as its own chunk.
                                let third = text.len() / 3;
                                let pieces = vec![
                                    text[..third].to_owned(),
                                    text[third..2 * third].to_owned(),
                                    text[2 * third..].to_owned(),
                                ];
                                let stream = futures::stream::iter(
                                    pieces.into_iter().map(Ok::<_, std::convert::Infallible>),
                                );
                                (
                                    [("content-type", "application/json")],
                                    axum::body::Body::from_stream(stream),
                                )
                            }
                        }),
                    );
                    let listener =
                        tokio::net::TcpListener::from_std(listener).expect("tokio listener");
                    axum::serve(listener, app)
                        .with_graceful_shutdown(async {
                            let _ = stopped.await;
                        })
                        .await
                        .expect("serve");
                });
            });
            FakeRobotd {
                bind,
                health,
                stop: Some(stop),
                thread: Some(thread),
            }
        }

        fn set(&self, health: Value) {
            *self.health.lock().expect("health") = health;
        }
    }

    impl Drop for FakeRobotd {
        fn drop(&mut self) {
            if let Some(stop) = self.stop.take() {
                let _ = stop.send(());
            }
            if let Some(thread) = self.thread.take() {
                let _ = thread.join();
            }
        }
    }

    /// The response head of `GET /health` read by hand, to see how the body is framed.
    fn raw_head(bind: &str) -> String {
        let mut stream = TcpStream::connect(bind).expect("connect");
        stream
            .set_read_timeout(Some(Duration::from_secs(2)))
            .expect("timeout");
        write!(
            stream,
            "GET /health HTTP/1.1\r\nHost: {bind}\r\nConnection: close\r\n\r\n"
        )
        .expect("send");
        let mut response = String::new();
        let _ = stream.read_to_string(&mut response);
        response
            .split_once("\r\n\r\n")
            .map(|(head, _)| head.to_ascii_lowercase())
            .unwrap_or_default()
    }

    #[test]
    fn chunked_health_is_read_and_summarised() {
        let server = FakeRobotd::start(json!({
            "status": "ok",
            "redis": {
                "state": "connected",
                "target": "redis://127.0.0.1:6379/0",
                "trust": "both",
                "streams": {
                    "robot_camera": {"published": 40, "dropped_queue_full": 2},
                    "detected_objects": {"published": 2, "consumed": 5, "skipped_bad_entry": 1},
                },
            },
        }));
        // The test means something only if the body really is chunked.
        let head = raw_head(&server.bind);
        assert!(head.contains("transfer-encoding: chunked"), "{head}");
        assert!(!head.contains("content-length"), "{head}");

        let check = check_redis_edge(Some(&server.bind));
        assert_eq!(check.status, Status::Ok, "{check:?}");
        assert!(
            check
                .found
                .contains("is connected to redis://127.0.0.1:6379/0 (trust both"),
            "{}",
            check.found
        );
        assert!(
            check
                .found
                .contains("42 entries published, 2 dropped, 5 consumed, 1 skipped as bad"),
            "{}",
            check.found
        );

        server.set(json!({"redis": {
            "state": "down",
            "target": "redis://10.9.9.9:6379/0",
            "last_error": "Connection refused",
            "streams": {},
        }}));
        let check = check_redis_edge(Some(&server.bind));
        assert_eq!(check.status, Status::Problem, "{check:?}");
        assert!(
            check
                .found
                .contains("cannot reach redis://10.9.9.9:6379/0 (down: Connection refused)"),
            "{}",
            check.found
        );
        assert!(check.fix.unwrap_or_default().contains("redis-server"));

        server.set(json!({"status": "ok", "redis": null}));
        let check = check_redis_edge(Some(&server.bind));
        assert_eq!(check.status, Status::Ok, "{check:?}");
        assert!(
            check.found.contains("runs without a Redis edge"),
            "{}",
            check.found
        );
    }

    #[test]
    fn no_robotd_or_no_address_is_ok() {
        let check = check_redis_edge(None);
        assert_eq!(check.status, Status::Ok);
        assert!(check.found.contains("no HTTP address"), "{}", check.found);

        let bind = format!("127.0.0.1:{}", free_port());
        let check = check_redis_edge(Some(&bind));
        assert_eq!(check.status, Status::Ok, "{check:?}");
        assert!(check.found.contains("no robotd answers"), "{}", check.found);
    }

    #[test]
    fn silent_http_server_is_bounded() {
        let listener = TcpListener::bind("127.0.0.1:0").expect("bind");
        let bind = listener.local_addr().expect("addr").to_string();
        let holder = std::thread::spawn(move || {
            let conn = listener.accept();
            std::thread::sleep(Duration::from_secs(2));
            drop(conn);
        });
        let start = Instant::now();
        let check = check_redis_edge(Some(&bind));
        assert!(check.found.contains("no robotd answers"), "{}", check.found);
        assert!(
            start.elapsed() < Duration::from_millis(1500),
            "{:?}",
            start.elapsed()
        );
        let _ = holder.join();
    }

    #[test]
    fn any_address_is_asked_on_loopback() {
        assert_eq!(health_url("0.0.0.0:8000"), "http://127.0.0.1:8000/health");
        assert_eq!(health_url("[::]:8000"), "http://[::1]:8000/health");
        assert_eq!(health_url("10.0.0.2:80"), "http://10.0.0.2:80/health");
        assert_eq!(health_url("localhost:80"), "http://localhost:80/health");
    }
}
