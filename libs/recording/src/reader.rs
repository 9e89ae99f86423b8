//! The messages of an MCAP file, one at a time, in the order they were written.
//!
//! [`Messages`] drives the `mcap` crate's sans-I/O [`LinearReader`] from a buffered file: it
//! holds one record (at most one chunk) at a time, so replaying a gigabyte-long session costs
//! megabytes, not a gigabyte. Chunk checksums are checked, and a record longer than
//! [`RECORD_LIMIT`] is refused rather than allocated.
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
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// The longest record read (a camera image is well under a megabyte).
pub const RECORD_LIMIT: usize = 64 << 20;

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
        match self.next_message() {
            Ok(Some(message)) => Some(Ok(message)),
            Ok(None) => {
                self.done = true;
                None
            }
            Err(error) => Some(Err(error)),
        }
    }
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
