//! The messages of an MCAP file, one at a time, in the order they were written.
//!
//! [`Messages`] drives the `mcap` crate's sans-I/O [`LinearReader`] from a buffered file: it
//! holds one record (at most one chunk) at a time, so replaying a gigabyte-long session costs
//! megabytes, not a gigabyte. Chunk checksums are checked, and a record longer than
//! [`RECORD_LIMIT`] is refused rather than allocated (so is a read the reader asks for beyond
//! it: a corrupt chunk header can claim gigabytes).
//!
//! The files are the user's, so a corrupt one must not take robotd down: `mcap` 0.25's reader
//! can panic on crafted input (an uncompressed chunk's records longer than the chunk overflow
//! its bookkeeping), so each step of the reader runs under `catch_unwind`, and a panic ends the
//! messages with [`ReadError::Damaged`] like any other corruption.
//!
//! Errors say which file and how far it got: a file that is not MCAP at all
//! ([`ReadError::NotMcap`]) differs from one that breaks off after some messages
//! ([`ReadError::Damaged`], e.g. a recorder killed before it closed the file): the messages
//! before the break are good, and a reader may keep them.

use mcap::records::Record;
use mcap::sans_io::linear_reader::{LinearReadEvent, LinearReader, LinearReaderOptions};
use std::collections::HashMap;
use std::fs::File;
use std::io::{BufReader, Read};
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// The longest record read (a camera image is well under a megabyte).
pub const RECORD_LIMIT: usize = 64 << 20;

/// The most bytes the reader may ask for at once: a record of [`RECORD_LIMIT`] with its opcode
/// and length, or a chunk header with a compression name of reasonable length. More is a
/// corrupt length field.
const READ_LIMIT: usize = RECORD_LIMIT + 1024;

/// Why a recording cannot be read (further).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ReadError {
    /// The file cannot be opened or read.
    #[error("cannot read {path}: {reason}")]
    Open {
        /// The file.
        path: PathBuf,
        /// The system's reason ("no such file", "permission denied").
        reason: String,
    },
    /// The file is not an MCAP file (or is empty).
    #[error("{path} is not an MCAP recording: {reason}")]
    NotMcap {
        /// The file.
        path: PathBuf,
        /// The reader's reason.
        reason: String,
    },
    /// The file breaks off or is corrupt after `messages` good messages.
    #[error("{path} is damaged after {messages} messages: {reason}")]
    Damaged {
        /// The file.
        path: PathBuf,
        /// Messages read before the damage.
        messages: u64,
        /// The reader's reason.
        reason: String,
    },
}

/// One recorded message.
#[derive(Debug, Clone, PartialEq)]
pub struct Message {
    /// Its channel's topic, e.g. `/camera` or `/bus/arm/state`.
    pub topic: Arc<str>,
    /// When it was logged, ns since the Unix epoch (a bus message's send time, a frame's
    /// capture time).
    pub log_time: u64,
    /// Its bytes, as the channel encodes them.
    pub data: Vec<u8>,
}

/// The messages of one file, as an iterator; it ends at the end of the file or at the first
/// error.
pub struct Messages {
    path: PathBuf,
    file: BufReader<File>,
    reader: LinearReader,
    channels: HashMap<u16, Arc<str>>,
    messages: u64,
    records: u64,
    done: bool,
}

impl std::fmt::Debug for Messages {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Messages")
            .field("path", &self.path)
            .field("messages", &self.messages)
            .finish_non_exhaustive()
    }
}

impl Messages {
    /// Opens `path` for reading from its start.
    pub fn open(path: &Path) -> Result<Messages, ReadError> {
        let file = File::open(path).map_err(|e| ReadError::Open {
            path: path.to_path_buf(),
            reason: match e.kind() {
                std::io::ErrorKind::NotFound => "no such file".to_owned(),
                _ => e.to_string(),
            },
        })?;
        if file.metadata().is_ok_and(|m| m.is_dir()) {
            return Err(ReadError::Open {
                path: path.to_path_buf(),
                reason: "it is a directory, not a recording".into(),
            });
        }
        let options = LinearReaderOptions::default()
            .with_validate_chunk_crcs(true)
            .with_record_length_limit(RECORD_LIMIT);
        Ok(Messages {
            path: path.to_path_buf(),
            file: BufReader::with_capacity(1 << 20, file),
            reader: LinearReader::new_with_options(options),
            channels: HashMap::new(),
            messages: 0,
            records: 0,
            done: false,
        })
    }

    /// How many messages were read so far.
    pub fn count(&self) -> u64 {
        self.messages
    }

    fn fail(&mut self, reason: String) -> ReadError {
        self.done = true;
        // Before the first record the file was never MCAP; after it, it broke off.
        if self.records == 0 {
            ReadError::NotMcap {
                path: self.path.clone(),
                reason,
            }
        } else {
            ReadError::Damaged {
                path: self.path.clone(),
                messages: self.messages,
                reason,
            }
        }
    }

    fn next_message(&mut self) -> Result<Option<Message>, ReadError> {
        loop {
            let event = match self.reader.next_event() {
                None => return Ok(None),
                Some(Err(error)) => {
                    let reason = match error {
                        mcap::McapError::BadMagic => "it does not start with the MCAP magic \
                                                      bytes"
                            .to_owned(),
                        mcap::McapError::UnexpectedEof if self.records == 0 => {
                            "the file is empty or too short".to_owned()
                        }
                        mcap::McapError::UnexpectedEof => "the file ends in the middle of a \
                                                           record (was the recorder stopped \
                                                           before it closed the file?)"
                            .to_owned(),
                        other => other.to_string(),
                    };
                    return Err(self.fail(reason));
                }
                Some(Ok(event)) => event,
            };
            match event {
                LinearReadEvent::ReadRequest(need) => {
                    if need > READ_LIMIT {
                        return Err(self.fail(format!(
                            "a record claims {need} more bytes (more than the {} MB limit: a \
                             corrupt length)",
                            RECORD_LIMIT >> 20
                        )));
                    }
                    let read = self.file.read(self.reader.insert(need));
                    match read {
                        Ok(n) => self.reader.notify_read(n),
                        Err(e) => return Err(self.fail(e.to_string())),
                    }
                }
                LinearReadEvent::Record { opcode, data } => {
                    let record = mcap::parse_record(opcode, data);
                    self.records += 1;
                    match record {
                        Ok(Record::Channel(channel)) => {
                            self.channels
                                .insert(channel.id, Arc::from(channel.topic.as_str()));
                        }
                        Ok(Record::Message { header, data }) => {
                            let Some(topic) = self.channels.get(&header.channel_id).cloned() else {
                                return Err(self.fail(format!(
                                    "a message of channel {} comes before that channel",
                                    header.channel_id
                                )));
                            };
                            self.messages += 1;
                            return Ok(Some(Message {
                                topic,
                                log_time: header.log_time,
                                data: data.into_owned(),
                            }));
                        }
                        Ok(_) => {}
                        Err(error) => return Err(self.fail(error.to_string())),
                    }
                }
            }
        }
    }
}

impl Iterator for Messages {
    type Item = Result<Message, ReadError>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.done {
            return None;
        }
        // The reader's state after a panic is unknown, so nothing more is read from it.
        let step = catch_unwind(AssertUnwindSafe(|| self.next_message()));
        match step {
            Ok(Ok(Some(message))) => Some(Ok(message)),
            Ok(Ok(None)) => {
                self.done = true;
                None
            }
            Ok(Err(error)) => Some(Err(error)),
            Err(panic) => {
                self.done = true;
                Some(Err(ReadError::Damaged {
                    path: self.path.clone(),
                    messages: self.messages,
                    reason: format!(
                        "the file is corrupt: the MCAP reader failed on it ({}); the messages \
                         before are good",
                        panic_message(panic.as_ref())
                    ),
                }))
            }
        }
    }
}

/// What a caught panic said.
fn panic_message(panic: &(dyn std::any::Any + Send)) -> &str {
    panic
        .downcast_ref::<&str>()
        .copied()
        .or_else(|| panic.downcast_ref::<String>().map(String::as_str))
        .unwrap_or("a panic")
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fixture::{write_recording, Recorded};

    #[test]
    fn messages_come_in_file_order_with_their_topics() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("s.mcap");
        write_recording(&path, &Recorded::short_session());
        let messages: Vec<Message> = Messages::open(&path)
            .unwrap()
            .collect::<Result<_, _>>()
            .unwrap();
        let topics: Vec<&str> = messages.iter().map(|m| &*m.topic).collect();
        assert_eq!(
            &topics[..4],
            [
                crate::ROBOT_DESCRIPTION,
                crate::ARM_STATE,
                crate::CAMERA,
                crate::CAMERA_META
            ]
        );
        assert!(messages.windows(2).all(|w| w[0].log_time <= w[1].log_time));
    }

    #[test]
    fn a_missing_file_an_empty_one_and_another_format_are_told_apart() {
        let dir = tempfile::tempdir().unwrap();
        let missing = Messages::open(&dir.path().join("none.mcap")).unwrap_err();
        assert!(missing.to_string().contains("no such file"), "{missing}");
        assert!(Messages::open(dir.path())
            .unwrap_err()
            .to_string()
            .contains("directory"));

        let empty = dir.path().join("empty.mcap");
        std::fs::write(&empty, b"").unwrap();
        let error = Messages::open(&empty).unwrap().next().unwrap().unwrap_err();
        assert!(matches!(error, ReadError::NotMcap { .. }), "{error}");
        assert!(error.to_string().contains("empty"), "{error}");

        let text = dir.path().join("notes.mcap");
        std::fs::write(&text, b"{\"this\": \"is json\"}").unwrap();
        let error = Messages::open(&text).unwrap().next().unwrap().unwrap_err();
        assert!(error.to_string().contains("MCAP magic"), "{error}");
    }

    /// Where the body of the first chunk record of an MCAP file starts.
    pub(crate) fn first_chunk_body(bytes: &[u8]) -> usize {
        let mut at = 8; // the magic
        loop {
            let opcode = bytes[at];
            let len = u64::from_le_bytes(bytes[at + 1..at + 9].try_into().unwrap()) as usize;
            if opcode == 0x06 {
                return at + 9;
            }
            at += 9 + len;
        }
    }

    /// The fixture with its first chunk's header changed by `change(header bytes)`.
    fn with_chunk_header(dir: &Path, change: impl Fn(&mut [u8])) -> PathBuf {
        let path = dir.join("s.mcap");
        write_recording(&path, &Recorded::short_session());
        let mut bytes = std::fs::read(&path).unwrap();
        let body = first_chunk_body(&bytes);
        change(&mut bytes[body..]);
        let changed = dir.join("changed.mcap");
        std::fs::write(&changed, &bytes).unwrap();
        changed
    }

    fn first_error(path: &Path) -> (u64, ReadError) {
        let mut messages = Messages::open(path).unwrap();
        let mut good = 0;
        loop {
            match messages.next() {
                Some(Ok(_)) => good += 1,
                Some(Err(error)) => {
                    assert!(messages.next().is_none(), "nothing after an error");
                    return (good, error);
                }
                None => panic!("a corrupt file must not end cleanly"),
            }
        }
    }

    #[test]
    fn a_chunk_whose_records_overrun_it_is_damaged_not_a_panic() {
        // A chunk header: start, end, uncompressed size (u64 each), uncompressed CRC (u32),
        // compression (u32 length + bytes; empty), compressed size (u64). A compressed size of
        // 1 makes mcap 0.25 subtract the first record's length from 1 (a panic in debug).
        let dir = tempfile::tempdir().unwrap();
        let path = with_chunk_header(dir.path(), |header| {
            assert_eq!(header[28..32], [0, 0, 0, 0], "an uncompressed chunk");
            header[32..40].copy_from_slice(&1u64.to_le_bytes());
        });
        let (_, error) = first_error(&path);
        assert!(matches!(error, ReadError::Damaged { .. }), "{error}");
        let text = error.to_string();
        assert!(text.contains("is damaged after"), "{text}");
        assert!(text.contains("changed.mcap"), "{text}");
        let contents = crate::contents::Contents::inspect(&path).unwrap();
        assert!(contents.damaged.is_some(), "described up to the damage");
    }

    #[test]
    fn a_chunk_header_claiming_gigabytes_is_refused_not_allocated() {
        let dir = tempfile::tempdir().unwrap();
        let path = with_chunk_header(dir.path(), |header| {
            header[28..32].copy_from_slice(&0xFFFF_FF00u32.to_le_bytes());
        });
        let (_, error) = first_error(&path);
        assert!(matches!(error, ReadError::Damaged { .. }), "{error}");
        assert!(error.to_string().contains("corrupt length"), "{error}");
    }

    #[test]
    fn a_file_that_breaks_off_keeps_its_first_messages() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("s.mcap");
        write_recording(&path, &Recorded::short_session());
        let whole = std::fs::read(&path).unwrap();
        let cut = dir.path().join("cut.mcap");
        std::fs::write(&cut, &whole[..whole.len() * 2 / 3]).unwrap();
        let mut messages = Messages::open(&cut).unwrap();
        let mut good = 0;
        let error = loop {
            match messages.next() {
                Some(Ok(_)) => good += 1,
                Some(Err(error)) => break error,
                None => panic!("a cut file must not end cleanly"),
            }
        };
        assert!(good > 0);
        assert!(
            matches!(error, ReadError::Damaged { messages, .. } if messages == good),
            "{error}"
        );
        assert!(messages.next().is_none(), "nothing after the damage");
    }
}
