//! The dashboard's HTTP/JSON API refuses what it cannot serve with a status and a JSON
//! `{"error": …}` a script can act on: malformed chat requests, over-long ones, and any chat
//! or cancel while no LLM is configured (the page shows the same reason).

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
    assert!(reason.contains("OPENAI_API_KEY"), "says how to configure one: {reason}");
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
