//! Small recordings written from scratch, in the layout robotd's recorder writes, for the
//! tests of what reads them (this crate, the replay driver). Built with the `fixture` feature
//! (and in this crate's own tests).
//!
//! [`Recorded::short_session`] is three seconds of a Ned2: a frame every 0.25 s, an arm state
//! every 0.5 s with a motion from 1.0 s to 1.8 s, two gripper states. Entries are written in
//! the order given, so a test can also write them out of time order, as a recorder may.

use crate::camera::FrameMeta;
use foxglove::messages::CompressedImage;
use robotd_protocol::arm::ArmState;
use robotd_protocol::camera::CameraIntrinsics;
use robotd_protocol::geometry::{JointState, Pose, RobotModel};
use robotd_protocol::gripper::GripperState;
use std::collections::BTreeMap;
use std::path::Path;

/// Log time of the first entry of [`Recorded::short_session`], ns since the Unix epoch.
pub const T0: u64 = 1_700_000_000_000_000_000;

/// `seconds` after [`T0`], ns.
pub fn at(seconds: f64) -> u64 {
    T0 + (seconds * 1e9).round() as u64
}

/// One entry of a recording.
#[derive(Debug, Clone, PartialEq)]
pub enum Entry {
    /// A camera frame: `/camera` and `/camera/meta`.
    Frame {
        /// Its header.
        meta: FrameMeta,
        /// Its JPEG.
        jpeg: Vec<u8>,
    },
    /// `/bus/arm/state`.
    Arm(ArmState),
    /// `/bus/gripper/state`.
    Gripper(GripperState),
    /// `/robot_description` with this URDF.
    Description(String),
    /// A message on another channel.
    Other(String, Vec<u8>),
}

/// A recording to write: entries at their log times, in writing order.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Recorded {
    /// `(log time, entry)`, written in this order.
    pub entries: Vec<(u64, Entry)>,
}

/// A `width × height` JPEG of one grey `shade`.
pub fn jpeg_image(width: u32, height: u32, shade: u8) -> Vec<u8> {
    let rgb = vec![shade; (width * height * 3) as usize];
    robotd_render::encode_jpeg(&rgb, width, height, 95).expect("a JPEG")
}

/// `jpeg` as a `/camera` message.
pub fn compressed_jpeg(jpeg: &[u8]) -> Vec<u8> {
    let image = CompressedImage {
        timestamp: None,
        frame_id: "camera_link".into(),
        data: jpeg.to_vec().into(),
        format: "jpeg".into(),
    };
    let mut bytes = Vec::new();
    foxglove::Encode::encode(&image, &mut bytes).expect("encodes");
    bytes
}

/// Intrinsics of a `width × height` pinhole camera.
pub fn intrinsics(width: u32, height: u32) -> CameraIntrinsics {
    CameraIntrinsics {
        width,
        height,
        fx: f64::from(width),
        fy: f64::from(width),
        cx: f64::from(width) / 2.0,
        cy: f64::from(height) / 2.0,
        distortion: [0.0; 5],
    }
}

/// The header of frame `frame_id` taken at `t`, `width × height`, with intrinsics.
pub fn meta(frame_id: u64, t: u64, width: u32, height: u32) -> FrameMeta {
    FrameMeta {
        frame_id,
        timestamp_unix_ns: t,
        width,
        height,
        camera_pose: [0.2, 0.0, 0.3, 0.0, std::f64::consts::PI, 0.0],
        intrinsics: Some(intrinsics(width, height)),
    }
}

/// An arm state: joint 1 at `j1` rad, the others 0; `still_since` 0 = moving.
pub fn arm_state(j1: f64, still_since: u64) -> ArmState {
    ArmState {
        joints: JointState::from_positions(vec![j1, 0.0, 0.0, 0.0, 0.0, 0.0], 0),
        tool_pose: Pose::default(),
        moving: still_since == 0,
        collision_detected: false,
        calibrated: true,
        estop_engaged: false,
        still_since_unix_ns: still_since,
    }
}

impl Recorded {
    /// Three seconds of a Ned2 (see the module's description).
    pub fn short_session() -> Recorded {
        let mut entries = vec![(
            T0,
            Entry::Description(
                robotd_kinematics::Kinematics::new(RobotModel::Ned2)
                    .urdf()
                    .to_owned(),
            ),
        )];
        for k in 0..7 {
            let t = at(0.5 * f64::from(k));
            let still_since = match k {
                0 | 1 => T0 - 1_000_000_000,
                2 | 3 => 0,
                _ => at(1.8),
            };
            entries.push((t, Entry::Arm(arm_state(0.1 * f64::from(k), still_since))));
        }
        for j in 0..13u32 {
            let t = at(0.25 * f64::from(j));
            entries.push((
                t,
                Entry::Frame {
                    meta: meta(u64::from(j), t, 16, 12),
                    jpeg: jpeg_image(16, 12, (j * 15) as u8),
                },
            ));
        }
        for (t, width_m, holding) in [(0.1, 0.03, false), (2.1, 0.01, true)] {
            entries.push((
                at(t),
                Entry::Gripper(GripperState {
                    holding,
                    width_m,
                    moving: false,
                }),
            ));
        }
        entries.sort_by_key(|(t, _)| *t);
        Recorded { entries }
    }

    /// The same without any entry `keep` refuses.
    pub fn without(mut self, keep: impl Fn(&Entry) -> bool) -> Recorded {
        self.entries.retain(|(_, entry)| keep(entry));
        self
    }

    /// Camera frames in it.
    pub fn frames(&self) -> usize {
        self.entries
            .iter()
            .filter(|(_, e)| matches!(e, Entry::Frame { .. }))
            .count()
    }

    /// Arm states in it.
    pub fn arm_states(&self) -> usize {
        self.entries
            .iter()
            .filter(|(_, e)| matches!(e, Entry::Arm(_)))
            .count()
    }

    /// The first arm state.
    pub fn first_arm_state(&self) -> ArmState {
        self.entries
            .iter()
            .find_map(|(_, e)| match e {
                Entry::Arm(state) => Some(state.clone()),
                _ => None,
            })
            .expect("an arm state")
    }
}

/// Writes `recorded` as an MCAP file at `path` (channels as robotd's recorder names them).
pub fn write_recording(path: &Path, recorded: &Recorded) {
    let file = std::io::BufWriter::new(std::fs::File::create(path).expect("creates the file"));
    let mut writer = mcap::Writer::new(file).expect("an MCAP writer");
    let mut channels: BTreeMap<String, u16> = BTreeMap::new();
    let mut sequence = 0;
    let mut write = |topic: &str, encoding: &str, t: u64, data: &[u8]| {
        let id = match channels.get(topic) {
            Some(id) => *id,
            None => {
                let id = writer
                    .add_channel(0, topic, encoding, &BTreeMap::new())
                    .expect("a channel");
                channels.insert(topic.to_owned(), id);
                id
            }
        };
        sequence += 1;
        let header = mcap::records::MessageHeader {
            channel_id: id,
            sequence,
            log_time: t,
            publish_time: t,
        };
        writer
            .write_to_known_channel(&header, data)
            .expect("a message");
    };
    for (t, entry) in &recorded.entries {
        match entry {
            Entry::Frame { meta, jpeg } => {
                write(crate::CAMERA, "protobuf", *t, &compressed_jpeg(jpeg));
                let header = serde_json::to_vec(meta).expect("JSON");
                write(crate::CAMERA_META, "json", *t, &header);
            }
            Entry::Arm(state) => {
                let body = serde_json::to_vec(state).expect("JSON");
                write(crate::ARM_STATE, "json", *t, &body);
            }
            Entry::Gripper(state) => {
                let body = serde_json::to_vec(state).expect("JSON");
                write(crate::GRIPPER_STATE, "json", *t, &body);
            }
            Entry::Description(urdf) => {
                let body = serde_json::json!({ "data": urdf }).to_string();
                write(crate::ROBOT_DESCRIPTION, "json", *t, body.as_bytes());
            }
            Entry::Other(topic, data) => write(topic, "json", *t, data),
        }
    }
    writer.finish().expect("closes the file");
}

/// Recordings damaged on purpose, for the fuzz tests of what reads them (this crate's reader
/// and description, the replay driver): cut, bits flipped, words overwritten, and length
/// fields changed (random bytes seldom hit those, and they are what a reader trusts).
pub mod damage {
    /// One change to a file's bytes; offsets are fractions of its length, or indices into its
    /// [`length_fields`].
    #[derive(Debug, Clone, PartialEq)]
    pub enum Damage {
        /// Cut the file at this fraction of its length.
        Truncate(f64),
        /// Flip one bit (0-7) of the byte at this fraction.
        Flip(f64, u8),
        /// Overwrite the 8 bytes at this fraction (a length field, a time) with a value.
        Word(f64, u64),
        /// Add to the length field of this index (modulo their number; wrapping).
        Length(usize, i64),
    }

    /// Where an MCAP file's length fields are, as `(offset, width in bytes)`: every record's
    /// (in the file and in its chunks) and each chunk header's uncompressed size, compression
    /// name length (4 bytes) and compressed size. Reads a valid file (panics on another).
    pub fn length_fields(bytes: &[u8]) -> Vec<(usize, usize)> {
        let u64_at = |i: usize| u64::from_le_bytes(bytes[i..i + 8].try_into().unwrap()) as usize;
        let mut fields = Vec::new();
        let mut at = 8; // the magic
        while at + 9 <= bytes.len() - 8 {
            fields.push((at + 1, 8));
            let (opcode, len) = (bytes[at], u64_at(at + 1));
            if opcode == 0x06 {
                // Chunk: start, end, uncompressed size, CRC, compression, compressed size.
                let body = at + 9;
                let compression =
                    u32::from_le_bytes(bytes[body + 28..body + 32].try_into().unwrap());
                let sizes = body + 32 + compression as usize;
                fields.extend([(body + 16, 8), (body + 28, 4), (sizes, 8)]);
                let (mut inner, end) = (sizes + 8, sizes + 8 + u64_at(sizes));
                while inner + 9 <= end {
                    fields.push((inner + 1, 8));
                    inner += 9 + u64_at(inner + 1);
                }
            }
            at += 9 + len;
        }
        fields
    }

    /// `bytes` (whose [`length_fields`] are `fields`) with `changes` applied in order.
    pub fn apply(bytes: &[u8], fields: &[(usize, usize)], changes: &[Damage]) -> Vec<u8> {
        let mut bytes = bytes.to_vec();
        let at = |fraction: f64, len: usize| ((fraction * len as f64) as usize).min(len - 1);
        for change in changes {
            match *change {
                Damage::Truncate(fraction) if !bytes.is_empty() => {
                    let len = bytes.len();
                    bytes.truncate(at(fraction, len));
                }
                Damage::Flip(fraction, bit) if !bytes.is_empty() => {
                    let i = at(fraction, bytes.len());
                    bytes[i] ^= 1 << (bit % 8);
                }
                Damage::Word(fraction, word) if bytes.len() >= 8 => {
                    let i = at(fraction, bytes.len() - 7);
                    bytes[i..i + 8].copy_from_slice(&word.to_le_bytes());
                }
                Damage::Length(field, delta) if !fields.is_empty() => {
                    let (i, width) = fields[field % fields.len()];
                    if i + width <= bytes.len() {
                        let mut word = [0u8; 8];
                        word[..width].copy_from_slice(&bytes[i..i + width]);
                        let value = u64::from_le_bytes(word).wrapping_add_signed(delta);
                        bytes[i..i + width].copy_from_slice(&value.to_le_bytes()[..width]);
                    }
                }
                _ => {}
            }
        }
        bytes
    }
}
