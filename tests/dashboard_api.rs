//! The dashboard's HTTP/JSON API refuses what it cannot serve with a status and a JSON
//! `{"error": …}` a script can act on: malformed chat requests, over-long ones, and any chat
//! or cancel while no LLM is configured (the page shows the same reason). And the rate
//! history a page plots when it opens.

mod common;

use serde_json::Value;

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
