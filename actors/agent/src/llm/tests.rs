//! Tests of the LLM client: the OpenAI and Ollama request bodies, and reading Retry-After.

use super::*;

fn spec() -> ToolSpec {
    ToolSpec {
        name: "get_detected_objects".into(),
        description: "Objects".into(),
        parameters: json!({"type": "object", "properties": {}})
            .as_object()
            .cloned()
            .unwrap(),
    }
}

fn conversation() -> Vec<Message> {
    vec![
        Message::System("sys".into()),
        Message::user("look"),
        Message::Assistant {
            content: Some("I will look.".into()),
            tool_calls: vec![ToolCall {
                id: "c1".into(),
                name: "get_detected_objects".into(),
                arguments: r#"{"label":"pencil"}"#.into(),
            }],
        },
        Message::Tool {
            call_id: "c1".into(),
            name: "get_detected_objects".into(),
            content: "✓ Found 1 object(s)".into(),
        },
    ]
}

#[test]
fn openai_wire_format() {
    let body = openai_body("m", &conversation(), &[spec()]);
    assert_eq!(body["model"], "m");
    assert_eq!(body["tools"][0]["type"], "function");
    assert_eq!(body["tools"][0]["function"]["name"], "get_detected_objects");
    let m = &body["messages"];
    assert_eq!(m[2]["tool_calls"][0]["id"], "c1");
    assert_eq!(
        m[2]["tool_calls"][0]["function"]["arguments"],
        r#"{"label":"pencil"}"#
    );
    assert_eq!(m[3]["role"], "tool");
    assert_eq!(m[3]["tool_call_id"], "c1");
    let reply = r#"{"choices":[{"message":{"role":"assistant","content":null,
        "tool_calls":[{"id":"x","type":"function","function":{"name":"speak","arguments":"{\"text\":\"hi\"}"}}]}}],
        "usage":{"prompt_tokens":12,"completion_tokens":3}}"#;
    let c = parse_openai(reply).unwrap();
    assert_eq!(c.content, None);
    assert_eq!(c.tool_calls[0].name, "speak");
    assert_eq!(c.tool_calls[0].arguments, r#"{"text":"hi"}"#);
    assert_eq!(
        c.usage,
        Some(Usage {
            prompt_tokens: 12,
            completion_tokens: 3
        })
    );
    for bad in [
        "",
        "{",
        r#"{"choices":[]}"#,
        r#"{"choices":[{"message":{"tool_calls":[{"function":{}}]}}]}"#,
    ] {
        assert!(parse_openai(bad).is_err(), "{bad}");
    }
}

#[test]
fn ollama_wire_format() {
    let body = ollama_body("llama3.2:1b", &conversation(), &[spec()]);
    assert_eq!(body["stream"], false);
    assert_eq!(body["tools"][0]["function"]["name"], "get_detected_objects");
    let m = &body["messages"];
    // Arguments travel as an object, tool results name their tool.
    assert_eq!(
        m[2]["tool_calls"][0]["function"]["arguments"],
        json!({"label": "pencil"})
    );
    assert_eq!(m[3]["role"], "tool");
    assert_eq!(m[3]["tool_name"], "get_detected_objects");
    let reply = r#"{"model":"llama3.2:1b","message":{"role":"assistant","content":"",
        "tool_calls":[{"function":{"name":"move2observation_pose","arguments":{"workspace_id":"niryo_ws"}}}]},
        "done":true,"prompt_eval_count":40,"eval_count":7}"#;
    let c = parse_ollama(reply).unwrap();
    assert_eq!(c.content, None);
    assert_eq!(c.tool_calls[0].name, "move2observation_pose");
    assert_eq!(
        serde_json::from_str::<Value>(&c.tool_calls[0].arguments).unwrap(),
        json!({"workspace_id": "niryo_ws"})
    );
    assert_eq!(
        c.usage,
        Some(Usage {
            prompt_tokens: 40,
            completion_tokens: 7
        })
    );
    assert!(parse_ollama(r#"{"error":"model 'x' not found"}"#)
        .unwrap_err()
        .contains("not found"));
}

#[test]
fn retry_after_is_read_in_seconds() {
    let mut h = reqwest::header::HeaderMap::new();
    assert_eq!(retry_after(&h), None);
    h.insert(reqwest::header::RETRY_AFTER, "2".parse().unwrap());
    assert_eq!(retry_after(&h), Some(Duration::from_secs(2)));
    h.insert(
        reqwest::header::RETRY_AFTER,
        "Wed, 21 Oct 2015 07:28:00 GMT".parse().unwrap(),
    );
    assert_eq!(retry_after(&h), None);
}
