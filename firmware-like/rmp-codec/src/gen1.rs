//! The older RMP 50/100/200/400 protocol ("Gen-1", reference §1): 0x0413 motion with an
//! optional configuration command, 0x0412 shutdown, feedback 0x0400..0x0407 and 0x0680.
//!
//! Payloads are four big-endian 16-bit slots; 32-bit values span two slots, low word first.
//! Commands are in the base's own counts; [`Gen1Scaling`] converts, with the per-model factors
//! the sources disagree on kept as settings.

use crate::RawFrame;
use crate::v3::{DecodeError, EncodeError};

/// Motion + configuration command.
pub const MOTION_ID: u16 = 0x0413;
/// Shutdown (powers the base down at once). The UI box also sends this id when the power base
/// is off, so a host must not read a received 0x0412 as its own.
pub const SHUTDOWN_ID: u16 = 0x0412;
/// Velocity command limit, counts (about 8 mph).
pub const MAX_VELOCITY_COUNTS: i16 = 1176;
/// Turn command limit on standard firmware, counts.
pub const MAX_TURN_COUNTS: i16 = 1024;

fn slot(data: &[u8], k: usize) -> u16 {
    u16::from_be_bytes([data[2 * k], data[2 * k + 1]])
}

fn slot_i32(data: &[u8], k: usize) -> i32 {
    // Low word first (ORCA rawrxdata, PLAYER, CARMEN, LIB agree).
    ((slot(data, k + 1) as u32) << 16 | slot(data, k) as u32) as i32
}

fn slots(s: [u16; 4]) -> [u8; 8] {
    let mut out = [0u8; 8];
    for (k, v) in s.iter().enumerate() {
        out[2 * k..2 * k + 2].copy_from_slice(&v.to_be_bytes());
    }
    out
}

/// Operational mode (0x0406 slot 0, and the parameter of config command 16).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[repr(u16)]
pub enum Gen1Mode {
    /// 0: disabled.
    Disabled = 0,
    /// 1: tractor.
    Tractor = 1,
    /// 2: balance.
    Balance = 2,
    /// 3: power down (LIB only).
    PowerDown = 3,
}

impl Gen1Mode {
    fn from_slot(v: u16) -> Option<Self> {
        Some(match v {
            0 => Self::Disabled,
            1 => Self::Tractor,
            2 => Self::Balance,
            3 => Self::PowerDown,
            _ => return None,
        })
    }
}

/// Configuration command carried in slots 2..3 of 0x0413.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Gen1Config {
    /// 10: max velocity scale, 0..=16 (scale x 16).
    MaxVelocityScale(u16),
    /// 11: max acceleration scale, 0..=16.
    MaxAccelerationScale(u16),
    /// 12: max turn-rate scale, 0..=16.
    MaxTurnRateScale(u16),
    /// 13: balance gain schedule: 0 normal, 1 tall, 2 heavy.
    GainSchedule(u16),
    /// 14: current-limit scale, 0..=256 (scale x 256).
    CurrentLimitScale(u16),
    /// 15: balance-mode lockout.
    BalanceLockout(bool),
    /// 16: set operational mode.
    SetMode(Gen1Mode),
    /// 50: reset integrators, mask 0x01 right wheel, 0x02 left wheel, 0x04 yaw, 0x08 fore/aft.
    ResetIntegrators(u16),
}

impl Gen1Config {
    fn to_slots(self) -> Result<(u16, u16), EncodeError> {
        let ranged = |id: u16, v: u16, max: u16| {
            if v > max {
                Err(EncodeError::OutOfRange {
                    value: v as f32,
                    min: 0.0,
                    max: max as f32,
                })
            } else {
                Ok((id, v))
            }
        };
        match self {
            Self::MaxVelocityScale(v) => ranged(10, v, 16),
            Self::MaxAccelerationScale(v) => ranged(11, v, 16),
            Self::MaxTurnRateScale(v) => ranged(12, v, 16),
            Self::GainSchedule(v) => ranged(13, v, 2),
            Self::CurrentLimitScale(v) => ranged(14, v, 256),
            Self::BalanceLockout(on) => Ok((15, on as u16)),
            Self::SetMode(m) => Ok((16, m as u16)),
            Self::ResetIntegrators(mask) => ranged(50, mask, 0x0F),
        }
    }

    fn from_slots(id: u16, p: u16) -> Result<Option<Self>, DecodeError> {
        let bad = DecodeError::BadParameter {
            command: id as u32,
            parameter: p as u32,
        };
        let ranged = |max: u16| if p <= max { Ok(p) } else { Err(bad) };
        Ok(Some(match id {
            0 => return Ok(None),
            10 => Self::MaxVelocityScale(ranged(16)?),
            11 => Self::MaxAccelerationScale(ranged(16)?),
            12 => Self::MaxTurnRateScale(ranged(16)?),
            13 => Self::GainSchedule(ranged(2)?),
            14 => Self::CurrentLimitScale(ranged(256)?),
            15 => Self::BalanceLockout(ranged(1)? == 1),
            16 => Self::SetMode(Gen1Mode::from_slot(p).ok_or(bad)?),
            50 => Self::ResetIntegrators(ranged(0x0F)?),
            other => {
                return Err(DecodeError::UnknownCommand {
                    command: other as u32,
                });
            }
        }))
    }
}

/// 0x0413: velocity and turn in counts, plus an optional configuration command. Send the
/// current motion with a configuration command so the base does not stop for a cycle.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Gen1Command {
    /// Velocity, counts, |v| <= 1176.
    pub velocity_counts: i16,
    /// Turn, counts, |t| <= 1024.
    pub turn_counts: i16,
    /// Configuration command, if any.
    pub config: Option<Gen1Config>,
}

impl Gen1Command {
    /// The 0x0413 frame; rejects counts beyond the limits.
    pub fn encode(&self) -> Result<RawFrame, EncodeError> {
        let limit = |v: i16, max: i16| {
            if v.unsigned_abs() > max as u16 {
                Err(EncodeError::OutOfRange {
                    value: v as f32,
                    min: -(max as f32),
                    max: max as f32,
                })
            } else {
                Ok(v as u16)
            }
        };
        let (cid, param) = match self.config {
            Some(c) => c.to_slots()?,
            None => (0, 0),
        };
        Ok(RawFrame::full(
            MOTION_ID,
            slots([
                limit(self.velocity_counts, MAX_VELOCITY_COUNTS)?,
                limit(self.turn_counts, MAX_TURN_COUNTS)?,
                cid,
                param,
            ]),
        ))
    }

    /// Decodes 0x0413 (the base side).
    pub fn decode(frame: &RawFrame) -> Result<Self, DecodeError> {
        expect(frame, MOTION_ID)?;
        let d = frame.data();
        let velocity_counts = slot(d, 0) as i16;
        let turn_counts = slot(d, 1) as i16;
        for (field, v, max) in [
            (0u8, velocity_counts, MAX_VELOCITY_COUNTS),
            (1, turn_counts, MAX_TURN_COUNTS),
        ] {
            if v.unsigned_abs() > max as u16 {
                return Err(DecodeError::OutOfRange {
                    id: MOTION_ID,
                    field,
                    value: v as f32,
                });
            }
        }
        Ok(Self {
            velocity_counts,
            turn_counts,
            config: Gen1Config::from_slots(slot(d, 2), slot(d, 3))?,
        })
    }
}

/// The 0x0412 shutdown frame (all zeros).
pub fn shutdown_frame() -> RawFrame {
    RawFrame::full(SHUTDOWN_ID, [0; 8])
}

fn expect(frame: &RawFrame, id: u16) -> Result<(), DecodeError> {
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

/// One decoded Gen-1 feedback frame, raw counts (convert with [`Gen1Scaling`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum Gen1Feedback {
    /// 0x0400: firmware build id (slot 0); the other slots are undefined.
    BuildId(u16),
    /// 0x0401: pitch, pitch rate, roll, roll rate, counts of 1/7.8 deg (deg/s).
    Attitude {
        /// Pitch.
        pitch: i16,
        /// Pitch rate.
        pitch_rate: i16,
        /// Roll.
        roll: i16,
        /// Roll rate.
        roll_rate: i16,
    },
    /// 0x0402: wheel velocities, yaw rate, servo frame counter (0.01 s per count).
    Velocities {
        /// Left wheel velocity.
        left_wheel: i16,
        /// Right wheel velocity.
        right_wheel: i16,
        /// Yaw rate, 1/7.8 deg/s.
        yaw_rate: i16,
        /// Servo frame counter (wraps).
        frame_counter: u16,
    },
    /// 0x0403: wheel displacements (wrap; difference with roll-over).
    WheelDisplacement {
        /// Left.
        left: i32,
        /// Right.
        right: i32,
    },
    /// 0x0404: fore/aft displacement and yaw displacement.
    Integrated {
        /// Fore/aft.
        fore_aft: i32,
        /// Yaw, counts per revolution per model.
        yaw: i32,
    },
    /// 0x0405: motor torques.
    MotorTorque {
        /// Left.
        left: i16,
        /// Right.
        right: i16,
    },
    /// 0x0406: mode, gain schedule, batteries.
    ModeAndBattery {
        /// Operational mode; `None` for an undocumented value.
        mode: Option<Gen1Mode>,
        /// Gain schedule.
        gain_schedule: u16,
        /// UI battery, V = 1.4 + 0.0125 n.
        ui_battery: u16,
        /// Power-base battery, V = n / 4.
        base_battery: u16,
    },
    /// 0x0407: the velocity and turn command as received.
    CommandEcho {
        /// Velocity counts.
        velocity: i16,
        /// Turn counts.
        turn: i16,
    },
    /// 0x0680: controller status words 1 and 2.
    Status {
        /// Status word 1 (0x0080 = motors enabled).
        word1: u16,
        /// Status word 2 (side A low byte, side B high byte).
        word2: u16,
    },
}

/// Status word 1 bit: motors enabled.
pub const STATUS_MOTORS_ENABLED: u16 = 0x0080;

impl Gen1Feedback {
    /// Decodes a Gen-1 feedback frame.
    pub fn decode(frame: &RawFrame) -> Result<Self, DecodeError> {
        let id = frame.id();
        if !matches!(id, 0x0400..=0x0407 | 0x0680) {
            return Err(DecodeError::WrongId {
                expected: 0x0400,
                got: id,
            });
        }
        expect(frame, id)?;
        let d = frame.data();
        let s = |k| slot(d, k);
        let i = |k| slot(d, k) as i16;
        Ok(match id {
            0x0400 => Self::BuildId(s(0)),
            0x0401 => Self::Attitude {
                pitch: i(0),
                pitch_rate: i(1),
                roll: i(2),
                roll_rate: i(3),
            },
            0x0402 => Self::Velocities {
                left_wheel: i(0),
                right_wheel: i(1),
                yaw_rate: i(2),
                frame_counter: s(3),
            },
            0x0403 => Self::WheelDisplacement {
                left: slot_i32(d, 0),
                right: slot_i32(d, 2),
            },
            0x0404 => Self::Integrated {
                fore_aft: slot_i32(d, 0),
                yaw: slot_i32(d, 2),
            },
            0x0405 => Self::MotorTorque {
                left: i(0),
                right: i(1),
            },
            0x0406 => Self::ModeAndBattery {
                mode: Gen1Mode::from_slot(s(0)),
                gain_schedule: s(1),
                ui_battery: s(2),
                base_battery: s(3),
            },
            0x0407 => Self::CommandEcho {
                velocity: i(0),
                turn: i(1),
            },
            _ => Self::Status {
                word1: s(1),
                word2: s(2),
            },
        })
    }
}

/// Count-to-SI factors, which differ per model and between sources (reference §1.9).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Gen1Scaling {
    /// Velocity counts per m/s (332 on RMP 200/400, 401 on RMP 50/100).
    pub velocity_counts_per_mps: f32,
    /// Displacement counts per metre (33215 or 40181).
    pub displacement_counts_per_m: f32,
    /// Yaw displacement counts per revolution (112644 or 117031).
    pub yaw_counts_per_rev: f32,
    /// Pitch/roll/yaw-rate counts per degree (per second): 7.8.
    pub angle_counts_per_deg: f32,
}

impl Gen1Scaling {
    /// RMP 200 / 400 per LIB and ORCA.
    pub const RMP_200_400: Self = Self {
        velocity_counts_per_mps: 332.0,
        displacement_counts_per_m: 33215.0,
        yaw_counts_per_rev: 112644.0,
        angle_counts_per_deg: 7.8,
    };
    /// RMP 50 / 100 per LIB.
    pub const RMP_50_100: Self = Self {
        velocity_counts_per_mps: 401.0,
        displacement_counts_per_m: 40181.0,
        yaw_counts_per_rev: 117031.0,
        angle_counts_per_deg: 7.8,
    };

    /// Velocity counts for `speed_mps`, rounded and clamped to +-1176.
    pub fn velocity_counts(&self, speed_mps: f32) -> i16 {
        let counts = libm_round(speed_mps * self.velocity_counts_per_mps);
        counts.clamp(-(MAX_VELOCITY_COUNTS as f32), MAX_VELOCITY_COUNTS as f32) as i16
    }

    /// Metres for displacement counts.
    pub fn displacement_m(&self, counts: i32) -> f32 {
        counts as f32 / self.displacement_counts_per_m
    }

    /// m/s for wheel-velocity counts.
    pub fn speed_mps(&self, counts: i16) -> f32 {
        counts as f32 / self.velocity_counts_per_mps
    }
}

/// Round half away from zero without std.
fn libm_round(x: f32) -> f32 {
    let t = x as i32 as f32; // truncation; callers clamp to i16 range first or after
    if x - t >= 0.5 {
        t + 1.0
    } else if t - x >= 0.5 {
        t - 1.0
    } else {
        t
    }
}

/// Difference of two wrapping 32-bit counters (roll-over safe).
pub const fn counter_delta(previous: i32, current: i32) -> i32 {
    current.wrapping_sub(previous)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reference_command_vectors() {
        // rmp-can.md §1.8.
        let v = Gen1Scaling::RMP_200_400.velocity_counts(0.5);
        assert_eq!(v, 166);
        let f = Gen1Command {
            velocity_counts: v,
            turn_counts: 0,
            config: None,
        }
        .encode()
        .unwrap();
        assert_eq!(f.id(), 0x413);
        assert_eq!(f.data(), &[0x00, 0xA6, 0, 0, 0, 0, 0, 0]);
        let tractor = Gen1Command {
            velocity_counts: 0,
            turn_counts: 0,
            config: Some(Gen1Config::SetMode(Gen1Mode::Tractor)),
        }
        .encode()
        .unwrap();
        assert_eq!(tractor.data(), &[0, 0, 0, 0, 0x00, 0x10, 0x00, 0x01]);
        let reset = Gen1Command {
            velocity_counts: 0,
            turn_counts: 0,
            config: Some(Gen1Config::ResetIntegrators(0x0F)),
        }
        .encode()
        .unwrap();
        assert_eq!(reset.data(), &[0, 0, 0, 0, 0x00, 0x32, 0x00, 0x0F]);
        assert_eq!(
            Gen1Command::decode(&reset).unwrap().config,
            Some(Gen1Config::ResetIntegrators(15))
        );
        assert_eq!(shutdown_frame().id(), 0x412);
    }

    #[test]
    fn reference_log_frames_decode() {
        // ORCA CAN log, rmp-can.md §1.2 and §1.4.
        let disp = RawFrame::new(0x403, &[0xBF, 0x8F, 0xFF, 0xFF, 0, 0, 0, 0]).unwrap();
        assert_eq!(
            Gen1Feedback::decode(&disp),
            Ok(Gen1Feedback::WheelDisplacement {
                left: -16497,
                right: 0
            })
        );
        let mode = RawFrame::new(0x406, &[0x00, 0x01, 0x00, 0x00, 0x01, 0x8D, 0x01, 0x30]).unwrap();
        let Ok(Gen1Feedback::ModeAndBattery {
            mode,
            ui_battery,
            base_battery,
            ..
        }) = Gen1Feedback::decode(&mode)
        else {
            panic!("0x406 did not decode");
        };
        assert_eq!(mode, Some(Gen1Mode::Tractor));
        assert!((1.4 + 0.0125 * ui_battery as f32 - 6.3625).abs() < 1e-4);
        assert_eq!(base_battery / 4, 76);
        let status =
            RawFrame::new(0x680, &[0x00, 0x05, 0x00, 0x80, 0x00, 0x00, 0x3E, 0x57]).unwrap();
        assert_eq!(
            Gen1Feedback::decode(&status),
            Ok(Gen1Feedback::Status {
                word1: STATUS_MOTORS_ENABLED,
                word2: 0
            })
        );
    }

    #[test]
    fn limits_and_errors() {
        let too_fast = Gen1Command {
            velocity_counts: 1177,
            turn_counts: 0,
            config: None,
        };
        assert!(matches!(
            too_fast.encode(),
            Err(EncodeError::OutOfRange { .. })
        ));
        assert!(
            Gen1Command {
                velocity_counts: 0,
                turn_counts: 0,
                config: Some(Gen1Config::MaxVelocityScale(17)),
            }
            .encode()
            .is_err()
        );
        let unknown = RawFrame::new(0x413, &[0, 0, 0, 0, 0, 99, 0, 0]).unwrap();
        assert_eq!(
            Gen1Command::decode(&unknown),
            Err(DecodeError::UnknownCommand { command: 99 })
        );
        assert_eq!(
            Gen1Feedback::decode(&RawFrame::new(0x408, &[0; 8]).unwrap()),
            Err(DecodeError::WrongId {
                expected: 0x400,
                got: 0x408
            })
        );
        assert_eq!(Gen1Scaling::RMP_200_400.velocity_counts(100.0), 1176);
        assert_eq!(Gen1Scaling::RMP_200_400.velocity_counts(-0.5), -166);
        assert_eq!(counter_delta(i32::MAX, i32::MIN), 1);
    }
}
