//! The VLP-16 data packet (user manual 63-9243, section 9.3): the 1206-byte UDP payload sent to
//! port 2368, decoded and encoded byte for byte.
//!
//! Layout (all integers little-endian; the flag is two bytes in the order the manual writes them:
//! `FF EE` on the wire, as the ROS driver, `velodyne-decoder` and `velodyne-lidar` read it, and
//! as captures of real sensors show):
//!
//! | bytes | content |
//! |---|---|
//! | `100 k .. 100 k + 2` | block `k`'s flag: the bytes `FF EE` (the manual's `0xFFEE`), `k` in 0..12 |
//! | `100 k + 2 .. + 4` | block `k`'s azimuth in hundredths of a degree, 0..=35999 |
//! | `100 k + 4 + 3 r .. + 3` | return `r` (0..32): distance in 2 mm units (0: no return), reflectivity |
//! | `1200 .. 1204` | timestamp: microseconds past the top of the hour, < 3,600,000,000 |
//! | `1204` | return mode: `0x37` strongest, `0x38` last, `0x39` dual |
//! | `1205` | product id: `0x22` for the VLP-16 and Puck LITE |
//!
//! Returns `0..16` are the first firing sequence (laser `r`), `16..32` the second (laser
//! `r - 16`). Decoding keeps every byte, so `encode(decode(x)) == x` for every valid `x`.

/// Bytes in a data packet's UDP payload.
pub const PAYLOAD_LEN: usize = 1206;
/// The UDP port the sensor sends data packets to.
pub const DATA_PORT: u16 = 2368;
/// Data blocks per packet.
pub const BLOCKS: usize = 12;
/// Lasers of the VLP-16.
pub const LASERS: usize = 16;
/// Returns per block: two firing sequences of the 16 lasers.
pub const RETURNS_PER_BLOCK: usize = 2 * LASERS;
/// Bytes per data block.
pub const BLOCK_LEN: usize = 100;
/// The flag that starts every data block: the bytes `FF EE` in this order (the manual's
/// `0xFFEE`; read as a little-endian u16 it is 0xEEFF).
pub const BLOCK_FLAG: [u8; 2] = [0xFF, 0xEE];
/// Product id of the VLP-16 (and the Puck LITE, which shares its packet format).
pub const PRODUCT_ID_VLP16: u8 = 0x22;
/// Byte offset of the timestamp.
pub const TIMESTAMP_OFFSET: usize = BLOCKS * BLOCK_LEN;
/// Byte offset of the return mode.
pub const RETURN_MODE_OFFSET: usize = TIMESTAMP_OFFSET + 4;
/// Byte offset of the product id.
pub const PRODUCT_ID_OFFSET: usize = RETURN_MODE_OFFSET + 1;
/// Azimuths are in hundredths of a degree below this.
pub const AZIMUTH_UNITS: u16 = 36_000;
/// Microseconds in an hour: the timestamp counts up to this and wraps to 0.
pub const HOUR_US: u32 = 3_600_000_000;
/// Metres per distance unit.
pub const DISTANCE_UNIT_M: f64 = 0.002;

/// Which return each block carries (factory byte 1204).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[repr(u8)]
pub enum ReturnMode {
    /// The strongest return of each firing; 12 firing cycles a packet.
    Strongest = 0x37,
    /// The last return of each firing; 12 firing cycles a packet.
    Last = 0x38,
    /// Both: blocks come in pairs with the same azimuth (even block: last return, odd block:
    /// strongest, or second strongest where the last is the strongest); 6 firing cycles a packet.
    Dual = 0x39,
}

impl ReturnMode {
    /// The mode a factory byte names, if any.
    pub fn from_byte(byte: u8) -> Option<Self> {
        match byte {
            0x37 => Some(Self::Strongest),
            0x38 => Some(Self::Last),
            0x39 => Some(Self::Dual),
            _ => None,
        }
    }

    /// Blocks per firing cycle: 2 in dual-return mode, else 1.
    pub fn blocks_per_cycle(self) -> usize {
        if self == Self::Dual { 2 } else { 1 }
    }
}

/// One laser return.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct Return {
    /// Distance in 2 mm units; 0 means no return.
    pub distance_2mm: u16,
    /// Calibrated reflectivity (0-100 diffuse, 101-255 retro-reflective).
    pub reflectivity: u8,
}

impl Return {
    /// The distance in metres (0 for no return).
    pub fn distance_m(self) -> f64 {
        f64::from(self.distance_2mm) * DISTANCE_UNIT_M
    }
}

/// One data block: two firing sequences of the 16 lasers.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Block {
    /// The azimuth of the block's first firing, in hundredths of a degree (0..=35999),
    /// clockwise seen from above (Velodyne's convention).
    pub azimuth_cdeg: u16,
    /// Returns `0..16`: first sequence, laser `r`; `16..32`: second sequence, laser `r - 16`.
    pub returns: [Return; RETURNS_PER_BLOCK],
}

/// A decoded data packet.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct DataPacket {
    /// The 12 data blocks.
    pub blocks: [Block; BLOCKS],
    /// Microseconds past the top of the hour of the first firing of the first block.
    pub timestamp_us: u32,
    /// Which returns the blocks carry.
    pub return_mode: ReturnMode,
    /// The product id (factory byte 1205); a foreign id is decoded and reported by the health
    /// check.
    pub product_id: u8,
}

/// What was wrong with a datagram that is not a data packet, and where.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum PacketError {
    /// The payload is not 1206 bytes (the byte offset is where the payload ends).
    #[error("a VLP-16 data packet has 1206 bytes, this datagram has {len}")]
    WrongLength {
        /// The datagram's length.
        len: usize,
    },
    /// A block does not start with the flag bytes `FF EE`.
    #[error("block {block} at byte {offset}: flag bytes {:02X} {:02X}, not FF EE", found[0], found[1])]
    BadBlockFlag {
        /// The block index (0..12).
        block: usize,
        /// The flag's byte offset.
        offset: usize,
        /// The two bytes found.
        found: [u8; 2],
    },
    /// A block's azimuth is 360 degrees or more.
    #[error("block {block} at byte {offset}: azimuth {azimuth_cdeg} cdeg is not below 36000")]
    AzimuthOutOfRange {
        /// The block index (0..12).
        block: usize,
        /// The azimuth's byte offset.
        offset: usize,
        /// The azimuth found.
        azimuth_cdeg: u16,
    },
    /// The timestamp is an hour or more.
    #[error("byte 1200: timestamp {timestamp_us} us is not below an hour (3600000000 us)")]
    TimestampOutOfRange {
        /// The timestamp found.
        timestamp_us: u32,
    },
    /// The return-mode byte is none of 0x37, 0x38, 0x39.
    #[error("byte 1204: return mode {byte:#04x} is none of 0x37, 0x38, 0x39")]
    UnknownReturnMode {
        /// The byte found.
        byte: u8,
    },
}

impl PacketError {
    /// The byte offset of what was wrong (for a wrong length: the datagram's length).
    pub fn offset(&self) -> usize {
        match *self {
            Self::WrongLength { len } => len,
            Self::BadBlockFlag { offset, .. } | Self::AzimuthOutOfRange { offset, .. } => offset,
            Self::TimestampOutOfRange { .. } => TIMESTAMP_OFFSET,
            Self::UnknownReturnMode { .. } => RETURN_MODE_OFFSET,
        }
    }

    /// A wrong length (short or long datagram), as opposed to a malformed packet.
    pub fn is_wrong_length(&self) -> bool {
        matches!(self, Self::WrongLength { .. })
    }
}

fn u16_at(bytes: &[u8; PAYLOAD_LEN], offset: usize) -> u16 {
    u16::from_le_bytes([bytes[offset], bytes[offset + 1]])
}

impl DataPacket {
    /// Decodes a UDP payload; never panics. Checks, in byte order: the length, each block's flag
    /// and azimuth, the timestamp and the return mode. The product id is not checked here.
    pub fn decode(bytes: &[u8]) -> Result<DataPacket, PacketError> {
        let Ok(bytes) = <&[u8; PAYLOAD_LEN]>::try_from(bytes) else {
            return Err(PacketError::WrongLength { len: bytes.len() });
        };
        let empty = Block {
            azimuth_cdeg: 0,
            returns: [Return::default(); RETURNS_PER_BLOCK],
        };
        let mut blocks = [empty; BLOCKS];
        for (k, block) in blocks.iter_mut().enumerate() {
            let base = k * BLOCK_LEN;
            let flag = [bytes[base], bytes[base + 1]];
            if flag != BLOCK_FLAG {
                return Err(PacketError::BadBlockFlag {
                    block: k,
                    offset: base,
                    found: flag,
                });
            }
            let azimuth = u16_at(bytes, base + 2);
            if azimuth >= AZIMUTH_UNITS {
                return Err(PacketError::AzimuthOutOfRange {
                    block: k,
                    offset: base + 2,
                    azimuth_cdeg: azimuth,
                });
            }
            block.azimuth_cdeg = azimuth;
            for (r, ret) in block.returns.iter_mut().enumerate() {
                let at = base + 4 + 3 * r;
                *ret = Return {
                    distance_2mm: u16_at(bytes, at),
                    reflectivity: bytes[at + 2],
                };
            }
        }
        let timestamp_us = u32::from_le_bytes([
            bytes[TIMESTAMP_OFFSET],
            bytes[TIMESTAMP_OFFSET + 1],
            bytes[TIMESTAMP_OFFSET + 2],
            bytes[TIMESTAMP_OFFSET + 3],
        ]);
        if timestamp_us >= HOUR_US {
            return Err(PacketError::TimestampOutOfRange { timestamp_us });
        }
        let mode_byte = bytes[RETURN_MODE_OFFSET];
        let Some(return_mode) = ReturnMode::from_byte(mode_byte) else {
            return Err(PacketError::UnknownReturnMode { byte: mode_byte });
        };
        Ok(DataPacket {
            blocks,
            timestamp_us,
            return_mode,
            product_id: bytes[PRODUCT_ID_OFFSET],
        })
    }

    /// Encodes the packet into a payload. Every field is written as it is (an azimuth of 36000
    /// or more, or a timestamp of an hour or more, is written too, and would not decode).
    pub fn encode(&self, out: &mut [u8; PAYLOAD_LEN]) {
        for (k, block) in self.blocks.iter().enumerate() {
            let base = k * BLOCK_LEN;
            out[base..base + 2].copy_from_slice(&BLOCK_FLAG);
            out[base + 2..base + 4].copy_from_slice(&block.azimuth_cdeg.to_le_bytes());
            for (r, ret) in block.returns.iter().enumerate() {
                let at = base + 4 + 3 * r;
                out[at..at + 2].copy_from_slice(&ret.distance_2mm.to_le_bytes());
                out[at + 2] = ret.reflectivity;
            }
        }
        out[TIMESTAMP_OFFSET..TIMESTAMP_OFFSET + 4]
            .copy_from_slice(&self.timestamp_us.to_le_bytes());
        out[RETURN_MODE_OFFSET] = self.return_mode as u8;
        out[PRODUCT_ID_OFFSET] = self.product_id;
    }

    /// The packet as a payload.
    pub fn to_bytes(&self) -> [u8; PAYLOAD_LEN] {
        let mut out = [0u8; PAYLOAD_LEN];
        self.encode(&mut out);
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> DataPacket {
        let mut blocks = [Block {
            azimuth_cdeg: 0,
            returns: [Return::default(); RETURNS_PER_BLOCK],
        }; BLOCKS];
        for (k, b) in blocks.iter_mut().enumerate() {
            b.azimuth_cdeg = 35_900 + 40 * k as u16 % 36_000;
            b.azimuth_cdeg %= 36_000;
            for (r, ret) in b.returns.iter_mut().enumerate() {
                ret.distance_2mm = (1000 + 7 * r + 131 * k) as u16;
                ret.reflectivity = (r * 3 + k) as u8;
            }
        }
        DataPacket {
            blocks,
            timestamp_us: 3_599_999_000,
            return_mode: ReturnMode::Strongest,
            product_id: PRODUCT_ID_VLP16,
        }
    }

    #[test]
    fn round_trip_and_byte_positions() {
        let p = sample();
        let bytes = p.to_bytes();
        assert_eq!(&bytes[0..2], &[0xFF, 0xEE]);
        assert_eq!(
            u16::from_le_bytes([bytes[102], bytes[103]]),
            p.blocks[1].azimuth_cdeg
        );
        // Block 2, return 5: distance at 200 + 4 + 15.
        assert_eq!(
            u16::from_le_bytes([bytes[219], bytes[220]]),
            1000 + 35 + 262
        );
        assert_eq!(bytes[221], 17);
        assert_eq!(&bytes[1200..1204], &3_599_999_000u32.to_le_bytes());
        assert_eq!(bytes[1204], 0x37);
        assert_eq!(bytes[1205], 0x22);
        assert_eq!(DataPacket::decode(&bytes), Ok(p));
    }

    #[test]
    fn errors_name_what_and_where() {
        let good = sample().to_bytes();
        assert_eq!(
            DataPacket::decode(&good[..1000]),
            Err(PacketError::WrongLength { len: 1000 })
        );
        let mut b = good;
        b[701] = 0xEF;
        let e = DataPacket::decode(&b).unwrap_err();
        assert_eq!(
            e,
            PacketError::BadBlockFlag {
                block: 7,
                offset: 700,
                found: [0xFF, 0xEF]
            }
        );
        assert_eq!(e.offset(), 700);
        assert!(e.to_string().contains("block 7 at byte 700"), "{e}");
        let mut b = good;
        b[302..304].copy_from_slice(&36_000u16.to_le_bytes());
        assert_eq!(
            DataPacket::decode(&b),
            Err(PacketError::AzimuthOutOfRange {
                block: 3,
                offset: 302,
                azimuth_cdeg: 36_000
            })
        );
        let mut b = good;
        b[1200..1204].copy_from_slice(&HOUR_US.to_le_bytes());
        assert_eq!(
            DataPacket::decode(&b).map_err(|e| e.offset()),
            Err(TIMESTAMP_OFFSET)
        );
        let mut b = good;
        b[1204] = 0x40;
        assert_eq!(
            DataPacket::decode(&b),
            Err(PacketError::UnknownReturnMode { byte: 0x40 })
        );
        let mut b = good;
        b[1205] = 0x28;
        assert_eq!(DataPacket::decode(&b).map(|p| p.product_id), Ok(0x28));
    }
}
