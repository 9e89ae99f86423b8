//! Protocol 2.0 packet framing, shared by the real bus and the fake servo bus: packets
//! reassembled from a byte stream, status packets built.
//!
//! On the servo side (the fake servo bus, `robotd-fake-widowx`) instruction packets come in
//! and status packets go out. A controller's bytes arrive in arbitrary pieces; [`Deframer`]
//! keeps what it has, skips what is not a header, and hands out each complete instruction
//! packet once its CRC has been checked over the stuffed bytes and the stuffing removed.
//! Anything malformed is reported as [`FrameError`] and skipped, never trusted.
//! [`status_packet`] builds a reply with stuffing and CRC. The CRC is dynamixel2's (the same table the vendor SDK uses).
//!
//! Status packets are framed the same way, so the real bus reads the servos' sync-read replies
//! with [`Deframer`] too (`crate::bus`): `instruction` is then 0x55 ([`STATUS`]) and `params`
//! the error byte followed by the data.

use dynamixel2::checksum::calculate_checksum;

/// The packet header.
pub const HEADER: [u8; 4] = [0xFF, 0xFF, 0xFD, 0x00];
/// Instruction of a status packet.
pub const STATUS: u8 = 0x55;
/// Largest packet framed (the servos' control tables, and the fake's, are 256 bytes).
const MAX_LENGTH: usize = 1024;

/// One instruction packet, unstuffed.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Instruction {
    /// Target ID (0xFE = broadcast).
    pub id: u8,
    /// Instruction code.
    pub instruction: u8,
    /// Parameters.
    pub params: Vec<u8>,
}

/// A packet that was thrown away.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum FrameError {
    /// The CRC did not match.
    #[error("bad CRC on a packet for ID {id}")]
    Crc {
        /// Target ID.
        id: u8,
    },
    /// The length field is impossible.
    #[error("impossible packet length {length}")]
    Length {
        /// The length field.
        length: usize,
    },
    /// The body holds a header (`FF FF FD`) without the stuffing byte a sender always adds:
    /// the length field or the bytes are wrong even though the CRC matches.
    #[error("an unstuffed header inside a packet for ID {id}")]
    Stuffing {
        /// Target ID.
        id: u8,
    },
}

/// Reassembles instruction packets from a byte stream.
#[derive(Debug, Default)]
pub struct Deframer {
    buffer: Vec<u8>,
}

impl Deframer {
    /// Adds received bytes.
    pub fn push(&mut self, bytes: &[u8]) {
        self.buffer.extend_from_slice(bytes);
        if self.buffer.len() > 8 * MAX_LENGTH {
            // Nothing sane fills this much: start over.
            self.buffer.clear();
        }
    }

    /// The next complete packet, if any.
    pub fn next_packet(&mut self) -> Option<Result<Instruction, FrameError>> {
        loop {
            let start = find_header(&self.buffer)?;
            self.buffer.drain(..start);
            if self.buffer.len() < 7 {
                return None;
            }
            let length = usize::from(u16::from_le_bytes([self.buffer[5], self.buffer[6]]));
            if !(3..=MAX_LENGTH).contains(&length) {
                // Skip this header and look for the next one.
                self.buffer.drain(..4);
                return Some(Err(FrameError::Length { length }));
            }
            let total = 7 + length;
            if self.buffer.len() < total {
                return None;
            }
            let packet: Vec<u8> = self.buffer.drain(..total).collect();
            let id = packet[4];
            let crc = u16::from_le_bytes([packet[total - 2], packet[total - 1]]);
            if calculate_checksum(0, &packet[..total - 2]) != crc {
                return Some(Err(FrameError::Crc { id }));
            }
            let Some(body) = unstuff(&packet[7..total - 2]) else {
                return Some(Err(FrameError::Stuffing { id }));
            };
            let (instruction, params) = match body.split_first() {
                Some((i, p)) => (*i, p.to_vec()),
                None => continue,
            };
            return Some(Ok(Instruction {
                id,
                instruction,
                params,
            }));
        }
    }
}

/// Where the next header starts (`FF FF FD` not followed by `FD`).
fn find_header(buffer: &[u8]) -> Option<usize> {
    buffer
        .windows(4)
        .position(|w| w[0] == 0xFF && w[1] == 0xFF && w[2] == 0xFD && w[3] != 0xFD)
}

/// Removes the `FD` inserted after every `FF FF FD`; `None` when one is missing (a sender
/// stuffs every such run, so its absence means the packet was cut or corrupted).
pub fn unstuff(body: &[u8]) -> Option<Vec<u8>> {
    let mut out = Vec::with_capacity(body.len());
    let mut i = 0;
    while i < body.len() {
        out.push(body[i]);
        if i >= 2 && body[i - 2..=i] == [0xFF, 0xFF, 0xFD] {
            if body.get(i + 1) != Some(&0xFD) {
                return None;
            }
            i += 1;
        }
        i += 1;
    }
    Some(out)
}

/// Inserts an `FD` after every `FF FF FD`.
pub fn stuff(body: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(body.len() + 4);
    for (i, byte) in body.iter().enumerate() {
        out.push(*byte);
        if i >= 2 && body[i - 2..=i] == [0xFF, 0xFF, 0xFD] {
            out.push(0xFD);
        }
    }
    out
}

/// A status packet from `id` with `error` and `params`, stuffed, with its CRC.
pub fn status_packet(id: u8, error: u8, params: &[u8]) -> Vec<u8> {
    let mut body = vec![STATUS, error];
    body.extend_from_slice(params);
    let body = stuff(&body);
    let mut packet = HEADER.to_vec();
    packet.push(id);
    packet.extend_from_slice(&((body.len() + 2) as u16).to_le_bytes());
    packet.extend_from_slice(&body);
    let crc = calculate_checksum(0, &packet);
    packet.extend_from_slice(&crc.to_le_bytes());
    packet
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn crc_matches_the_manuals_examples() {
        // Ping to ID 1 → CRC 19 4E; a status from ID 1 → 8C C0 (docs/dynamixel.md).
        assert_eq!(
            calculate_checksum(0, &[0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x03, 0x00, 0x01]),
            0x4E19
        );
        let status = status_packet(1, 0, &[0xA6, 0x00, 0x00, 0x00]);
        assert_eq!(&status[status.len() - 2..], &[0x8C, 0xC0]);
    }

    #[test]
    fn stuffing_round_trips() {
        let raw = [0x03, 0xFF, 0xFF, 0xFD, 0xFF, 0x01];
        let stuffed = stuff(&raw);
        assert_eq!(stuffed, vec![0x03, 0xFF, 0xFF, 0xFD, 0xFD, 0xFF, 0x01]);
        assert_eq!(unstuff(&stuffed), Some(raw.to_vec()));
        let raw = [0xFF, 0xFF, 0xFD, 0xFD, 0xFF, 0xFF, 0xFD];
        assert_eq!(unstuff(&stuff(&raw)), Some(raw.to_vec()));
    }

    #[test]
    fn deframer_skips_garbage_and_rejects_bad_crc() {
        let mut ping = vec![0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x03, 0x00, 0x01, 0x19, 0x4E];
        let mut d = Deframer::default();
        d.push(&[0x00, 0x13, 0xFF]);
        d.push(&ping);
        assert_eq!(
            d.next_packet(),
            Some(Ok(Instruction {
                id: 1,
                instruction: 1,
                params: vec![]
            }))
        );
        ping[8] ^= 0x01;
        d.push(&ping);
        assert_eq!(d.next_packet(), Some(Err(FrameError::Crc { id: 1 })));
        d.push(&[0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x01, 0x00]);
        assert_eq!(d.next_packet(), Some(Err(FrameError::Length { length: 1 })));
        assert_eq!(d.next_packet(), None);
    }

    #[test]
    fn a_header_without_its_stuffing_byte_is_refused_even_with_a_good_crc() {
        // A status whose position ends in FF FF FD, its stuffing byte cut off and the CRC
        // recomputed: the length field says 8, as for an unstuffed reply.
        let mut packet = vec![0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x08, 0x00];
        packet.extend_from_slice(&[STATUS, 0x00, 0x00, 0xFF, 0xFF, 0xFD]);
        let crc = calculate_checksum(0, &packet);
        packet.extend_from_slice(&crc.to_le_bytes());
        let mut d = Deframer::default();
        d.push(&packet);
        assert_eq!(d.next_packet(), Some(Err(FrameError::Stuffing { id: 1 })));
        assert_eq!(unstuff(&[0xFF, 0xFF, 0xFD, 0x01]), None);
    }
}
