//! RTDE protocol 2 wire format: package framing, field types and values, text messages.
//!
//! Shared by the client in this crate and by the simulated controller (`sim-ur5e`), so both
//! sides speak exactly one encoding; the byte-level tests below pin it to the reference
//! (`shared/reference/ur5e.md` §2.1-2.3). Everything is big-endian; a package is
//! `u16 size (header included) | u8 type | payload`.

use thiserror::Error;

/// Length of the package header: `u16` size plus `u8` type.
pub const HEADER_LEN: usize = 3;
/// Largest payload a package can carry (the size field is a `u16` that counts the header).
pub const MAX_PAYLOAD_LEN: usize = u16::MAX as usize - HEADER_LEN;
/// The protocol version this crate speaks (v2: recipe ids in O replies and U packages).
pub const PROTOCOL_VERSION: u16 = 2;
/// Longest comma-separated variable list a setup request may carry (G-RTDE).
pub const MAX_VARIABLE_LIST_LEN: usize = 2048;

/// RTDE package types (the ASCII letter is the wire value).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[repr(u8)]
pub enum PackageType {
    /// `V`: client asks for a protocol version; reply `u8` accepted.
    RequestProtocolVersion = b'V',
    /// `v`: client asks for the controller version; reply 4 x `u32`.
    GetUrcontrolVersion = b'v',
    /// `M`: text message (log line), either direction, no reply.
    TextMessage = b'M',
    /// `U`: data package, either direction, no reply.
    DataPackage = b'U',
    /// `O`: output recipe setup (frequency + names); reply recipe id + types.
    SetupOutputs = b'O',
    /// `I`: input recipe setup (names); reply recipe id + types.
    SetupInputs = b'I',
    /// `S`: start the output stream; reply `u8` accepted.
    Start = b'S',
    /// `P`: pause the output stream; reply `u8` accepted.
    Pause = b'P',
}

impl PackageType {
    /// Maps a wire byte to a package type; `None` for letters RTDE does not define.
    pub fn from_byte(byte: u8) -> Option<Self> {
        Some(match byte {
            b'V' => Self::RequestProtocolVersion,
            b'v' => Self::GetUrcontrolVersion,
            b'M' => Self::TextMessage,
            b'U' => Self::DataPackage,
            b'O' => Self::SetupOutputs,
            b'I' => Self::SetupInputs,
            b'S' => Self::Start,
            b'P' => Self::Pause,
            _ => return None,
        })
    }
}

/// Errors while framing or building packages.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Error)]
#[non_exhaustive]
pub enum FrameError {
    /// The size field is smaller than the 3-byte header it must include.
    #[error("RTDE package size field {size} is smaller than the 3-byte header")]
    SizeBelowHeader {
        /// The size field as received.
        size: u16,
    },
    /// A payload too long for the `u16` size field.
    #[error("RTDE payload of {len} bytes exceeds the {MAX_PAYLOAD_LEN}-byte maximum")]
    PayloadTooLong {
        /// Payload length that was asked for.
        len: usize,
    },
}

/// One framed package borrowed from a receive buffer.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RawPackage<'a> {
    /// The type byte (not yet validated against [`PackageType`]).
    pub type_byte: u8,
    /// Payload after the 3-byte header.
    pub payload: &'a [u8],
}

/// Finds the first complete package at the start of `buf`.
///
/// Returns `Ok(None)` when more bytes are needed, or the package and the number of bytes it
/// occupies. A size field below 3 cannot be resynchronised and is an error.
pub fn split_package(buf: &[u8]) -> Result<Option<(RawPackage<'_>, usize)>, FrameError> {
    if buf.len() < HEADER_LEN {
        return Ok(None);
    }
    let size = u16::from_be_bytes([buf[0], buf[1]]);
    if (size as usize) < HEADER_LEN {
        return Err(FrameError::SizeBelowHeader { size });
    }
    let size = size as usize;
    if buf.len() < size {
        return Ok(None);
    }
    Ok(Some((
        RawPackage {
            type_byte: buf[2],
            payload: &buf[HEADER_LEN..size],
        },
        size,
    )))
}

/// Bytes to drop from the start of `buf` after a framing error so that it starts at the next
/// plausible package header (size field of at least 3 and a type letter RTDE defines), or,
/// when none is buffered yet, so that only a possible header start (the last 2 bytes) remains.
///
/// TCP keeps no package boundaries, so once a size field is wrong the boundary is a guess:
/// a payload byte pair that looks like a header is taken for one, and whatever that frames is
/// then judged (unknown type, data that does not match the recipe) and dropped in turn until
/// the stream is back on real headers. Always at least 1 for a non-empty `buf`, so a caller
/// that drops this many bytes makes progress.
pub fn resync_offset(buf: &[u8]) -> usize {
    if buf.is_empty() {
        return 0;
    }
    (1..buf.len())
        .find(|&i| match buf.get(i..i + HEADER_LEN) {
            Some(h) => {
                u16::from_be_bytes([h[0], h[1]]) as usize >= HEADER_LEN
                    && PackageType::from_byte(h[2]).is_some()
            }
            // Too few bytes left to judge: keep them, more may complete a header.
            None => true,
        })
        .unwrap_or(buf.len())
}

/// Appends a header for a package of `payload_len` bytes, then the caller appends the payload.
pub fn push_header(
    out: &mut Vec<u8>,
    ty: PackageType,
    payload_len: usize,
) -> Result<(), FrameError> {
    if payload_len > MAX_PAYLOAD_LEN {
        return Err(FrameError::PayloadTooLong { len: payload_len });
    }
    let size = (payload_len + HEADER_LEN) as u16;
    out.extend_from_slice(&size.to_be_bytes());
    out.push(ty as u8);
    Ok(())
}

/// Appends a whole package (header and payload) to `out`.
pub fn push_package(out: &mut Vec<u8>, ty: PackageType, payload: &[u8]) -> Result<(), FrameError> {
    push_header(out, ty, payload.len())?;
    out.extend_from_slice(payload);
    Ok(())
}

/// Rewrites the size field of a package that starts at `start` in `out` after its payload was
/// appended in place (used to encode data packages without a scratch buffer).
pub fn patch_size(out: &mut [u8], start: usize) -> Result<(), FrameError> {
    let len = out.len() - start;
    if len > u16::MAX as usize {
        return Err(FrameError::PayloadTooLong {
            len: len - HEADER_LEN,
        });
    }
    out[start..start + 2].copy_from_slice(&(len as u16).to_be_bytes());
    Ok(())
}

/// The RTDE field types (G-RTDE "Data types").
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum RtdeType {
    /// 1 byte, 0 = false.
    Bool,
    /// 1 byte.
    Uint8,
    /// 4 bytes.
    Uint32,
    /// 8 bytes.
    Uint64,
    /// 4 bytes, signed.
    Int32,
    /// 8 bytes, IEEE-754.
    Double,
    /// 3 doubles.
    Vector3d,
    /// 6 doubles.
    Vector6d,
    /// 6 signed 32-bit integers.
    Vector6Int32,
    /// 6 unsigned 32-bit integers.
    Vector6Uint32,
}

impl RtdeType {
    /// Every type, for exhaustive tests.
    pub const ALL: [RtdeType; 10] = [
        Self::Bool,
        Self::Uint8,
        Self::Uint32,
        Self::Uint64,
        Self::Int32,
        Self::Double,
        Self::Vector3d,
        Self::Vector6d,
        Self::Vector6Int32,
        Self::Vector6Uint32,
    ];

    /// Bytes one value of this type occupies on the wire.
    pub const fn wire_len(self) -> usize {
        match self {
            Self::Bool | Self::Uint8 => 1,
            Self::Uint32 | Self::Int32 => 4,
            Self::Uint64 | Self::Double => 8,
            Self::Vector3d | Self::Vector6Int32 | Self::Vector6Uint32 => 24,
            Self::Vector6d => 48,
        }
    }

    /// The type name the controller writes in setup replies.
    pub const fn name(self) -> &'static str {
        match self {
            Self::Bool => "BOOL",
            Self::Uint8 => "UINT8",
            Self::Uint32 => "UINT32",
            Self::Uint64 => "UINT64",
            Self::Int32 => "INT32",
            Self::Double => "DOUBLE",
            Self::Vector3d => "VECTOR3D",
            Self::Vector6d => "VECTOR6D",
            Self::Vector6Int32 => "VECTOR6INT32",
            Self::Vector6Uint32 => "VECTOR6UINT32",
        }
    }

    /// Parses a type name from a setup reply; `None` for unknown words (including the
    /// special words `NOT_FOUND` and `IN_USE`, which [`SetupField`] handles).
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|t| t.name() == name)
    }
}

/// One entry of a setup reply: a type, or one of the two refusal words.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SetupField {
    /// The variable exists and has this type.
    Type(RtdeType),
    /// `NOT_FOUND`: the controller does not know the name.
    NotFound,
    /// `IN_USE`: another client (or a fieldbus) controls this input.
    InUse,
}

impl SetupField {
    /// The word the controller writes for this entry.
    pub const fn name(self) -> &'static str {
        match self {
            Self::Type(t) => t.name(),
            Self::NotFound => "NOT_FOUND",
            Self::InUse => "IN_USE",
        }
    }

    /// Parses one word of a setup reply; `None` for words that are neither a type nor a
    /// refusal word.
    pub fn from_name(word: &str) -> Option<Self> {
        match word {
            "NOT_FOUND" => Some(Self::NotFound),
            "IN_USE" => Some(Self::InUse),
            other => RtdeType::from_name(other).map(Self::Type),
        }
    }
}

/// One decoded field value.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum RtdeValue {
    /// `BOOL`.
    Bool(bool),
    /// `UINT8`.
    Uint8(u8),
    /// `UINT32`.
    Uint32(u32),
    /// `UINT64`.
    Uint64(u64),
    /// `INT32`.
    Int32(i32),
    /// `DOUBLE`.
    Double(f64),
    /// `VECTOR3D`.
    Vector3d([f64; 3]),
    /// `VECTOR6D`.
    Vector6d([f64; 6]),
    /// `VECTOR6INT32`.
    Vector6Int32([i32; 6]),
    /// `VECTOR6UINT32`.
    Vector6Uint32([u32; 6]),
}

/// Errors while decoding field values from a payload.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Error)]
#[non_exhaustive]
pub enum ValueDecodeError {
    /// The payload ended inside field `index`.
    #[error(
        "data package too short: field {index} ({ty:?}) needs {needed} bytes, {available} left"
    )]
    Truncated {
        /// Field position in the recipe.
        index: usize,
        /// Its type.
        ty: RtdeType,
        /// Bytes the field needs.
        needed: usize,
        /// Bytes that were left.
        available: usize,
    },
    /// Bytes left over after the last field: the package does not match the recipe.
    #[error("data package has {extra} bytes after the last recipe field")]
    TrailingBytes {
        /// Number of unused bytes.
        extra: usize,
    },
    /// A value of the wrong type was given for a field while encoding.
    #[error("field {index}: value of type {given:?} given where the recipe has {expected:?}")]
    TypeMismatch {
        /// Field position in the recipe.
        index: usize,
        /// The recipe's type.
        expected: RtdeType,
        /// The value's type.
        given: RtdeType,
    },
    /// Wrong number of values for the recipe while encoding.
    #[error("{given} values given for a recipe of {expected} fields")]
    CountMismatch {
        /// Recipe length.
        expected: usize,
        /// Values given.
        given: usize,
    },
}

fn f64_at(b: &[u8], i: usize) -> f64 {
    let mut a = [0u8; 8];
    a.copy_from_slice(&b[i * 8..i * 8 + 8]);
    f64::from_be_bytes(a)
}

fn u32_at(b: &[u8], i: usize) -> u32 {
    let mut a = [0u8; 4];
    a.copy_from_slice(&b[i * 4..i * 4 + 4]);
    u32::from_be_bytes(a)
}

impl RtdeValue {
    /// The type of this value.
    pub const fn rtde_type(&self) -> RtdeType {
        match self {
            Self::Bool(_) => RtdeType::Bool,
            Self::Uint8(_) => RtdeType::Uint8,
            Self::Uint32(_) => RtdeType::Uint32,
            Self::Uint64(_) => RtdeType::Uint64,
            Self::Int32(_) => RtdeType::Int32,
            Self::Double(_) => RtdeType::Double,
            Self::Vector3d(_) => RtdeType::Vector3d,
            Self::Vector6d(_) => RtdeType::Vector6d,
            Self::Vector6Int32(_) => RtdeType::Vector6Int32,
            Self::Vector6Uint32(_) => RtdeType::Vector6Uint32,
        }
    }

    /// A zero value of the given type (used to preallocate decode buffers).
    pub const fn zero(ty: RtdeType) -> Self {
        match ty {
            RtdeType::Bool => Self::Bool(false),
            RtdeType::Uint8 => Self::Uint8(0),
            RtdeType::Uint32 => Self::Uint32(0),
            RtdeType::Uint64 => Self::Uint64(0),
            RtdeType::Int32 => Self::Int32(0),
            RtdeType::Double => Self::Double(0.0),
            RtdeType::Vector3d => Self::Vector3d([0.0; 3]),
            RtdeType::Vector6d => Self::Vector6d([0.0; 6]),
            RtdeType::Vector6Int32 => Self::Vector6Int32([0; 6]),
            RtdeType::Vector6Uint32 => Self::Vector6Uint32([0; 6]),
        }
    }

    /// Appends the big-endian encoding of this value.
    pub fn encode(&self, out: &mut Vec<u8>) {
        match *self {
            Self::Bool(v) => out.push(u8::from(v)),
            Self::Uint8(v) => out.push(v),
            Self::Uint32(v) => out.extend_from_slice(&v.to_be_bytes()),
            Self::Uint64(v) => out.extend_from_slice(&v.to_be_bytes()),
            Self::Int32(v) => out.extend_from_slice(&v.to_be_bytes()),
            Self::Double(v) => out.extend_from_slice(&v.to_be_bytes()),
            Self::Vector3d(v) => v
                .iter()
                .for_each(|x| out.extend_from_slice(&x.to_be_bytes())),
            Self::Vector6d(v) => v
                .iter()
                .for_each(|x| out.extend_from_slice(&x.to_be_bytes())),
            Self::Vector6Int32(v) => v
                .iter()
                .for_each(|x| out.extend_from_slice(&x.to_be_bytes())),
            Self::Vector6Uint32(v) => v
                .iter()
                .for_each(|x| out.extend_from_slice(&x.to_be_bytes())),
        }
    }

    /// Decodes one value of type `ty` from exactly `ty.wire_len()` bytes.
    ///
    /// The caller guarantees the length (see [`decode_fields`]).
    fn decode_exact(ty: RtdeType, b: &[u8]) -> Self {
        match ty {
            // "0 = False, everything else = True" (G-RTDE).
            RtdeType::Bool => Self::Bool(b[0] != 0),
            RtdeType::Uint8 => Self::Uint8(b[0]),
            RtdeType::Uint32 => Self::Uint32(u32_at(b, 0)),
            RtdeType::Uint64 => {
                let mut a = [0u8; 8];
                a.copy_from_slice(&b[..8]);
                Self::Uint64(u64::from_be_bytes(a))
            }
            RtdeType::Int32 => Self::Int32(u32_at(b, 0) as i32),
            RtdeType::Double => Self::Double(f64_at(b, 0)),
            RtdeType::Vector3d => Self::Vector3d(core::array::from_fn(|i| f64_at(b, i))),
            RtdeType::Vector6d => Self::Vector6d(core::array::from_fn(|i| f64_at(b, i))),
            RtdeType::Vector6Int32 => {
                Self::Vector6Int32(core::array::from_fn(|i| u32_at(b, i) as i32))
            }
            RtdeType::Vector6Uint32 => Self::Vector6Uint32(core::array::from_fn(|i| u32_at(b, i))),
        }
    }

    /// The value as `f64` when it is a scalar number (booleans as 0/1).
    pub fn as_f64(&self) -> Option<f64> {
        Some(match *self {
            Self::Bool(v) => f64::from(u8::from(v)),
            Self::Uint8(v) => f64::from(v),
            Self::Uint32(v) => f64::from(v),
            Self::Uint64(v) => v as f64,
            Self::Int32(v) => f64::from(v),
            Self::Double(v) => v,
            _ => return None,
        })
    }
}

/// Checks that `bytes` hold exactly the fields of `types`, without decoding them.
pub fn check_fields_len(types: &[RtdeType], bytes: &[u8]) -> Result<(), ValueDecodeError> {
    let mut available = bytes.len();
    for (index, &ty) in types.iter().enumerate() {
        let needed = ty.wire_len();
        if available < needed {
            return Err(ValueDecodeError::Truncated {
                index,
                ty,
                needed,
                available,
            });
        }
        available -= needed;
    }
    if available != 0 {
        return Err(ValueDecodeError::TrailingBytes { extra: available });
    }
    Ok(())
}

/// Decodes the fields of a data package (after the recipe id byte) by the recipe's types,
/// writing into `out` (which must have `types.len()` slots; no allocation). The length is
/// checked first, so on an error `out` is left as it was (a receiver keeps its last good
/// values rather than a mix of two packages).
pub fn decode_fields(
    types: &[RtdeType],
    mut bytes: &[u8],
    out: &mut [RtdeValue],
) -> Result<(), ValueDecodeError> {
    if out.len() != types.len() {
        return Err(ValueDecodeError::CountMismatch {
            expected: types.len(),
            given: out.len(),
        });
    }
    check_fields_len(types, bytes)?;
    for (&ty, slot) in types.iter().zip(out.iter_mut()) {
        let (field, rest) = bytes.split_at(ty.wire_len());
        *slot = RtdeValue::decode_exact(ty, field);
        bytes = rest;
    }
    Ok(())
}

/// Appends the encoding of `values`, checking them against the recipe's `types`.
pub fn encode_fields(
    types: &[RtdeType],
    values: &[RtdeValue],
    out: &mut Vec<u8>,
) -> Result<(), ValueDecodeError> {
    if types.len() != values.len() {
        return Err(ValueDecodeError::CountMismatch {
            expected: types.len(),
            given: values.len(),
        });
    }
    for (index, (&expected, value)) in types.iter().zip(values).enumerate() {
        let given = value.rtde_type();
        if given != expected {
            return Err(ValueDecodeError::TypeMismatch {
                index,
                expected,
                given,
            });
        }
        value.encode(out);
    }
    Ok(())
}

/// Severity of a text message (G-RTDE).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum TextLevel {
    /// 0.
    Exception,
    /// 1.
    Error,
    /// 2.
    Warning,
    /// 3.
    Info,
}

impl TextLevel {
    /// Level from its wire byte; unknown values read as `Info` would hide errors, so they are
    /// mapped to `Exception` (the most severe) instead.
    pub fn from_byte(b: u8) -> Self {
        match b {
            1 => Self::Error,
            2 => Self::Warning,
            3 => Self::Info,
            _ => Self::Exception,
        }
    }

    /// The wire byte.
    pub fn to_byte(self) -> u8 {
        match self {
            Self::Exception => 0,
            Self::Error => 1,
            Self::Warning => 2,
            Self::Info => 3,
        }
    }
}

/// A protocol-2 text message.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TextMessage {
    /// The message text.
    pub message: String,
    /// Who sent it (e.g. `"RTDE"`).
    pub source: String,
    /// Severity.
    pub level: TextLevel,
}

/// Errors while decoding a text message payload.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Error)]
#[non_exhaustive]
pub enum TextDecodeError {
    /// The payload ended before the declared lengths.
    #[error("text message payload of {len} bytes is truncated")]
    Truncated {
        /// Payload length.
        len: usize,
    },
}

impl TextMessage {
    /// Decodes a v2 payload: `u8` length, message, `u8` length, source, `u8` level.
    /// Non-UTF-8 bytes are replaced rather than rejected: this is a log line.
    pub fn decode(payload: &[u8]) -> Result<Self, TextDecodeError> {
        let err = TextDecodeError::Truncated { len: payload.len() };
        let (&mlen, rest) = payload.split_first().ok_or(err)?;
        let message = rest.get(..mlen as usize).ok_or(err)?;
        let rest = &rest[mlen as usize..];
        let (&slen, rest) = rest.split_first().ok_or(err)?;
        let source = rest.get(..slen as usize).ok_or(err)?;
        let level = *rest.get(slen as usize).ok_or(err)?;
        Ok(Self {
            message: String::from_utf8_lossy(message).into_owned(),
            source: String::from_utf8_lossy(source).into_owned(),
            level: TextLevel::from_byte(level),
        })
    }

    /// Appends the v2 payload; texts longer than 255 bytes are cut at a character boundary.
    pub fn encode(&self, out: &mut Vec<u8>) {
        fn push_short(out: &mut Vec<u8>, s: &str) {
            let mut end = s.len().min(255);
            while !s.is_char_boundary(end) {
                end -= 1;
            }
            out.push(end as u8);
            out.extend_from_slice(&s.as_bytes()[..end]);
        }
        push_short(out, &self.message);
        push_short(out, &self.source);
        out.push(self.level.to_byte());
    }
}

/// Controller version from the `v` reply.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub struct ControllerVersion {
    /// Major (5 on e-Series with PolyScope 5).
    pub major: u32,
    /// Minor.
    pub minor: u32,
    /// Bugfix.
    pub bugfix: u32,
    /// Build.
    pub build: u32,
}

impl ControllerVersion {
    /// Decodes the 16-byte `v` reply payload; `None` for any other length (URPY rejects those too).
    pub fn decode(payload: &[u8]) -> Option<Self> {
        if payload.len() != 16 {
            return None;
        }
        Some(Self {
            major: u32_at(payload, 0),
            minor: u32_at(payload, 1),
            bugfix: u32_at(payload, 2),
            build: u32_at(payload, 3),
        })
    }

    /// The 16-byte `v` reply payload.
    pub fn encode(&self) -> [u8; 16] {
        let mut b = [0u8; 16];
        for (i, v) in [self.major, self.minor, self.bugfix, self.build]
            .iter()
            .enumerate()
        {
            b[i * 4..i * 4 + 4].copy_from_slice(&v.to_be_bytes());
        }
        b
    }
}

impl core::fmt::Display for ControllerVersion {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(
            f,
            "{}.{}.{}.{}",
            self.major, self.minor, self.bugfix, self.build
        )
    }
}

/// Splits a comma-separated variable list, dropping empty names (ur_rtde ends its lists with a
/// comma, reference §2.4).
pub fn split_names(list: &str) -> impl Iterator<Item = &str> {
    list.split(',').map(str::trim).filter(|n| !n.is_empty())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frequency_500_is_encoded_as_in_the_ur_rtde_trace() {
        // Reference §2.5: ur_rtde's O request carried 40 7F 40 00 00 00 00 00 for 500.0.
        let mut out = Vec::new();
        RtdeValue::Double(500.0).encode(&mut out);
        assert_eq!(out, [0x40, 0x7F, 0x40, 0, 0, 0, 0, 0]);
    }

    #[test]
    fn header_counts_itself_and_is_big_endian() {
        let mut out = Vec::new();
        push_package(&mut out, PackageType::RequestProtocolVersion, &[0, 2]).unwrap();
        assert_eq!(out, [0x00, 0x05, b'V', 0x00, 0x02]);
        let (pkg, used) = split_package(&out).unwrap().unwrap();
        assert_eq!(used, 5);
        assert_eq!(pkg.type_byte, b'V');
        assert_eq!(pkg.payload, &[0, 2]);
    }

    #[test]
    fn incomplete_packages_wait_for_more_bytes() {
        assert_eq!(split_package(&[0x00]).unwrap(), None);
        assert_eq!(split_package(&[0x00, 0x05, b'V', 0]).unwrap(), None);
    }

    #[test]
    fn size_below_header_is_an_error() {
        assert_eq!(
            split_package(&[0x00, 0x02, b'V']),
            Err(FrameError::SizeBelowHeader { size: 2 })
        );
    }

    #[test]
    fn a_failed_decode_leaves_the_previous_values() {
        let types = [RtdeType::Double, RtdeType::Int32];
        let mut out = [RtdeValue::Double(7.0), RtdeValue::Int32(7)];
        // The first field is whole, the second is cut: nothing may be written.
        let mut bytes = 1.5f64.to_be_bytes().to_vec();
        bytes.extend_from_slice(&[0, 0]);
        assert!(matches!(
            decode_fields(&types, &bytes, &mut out),
            Err(ValueDecodeError::Truncated { index: 1, .. })
        ));
        assert_eq!(out, [RtdeValue::Double(7.0), RtdeValue::Int32(7)]);
    }

    #[test]
    fn resync_skips_to_the_next_plausible_header() {
        let mut good = Vec::new();
        push_package(&mut good, PackageType::DataPackage, &[1, 2, 3]).unwrap();
        // Garbage whose pairs do not look like a header, then a real package.
        let buf = [&[0x00, 0x01, 0xAA][..], &good].concat();
        assert_eq!(resync_offset(&buf), 3);
        // No header in sight: keep only the last 2 bytes, which may start one.
        assert_eq!(resync_offset(&[0x00, 0x01, 0xAA, 0xBB, 0xCC]), 3);
        assert_eq!(resync_offset(&[0x00]), 1);
        assert_eq!(resync_offset(&[]), 0);
    }

    #[test]
    fn every_type_round_trips_and_has_its_documented_size() {
        let sizes = [1, 1, 4, 8, 4, 8, 24, 48, 24, 24];
        for (ty, size) in RtdeType::ALL.into_iter().zip(sizes) {
            assert_eq!(ty.wire_len(), size, "{ty:?}");
            assert_eq!(RtdeType::from_name(ty.name()), Some(ty));
        }
        let values = [
            RtdeValue::Bool(true),
            RtdeValue::Uint8(200),
            RtdeValue::Uint32(0xDEAD_BEEF),
            RtdeValue::Uint64(u64::MAX - 7),
            RtdeValue::Int32(-123_456),
            RtdeValue::Double(-1.25e-3),
            RtdeValue::Vector3d([1.0, -2.0, 3.5]),
            RtdeValue::Vector6d([0.1, 0.2, 0.3, -0.4, 0.5, 6.0]),
            RtdeValue::Vector6Int32([-1, 2, -3, 4, -5, i32::MIN]),
            RtdeValue::Vector6Uint32([1, 2, 3, 4, 5, u32::MAX]),
        ];
        let types: Vec<_> = values.iter().map(RtdeValue::rtde_type).collect();
        let mut bytes = Vec::new();
        encode_fields(&types, &values, &mut bytes).unwrap();
        assert_eq!(bytes.len(), sizes.iter().sum::<usize>());
        let mut out = vec![RtdeValue::Bool(false); values.len()];
        decode_fields(&types, &bytes, &mut out).unwrap();
        assert_eq!(out, values);
    }

    #[test]
    fn int32_is_big_endian_twos_complement() {
        let mut out = Vec::new();
        RtdeValue::Int32(-2).encode(&mut out);
        assert_eq!(out, [0xFF, 0xFF, 0xFF, 0xFE]);
    }

    #[test]
    fn any_nonzero_bool_byte_is_true() {
        let mut out = [RtdeValue::Bool(false)];
        decode_fields(&[RtdeType::Bool], &[7], &mut out).unwrap();
        assert_eq!(out[0], RtdeValue::Bool(true));
    }

    #[test]
    fn short_and_long_data_packages_are_typed_errors() {
        let types = [RtdeType::Double, RtdeType::Int32];
        let mut out = [RtdeValue::Double(0.0), RtdeValue::Int32(0)];
        assert!(matches!(
            decode_fields(&types, &[0u8; 10], &mut out),
            Err(ValueDecodeError::Truncated { index: 1, .. })
        ));
        assert_eq!(
            decode_fields(&types, &[0u8; 13], &mut out),
            Err(ValueDecodeError::TrailingBytes { extra: 1 })
        );
    }

    #[test]
    fn encoding_checks_types_against_the_recipe() {
        let mut out = Vec::new();
        assert!(matches!(
            encode_fields(&[RtdeType::Int32], &[RtdeValue::Double(1.0)], &mut out),
            Err(ValueDecodeError::TypeMismatch { index: 0, .. })
        ));
    }

    #[test]
    fn text_message_round_trips_and_rejects_truncation() {
        let msg = TextMessage {
            message: "protective stop".into(),
            source: "RTDE".into(),
            level: TextLevel::Warning,
        };
        let mut bytes = Vec::new();
        msg.encode(&mut bytes);
        assert_eq!(TextMessage::decode(&bytes).unwrap(), msg);
        for cut in 0..bytes.len() {
            assert!(TextMessage::decode(&bytes[..cut]).is_err(), "cut at {cut}");
        }
    }

    #[test]
    fn controller_version_needs_exactly_16_bytes() {
        let v = ControllerVersion {
            major: 5,
            minor: 21,
            bugfix: 0,
            build: 1_210_631,
        };
        assert_eq!(ControllerVersion::decode(&v.encode()), Some(v));
        assert_eq!(ControllerVersion::decode(&[0u8; 15]), None);
    }

    #[test]
    fn trailing_comma_names_are_ignored() {
        let names: Vec<_> = split_names("timestamp,actual_q,").collect();
        assert_eq!(names, ["timestamp", "actual_q"]);
    }
}

#[cfg(test)]
mod properties {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        /// Whatever arrives on the socket, the decoders return a value or an error, never panic.
        #[test]
        fn decoders_never_panic_on_arbitrary_bytes(bytes in proptest::collection::vec(any::<u8>(), 0..300)) {
            let _ = split_package(&bytes);
            let skip = resync_offset(&bytes);
            prop_assert!(skip <= bytes.len() && (bytes.is_empty() || skip >= 1));
            let _ = TextMessage::decode(&bytes);
            let _ = ControllerVersion::decode(&bytes);
            let types = [RtdeType::Double, RtdeType::Vector6d, RtdeType::Int32, RtdeType::Bool];
            let mut out = [RtdeValue::Bool(false); 4];
            let _ = decode_fields(&types, &bytes, &mut out);
        }

        /// Encoding then decoding a recipe's values gives them back.
        #[test]
        fn vectors_round_trip(v in proptest::array::uniform6(-1e6f64..1e6), i in any::<i32>(), u in any::<u64>()) {
            let values = [RtdeValue::Vector6d(v), RtdeValue::Int32(i), RtdeValue::Uint64(u)];
            let types = [RtdeType::Vector6d, RtdeType::Int32, RtdeType::Uint64];
            let mut bytes = Vec::new();
            encode_fields(&types, &values, &mut bytes).unwrap();
            let mut out = [RtdeValue::Bool(false); 3];
            decode_fields(&types, &bytes, &mut out).unwrap();
            prop_assert_eq!(out, values);
        }
    }
}
