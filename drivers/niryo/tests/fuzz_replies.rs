//! Fuzzing the Niryo reply reader: whatever bytes arrive on the robot's socket, reading a reply
//! answers `Ok` or a clear error, never panics, and never asks for more than the 8 MiB payload
//! limit. Bounded cases (the CI runs them on every push); failures found are kept by proptest
//! in `proptest-regressions/` and replayed first.

use proptest::prelude::*;
use robotd_driver_niryo::wire::{parse_reply, read_reply};
use serde_json::{json, Value};

/// JSON values of every shape, with object keys biased to the reply's fields.
fn any_json() -> impl Strategy<Value = Value> {
    let leaf = prop_oneof![
        Just(Value::Null),
        any::<bool>().prop_map(Value::Bool),
        any::<i64>().prop_map(|n| json!(n)),
        any::<f64>()
            .prop_map(|f| serde_json::Number::from_f64(f).map_or(Value::Null, Value::Number)),
        ".{0,20}".prop_map(Value::String),
        prop_oneof![Just("OK"), Just("KO"), Just("GET_JOINTS")].prop_map(|s| json!(s)),
    ];
    leaf.prop_recursive(3, 32, 6, |inner| {
        let key = prop_oneof![
            Just("command".to_owned()),
            Just("status".to_owned()),
            Just("list_ret_param".to_owned()),
            Just("payload_size".to_owned()),
            Just("message".to_owned()),
            ".{0,8}",
        ];
        prop_oneof![
            proptest::collection::vec(inner.clone(), 0..6).prop_map(Value::Array),
            proptest::collection::btree_map(key, inner, 0..6)
                .prop_map(|m| Value::Object(m.into_iter().collect())),
        ]
    })
}

fn read(bytes: Vec<u8>) -> Result<(), String> {
    let runtime = tokio::runtime::Builder::new_current_thread()
        .build()
        .expect("runtime");
    let mut input = std::io::Cursor::new(bytes);
    runtime
        .block_on(read_reply(&mut input))
        .map(drop)
        .map_err(|e| e.to_string())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(robotd_fuzzing::cases(400)))]

    /// Raw bytes: a reply, or an error that says something.
    #[test]
    fn any_bytes_give_a_reply_or_a_clear_error(bytes in proptest::collection::vec(any::<u8>(), 0..400)) {
        if let Err(reason) = read(bytes) {
            prop_assert!(!reason.trim().is_empty());
        }
    }

    /// Well-framed JSON of any shape (length prefix right), then random trailing bytes.
    #[test]
    fn framed_json_of_any_shape(value in any_json(), tail in proptest::collection::vec(any::<u8>(), 0..64)) {
        let text = value.to_string();
        prop_assume!(text.len() <= usize::from(u16::MAX));
        let mut bytes = (text.len() as u16).to_le_bytes().to_vec();
        bytes.extend_from_slice(text.as_bytes());
        bytes.extend_from_slice(&tail);
        if let Err(reason) = read(bytes) {
            prop_assert!(!reason.trim().is_empty());
        }
        // The parser alone: a payload size is never above the limit.
        if let Ok((_, _, payload)) = parse_reply(&value) {
            prop_assert!(payload <= 8 * 1024 * 1024);
        }
    }
}
