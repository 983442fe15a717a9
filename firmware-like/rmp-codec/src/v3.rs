//! RMP v3 over CAN, Segway Inc firmware ("family B1"): motion (0x500), configuration and
//! general-purpose commands (0x501), operational modes and states.
//!
//! Every frame is DLC 8 and holds two big-endian 32-bit words. The motion command is
//! *normalised*: 1.0 means the base's configured velocity (or yaw-rate) limit, so a driver
//! divides its SI command by the limits it configured. The base answers every 0x500 / 0x501
//! with one feedback set (see [`crate::feedback`]).

use core::fmt;

use crate::RawFrame;
use crate::frame::{be_word, be_words};

/// Standard motion command: normalised velocity and yaw rate, float32 each.
pub const MOTION_ID: u16 = 0x500;
/// Configuration / general-purpose command: command id and parameter, u32 each.
pub const CONFIG_ID: u16 = 0x501;
/// Omni-platform motion command (not used by differential bases, never sent by this codec).
pub const OMNI_MOTION_ID: u16 = 0x600;

/// Why a received frame could not be decoded. Shared by the v3 and gen1 decoders.
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub enum DecodeError {
    /// The frame's id is not the one this decoder handles.
    WrongId {
        /// Id the decoder expects.
        expected: u16,
        /// Id that arrived.
        got: u16,
    },
    /// The payload length is not what the protocol defines for this id.
    BadLength {
        /// Frame id.
        id: u16,
        /// Bytes the protocol requires.
        expected: usize,
        /// Bytes that arrived.
        got: usize,
    },
    /// A float32 field holds NaN or an infinity.
    NonFinite {
        /// Frame id.
        id: u16,
        /// Which word (0 or 1) or slot.
        field: u8,
    },
    /// A numeric field lies outside the range the protocol allows.
    OutOfRange {
        /// Frame id.
        id: u16,
        /// Which word or slot.
        field: u8,
        /// The value as received (float bit patterns shown as their value).
        value: f32,
    },
    /// A configuration command id that the firmware profile does not define.
    UnknownCommand {
        /// The command id.
        command: u32,
    },
    /// A configuration command with a parameter outside its documented set or range.
    BadParameter {
        /// The command id.
        command: u32,
        /// The raw 32-bit parameter.
        parameter: u32,
    },
}

impl fmt::Display for DecodeError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            DecodeError::WrongId { expected, got } => {
                write!(f, "frame id {got:#05x}, expected {expected:#05x}")
            }
            DecodeError::BadLength { id, expected, got } => {
                write!(
                    f,
                    "frame {id:#05x} has {got} data bytes, expected {expected}"
                )
            }
            DecodeError::NonFinite { id, field } => {
                write!(f, "frame {id:#05x} field {field} is not a finite float")
            }
            DecodeError::OutOfRange { id, field, value } => {
                write!(f, "frame {id:#05x} field {field} = {value} is out of range")
            }
            DecodeError::UnknownCommand { command } => {
                write!(f, "unknown configuration command {command}")
            }
            DecodeError::BadParameter { command, parameter } => {
                write!(
                    f,
                    "configuration command {command}: bad parameter {parameter:#x}"
                )
            }
        }
    }
}

impl core::error::Error for DecodeError {}

/// Why a command could not be encoded. Shared by the v3 and gen1 encoders.
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub enum EncodeError {
    /// A float argument is NaN or infinite.
    NonFinite,
    /// A value lies outside the protocol's range.
    OutOfRange {
        /// The value given.
        value: f32,
        /// Lowest allowed value.
        min: f32,
        /// Highest allowed value.
        max: f32,
    },
    /// The selected firmware profile has no command with this meaning.
    UnsupportedByProfile {
        /// The profile in use.
        profile: FirmwareProfile,
    },
}

impl fmt::Display for EncodeError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            EncodeError::NonFinite => write!(f, "value is NaN or infinite"),
            EncodeError::OutOfRange { value, min, max } => {
                write!(f, "value {value} outside [{min}, {max}]")
            }
            EncodeError::UnsupportedByProfile { profile } => {
                write!(f, "firmware profile {profile:?} has no such command")
            }
        }
    }
}

impl core::error::Error for EncodeError {}

fn check_range(value: f32, min: f32, max: f32) -> Result<f32, EncodeError> {
    if !value.is_finite() {
        return Err(EncodeError::NonFinite);
    }
    if value < min || value > max {
        return Err(EncodeError::OutOfRange { value, min, max });
    }
    Ok(value)
}

fn expect_frame(frame: &RawFrame, id: u16) -> Result<(), DecodeError> {
    if frame.id() != id {
        return Err(DecodeError::WrongId {
            expected: id,
            got: frame.id(),
        });
    }
    if frame.len() != 8 {
        return Err(DecodeError::BadLength {
            id,
            expected: 8,
            got: frame.len(),
        });
    }
    Ok(())
}

/// 0x500: normalised velocity and yaw rate in [-1, 1], where 1.0 is the configured NVM limit
/// (velocity limit in m/s, yaw-rate limit in rad/s).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct MotionCommand {
    velocity: f32,
    yaw_rate: f32,
}

impl MotionCommand {
    /// Standing still.
    pub const ZERO: Self = Self {
        velocity: 0.0,
        yaw_rate: 0.0,
    };

    /// Builds a command; both values must be finite and within [-1, 1] (the firmware rejects
    /// anything else).
    pub fn new(velocity: f32, yaw_rate: f32) -> Result<Self, EncodeError> {
        Ok(Self {
            velocity: check_range(velocity, -1.0, 1.0)?,
            yaw_rate: check_range(yaw_rate, -1.0, 1.0)?,
        })
    }

    /// Normalised forward velocity (fraction of the velocity limit).
    pub const fn velocity(&self) -> f32 {
        self.velocity
    }

    /// Normalised yaw rate (fraction of the yaw-rate limit), positive = counter-clockwise as the
    /// codec sees it; the driver owns the sign convention of its base.
    pub const fn yaw_rate(&self) -> f32 {
        self.yaw_rate
    }

    /// The 0x500 frame.
    pub fn encode(&self) -> RawFrame {
        RawFrame::full(
            MOTION_ID,
            be_words(self.velocity.to_bits(), self.yaw_rate.to_bits()),
        )
    }

    /// Decodes a 0x500 frame, rejecting non-finite or out-of-range values.
    pub fn decode(frame: &RawFrame) -> Result<Self, DecodeError> {
        expect_frame(frame, MOTION_ID)?;
        let mut values = [0.0f32; 2];
        for (field, value) in values.iter_mut().enumerate() {
            let v = f32::from_bits(be_word(frame.data(), field));
            if !v.is_finite() {
                return Err(DecodeError::NonFinite {
                    id: MOTION_ID,
                    field: field as u8,
                });
            }
            if !(-1.0..=1.0).contains(&v) {
                return Err(DecodeError::OutOfRange {
                    id: MOTION_ID,
                    field: field as u8,
                    value: v,
                });
            }
            *value = v;
        }
        Ok(Self {
            velocity: values[0],
            yaw_rate: values[1],
        })
    }
}

/// Which release's configuration-command numbering to speak (the numbering moved between
/// firmware releases; reference §2.9 item 1). Read the build id from feedback and pick one.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
#[non_exhaustive]
pub enum FirmwareProfile {
    /// Segway Inc 2013/2014 firmware as in the Segway OCU demo and the 2014 C++ library
    /// (wheel-base command 9, four feedback bitmaps at 17..20, mode at 32). The default and the
    /// one the simulator implements.
    #[default]
    SegwayInc2014,
    /// The older numbering seen in a SocketCAN driver for a 440-class base (no wheel-base
    /// command, three feedback bitmaps at 0x10..0x12, mode at 0x15).
    Older440,
}

/// Operational mode a host may request with the set-mode command.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[repr(u32)]
pub enum ModeRequest {
    /// Disable the drive.
    Disable = 1,
    /// Power the base down.
    PowerDown = 2,
    /// Decelerate to zero, then stand by.
    DecelToZero = 3,
    /// Standby: powered, wheels not driven. The state after start-up.
    Standby = 4,
    /// Tractor: the only mode in which motion commands move a statically stable base.
    Tractor = 5,
    /// Balance (RMP 220 only).
    Balance = 6,
}

impl ModeRequest {
    /// Parses the set-mode parameter.
    pub fn from_parameter(parameter: u32) -> Option<Self> {
        Some(match parameter {
            1 => Self::Disable,
            2 => Self::PowerDown,
            3 => Self::DecelToZero,
            4 => Self::Standby,
            5 => Self::Tractor,
            6 => Self::Balance,
            _ => return None,
        })
    }
}

/// The `operational_state` feedback item (reference §2.6).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum OperationalState {
    /// 0: central control unit initialising.
    CcuInit,
    /// 1: propulsion initialising.
    PropulsionInit,
    /// 2: checking start-up issues.
    CheckStartup,
    /// 3: standby.
    Standby,
    /// 4: tractor.
    Tractor,
    /// 5: drive disabled / power being removed (balance on balancing firmware).
    DisablePower,
    /// A value no source documents; kept so that a driver can report it.
    Unknown(u32),
}

impl OperationalState {
    /// Decodes the feedback word.
    pub const fn from_word(word: u32) -> Self {
        match word {
            0 => Self::CcuInit,
            1 => Self::PropulsionInit,
            2 => Self::CheckStartup,
            3 => Self::Standby,
            4 => Self::Tractor,
            5 => Self::DisablePower,
            other => Self::Unknown(other),
        }
    }

    /// The feedback word.
    pub const fn to_word(self) -> u32 {
        match self {
            Self::CcuInit => 0,
            Self::PropulsionInit => 1,
            Self::CheckStartup => 2,
            Self::Standby => 3,
            Self::Tractor => 4,
            Self::DisablePower => 5,
            Self::Unknown(v) => v,
        }
    }

    /// The state a successful mode request leads to, where the sources say.
    pub const fn reached_by(request: ModeRequest) -> Option<Self> {
        match request {
            ModeRequest::Standby | ModeRequest::DecelToZero => Some(Self::Standby),
            ModeRequest::Tractor => Some(Self::Tractor),
            ModeRequest::Disable => Some(Self::DisablePower),
            ModeRequest::PowerDown | ModeRequest::Balance => None,
        }
    }
}

/// Float parameters stored in the base's NVM (F-RAM): id, range and default per reference §2.5.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum NvmFloat {
    /// Velocity limit, m/s; a normalised velocity of 1.0 means this.
    MaxVelocityMps,
    /// Acceleration limit, m/s^2.
    MaxAccelerationMps2,
    /// Deceleration limit, m/s^2; also the slew rate after a lost link.
    MaxDecelerationMps2,
    /// Decel-to-zero rate, m/s^2.
    MaxDtzDecelMps2,
    /// Coast-down acceleration, m/s^2.
    CoastDownAccelMps2,
    /// Yaw-rate limit, rad/s; a normalised yaw rate of 1.0 means this.
    MaxTurnRateRadps,
    /// Yaw acceleration limit, rad/s^2.
    MaxTurnAccelerationRadps2,
    /// Tyre diameter, m.
    TireDiameterM,
    /// Wheel base, m (not settable on the older numbering).
    WheelBaseM,
    /// Track width, m.
    TrackWidthM,
    /// Gearbox ratio.
    TransmissionRatio,
}

impl NvmFloat {
    /// All float parameters in parameter-id order (ids 1..=11 on the 2014 numbering).
    pub const ALL: [NvmFloat; 11] = [
        Self::MaxVelocityMps,
        Self::MaxAccelerationMps2,
        Self::MaxDecelerationMps2,
        Self::MaxDtzDecelMps2,
        Self::CoastDownAccelMps2,
        Self::MaxTurnRateRadps,
        Self::MaxTurnAccelerationRadps2,
        Self::TireDiameterM,
        Self::WheelBaseM,
        Self::TrackWidthM,
        Self::TransmissionRatio,
    ];

    /// Allowed (min, max).
    pub const fn range(self) -> (f32, f32) {
        match self {
            Self::MaxVelocityMps => (0.0, 8.047),
            Self::MaxAccelerationMps2 | Self::MaxDecelerationMps2 | Self::MaxDtzDecelMps2 => {
                (0.0, 7.848)
            }
            Self::CoastDownAccelMps2 => (0.0, 1.961),
            Self::MaxTurnRateRadps => (0.0, 4.5),
            Self::MaxTurnAccelerationRadps2 => (0.0, 28.274),
            Self::TireDiameterM => (0.1524, 1.0),
            Self::WheelBaseM => (0.4142, 1.0),
            Self::TrackWidthM => (0.506476, 1.0),
            Self::TransmissionRatio => (1.0, 200.0),
        }
    }

    /// Factory default.
    pub const fn default_value(self) -> f32 {
        match self {
            Self::MaxVelocityMps => 2.2352,
            Self::MaxAccelerationMps2 | Self::MaxDecelerationMps2 | Self::MaxDtzDecelMps2 => 3.923,
            Self::CoastDownAccelMps2 => 0.1962,
            Self::MaxTurnRateRadps => 3.0,
            Self::MaxTurnAccelerationRadps2 => 28.274,
            Self::TireDiameterM => 0.483616,
            Self::WheelBaseM => 0.5842,
            Self::TrackWidthM => 0.7112,
            Self::TransmissionRatio => 24.2667,
        }
    }
}

/// Ethernet settings stored in NVM (effective after a power cycle).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum EthernetField {
    /// IPv4 address, a.b.c.d = a*2^24 + b*2^16 + c*2^8 + d.
    Ip,
    /// UDP port.
    Port,
    /// Subnet mask.
    Subnet,
    /// Gateway address.
    Gateway,
}

/// A 0x501 command: command id (numbered per [`FirmwareProfile`]) and its 32-bit parameter.
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub enum ConfigCommand {
    /// No action; the base answers with a feedback set (used as keep-alive and probe).
    None,
    /// Set one float NVM parameter.
    SetFloat(NvmFloat, f32),
    /// Set the input-configuration bitmap.
    SetInputConfigBitmap(u32),
    /// Set one Ethernet field.
    SetEthernet(EthernetField, u32),
    /// Set user feedback bitmap `index` (0-based: 0..=3 on the 2014 numbering, 0..=2 older).
    SetFeedbackBitmap {
        /// 0-based bitmap number.
        index: u8,
        /// Item-selection bits.
        bitmap: u32,
    },
    /// Make the feedback carry the NVM configuration instead of the user items.
    ForceConfigFeedback(bool),
    /// Play a song (0 = none, up to 16).
    Audio(u8),
    /// Request an operational mode.
    SetOperationalMode(ModeRequest),
    /// Request the fault log (`true` = new request, `false` = next packet).
    SendFaultLog(bool),
    /// Reset integrators: 0x01 linear position, 0x02 RF, 0x04 LF, 0x08 RR, 0x10 LR wheel.
    ResetIntegrators(u8),
    /// Reset NVM parameters to factory defaults.
    ResetParametersToDefault,
}

/// Integrator-reset mask bits (command "reset integrators").
pub mod reset {
    /// Linear position.
    pub const LINEAR_POSITION: u8 = 0x01;
    /// Right-front wheel position.
    pub const RIGHT_FRONT: u8 = 0x02;
    /// Left-front wheel position.
    pub const LEFT_FRONT: u8 = 0x04;
    /// Right-rear wheel position.
    pub const RIGHT_REAR: u8 = 0x08;
    /// Left-rear wheel position.
    pub const LEFT_REAR: u8 = 0x10;
    /// Everything.
    pub const ALL: u8 = 0x1F;
}

/// The numbering of one firmware profile: id for each command kind.
struct Numbering {
    /// Ids of the float parameters, `None` where the profile lacks the command.
    floats: [Option<u32>; 11],
    input_bitmap: u32,
    ethernet: u32,
    feedback_bitmaps: u32,
    feedback_bitmap_count: u8,
    force_config: u32,
    audio: u32,
    mode: u32,
    fault_log: u32,
    reset_integrators: u32,
    reset_defaults: u32,
}

const SEGWAY_2014: Numbering = Numbering {
    floats: [
        Some(1),
        Some(2),
        Some(3),
        Some(4),
        Some(5),
        Some(6),
        Some(7),
        Some(8),
        Some(9),
        Some(10),
        Some(11),
    ],
    input_bitmap: 12,
    ethernet: 13,
    feedback_bitmaps: 17,
    feedback_bitmap_count: 4,
    force_config: 30,
    audio: 31,
    mode: 32,
    fault_log: 33,
    reset_integrators: 34,
    reset_defaults: 35,
};

const OLDER_440: Numbering = Numbering {
    floats: [
        Some(1),
        Some(2),
        Some(3),
        Some(4),
        Some(5),
        Some(6),
        Some(7),
        Some(8),
        None,
        Some(9),
        Some(0x0A),
    ],
    input_bitmap: 0x0B,
    ethernet: 0x0C,
    feedback_bitmaps: 0x10,
    feedback_bitmap_count: 3,
    force_config: 0x13,
    audio: 0x14,
    mode: 0x15,
    fault_log: 0x16,
    reset_integrators: 0x17,
    reset_defaults: 0x18,
};

impl FirmwareProfile {
    fn numbering(self) -> &'static Numbering {
        match self {
            FirmwareProfile::SegwayInc2014 => &SEGWAY_2014,
            FirmwareProfile::Older440 => &OLDER_440,
        }
    }

    /// How many user feedback bitmaps this firmware has.
    pub fn feedback_bitmap_count(self) -> u8 {
        self.numbering().feedback_bitmap_count
    }
}

const ETHERNET_FIELDS: [EthernetField; 4] = [
    EthernetField::Ip,
    EthernetField::Port,
    EthernetField::Subnet,
    EthernetField::Gateway,
];

impl ConfigCommand {
    /// (command id, parameter) for `profile`, validating the parameter.
    pub fn to_words(&self, profile: FirmwareProfile) -> Result<(u32, u32), EncodeError> {
        let n = profile.numbering();
        let unsupported = EncodeError::UnsupportedByProfile { profile };
        Ok(match *self {
            ConfigCommand::None => (0, 0),
            ConfigCommand::SetFloat(which, value) => {
                let (min, max) = which.range();
                let value = check_range(value, min, max)?;
                let index = NvmFloat::ALL.iter().position(|p| *p == which).unwrap_or(0);
                (n.floats[index].ok_or(unsupported)?, value.to_bits())
            }
            ConfigCommand::SetInputConfigBitmap(bits) => (n.input_bitmap, bits),
            ConfigCommand::SetEthernet(field, value) => {
                let offset = ETHERNET_FIELDS
                    .iter()
                    .position(|f| *f == field)
                    .unwrap_or(0);
                (n.ethernet + offset as u32, value)
            }
            ConfigCommand::SetFeedbackBitmap { index, bitmap } => {
                if index >= n.feedback_bitmap_count {
                    return Err(EncodeError::OutOfRange {
                        value: index as f32,
                        min: 0.0,
                        max: (n.feedback_bitmap_count - 1) as f32,
                    });
                }
                (n.feedback_bitmaps + index as u32, bitmap)
            }
            ConfigCommand::ForceConfigFeedback(on) => (n.force_config, on as u32),
            ConfigCommand::Audio(song) => {
                check_range(song as f32, 0.0, 16.0)?;
                (n.audio, song as u32)
            }
            ConfigCommand::SetOperationalMode(mode) => (n.mode, mode as u32),
            ConfigCommand::SendFaultLog(new) => (n.fault_log, new as u32),
            ConfigCommand::ResetIntegrators(mask) => {
                check_range(mask as f32, 0.0, reset::ALL as f32)?;
                (n.reset_integrators, mask as u32)
            }
            ConfigCommand::ResetParametersToDefault => (n.reset_defaults, 0),
        })
    }

    /// The 0x501 frame for `profile`.
    pub fn encode(&self, profile: FirmwareProfile) -> Result<RawFrame, EncodeError> {
        let (command, parameter) = self.to_words(profile)?;
        Ok(RawFrame::full(CONFIG_ID, be_words(command, parameter)))
    }

    /// Parses (command id, parameter) numbered per `profile`.
    pub fn from_words(
        profile: FirmwareProfile,
        command: u32,
        parameter: u32,
    ) -> Result<Self, DecodeError> {
        let n = profile.numbering();
        let bad = DecodeError::BadParameter { command, parameter };
        if command == 0 {
            return Ok(ConfigCommand::None);
        }
        if let Some(index) = n.floats.iter().position(|id| *id == Some(command)) {
            let which = NvmFloat::ALL[index];
            let value = f32::from_bits(parameter);
            let (min, max) = which.range();
            if !value.is_finite() || value < min || value > max {
                return Err(bad);
            }
            return Ok(ConfigCommand::SetFloat(which, value));
        }
        if command == n.input_bitmap {
            return Ok(ConfigCommand::SetInputConfigBitmap(parameter));
        }
        if (n.ethernet..n.ethernet + 4).contains(&command) {
            let field = ETHERNET_FIELDS[(command - n.ethernet) as usize];
            return Ok(ConfigCommand::SetEthernet(field, parameter));
        }
        let bitmaps = n.feedback_bitmaps..n.feedback_bitmaps + n.feedback_bitmap_count as u32;
        if bitmaps.contains(&command) {
            return Ok(ConfigCommand::SetFeedbackBitmap {
                index: (command - n.feedback_bitmaps) as u8,
                bitmap: parameter,
            });
        }
        let flag = |p: u32| match p {
            0 => Ok(false),
            1 => Ok(true),
            _ => Err(bad),
        };
        if command == n.force_config {
            return Ok(ConfigCommand::ForceConfigFeedback(flag(parameter)?));
        }
        if command == n.audio {
            return match parameter {
                0..=16 => Ok(ConfigCommand::Audio(parameter as u8)),
                _ => Err(bad),
            };
        }
        if command == n.mode {
            return ModeRequest::from_parameter(parameter)
                .map(ConfigCommand::SetOperationalMode)
                .ok_or(bad);
        }
        if command == n.fault_log {
            return Ok(ConfigCommand::SendFaultLog(flag(parameter)?));
        }
        if command == n.reset_integrators {
            return match parameter {
                0..=0x1F => Ok(ConfigCommand::ResetIntegrators(parameter as u8)),
                _ => Err(bad),
            };
        }
        if command == n.reset_defaults {
            return Ok(ConfigCommand::ResetParametersToDefault);
        }
        Err(DecodeError::UnknownCommand { command })
    }

    /// Decodes a 0x501 frame numbered per `profile`.
    pub fn decode(profile: FirmwareProfile, frame: &RawFrame) -> Result<Self, DecodeError> {
        expect_frame(frame, CONFIG_ID)?;
        Self::from_words(profile, be_word(frame.data(), 0), be_word(frame.data(), 1))
    }
}

/// Any host-to-base v3 frame, for the base side that must tell them apart.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum HostCommand {
    /// 0x500.
    Motion(MotionCommand),
    /// 0x501.
    Config(ConfigCommand),
}

impl HostCommand {
    /// Decodes 0x500 or 0x501; any other id is [`DecodeError::WrongId`] (expected 0x500).
    pub fn decode(profile: FirmwareProfile, frame: &RawFrame) -> Result<Self, DecodeError> {
        match frame.id() {
            CONFIG_ID => ConfigCommand::decode(profile, frame).map(HostCommand::Config),
            _ => MotionCommand::decode(frame).map(HostCommand::Motion),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reference_vectors_motion_and_config() {
        // rmp-can.md §2.7: 0x500, v = 0.5, yaw 0 -> 3F 00 00 00 00 00 00 00.
        let m = MotionCommand::new(0.5, 0.0).unwrap().encode();
        assert_eq!(m.id(), 0x500);
        assert_eq!(m.data(), &[0x3F, 0, 0, 0, 0, 0, 0, 0]);
        // §2.7 (payload part of the USB vector): tractor = (32, 5).
        let t = ConfigCommand::SetOperationalMode(ModeRequest::Tractor)
            .encode(FirmwareProfile::SegwayInc2014)
            .unwrap();
        assert_eq!(t.id(), 0x501);
        assert_eq!(t.data(), &[0, 0, 0, 0x20, 0, 0, 0, 5]);
        let none = ConfigCommand::None
            .encode(FirmwareProfile::SegwayInc2014)
            .unwrap();
        assert_eq!(none.data(), &[0; 8]);
        // Older numbering: mode is 0x15 (ITA).
        let t_old = ConfigCommand::SetOperationalMode(ModeRequest::Standby)
            .encode(FirmwareProfile::Older440)
            .unwrap();
        assert_eq!(t_old.data(), &[0, 0, 0, 0x15, 0, 0, 0, 4]);
    }

    #[test]
    fn motion_rejects_out_of_range_and_nan() {
        assert!(matches!(
            MotionCommand::new(1.5, 0.0),
            Err(EncodeError::OutOfRange { .. })
        ));
        assert_eq!(
            MotionCommand::new(0.0, f32::NAN),
            Err(EncodeError::NonFinite)
        );
        let nan = RawFrame::new(0x500, &[0x7F, 0xC0, 0, 0, 0, 0, 0, 0]).unwrap();
        assert_eq!(
            MotionCommand::decode(&nan),
            Err(DecodeError::NonFinite {
                id: 0x500,
                field: 0
            })
        );
        let two = RawFrame::new(0x500, &[0, 0, 0, 0, 0x40, 0, 0, 0]).unwrap();
        assert!(matches!(
            MotionCommand::decode(&two),
            Err(DecodeError::OutOfRange { field: 1, .. })
        ));
        let short = RawFrame::new(0x500, &[0x3F, 0, 0, 0]).unwrap();
        assert_eq!(
            MotionCommand::decode(&short),
            Err(DecodeError::BadLength {
                id: 0x500,
                expected: 8,
                got: 4
            })
        );
    }

    #[test]
    fn wheel_base_is_missing_on_older_firmware() {
        let cmd = ConfigCommand::SetFloat(NvmFloat::WheelBaseM, 0.6);
        assert!(cmd.encode(FirmwareProfile::SegwayInc2014).is_ok());
        assert_eq!(
            cmd.encode(FirmwareProfile::Older440),
            Err(EncodeError::UnsupportedByProfile {
                profile: FirmwareProfile::Older440
            })
        );
        // Track width moved from 10 to 9.
        let tw = ConfigCommand::SetFloat(NvmFloat::TrackWidthM, 0.7)
            .to_words(FirmwareProfile::Older440)
            .unwrap();
        assert_eq!(tw.0, 9);
    }

    #[test]
    fn every_command_round_trips_on_both_profiles() {
        let commands = [
            ConfigCommand::None,
            ConfigCommand::SetFloat(NvmFloat::MaxVelocityMps, 1.2),
            ConfigCommand::SetFloat(NvmFloat::TransmissionRatio, 24.2667),
            ConfigCommand::SetInputConfigBitmap(0x0301),
            ConfigCommand::SetEthernet(EthernetField::Gateway, 0xC0A8_0001),
            ConfigCommand::SetFeedbackBitmap {
                index: 2,
                bitmap: 0x1234,
            },
            ConfigCommand::ForceConfigFeedback(true),
            ConfigCommand::Audio(16),
            ConfigCommand::SetOperationalMode(ModeRequest::Tractor),
            ConfigCommand::SendFaultLog(false),
            ConfigCommand::ResetIntegrators(reset::ALL),
            ConfigCommand::ResetParametersToDefault,
        ];
        for profile in [FirmwareProfile::SegwayInc2014, FirmwareProfile::Older440] {
            for c in commands {
                let frame = c.encode(profile).unwrap();
                assert_eq!(ConfigCommand::decode(profile, &frame), Ok(c), "{profile:?}");
                assert_eq!(
                    HostCommand::decode(profile, &frame),
                    Ok(HostCommand::Config(c))
                );
            }
        }
    }

    #[test]
    fn config_decode_errors_are_typed() {
        let p = FirmwareProfile::SegwayInc2014;
        assert_eq!(
            ConfigCommand::from_words(p, 99, 0),
            Err(DecodeError::UnknownCommand { command: 99 })
        );
        assert_eq!(
            ConfigCommand::from_words(p, 32, 9),
            Err(DecodeError::BadParameter {
                command: 32,
                parameter: 9
            })
        );
        // 9 m/s is above the 8.047 m/s velocity ceiling.
        assert!(matches!(
            ConfigCommand::from_words(p, 1, 9.0f32.to_bits()),
            Err(DecodeError::BadParameter { command: 1, .. })
        ));
        assert_eq!(
            ConfigCommand::from_words(FirmwareProfile::Older440, 0x13, 2),
            Err(DecodeError::BadParameter {
                command: 0x13,
                parameter: 2
            })
        );
    }

    #[test]
    fn operational_state_words() {
        for w in 0..8 {
            assert_eq!(OperationalState::from_word(w).to_word(), w);
        }
        assert_eq!(
            OperationalState::reached_by(ModeRequest::Tractor),
            Some(OperationalState::Tractor)
        );
    }
}
