//! USB / Ethernet framing of the v3 messages (reference §2.7, §3.1) and the Gen-1 USB tunnel
//! (§1.7), for a link other than CAN behind the driver's transport trait.
//!
//! v3 command packet: 16-bit id, N big-endian words, CRC-16/ARC appended most significant byte
//! first. Gen-1 USB packet: 18 bytes wrapping one CAN frame, with an 8-bit end-around-carry
//! checksum.

use core::fmt;

/// Longest v3 command packet this module builds: id + 3 words + CRC.
pub const MAX_COMMAND_PACKET: usize = 2 + 3 * 4 + 2;

/// Why a packet could not be built or parsed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum PacketError {
    /// Too many words, or an output buffer too small.
    TooLong,
    /// The packet's length is not 2 + 4N + 2.
    BadLength {
        /// Bytes received.
        len: usize,
    },
    /// The CRC does not match.
    BadCrc {
        /// CRC in the packet.
        received: u16,
        /// CRC computed over the packet.
        computed: u16,
    },
    /// A Gen-1 USB packet with a wrong start byte, length or checksum.
    BadUsbPacket,
}

impl fmt::Display for PacketError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            PacketError::TooLong => write!(f, "packet too long"),
            PacketError::BadLength { len } => {
                write!(f, "packet of {len} bytes has no valid layout")
            }
            PacketError::BadCrc { received, computed } => {
                write!(f, "CRC {received:#06x} in packet, {computed:#06x} computed")
            }
            PacketError::BadUsbPacket => write!(f, "malformed Gen-1 USB packet"),
        }
    }
}

impl core::error::Error for PacketError {}

/// CRC-16/ARC (poly 0x8005 reflected = 0xA001, init 0, no final xor), bitwise.
pub fn crc16(bytes: &[u8]) -> u16 {
    let mut crc: u16 = 0;
    for &b in bytes {
        crc ^= b as u16;
        for _ in 0..8 {
            crc = if crc & 1 != 0 {
                (crc >> 1) ^ 0xA001
            } else {
                crc >> 1
            };
        }
    }
    crc
}

/// Builds a v3 command packet into `out`; returns its length.
pub fn encode_command(id: u16, words: &[u32], out: &mut [u8]) -> Result<usize, PacketError> {
    let len = 2 + 4 * words.len() + 2;
    if words.len() > 3 || out.len() < len {
        return Err(PacketError::TooLong);
    }
    out[..2].copy_from_slice(&id.to_be_bytes());
    for (k, w) in words.iter().enumerate() {
        out[2 + 4 * k..6 + 4 * k].copy_from_slice(&w.to_be_bytes());
    }
    let crc = crc16(&out[..len - 2]);
    out[len - 2..len].copy_from_slice(&crc.to_be_bytes());
    Ok(len)
}

/// Parses a v3 command packet: (id, words, word count).
pub fn decode_command(packet: &[u8]) -> Result<(u16, [u32; 3], usize), PacketError> {
    let len = packet.len();
    if len < 4 || (len - 4) % 4 != 0 {
        return Err(PacketError::BadLength { len });
    }
    let n = (len - 4) / 4;
    if n > 3 {
        return Err(PacketError::TooLong);
    }
    let received = u16::from_be_bytes([packet[len - 2], packet[len - 1]]);
    let computed = crc16(&packet[..len - 2]);
    if received != computed {
        return Err(PacketError::BadCrc { received, computed });
    }
    let mut words = [0u32; 3];
    for (k, w) in words.iter_mut().take(n).enumerate() {
        let s = 2 + 4 * k;
        *w = u32::from_be_bytes([packet[s], packet[s + 1], packet[s + 2], packet[s + 3]]);
    }
    Ok((u16::from_be_bytes([packet[0], packet[1]]), words, n))
}

/// Gen-1 USB checksum over bytes 0..=16: 16-bit sum, high byte folded into the low byte twice,
/// two's complement of the result.
pub fn gen1_usb_checksum(bytes: &[u8]) -> u8 {
    let mut sum: u16 = bytes.iter().fold(0u16, |s, b| s.wrapping_add(*b as u16));
    for _ in 0..2 {
        sum = (sum & 0xFF) + (sum >> 8);
    }
    (!(sum as u8)).wrapping_add(1)
}

/// Wraps a host-to-base Gen-1 CAN frame in its 18-byte USB packet (channel byte 0, as ORCA).
pub fn gen1_usb_command(frame: &crate::RawFrame) -> [u8; 18] {
    let mut p = [0u8; 18];
    p[0] = 0xF0;
    p[1] = 0x55;
    p[6..8].copy_from_slice(&frame.id().to_be_bytes());
    p[9..9 + frame.len()].copy_from_slice(frame.data());
    p[17] = gen1_usb_checksum(&p[..17]);
    p
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gen1::{Gen1Command, Gen1Scaling};

    #[test]
    fn crc_check_value() {
        assert_eq!(crc16(b"123456789"), 0xBB3D);
    }

    #[test]
    fn reference_v3_packets() {
        let mut buf = [0u8; MAX_COMMAND_PACKET];
        // §2.7
        let n = encode_command(0x500, &[0.5f32.to_bits(), 0], &mut buf).unwrap();
        assert_eq!(&buf[..n], &[5, 0, 0x3F, 0, 0, 0, 0, 0, 0, 0, 0x44, 0x53]);
        let n = encode_command(0x501, &[32, 5], &mut buf).unwrap();
        assert_eq!(&buf[..n], &[5, 1, 0, 0, 0, 0x20, 0, 0, 0, 5, 0x44, 0x5C]);
        let n = encode_command(0x501, &[0, 0], &mut buf).unwrap();
        assert_eq!(&buf[..n], &[5, 1, 0, 0, 0, 0, 0, 0, 0, 0, 0x80, 0x1D]);
        // §3.1 (Stanley 0x1800 with three words).
        let n = encode_command(0x1800, &[0.5f32.to_bits(), 0, 0.2f32.to_bits()], &mut buf).unwrap();
        assert_eq!(
            &buf[..n],
            &[
                0x18, 0, 0x3F, 0, 0, 0, 0, 0, 0, 0, 0x3E, 0x4C, 0xCC, 0xCD, 0xE6, 0x14
            ]
        );
        assert_eq!(decode_command(&buf[..n]).unwrap().0, 0x1800);
        let n = encode_command(0x1803, &[6, 1], &mut buf).unwrap();
        assert_eq!(&buf[..n], &[0x18, 3, 0, 0, 0, 6, 0, 0, 0, 1, 0x4F, 0xDD]);
    }

    #[test]
    fn corrupted_packets_are_rejected() {
        let mut buf = [0u8; MAX_COMMAND_PACKET];
        let n = encode_command(0x501, &[32, 5], &mut buf).unwrap();
        buf[5] ^= 1;
        assert!(matches!(
            decode_command(&buf[..n]),
            Err(PacketError::BadCrc { .. })
        ));
        assert_eq!(
            decode_command(&buf[..5]),
            Err(PacketError::BadLength { len: 5 })
        );
        assert_eq!(
            encode_command(0x500, &[0; 4], &mut [0u8; 64]),
            Err(PacketError::TooLong)
        );
    }

    #[test]
    fn reference_gen1_usb_packet() {
        // §1.7: motion 0.5 m/s on an RMP 200.
        let frame = Gen1Command {
            velocity_counts: Gen1Scaling::RMP_200_400.velocity_counts(0.5),
            turn_counts: 0,
            config: None,
        }
        .encode()
        .unwrap();
        assert_eq!(
            gen1_usb_command(&frame),
            [
                0xF0, 0x55, 0, 0, 0, 0, 0x04, 0x13, 0, 0, 0xA6, 0, 0, 0, 0, 0, 0, 0xFC
            ]
        );
    }
}
