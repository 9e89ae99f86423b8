//! Fuzzing what reads user-supplied recordings: truncated and corrupted versions of a valid
//! recording (the fixture's short session) given to [`Contents::inspect`] and to [`Messages`]
//! must give `Ok` or a clear error, never a panic, and the messages must end. Bounded cases
//! (`PROPTEST_CASES` for a longer run); a failing case is kept in `proptest-regressions/`.

use crate::contents::Contents;
use crate::fixture::damage::{self, Damage};
use crate::fixture::{write_recording, Recorded};
use crate::reader::{Messages, ReadError};
use proptest::prelude::*;
use std::path::Path;
use std::sync::OnceLock;

/// The valid recording every case damages.
fn fixture() -> &'static [u8] {
    static BYTES: OnceLock<Vec<u8>> = OnceLock::new();
    BYTES.get_or_init(|| {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("s.mcap");
        write_recording(&path, &Recorded::short_session());
        std::fs::read(path).unwrap()
    })
}

/// The fixture's length fields.
fn length_fields() -> &'static [(usize, usize)] {
    static FIELDS: OnceLock<Vec<(usize, usize)>> = OnceLock::new();
    FIELDS.get_or_init(|| damage::length_fields(fixture()))
}

fn change() -> impl Strategy<Value = Damage> {
    prop_oneof![
        (0.0..1.0).prop_map(Damage::Truncate),
        (0.0..1.0, 0u8..8).prop_map(|(at, bit)| Damage::Flip(at, bit)),
        (
            any::<usize>(),
            prop_oneof![-64i64..64, any::<i64>(), Just(i64::MAX), Just(i64::MIN)]
        )
            .prop_map(|(field, delta)| Damage::Length(field, delta)),
        (
            0.0..1.0,
            prop_oneof![
                any::<u64>(),
                Just(u64::MAX),
                Just(0),
                (0u64..4096),
                Just(u64::from(u32::MAX))
            ]
        )
            .prop_map(|(at, word)| Damage::Word(at, word)),
    ]
}

/// The fixture with `changes` applied.
fn damaged(changes: &[Damage]) -> Vec<u8> {
    damage::apply(fixture(), length_fields(), changes)
}

fn clear(error: &ReadError, path: &Path) -> Result<(), TestCaseError> {
    let text = error.to_string();
    prop_assert!(
        text.contains(&path.display().to_string()),
        "the error names the file: {}",
        text
    );
    prop_assert!(
        !matches!(error, ReadError::Open { .. }),
        "the file opens: {}",
        text
    );
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(robotd_fuzzing::cases(300)))]

    #[test]
    fn a_damaged_recording_is_read_or_refused_never_a_panic(
        changes in proptest::collection::vec(change(), 1..4)
    ) {
        let bytes = damaged(&changes);
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("damaged.mcap");
        std::fs::write(&path, &bytes).unwrap();

        match Contents::inspect(&path) {
            Ok(contents) => {
                // Every record takes at least its opcode and length (9 bytes).
                let total: u64 = contents.messages.values().sum();
                prop_assert!(total as usize <= bytes.len() / 9, "{} messages", total);
                if let Some(reason) = &contents.damaged {
                    prop_assert!(!reason.is_empty());
                }
                let _ = contents.describe();
            }
            Err(error) => clear(&error, &path)?,
        }

        let mut messages = Messages::open(&path).unwrap();
        let mut read = 0;
        while let Some(message) = messages.next() {
            read += 1;
            prop_assert!(read <= bytes.len() / 9 + 1, "the messages do not end");
            if let Err(error) = message {
                clear(&error, &path)?;
                prop_assert!(messages.next().is_none(), "nothing after an error");
                break;
            }
        }
    }
}

#[test]
fn the_fixture_itself_reads_whole() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("s.mcap");
    std::fs::write(&path, damaged(&[])).unwrap();
    let contents = Contents::inspect(&path).unwrap();
    assert!(contents.damaged.is_none());
    let total: u64 = contents.messages.values().sum();
    assert_eq!(total, 36);
    // The file's records, its chunk's header sizes and the records in its chunks.
    assert!(length_fields().len() > 40, "{:?}", length_fields());
}
