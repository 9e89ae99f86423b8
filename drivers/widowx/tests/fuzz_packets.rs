//! Fuzzing the Protocol 2.0 packet reader (`packet::Deframer`: what robotd's fake WidowX reads
//! from the serial port, and how the real bus frames the servos' replies): any byte stream, in
//! any chunking, yields packets or framing errors, never a panic, and the reader's buffer
//! stays bounded. Bounded cases; regressions in
//! `proptest-regressions/`.

use proptest::prelude::*;
use robotd_driver_widowx::packet::Deframer;

/// Bytes that often look like the start of a Protocol 2.0 packet.
fn stream() -> impl Strategy<Value = Vec<u8>> {
    let piece = prop_oneof![
        proptest::collection::vec(any::<u8>(), 0..32),
        // A header with a random id, length and body.
        (
            any::<u8>(),
            any::<u16>(),
            proptest::collection::vec(any::<u8>(), 0..40)
        )
            .prop_map(|(id, len, body)| {
                let mut p = vec![0xFF, 0xFF, 0xFD, 0x00, id];
                p.extend_from_slice(&len.to_le_bytes());
                p.extend_from_slice(&body);
                p
            }),
        Just(vec![0xFF, 0xFF, 0xFD, 0xFD]),
    ];
    proptest::collection::vec(piece, 0..12).prop_map(|v| v.concat())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(robotd_fuzzing::cases(500)))]

    #[test]
    fn any_stream_gives_packets_or_errors(bytes in stream(), chunk in 1usize..17) {
        let mut deframer = Deframer::default();
        let mut results = 0;
        for piece in bytes.chunks(chunk) {
            deframer.push(piece);
            while let Some(result) = deframer.next_packet() {
                results += 1;
                prop_assert!(results < 10_000, "the reader loops");
                if let Err(error) = result {
                    prop_assert!(!error.to_string().is_empty());
                }
            }
        }
    }
}
