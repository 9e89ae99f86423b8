//! The dashboard's HTTP/JSON API refuses what it cannot serve with a status and a JSON
//! `{"error": …}` a script can act on: malformed chat requests, over-long ones, and any chat
//! or cancel while no LLM is configured (the page shows the same reason). The rate history a
//! page plots when it opens, and a camera view encoded only while someone watches.

mod common;

use serde_json::Value;
use std::io::{Read, Write};
use std::time::{Duration, Instant};

/// An open `/api/camera.mjpg` stream, read (and thrown away) on a thread of its own, as a
/// browser's `<img>` would; it closes when dropped.
struct CameraViewer(std::net::TcpStream);

impl CameraViewer {
    fn open(port: u16) -> Self {
        let mut stream = std::net::TcpStream::connect(("127.0.0.1", port)).expect("connect");
        let request = format!("GET /api/camera.mjpg HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\n\r\n");
        stream.write_all(request.as_bytes()).expect("send");
        let mut reader = stream.try_clone().expect("clone");
        std::thread::spawn(move || {
            let mut buffer = [0u8; 64 * 1024];
            while matches!(reader.read(&mut buffer), Ok(n) if n > 0) {}
        });
        CameraViewer(stream)
    }
}

impl Drop for CameraViewer {
    fn drop(&mut self) {
        let _ = self.0.shutdown(std::net::Shutdown::Both);
    }
}

/// `/api/status`'s camera figures.
fn camera_figures(port: u16) -> Value {
    let (status, body) = common::http_get(port, "/api/status");
    assert_eq!(status, 200, "{body}");
    let status: Value = serde_json::from_str(&body).unwrap();
    status["camera"].clone()
}

fn error_of(body: &str) -> String {
    let value: Value =
        serde_json::from_str(body).unwrap_or_else(|e| panic!("not JSON ({e}): {body}"));
    value["error"]
        .as_str()
        .unwrap_or_else(|| panic!("no \"error\" text: {body}"))
        .to_owned()
}

#[test]
fn chat_requests_it_cannot_serve_get_clear_errors() {
    let namespace = common::fresh_namespace("dashapi");
    let port = common::free_port();
    // No provider: the agent is off (keys cleared so the machine's own cannot turn it on).
    let no_keys = [
        ("OPENAI_API_KEY", ""),
        ("GROQ_API_KEY", ""),
        ("GEMINI_API_KEY", ""),
        ("API_KEY", ""),
        ("LLM_API_KEY", ""),
    ];
    let _robotd = common::start_robotd_with_env(&namespace, port, &[], &no_keys);
    let json = [("Content-Type", "application/json")];
    let chat = |body: &[u8]| common::http_request(port, "POST", "/api/chat", &json, body);

    let (status, body) = chat(b"{not json");
    assert_eq!(status, 400, "{body}");
    assert!(error_of(&body).contains("must be JSON"), "{body}");
    for empty in [&br#"{"text": "   "}"#[..], br#"{"text": 7}"#, br#"{}"#] {
        let (status, body) = chat(empty);
        assert_eq!(status, 400, "{body}");
        assert!(error_of(&body).contains("non-empty string"), "{body}");
    }
    let long = format!(r#"{{"text": "{}"}}"#, "a".repeat(4001));
    let (status, body) = chat(long.as_bytes());
    assert_eq!(status, 413, "{body}");
    assert!(error_of(&body).contains("4000 characters"), "{body}");

    let (status, body) = chat(br#"{"text": "pick up the pencil"}"#);
    assert_eq!(status, 503, "{body}");
    let reason = error_of(&body);
    assert!(reason.contains("no LLM agent is running"), "{reason}");
    assert!(
        reason.contains("OPENAI_API_KEY"),
        "says how to configure one: {reason}"
    );
    let (status, body) = common::http_request(port, "POST", "/api/chat/x-1/cancel", &json, b"");
    assert_eq!(status, 503, "{body}");

    // The page's status says the same.
    let (status, body) = common::http_get(port, "/api/status");
    assert_eq!(status, 200, "{body}");
    let status: Value = serde_json::from_str(&body).unwrap();
    assert_eq!(status["agent"]["available"], false, "{body}");
    assert!(
        status["agent"]["reason"]
            .as_str()
            .is_some_and(|r| r.contains("no LLM provider is configured")),
        "{body}"
    );
}

#[test]
fn the_rates_of_the_last_minutes_are_kept_for_a_page_that_opens() {
    let namespace = common::fresh_namespace("rates");
    let port = common::free_port();
    let _robotd = common::start_robotd(&namespace, port, &[]);
    // Frames are encoded for a viewer only.
    let _viewer = CameraViewer::open(port);
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(20);
    loop {
        let (status, body) = common::http_get(port, "/api/rates");
        assert_eq!(status, 200, "{body}");
        let rates: Value = serde_json::from_str(&body).unwrap();
        assert_eq!(rates["interval_s"], 1.0, "{body}");
        let samples = rates["samples"].as_array().unwrap();
        // Two seconds of a camera at work: the page's frame rate is in the history.
        if samples.len() >= 2 && samples.iter().any(|s| s["page_fps"].as_f64() > Some(0.0)) {
            let times: Vec<f64> = samples
                .iter()
                .map(|s| s["at_unix_s"].as_f64().unwrap())
                .collect();
            assert!(
                times.windows(2).all(|w| w[0] < w[1]),
                "oldest first: {times:?}"
            );
            assert!(samples.iter().all(|s| s["restarts"].is_u64()), "{body}");
            break;
        }
        assert!(
            std::time::Instant::now() < deadline,
            "no camera rate in the history: {body}"
        );
        std::thread::sleep(std::time::Duration::from_millis(200));
    }
}

#[test]
fn the_camera_is_encoded_only_while_someone_watches() {
    let namespace = common::fresh_namespace("unwatched");
    let port = common::free_port();
    let _robotd = common::start_robotd(&namespace, port, &[]);
    let wait_for = |what: &str, done: &dyn Fn(&Value) -> bool| {
        let deadline = Instant::now() + Duration::from_secs(20);
        loop {
            let camera = camera_figures(port);
            if done(&camera) {
                return camera;
            }
            assert!(Instant::now() < deadline, "{what}: {camera}");
            std::thread::sleep(Duration::from_millis(100));
        }
    };
    // A second of frames on the bus, and nobody watching: none encoded.
    let camera = wait_for("no camera frames on the bus", &|c| {
        c["bus_fps"].as_f64() > Some(0.0)
    });
    assert_eq!(camera["page_fps"], 0.0, "encoded for nobody: {camera}");
    assert_eq!(camera["frame_id"], 0, "encoded for nobody: {camera}");

    // A single frame asked for is encoded and served, and encoding goes on for a while.
    let (status, head, body) = common::http_response_from(
        std::net::Ipv4Addr::LOCALHOST,
        port,
        "GET",
        "/api/camera.jpg",
        &[],
        b"",
    );
    assert_eq!(status, 200, "{head}\n{body}");
    assert!(
        head.to_ascii_lowercase()
            .contains("content-type: image/jpeg"),
        "{head}"
    );
    wait_for("no frames encoded after /api/camera.jpg", &|c| {
        c["page_fps"].as_f64() > Some(0.0)
    });
    // Then, with nobody asking, it stops again.
    wait_for("still encoding with nobody watching", &|c| {
        c["page_fps"].as_f64() == Some(0.0)
    });
    // An MJPEG viewer keeps it going for as long as it watches.
    let viewer = CameraViewer::open(port);
    wait_for("no frames encoded for an MJPEG viewer", &|c| {
        c["page_fps"].as_f64() > Some(0.0)
    });
    drop(viewer);
    wait_for("still encoding after the viewer left", &|c| {
        c["page_fps"].as_f64() == Some(0.0)
    });
}
