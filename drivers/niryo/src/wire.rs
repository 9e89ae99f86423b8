//! The Ned2's TCP framing and message shapes, both directions.
//!
//! Every message is a little-endian `u16` length, then that many bytes of JSON; a reply whose
//! `payload_size` is N > 0 is followed by N raw bytes (the JPEG of `GET_IMAGE_COMPRESSED`).
//! The robot parses requests with Python's `ast.literal_eval`, so a request must never carry
//! the JSON literals `true`, `false` or `null`: [`Param`] writes booleans as `"TRUE"` /
//! `"FALSE"` and nothing as `"None"`, as pyniryo does. Replies come back with booleans as the
//! strings `"True"` / `"False"`; [`lenient_bool`] reads every spelling.
//!
//! Everything read from the socket is checked: a length, a JSON text, a status, a payload size
//! that does not make sense is a [`WireError`], never a panic. See `docs/niryo-tcp.md`.

use serde_json::{Map, Value};
use tokio::io::{AsyncRead, AsyncReadExt, AsyncWrite, AsyncWriteExt};

/// Largest payload robotd accepts after a reply (a 640×480 JPEG is 30–150 kB).
pub const MAX_PAYLOAD_BYTES: usize = 8 * 1024 * 1024;

/// What went wrong on the wire.
#[derive(Debug, thiserror::Error)]
pub enum WireError {
    /// The socket failed or closed.
    #[error("{0}")]
    Io(#[from] std::io::Error),
    /// A message that is not the protocol's.
    #[error("malformed message from the robot: {0}")]
    Malformed(String),
    /// A request that cannot be written (too long, a number JSON cannot carry).
    #[error("request cannot be sent: {0}")]
    Unsendable(String),
}

/// One request parameter, written the way the robot's parser accepts it.
#[derive(Debug, Clone, PartialEq)]
pub enum Param {
    /// A JSON number (must be finite).
    Float(f64),
    /// A JSON integer (gripper speed and torques must be integers).
    Int(i64),
    /// A string (enum names such as `"AUTO"`, frame names).
    Str(String),
    /// A boolean, sent as `"TRUE"` / `"FALSE"`.
    Bool(bool),
    /// A list of parameters.
    List(Vec<Param>),
}

impl Param {
    fn to_json(&self) -> Result<Value, WireError> {
        Ok(match self {
            Param::Float(x) => serde_json::Number::from_f64(*x)
                .map(Value::Number)
                .ok_or_else(|| WireError::Unsendable(format!("{x} is not a finite number")))?,
            Param::Int(i) => Value::from(*i),
            Param::Str(s) => Value::from(s.as_str()),
            Param::Bool(b) => Value::from(if *b { "TRUE" } else { "FALSE" }),
            Param::List(items) => {
                Value::Array(items.iter().map(Param::to_json).collect::<Result<_, _>>()?)
            }
        })
    }
}

/// The frame of the request `command` with `params`: prefix and body in one buffer, because
/// the robot reads the prefix with a single `recv(2)` and must get it whole.
pub fn encode_request(command: &str, params: &[Param]) -> Result<Vec<u8>, WireError> {
    let mut body = Map::new();
    body.insert("command".into(), Value::from(command));
    body.insert(
        "param_list".into(),
        Value::Array(
            params
                .iter()
                .map(Param::to_json)
                .collect::<Result<_, _>>()?,
        ),
    );
    frame(&Value::Object(body))
}

/// A JSON value as one frame (prefix + text).
pub fn frame(value: &Value) -> Result<Vec<u8>, WireError> {
    let text =
        serde_json::to_vec(value).map_err(|e| WireError::Unsendable(format!("JSON: {e}")))?;
    let len = u16::try_from(text.len()).map_err(|_| {
        WireError::Unsendable(format!(
            "{} bytes of JSON; the protocol allows at most 65535",
            text.len()
        ))
    })?;
    let mut out = Vec::with_capacity(2 + text.len());
    out.extend_from_slice(&len.to_le_bytes());
    out.extend_from_slice(&text);
    Ok(out)
}

/// Writes one already framed message.
pub async fn write_frame<W: AsyncWrite + Unpin>(
    out: &mut W,
    bytes: &[u8],
) -> Result<(), WireError> {
    out.write_all(bytes).await?;
    out.flush().await?;
    Ok(())
}

/// Reads one frame's JSON text and parses it.
pub async fn read_json<R: AsyncRead + Unpin>(input: &mut R) -> Result<Value, WireError> {
    let mut prefix = [0u8; 2];
    input.read_exact(&mut prefix).await?;
    let len = usize::from(u16::from_le_bytes(prefix));
    if len == 0 {
        return Err(WireError::Malformed("an empty message (length 0)".into()));
    }
    let mut text = vec![0u8; len];
    input.read_exact(&mut text).await?;
    serde_json::from_slice(&text).map_err(|e| {
        WireError::Malformed(format!(
            "not JSON ({e}): {}",
            String::from_utf8_lossy(&text[..len.min(80)])
        ))
    })
}

/// A reply of the robot.
#[derive(Debug, Clone, PartialEq)]
pub struct Reply {
    /// The command it answers (empty for `Unknown command`).
    pub command: String,
    /// `Ok(list_ret_param)`, or the KO message.
    pub outcome: Result<Vec<Value>, String>,
    /// The raw bytes that followed (an image), empty for most commands.
    pub payload: Vec<u8>,
}

/// Reads one reply and its payload.
pub async fn read_reply<R: AsyncRead + Unpin>(input: &mut R) -> Result<Reply, WireError> {
    let value = read_json(input).await?;
    let (command, outcome, payload_size) = parse_reply(&value)?;
    let mut payload = vec![0u8; payload_size];
    input.read_exact(&mut payload).await?;
    Ok(Reply {
        command,
        outcome,
        payload,
    })
}

type ParsedReply = (String, Result<Vec<Value>, String>, usize);

/// Checks a reply's JSON: its command, status, results and payload size.
pub fn parse_reply(value: &Value) -> Result<ParsedReply, WireError> {
    let bad = |what: &str| WireError::Malformed(format!("{what} in reply {}", clip(value)));
    let object = value.as_object().ok_or_else(|| bad("not an object"))?;
    let command = object
        .get("command")
        .and_then(Value::as_str)
        .ok_or_else(|| bad("no command"))?
        .to_owned();
    let payload_size = match object.get("payload_size") {
        None => 0,
        Some(size) => size
            .as_u64()
            .and_then(|n| usize::try_from(n).ok())
            .filter(|n| *n <= MAX_PAYLOAD_BYTES)
            .ok_or_else(|| bad("payload_size not a size up to 8 MiB"))?,
    };
    let outcome = match object.get("status").and_then(Value::as_str) {
        Some("OK") => Ok(match object.get("list_ret_param") {
            Some(Value::Array(items)) => items.clone(),
            None => Vec::new(),
            Some(_) => return Err(bad("list_ret_param not a list")),
        }),
        Some("KO") => Err(object
            .get("message")
            .and_then(Value::as_str)
            .unwrap_or("(no message)")
            .to_owned()),
        _ => return Err(bad("status neither OK nor KO")),
    };
    Ok((command, outcome, payload_size))
}

/// A short excerpt of a JSON value for error texts.
pub fn clip(value: &Value) -> String {
    let text = value.to_string();
    if text.len() <= 120 {
        text
    } else {
        let cut = (0..=120)
            .rev()
            .find(|i| text.is_char_boundary(*i))
            .unwrap_or(0);
        format!("{}…", &text[..cut])
    }
}

/// A boolean however the robot spells it: `true`, `"True"`, `"TRUE"`, `"true"`, `1`.
pub fn lenient_bool(value: &Value) -> Option<bool> {
    match value {
        Value::Bool(b) => Some(*b),
        Value::String(s) => match s.to_ascii_lowercase().as_str() {
            "true" => Some(true),
            "false" => Some(false),
            _ => None,
        },
        Value::Number(n) => n.as_i64().map(|i| i != 0),
        _ => None,
    }
}

/// `n` finite numbers (numeric strings too, as the robot's `float()` accepts them).
pub fn numbers(values: &[Value], n: usize, what: &str) -> Result<Vec<f64>, String> {
    if values.len() != n {
        return Err(format!(
            "{what}: {n} numbers expected, got {}",
            values.len()
        ));
    }
    values
        .iter()
        .map(|v| {
            let x = match v {
                Value::Number(n) => n.as_f64(),
                Value::String(s) => s.trim().parse().ok(),
                _ => None,
            };
            x.filter(|x: &f64| x.is_finite())
                .ok_or_else(|| format!("{what}: {} is not a finite number", clip(v)))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn requests_never_carry_json_literals_and_keep_integers() {
        let frame = encode_request(
            "OPEN_GRIPPER",
            &[Param::Int(500), Param::Bool(false), Param::Float(0.5)],
        )
        .unwrap();
        let len = u16::from_le_bytes([frame[0], frame[1]]) as usize;
        assert_eq!(len, frame.len() - 2);
        let text = std::str::from_utf8(&frame[2..]).unwrap();
        assert_eq!(
            text,
            r#"{"command":"OPEN_GRIPPER","param_list":[500,"FALSE",0.5]}"#
        );
        assert!(encode_request("MOVE_JOINTS", &[Param::Float(f64::NAN)]).is_err());
        let huge = vec![Param::Str("x".repeat(70_000))];
        assert!(matches!(
            encode_request("HANDSHAKE", &huge),
            Err(WireError::Unsendable(_))
        ));
    }

    #[tokio::test]
    async fn replies_are_read_with_their_payload_and_checked() {
        let mut bytes = frame(&json!({"status": "OK", "command": "GET_IMAGE_COMPRESSED",
            "list_ret_param": [], "payload_size": 3}))
        .unwrap();
        bytes.extend_from_slice(&[1, 2, 3]);
        let reply = read_reply(&mut bytes.as_slice()).await.unwrap();
        assert_eq!(reply.command, "GET_IMAGE_COMPRESSED");
        assert_eq!(reply.payload, vec![1, 2, 3]);

        let ko = frame(
            &json!({"command": "", "status": "KO", "message": "Unknown command",
            "list_ret_param": [], "payload_size": 0}),
        )
        .unwrap();
        let reply = read_reply(&mut ko.as_slice()).await.unwrap();
        assert_eq!(reply.outcome, Err("Unknown command".to_owned()));

        for garbage in [
            json!([1, 2]),
            json!({"status": "MAYBE", "command": "X"}),
            json!({"status": "OK"}),
            json!({"status": "OK", "command": "X", "payload_size": -1}),
            json!({"status": "OK", "command": "X", "payload_size": 1u64 << 40}),
            json!({"status": "OK", "command": "X", "list_ret_param": 5}),
        ] {
            let bytes = frame(&garbage).unwrap();
            assert!(
                matches!(
                    read_reply(&mut bytes.as_slice()).await,
                    Err(WireError::Malformed(_))
                ),
                "{garbage}"
            );
        }
        let not_json = [4u8, 0, b'{', b'x', 0xff, b'}'];
        assert!(matches!(
            read_reply(&mut not_json.as_slice()).await,
            Err(WireError::Malformed(_))
        ));
        let truncated = [10u8, 0, b'{'];
        assert!(matches!(
            read_reply(&mut truncated.as_slice()).await,
            Err(WireError::Io(_))
        ));
    }

    #[test]
    fn booleans_and_numbers_are_read_leniently_but_checked() {
        for (v, b) in [
            (json!("True"), true),
            (json!("FALSE"), false),
            (json!(true), true),
            (json!(0), false),
        ] {
            assert_eq!(lenient_bool(&v), Some(b));
        }
        assert_eq!(lenient_bool(&json!("maybe")), None);
        assert_eq!(
            numbers(&[json!(1), json!("0.5")], 2, "joints").unwrap(),
            vec![1.0, 0.5]
        );
        assert!(numbers(&[json!(1)], 2, "joints").is_err());
        assert!(numbers(&[json!("nan"), json!(1)], 2, "joints").is_err());
        assert!(numbers(&[json!(null), json!(1)], 2, "joints").is_err());
    }
}
