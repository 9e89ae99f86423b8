//! What is wrong with a posted message the MCP library could not read, answered the same way
//! on `/mcp` and `/messages/`.
//!
//! A body that is not JSON is HTTP 400 with JSON-RPC `-32700` (Parse error). A JSON body whose
//! envelope is not JSON-RPC 2.0 as MCP uses it is HTTP 400 with `-32600` (Invalid Request),
//! and the message says what is wrong with the envelope:
//!
//! - `jsonrpc` missing, or anything but `"2.0"`;
//! - an `id` that is neither a string nor an integer (an object, an array, a boolean, `null`,
//!   a fraction), or an integer beyond 64 bits (the MCP library keeps ids as `i64`);
//! - a `method` that is not a string, or neither a `method` nor a `result` or `error`;
//! - not an object at all (an array: MCP has no batches).
//!
//! A well-formed envelope whose params do not fit the MCP method it names is `-32602`
//! (Invalid params; HTTP 200 on `/mcp`, where it is an ordinary JSON-RPC answer, 400 on
//! `/messages/`, whose answers otherwise go onto the stream). The answer echoes the request's
//! id exactly as sent — its JSON text, so an id of 2^70 comes back as
//! `1180591620717411303424`, not as a rounded float — when it is a string or an integer, and
//! `null` otherwise, as JSON-RPC asks.

use axum::http::{header, StatusCode};
use axum::response::{IntoResponse, Response};
use serde_json::value::RawValue;
use serde_json::Value;
use std::collections::HashMap;

/// A posted body that is not a message robotd can serve, and its answer.
#[derive(Debug)]
pub(super) struct BadMessage {
    status: StatusCode,
    code: i32,
    message: String,
    /// The id as sent, when it is a string or a number; `null` is answered otherwise.
    id: Option<Box<RawValue>>,
}

/// What kind of JSON `value` is, in words.
fn kind(value: &Value) -> &'static str {
    match value {
        Value::Null => "null",
        Value::Bool(_) => "a boolean",
        Value::Number(_) => "a number",
        Value::String(_) => "a string",
        Value::Array(_) => "an array",
        Value::Object(_) => "an object",
    }
}

/// `raw` JSON text cut to 40 characters, for a message.
fn cut(raw: &RawValue) -> String {
    let text = raw.get();
    match text.char_indices().nth(40) {
        Some((at, _)) => format!("{}…", &text[..at]),
        None => text.to_owned(),
    }
}

/// What is wrong with an `id` (`raw`, read as `value`); `None` when MCP takes it.
fn id_problem(raw: &RawValue, value: &Value) -> Option<String> {
    match value {
        Value::String(_) => None,
        Value::Number(n) => {
            let text = raw.get();
            let integer = text
                .trim_start_matches('-')
                .bytes()
                .all(|b| b.is_ascii_digit());
            if integer && text.parse::<i64>().is_err() {
                Some(format!(
                    "\"id\" {text} does not fit in 64 bits: an integer id must lie within \
                     -9223372036854775808 … 9223372036854775807 (send a larger one as a string)"
                ))
            } else if !integer && n.as_f64().is_some_and(|f| f.fract() != 0.0) {
                Some(format!(
                    "\"id\" must be a string or an integer, not the fraction {text}"
                ))
            } else {
                None
            }
        }
        other => Some(format!(
            "\"id\" must be a string or an integer, not {}",
            kind(other)
        )),
    }
}

impl BadMessage {
    /// Why `bytes` could not be read as a client message (`error`, the MCP library's reason).
    /// `params_status` is the HTTP status of a params error (`-32602`).
    pub(super) fn of(bytes: &[u8], error: &serde_json::Error, params_status: StatusCode) -> Self {
        let refusal = |code, message: String, id| BadMessage {
            status: StatusCode::BAD_REQUEST,
            code,
            message,
            id,
        };
        let value = match serde_json::from_slice::<Value>(bytes) {
            Ok(value) => value,
            Err(e) => {
                return refusal(
                    -32700,
                    format!("Parse error: the body is not JSON: {e}"),
                    None,
                )
            }
        };
        let Ok(fields) = serde_json::from_slice::<HashMap<String, Box<RawValue>>>(bytes) else {
            let batch = if value.is_array() {
                " (MCP has no batches: post one message at a time)"
            } else {
                ""
            };
            return refusal(
                -32600,
                format!(
                    "Invalid Request: a JSON-RPC message is an object, not {}{batch}",
                    kind(&value)
                ),
                None,
            );
        };
        let mut problems = Vec::new();
        match (fields.get("jsonrpc"), value.get("jsonrpc")) {
            (Some(_), Some(Value::String(v))) if v == "2.0" => {}
            (Some(raw), _) => {
                problems.push(format!("\"jsonrpc\" must be \"2.0\", not {}", cut(raw)))
            }
            (None, _) => problems.push("\"jsonrpc\" is missing: it must be \"2.0\"".to_owned()),
        }
        let mut id = None;
        if let (Some(raw), Some(v)) = (fields.get("id"), value.get("id")) {
            match id_problem(raw, v) {
                // The integer beyond 64 bits is still the client's id: echoed as sent.
                Some(problem) => {
                    if v.is_number() && v.as_f64().is_some_and(|f| f.fract() == 0.0) {
                        id = Some(raw.clone());
                    }
                    problems.push(problem);
                }
                None => id = Some(raw.clone()),
            }
        }
        let method = value.get("method");
        match method {
            Some(Value::String(_)) => {}
            Some(other) => {
                problems.push(format!("\"method\" must be a string, not {}", kind(other)))
            }
            None if value.get("result").is_none() && value.get("error").is_none() => problems.push(
                "it has neither \"method\" (a request or notification) nor \"result\" or \
                     \"error\" (a response)"
                    .to_owned(),
            ),
            None => {}
        }
        if !problems.is_empty() {
            return refusal(
                -32600,
                format!("Invalid Request: {}", problems.join("; ")),
                id,
            );
        }
        // A request to an MCP method whose params do not fit it (`[1, 2]`, `{"x": 1}`).
        let mcp_method = method
            .and_then(Value::as_str)
            .filter(|m| crate::gate::is_mcp_method(m));
        if let (Some(method), Some(id)) = (mcp_method, id.clone()) {
            let error = crate::gate::invalid_params(method);
            return BadMessage {
                status: params_status,
                code: error.code.0,
                message: error.message.to_string(),
                id: Some(id),
            };
        }
        refusal(
            -32600,
            format!("Invalid Request: not a JSON-RPC message of an MCP client: {error}"),
            id,
        )
    }

    /// The answer: the status, and a JSON-RPC error with the id as sent.
    pub(super) fn into_response(self) -> Response {
        let error = serde_json::json!({"code": self.code, "message": self.message});
        let id = self.id.as_deref().map_or("null", RawValue::get);
        let body = format!(r#"{{"jsonrpc":"2.0","id":{id},"error":{error}}}"#);
        (
            self.status,
            [(header::CONTENT_TYPE, "application/json")],
            body,
        )
            .into_response()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rmcp::model::ClientJsonRpcMessage;

    /// The answer to `body` on `/mcp`: (status, code, message, id as JSON text).
    fn answer(body: &str) -> (u16, i64, String, String) {
        let error = serde_json::from_str::<ClientJsonRpcMessage>(body).expect_err("unreadable");
        let bad = BadMessage::of(body.as_bytes(), &error, StatusCode::OK);
        let id = bad.id.as_deref().map_or("null", RawValue::get).to_owned();
        (bad.status.as_u16(), i64::from(bad.code), bad.message, id)
    }

    #[test]
    fn envelope_problems_are_invalid_requests_that_say_what_is_wrong() {
        for (body, says, id) in [
            (
                r#"{"jsonrpc":"1.0","id":2,"method":"tools/list"}"#,
                r#""jsonrpc" must be "2.0", not "1.0""#,
                "2",
            ),
            (
                r#"{"id":"a","method":"tools/list"}"#,
                r#""jsonrpc" is missing"#,
                r#""a""#,
            ),
            (
                r#"{"jsonrpc":"2.0","id":{"a":1},"method":"tools/list"}"#,
                "not an object",
                "null",
            ),
            (
                r#"{"jsonrpc":"2.0","id":[1],"method":"ping"}"#,
                "not an array",
                "null",
            ),
            (
                r#"{"jsonrpc":"2.0","id":true,"method":"ping"}"#,
                "not a boolean",
                "null",
            ),
            (
                r#"{"jsonrpc":"2.0","id":1.5,"method":"ping"}"#,
                "not the fraction 1.5",
                "null",
            ),
            (
                r#"{"jsonrpc":"2.0","id":1180591620717411303424,"method":"ping"}"#,
                "does not fit in 64 bits",
                "1180591620717411303424",
            ),
            (
                r#"{"jsonrpc":"2.0","id":3,"method":7}"#,
                r#""method" must be a string"#,
                "3",
            ),
            (r#"{"jsonrpc":"2.0","id":3}"#, "neither \"method\"", "3"),
            (
                r#"[{"jsonrpc":"2.0","id":3,"method":"ping"}]"#,
                "no batches",
                "null",
            ),
        ] {
            let (status, code, message, echoed) = answer(body);
            assert_eq!((status, code), (400, -32600), "{body}: {message}");
            assert!(message.contains(says), "{body}: {message}");
            assert_eq!(echoed, id, "{body}");
        }
        let (status, code, message, _) = answer("{not json");
        assert_eq!((status, code), (400, -32700), "{message}");
    }

    #[test]
    fn a_good_envelope_with_bad_params_is_a_params_error_with_the_id_as_sent() {
        let (status, code, message, id) =
            answer(r#"{"jsonrpc":"2.0","id":"x-1","method":"tools/call","params":[1,2]}"#);
        assert_eq!(
            (status, code, id.as_str()),
            (200, -32602, r#""x-1""#),
            "{message}"
        );
        let response = BadMessage::of(
            br#"{"jsonrpc":"2.0","id":1180591620717411303424}"#,
            &serde_json::from_str::<Value>("x").unwrap_err(),
            StatusCode::OK,
        );
        assert_eq!(
            response.id.as_deref().map(RawValue::get),
            Some("1180591620717411303424")
        );
    }
}
