//! Classic CAN 2.0 identifiers and data frames.

use core::fmt;

/// Largest 11-bit (CAN 2.0A) identifier.
pub const MAX_STANDARD_ID: u16 = 0x7FF;
/// Largest 29-bit (CAN 2.0B) identifier.
pub const MAX_EXTENDED_ID: u32 = 0x1FFF_FFFF;
/// Most data bytes a classic CAN frame carries.
pub const MAX_DATA_LEN: usize = 8;

/// A CAN identifier: 11-bit standard or 29-bit extended.
///
/// The variants are public so that ids can be matched on; a value outside the range of its
/// variant is rejected by [`CanFrame::new`] and by [`CanId::standard`] / [`CanId::extended`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum CanId {
    /// 11-bit identifier, `0..=0x7FF`.
    Standard(u16),
    /// 29-bit identifier, `0..=0x1FFF_FFFF`.
    Extended(u32),
}

impl CanId {
    /// An 11-bit identifier, checked against `0..=0x7FF`.
    pub fn standard(raw: u16) -> Result<Self, FrameError> {
        if raw <= MAX_STANDARD_ID {
            Ok(Self::Standard(raw))
        } else {
            Err(FrameError::StandardIdOutOfRange { raw })
        }
    }

    /// A 29-bit identifier, checked against `0..=0x1FFF_FFFF`.
    pub fn extended(raw: u32) -> Result<Self, FrameError> {
        if raw <= MAX_EXTENDED_ID {
            Ok(Self::Extended(raw))
        } else {
            Err(FrameError::ExtendedIdOutOfRange { raw })
        }
    }

    /// Checks that the value lies within the range of its variant.
    pub fn validate(self) -> Result<Self, FrameError> {
        match self {
            Self::Standard(raw) => Self::standard(raw),
            Self::Extended(raw) => Self::extended(raw),
        }
    }

    /// The numeric identifier without the standard/extended distinction.
    pub fn raw(self) -> u32 {
        match self {
            Self::Standard(raw) => u32::from(raw),
            Self::Extended(raw) => raw,
        }
    }

    /// Whether this is a 29-bit identifier.
    pub fn is_extended(self) -> bool {
        matches!(self, Self::Extended(_))
    }
}

impl fmt::Display for CanId {
    /// candump notation: three hex digits for standard ids, eight for extended ids.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Standard(raw) => write!(f, "{raw:03X}"),
            Self::Extended(raw) => write!(f, "{raw:08X}"),
        }
    }
}

/// Why a frame could not be built.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum FrameError {
    /// A standard id above 0x7FF.
    #[error("standard CAN id 0x{raw:X} is out of range (max 0x7FF)")]
    StandardIdOutOfRange {
        /// The rejected value.
        raw: u16,
    },
    /// An extended id above 0x1FFF_FFFF.
    #[error("extended CAN id 0x{raw:X} is out of range (max 0x1FFFFFFF)")]
    ExtendedIdOutOfRange {
        /// The rejected value.
        raw: u32,
    },
    /// More than 8 data bytes (CAN FD is not supported).
    #[error("CAN frame data of {len} bytes is too long (classic CAN carries at most 8)")]
    DataTooLong {
        /// The rejected length.
        len: usize,
    },
}

/// A classic CAN data frame: a validated id and 0..=8 data bytes.
///
/// Remote (RTR), error and CAN FD frames are not represented: the RMP protocol uses none of them.
/// Bytes past `len` are always zero, so the derived equality compares only the payload.
#[derive(Clone, Copy, PartialEq, Eq, Hash)]
pub struct CanFrame {
    id: CanId,
    len: u8,
    data: [u8; MAX_DATA_LEN],
}

impl CanFrame {
    /// Builds a data frame; fails on an out-of-range id or more than 8 bytes.
    pub fn new(id: CanId, data: &[u8]) -> Result<Self, FrameError> {
        let id = id.validate()?;
        if data.len() > MAX_DATA_LEN {
            return Err(FrameError::DataTooLong { len: data.len() });
        }
        let mut bytes = [0u8; MAX_DATA_LEN];
        bytes[..data.len()].copy_from_slice(data);
        Ok(Self {
            id,
            // Cannot truncate: checked against MAX_DATA_LEN above.
            len: data.len() as u8,
            data: bytes,
        })
    }

    /// The frame's identifier.
    pub fn id(&self) -> CanId {
        self.id
    }

    /// The data bytes (0..=8 of them).
    pub fn data(&self) -> &[u8] {
        &self.data[..usize::from(self.len)]
    }

    /// The data length code (number of data bytes, 0..=8).
    pub fn dlc(&self) -> u8 {
        self.len
    }
}

impl fmt::Display for CanFrame {
    /// candump / cansend notation, e.g. `500#0102` or `00000413#`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}#", self.id)?;
        for byte in self.data() {
            write!(f, "{byte:02X}")?;
        }
        Ok(())
    }
}

impl fmt::Debug for CanFrame {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "CanFrame({self})")
    }
}

/// Why a candump-style text frame (`123#DEADBEEF`) could not be parsed.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum ParseFrameError {
    /// No `#` between id and data.
    #[error("CAN frame text {text:?} has no '#' between id and data")]
    MissingSeparator {
        /// The rejected text.
        text: String,
    },
    /// The id is not 3 (standard) or 8 (extended) hex digits.
    #[error("CAN id {text:?} must be 3 hex digits (standard) or 8 hex digits (extended)")]
    BadId {
        /// The rejected id text.
        text: String,
    },
    /// The data is not an even number of hex digits.
    #[error("CAN data {text:?} must be pairs of hex digits")]
    BadData {
        /// The rejected data text.
        text: String,
    },
    /// The values parse but do not make a valid frame.
    #[error(transparent)]
    Frame(#[from] FrameError),
}

impl core::str::FromStr for CanFrame {
    type Err = ParseFrameError;

    /// Parses cansend notation: `123#DEADBEEF` (standard) or `1F334455#11` (extended).
    fn from_str(text: &str) -> Result<Self, Self::Err> {
        let (id_text, data_text) =
            text.split_once('#')
                .ok_or_else(|| ParseFrameError::MissingSeparator {
                    text: text.to_owned(),
                })?;
        let bad_id = || ParseFrameError::BadId {
            text: id_text.to_owned(),
        };
        // from_str_radix alone would accept a leading '+'.
        if !id_text.bytes().all(|b| b.is_ascii_hexdigit()) {
            return Err(bad_id());
        }
        let id_value = u32::from_str_radix(id_text, 16).map_err(|_| bad_id())?;
        let id = match id_text.len() {
            3 => CanId::standard(u16::try_from(id_value).map_err(|_| bad_id())?)?,
            8 => CanId::extended(id_value)?,
            _ => return Err(bad_id()),
        };
        let bad_data = || ParseFrameError::BadData {
            text: data_text.to_owned(),
        };
        if data_text.len() % 2 != 0 || !data_text.bytes().all(|b| b.is_ascii_hexdigit()) {
            return Err(bad_data());
        }
        let mut data = [0u8; MAX_DATA_LEN];
        let len = data_text.len() / 2;
        if len > MAX_DATA_LEN {
            return Err(FrameError::DataTooLong { len }.into());
        }
        for (index, byte) in data.iter_mut().take(len).enumerate() {
            let pair = &data_text[2 * index..2 * index + 2];
            *byte = u8::from_str_radix(pair, 16).map_err(|_| bad_data())?;
        }
        Ok(Self::new(id, &data[..len])?)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ids_are_checked_against_their_width() {
        assert_eq!(CanId::standard(0x7FF), Ok(CanId::Standard(0x7FF)));
        assert_eq!(
            CanId::standard(0x800),
            Err(FrameError::StandardIdOutOfRange { raw: 0x800 })
        );
        assert_eq!(
            CanId::extended(0x1FFF_FFFF),
            Ok(CanId::Extended(0x1FFF_FFFF))
        );
        assert_eq!(
            CanId::extended(0x2000_0000),
            Err(FrameError::ExtendedIdOutOfRange { raw: 0x2000_0000 })
        );
    }

    #[test]
    fn new_rejects_bad_ids_and_long_data() {
        assert!(CanFrame::new(CanId::Standard(0x800), &[]).is_err());
        assert!(CanFrame::new(CanId::Extended(u32::MAX), &[]).is_err());
        assert_eq!(
            CanFrame::new(CanId::Standard(1), &[0; 9]),
            Err(FrameError::DataTooLong { len: 9 })
        );
    }

    #[test]
    fn data_holds_exactly_the_given_bytes_for_every_dlc() {
        let bytes = [1, 2, 3, 4, 5, 6, 7, 8];
        for len in 0..=MAX_DATA_LEN {
            let frame = CanFrame::new(CanId::Standard(0x500), &bytes[..len]).unwrap();
            assert_eq!(frame.data(), &bytes[..len]);
            assert_eq!(usize::from(frame.dlc()), len);
        }
    }

    #[test]
    fn text_round_trips_through_candump_notation() {
        let frame = CanFrame::new(CanId::Standard(0x502), &[0xDE, 0xAD]).unwrap();
        assert_eq!(frame.to_string(), "502#DEAD");
        assert_eq!("502#DEAD".parse::<CanFrame>(), Ok(frame));
        let ext = CanFrame::new(CanId::Extended(0x413), &[]).unwrap();
        assert_eq!(ext.to_string(), "00000413#");
        assert_eq!("00000413#".parse::<CanFrame>(), Ok(ext));
    }

    #[test]
    fn malformed_text_gives_typed_errors() {
        assert!(matches!(
            "502DEAD".parse::<CanFrame>(),
            Err(ParseFrameError::MissingSeparator { .. })
        ));
        assert!(matches!(
            "5020#00".parse::<CanFrame>(),
            Err(ParseFrameError::BadId { .. })
        ));
        assert!(matches!(
            "800#00".parse::<CanFrame>(),
            Err(ParseFrameError::Frame(
                FrameError::StandardIdOutOfRange { .. }
            ))
        ));
        assert!(matches!(
            "123#0".parse::<CanFrame>(),
            Err(ParseFrameError::BadData { .. })
        ));
        assert!(matches!(
            "123#ZZ".parse::<CanFrame>(),
            Err(ParseFrameError::BadData { .. })
        ));
        assert!(matches!(
            "123#001122334455667788".parse::<CanFrame>(),
            Err(ParseFrameError::Frame(FrameError::DataTooLong { len: 9 }))
        ));
        assert!(matches!(
            "+12#00".parse::<CanFrame>(),
            Err(ParseFrameError::BadId { .. })
        ));
        assert!(matches!(
            "123#+1".parse::<CanFrame>(),
            Err(ParseFrameError::BadData { .. })
        ));
        assert!(matches!(
            "123#é1".parse::<CanFrame>(),
            Err(ParseFrameError::BadData { .. })
        ));
    }
}
