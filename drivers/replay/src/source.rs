//! The reader thread: the recording read from its file, one message at a time, decoded into the
//! [`Item`]s the player plays.
//!
//! Reading and JPEG decoding are blocking work, so they run on a thread of their own and hand
//! the player decoded messages through a small bounded channel: the thread is never more than
//! a few messages ahead, however long the file. A message that does not decode is skipped,
//! never played half-read, and counted by kind (camera frame, arm state, gripper state): the
//! first of each kind is logged with its reason, once for the thread's life, and the first lap
//! ends with one line of counts, so a file full of bad messages costs a few lines, not one per
//! message (or per lap). A file that breaks off ends the lap where it breaks. With `loop` the
//! file is read again from its start; the thread stops when the player is gone (the channel's
//! receiver dropped).

use crate::player::Item;
use robotd_protocol::arm::ArmState;
use robotd_protocol::gripper::GripperState;
use robotd_recording::camera::FramePairer;
use robotd_recording::reader::{Messages, ReadError};
use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use tokio::sync::mpsc::Sender;

/// Starts the reader thread on `path`, sending into `items`.
pub fn spawn(
    path: PathBuf,
    looping: bool,
    items: Sender<Item>,
) -> std::io::Result<std::thread::JoinHandle<()>> {
    std::thread::Builder::new()
        .name("replay-reader".into())
        .spawn(move || {
            let mut skipped = Skipped::default();
            loop {
                match read_once(&path, &items, &mut skipped) {
                    Ok(true) => {
                        if items.blocking_send(Item::End).is_err() || !looping {
                            return;
                        }
                    }
                    Ok(false) => return,
                    Err(reason) => {
                        let _ = items.blocking_send(Item::Failed(reason));
                        return;
                    }
                }
            }
        })
}

/// A skipped camera frame: its image or header does not decode, or one half came without the
/// other.
pub const CAMERA_FRAME: &str = "camera frame";
/// A skipped arm state: not an `arm.state` message.
pub const ARM_STATE: &str = "arm state";
/// A skipped gripper state: not a `gripper.state` message.
pub const GRIPPER_STATE: &str = "gripper state";

/// The messages skipped because they do not decode, by kind: a few kinds, whatever the file
/// holds (reasons carry frame ids and JSON positions, so they are examples, not keys).
#[derive(Debug, Default)]
pub struct Skipped {
    /// This pass: per kind, how many and the first one's reason.
    pass: BTreeMap<&'static str, (u64, String)>,
    /// The last pass that ended: per kind, how many.
    last_pass: BTreeMap<&'static str, u64>,
    /// The kinds already logged (once for the thread's life, whatever the laps).
    logged: BTreeSet<&'static str>,
    /// Passes ended.
    passes: u64,
}

impl Skipped {
    /// Notes a skipped message of `kind`, logging the first of its kind.
    pub fn note(&mut self, path: &Path, kind: &'static str, reason: String) {
        let (count, example) = self.pass.entry(kind).or_insert((0, reason));
        *count += 1;
        if self.logged.insert(kind) {
            tracing::warn!(
                file = %path.display(),
                kind,
                reason = %example,
                "replay: a message is skipped (it does not decode); more of its kind are counted"
            );
        }
    }

    /// The messages the last pass that ended skipped, per kind.
    pub fn last_pass(&self) -> &BTreeMap<&'static str, u64> {
        &self.last_pass
    }

    /// Ends a pass: the first says what it skipped, in one line.
    fn end_pass(&mut self, path: &Path) {
        if !self.pass.is_empty() && self.passes == 0 {
            let skipped = self
                .pass
                .iter()
                .map(|(kind, (n, example))| format!("{n} {kind} (e.g. {example})"))
                .collect::<Vec<_>>()
                .join("; ");
            tracing::warn!(file = %path.display(), %skipped, "replay: messages skipped in this pass");
        }
        self.passes += 1;
        self.last_pass = std::mem::take(&mut self.pass)
            .into_iter()
            .map(|(kind, (n, _))| (kind, n))
            .collect();
    }
}

/// Sends every message of one pass over the file; `Ok(false)` when the player is gone.
fn read_once(path: &Path, items: &Sender<Item>, skipped: &mut Skipped) -> Result<bool, String> {
    let mut pairer = FramePairer::default();
    let first_pass = skipped.passes == 0;
    let mut skip = |kind: &'static str, reason: String| skipped.note(path, kind, reason);
    for message in Messages::open(path).map_err(|e| e.to_string())? {
        let message = match message {
            Ok(message) => message,
            Err(error @ ReadError::Damaged { .. }) => {
                // Once, not once a lap.
                if first_pass {
                    tracing::warn!(%error, "replay: the recording ends here");
                }
                break;
            }
            Err(error) => return Err(error.to_string()),
        };
        let item = match &*message.topic {
            robotd_recording::CAMERA | robotd_recording::CAMERA_META => {
                match pairer.take(&message).and_then(|frame| match frame {
                    Some(frame) => frame.decode().map(|rgb| Some((frame, rgb))),
                    None => Ok(None),
                }) {
                    Ok(Some((frame, rgb))) => Item::Frame {
                        log_time: frame.log_time,
                        meta: frame.meta,
                        rgb,
                    },
                    Ok(None) => continue,
                    Err(reason) => {
                        skip(CAMERA_FRAME, reason);
                        continue;
                    }
                }
            }
            robotd_recording::ARM_STATE => {
                match serde_json::from_slice::<ArmState>(&message.data) {
                    Ok(state) => Item::Arm {
                        log_time: message.log_time,
                        state,
                    },
                    Err(e) => {
                        skip(ARM_STATE, format!("arm state: {e}"));
                        continue;
                    }
                }
            }
            robotd_recording::GRIPPER_STATE => {
                match serde_json::from_slice::<GripperState>(&message.data) {
                    Ok(state) => Item::Gripper {
                        log_time: message.log_time,
                        state,
                    },
                    Err(e) => {
                        skip(GRIPPER_STATE, format!("gripper state: {e}"));
                        continue;
                    }
                }
            }
            _ => continue,
        };
        if items.blocking_send(item).is_err() {
            return Ok(false);
        }
    }
    skipped.end_pass(path);
    Ok(true)
}

#[cfg(test)]
mod tests {
    use super::*;
    use robotd_recording::fixture::{write_recording, Entry, Recorded};

    fn drain(rx: &mut tokio::sync::mpsc::Receiver<Item>, until_ends: usize) -> Vec<Item> {
        let mut items = Vec::new();
        let mut ends = 0;
        while let Some(item) = rx.blocking_recv() {
            let end = matches!(item, Item::End | Item::Failed(_));
            items.push(item);
            if end {
                ends += 1;
                if ends == until_ends {
                    break;
                }
            }
        }
        items
    }

    #[test]
    fn a_pass_sends_frames_decoded_states_and_the_end_skipping_what_does_not_decode() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("s.mcap");
        let mut session = Recorded::short_session();
        session.entries.insert(
            3,
            (
                robotd_recording::fixture::T0,
                Entry::Other(robotd_recording::ARM_STATE.into(), b"{\"no\":1}".to_vec()),
            ),
        );
        write_recording(&path, &session);
        let (tx, mut rx) = tokio::sync::mpsc::channel(4);
        let reader = spawn(path, false, tx).unwrap();
        let items = drain(&mut rx, 1);
        reader.join().unwrap();
        let frames = items
            .iter()
            .filter(|i| matches!(i, Item::Frame { rgb, .. } if rgb.len() == 16 * 12 * 3))
            .count();
        let arms = items
            .iter()
            .filter(|i| matches!(i, Item::Arm { .. }))
            .count();
        let grippers = items
            .iter()
            .filter(|i| matches!(i, Item::Gripper { .. }))
            .count();
        assert_eq!((frames, arms, grippers), (13, 7, 2));
        assert!(matches!(items.last(), Some(Item::End)));
        assert!(rx.blocking_recv().is_none(), "no second lap without loop");
    }

    #[test]
    fn bad_messages_are_counted_by_kind_and_logged_once_not_once_each() {
        // 50 arm states that fail at 50 different JSON positions, 5 bad gripper states, and
        // 3 frames whose JPEG does not decode, in a file read twice (a loop).
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("s.mcap");
        let mut session = Recorded::short_session();
        let t = robotd_recording::fixture::T0;
        for k in 0..50 {
            let bad = format!("{{{}\"joints\": 1}}", " ".repeat(k));
            let entry = Entry::Other(robotd_recording::ARM_STATE.into(), bad.into_bytes());
            session.entries.push((t, entry));
        }
        for k in 0..5 {
            let bad = format!("[{k}]").into_bytes();
            let entry = Entry::Other(robotd_recording::GRIPPER_STATE.into(), bad);
            session.entries.push((t, entry));
        }
        for (_, entry) in session.entries.iter_mut().take(12).skip(6) {
            if let Entry::Frame { jpeg, .. } = entry {
                jpeg.truncate(4);
            }
        }
        write_recording(&path, &session);
        let (tx, mut rx) = tokio::sync::mpsc::channel(1000);
        let mut skipped = Skipped::default();
        let (counts, warnings) = crate::warnings_of(|| {
            assert_eq!(read_once(&path, &tx, &mut skipped), Ok(true));
            let counts = skipped.last_pass().clone();
            assert_eq!(read_once(&path, &tx, &mut skipped), Ok(true));
            assert_eq!(
                skipped.last_pass(),
                &counts,
                "the second lap skips the same"
            );
            counts
        });
        assert_eq!(counts[ARM_STATE], 50);
        assert_eq!(counts[GRIPPER_STATE], 5);
        assert!(counts[CAMERA_FRAME] >= 1, "{counts:?}");
        assert_eq!(counts.len(), 3, "{counts:?}");
        let firsts: Vec<&String> = warnings
            .iter()
            .filter(|w| w.contains("a message is skipped"))
            .collect();
        assert_eq!(
            firsts.len(),
            3,
            "one per kind, over both laps: {warnings:#?}"
        );
        let summaries: Vec<&String> = warnings
            .iter()
            .filter(|w| w.contains("messages skipped in this pass"))
            .collect();
        assert_eq!(summaries.len(), 1, "the first lap's: {warnings:#?}");
        assert!(
            summaries[0].contains("50 arm state (e.g. arm state: "),
            "{summaries:?}"
        );
        assert_eq!(warnings.len(), 4, "{warnings:#?}");
        drop(tx);
        let mut frames = 0;
        while let Some(item) = rx.blocking_recv() {
            frames += usize::from(matches!(item, Item::Frame { .. }));
        }
        assert!(frames >= 2 * 7, "the good frames still play: {frames}");
    }

    #[test]
    fn a_loop_reads_again_and_the_thread_stops_when_the_player_is_gone() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("s.mcap");
        write_recording(&path, &Recorded::short_session());
        let (tx, mut rx) = tokio::sync::mpsc::channel(4);
        let reader = spawn(path.clone(), true, tx).unwrap();
        let two_laps = drain(&mut rx, 2);
        assert_eq!(
            two_laps.iter().filter(|i| matches!(i, Item::End)).count(),
            2
        );
        drop(rx);
        reader.join().unwrap();

        let (tx, mut rx) = tokio::sync::mpsc::channel(4);
        let reader = spawn(dir.path().join("gone.mcap"), true, tx).unwrap();
        let items = drain(&mut rx, 1);
        reader.join().unwrap();
        assert!(
            matches!(&items[..], [Item::Failed(reason)] if reason.contains("no such file")),
            "{items:?}"
        );
    }
}
