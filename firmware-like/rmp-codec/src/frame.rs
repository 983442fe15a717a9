//! The CAN frame as the codec sees it: an 11-bit identifier and up to 8 data bytes.

use core::fmt;

/// Largest standard (11-bit) CAN identifier.
pub const MAX_STANDARD_ID: u16 = 0x7FF;

/// A classic CAN frame with a standard identifier, the only kind the RMP protocols use.
///
/// Bus crates convert to and from their own frame type; the codec only needs the id and bytes.
#[derive(Clone, Copy, PartialEq, Eq, Hash)]
pub struct RawFrame {
    id: u16,
    len: u8,
    data: [u8; 8],
}

/// Why a [`RawFrame`] could not be built.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum FrameError {
    /// The identifier does not fit in 11 bits.
    IdOutOfRange {
        /// The identifier that was given.
        id: u16,
    },
    /// More than 8 data bytes.
    TooLong {
        /// The number of bytes that was given.
        len: usize,
    },
}

impl fmt::Display for FrameError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            FrameError::IdOutOfRange { id } => {
                write!(f, "CAN id {id:#x} does not fit in 11 bits")
            }
            FrameError::TooLong { len } => write!(f, "{len} data bytes, a CAN frame holds 8"),
        }
    }
}

impl core::error::Error for FrameError {}

impl RawFrame {
    /// Builds a frame; fails on an id above 0x7FF or more than 8 bytes.
    pub fn new(id: u16, data: &[u8]) -> Result<Self, FrameError> {
        if id > MAX_STANDARD_ID {
            return Err(FrameError::IdOutOfRange { id });
        }
        if data.len() > 8 {
            return Err(FrameError::TooLong { len: data.len() });
        }
        let mut bytes = [0u8; 8];
        bytes[..data.len()].copy_from_slice(data);
        Ok(Self {
            id,
            len: data.len() as u8,
            data: bytes,
        })
    }

    /// Builds an 8-byte frame from a known-good protocol id (codec-internal constants).
    pub(crate) const fn full(id: u16, data: [u8; 8]) -> Self {
        Self { id, len: 8, data }
    }

    /// The 11-bit identifier.
    pub const fn id(&self) -> u16 {
        self.id
    }

    /// The data bytes (DLC long).
    pub fn data(&self) -> &[u8] {
        &self.data[..self.len as usize]
    }

    /// Data length code.
    pub const fn len(&self) -> usize {
        self.len as usize
    }

    /// True when the frame carries no data bytes.
    pub const fn is_empty(&self) -> bool {
        self.len == 0
    }
}

impl fmt::Debug for RawFrame {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{:03X}#", self.id)?;
        for b in self.data() {
            write!(f, "{b:02X}")?;
        }
        Ok(())
    }
}

/// Reads big-endian word `index` (0 or 1) of an 8-byte payload.
pub(crate) fn be_word(data: &[u8], index: usize) -> u32 {
    let s = index * 4;
    u32::from_be_bytes([data[s], data[s + 1], data[s + 2], data[s + 3]])
}

/// Packs two big-endian words into an 8-byte payload.
pub(crate) fn be_words(first: u32, second: u32) -> [u8; 8] {
    let a = first.to_be_bytes();
    let b = second.to_be_bytes();
    [a[0], a[1], a[2], a[3], b[0], b[1], b[2], b[3]]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rejects_extended_ids_and_long_payloads() {
        assert_eq!(
            RawFrame::new(0x800, &[]),
            Err(FrameError::IdOutOfRange { id: 0x800 })
        );
        assert_eq!(
            RawFrame::new(0x500, &[0; 9]),
            Err(FrameError::TooLong { len: 9 })
        );
        let f = RawFrame::new(0x7FF, &[1, 2, 3]).unwrap();
        assert_eq!(f.data(), &[1, 2, 3]);
        assert_eq!(std::format!("{f:?}"), "7FF#010203");
    }
}
