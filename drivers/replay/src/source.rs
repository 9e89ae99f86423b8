//! The reader thread: the recording read from its file, one message at a time, decoded into the
//! [`Item`]s the player plays.
//!
//! Reading and JPEG decoding are blocking work, so they run on a thread of their own and hand
//! the player decoded messages through a small bounded channel: the thread is never more than
//! a few messages ahead, however long the file. A message that does not decode is skipped and
//! counted (the first of each kind is logged), never played half-read. A file that breaks off
//! ends the lap where it breaks. With `loop` the file is read again from its start; the
//! thread stops when the player is gone.

use crate::player::Item;
use robotd_protocol::arm::ArmState;
use robotd_protocol::gripper::GripperState;
use robotd_recording::camera::FramePairer;
use robotd_recording::reader::{Messages, ReadError};
use std::collections::BTreeMap;
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
        .spawn(move || loop {
            match read_once(&path, &items) {
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
        })
}

/// Sends every message of one pass over the file; `Ok(false)` when the player is gone.
fn read_once(path: &Path, items: &Sender<Item>) -> Result<bool, String> {
    let mut pairer = FramePairer::default();
    let mut skipped: BTreeMap<String, u64> = BTreeMap::new();
    let mut skip = |reason: String| {
        let count = skipped.entry(reason.clone()).or_insert(0);
        if *count == 0 {
            tracing::warn!(file = %path.display(), %reason, "replay: a message is skipped");
        }
        *count += 1;
    };
    for message in Messages::open(path).map_err(|e| e.to_string())? {
        let message = match message {
            Ok(message) => message,
            Err(error @ ReadError::Damaged { .. }) => {
                tracing::warn!(%error, "replay: the recording ends here");
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
                        skip(reason);
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
                        skip(format!("arm state: {e}"));
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
                        skip(format!("gripper state: {e}"));
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
    if !skipped.is_empty() {
        tracing::warn!(file = %path.display(), ?skipped, "replay: messages skipped in this pass");
    }
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
