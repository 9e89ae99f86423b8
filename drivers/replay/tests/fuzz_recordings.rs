//! Fuzzing the replay driver with damaged recordings: truncated and corrupted versions of a
//! valid one (the recording crate's fixture) given to the check `robotd serve` and `robotd
//! doctor` run ([`robotd_driver_replay::inspect`]) and to the reader thread that plays them
//! ([`robotd_driver_replay::source::spawn`]): the check says Ok or why not, naming the file;
//! the thread sends decoded messages and then the end of the lap or why it failed, and never
//! panics. Bounded cases (`PROPTEST_CASES` for a longer run); a failing case is kept next to
//! this file.

use proptest::prelude::*;
use robotd_driver::ReplayConfig;
use robotd_driver_replay::player::Item;
use robotd_driver_replay::{inspect, source};
use robotd_recording::fixture::damage::{self, Damage};
use robotd_recording::fixture::{write_recording, Recorded};
use std::sync::OnceLock;

/// A recording's bytes and its length fields.
type Fixture = (Vec<u8>, Vec<(usize, usize)>);

/// The valid recording every case damages, and its length fields.
fn fixture() -> &'static Fixture {
    static FIXTURE: OnceLock<Fixture> = OnceLock::new();
    FIXTURE.get_or_init(|| {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("s.mcap");
        write_recording(&path, &Recorded::short_session());
        let bytes = std::fs::read(path).unwrap();
        let fields = damage::length_fields(&bytes);
        (bytes, fields)
    })
}

fn change() -> impl Strategy<Value = Damage> {
    prop_oneof![
        (0.0..1.0).prop_map(Damage::Truncate),
        (0.0..1.0, 0u8..8).prop_map(|(at, bit)| Damage::Flip(at, bit)),
        (
            any::<usize>(),
            prop_oneof![-64i64..64, any::<i64>(), Just(i64::MIN)]
        )
            .prop_map(|(field, delta)| Damage::Length(field, delta)),
        (0.0..1.0, any::<u64>()).prop_map(|(at, word)| Damage::Word(at, word)),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(robotd_fuzzing::cases(150)))]

    #[test]
    fn a_damaged_recording_is_played_or_refused_never_a_panic(
        changes in proptest::collection::vec(change(), 1..4)
    ) {
        let (bytes, fields) = fixture();
        let bytes = damage::apply(bytes, fields, &changes);
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("damaged.mcap");
        std::fs::write(&path, &bytes).unwrap();
        let config = ReplayConfig {
            file: Some(path.clone()),
            ..ReplayConfig::default()
        };
        if let Err(error) = inspect(&config) {
            let text = error.to_string();
            prop_assert!(text.contains(&path.display().to_string()), "{}", text);
        }

        let (tx, mut rx) = tokio::sync::mpsc::channel(8);
        let reader = source::spawn(path.clone(), false, tx).unwrap();
        let mut items = 0;
        let last = loop {
            let Some(item) = rx.blocking_recv() else {
                break None;
            };
            items += 1;
            prop_assert!(items <= bytes.len() / 9 + 2, "the lap does not end");
            match item {
                Item::Frame { meta, rgb, .. } => prop_assert_eq!(
                    rgb.len(),
                    meta.width as usize * meta.height as usize * 3
                ),
                Item::End => break Some(Ok(())),
                Item::Failed(reason) => break Some(Err(reason)),
                Item::Arm { .. } | Item::Gripper { .. } => {}
            }
        };
        prop_assert!(reader.join().is_ok(), "the reader thread panicked");
        match last {
            Some(Ok(())) => {}
            Some(Err(reason)) => prop_assert!(!reason.is_empty()),
            None => prop_assert!(false, "the reader thread ended without a word"),
        }
        prop_assert!(rx.blocking_recv().is_none(), "nothing after the end");
    }
}
