//! The driver's settings: limits, feedback selection, timeouts, the base's stored limits it
//! writes, and their checks.

use std::time::Duration;

use motion_control::limiter::{LimitsError, TwistLimits};
use rmp_codec::feedback::{FeedbackBitmaps, FeedbackItem};
use rmp_codec::v3::{FirmwareProfile, ModeRequest, NvmFloat, OperationalState};

/// The feedback items the driver selects by default: everything it uses and nothing else
/// (16 items, 8 frames per reply instead of the factory 48, so about 1 ms of a 1 Mbit/s bus per
/// reply). `rmp-driver.dbc` describes this configuration.
pub const DRIVER_FEEDBACK_ITEMS: [FeedbackItem; 16] = [
    FeedbackItem::FaultStatusWord1,
    FeedbackItem::FaultStatusWord2,
    FeedbackItem::FaultStatusWord3,
    FeedbackItem::FaultStatusWord4,
    FeedbackItem::OperationalState,
    FeedbackItem::MinPropulsionBattSoc,
    FeedbackItem::YawRateLimit,
    FeedbackItem::VelocityLimit,
    FeedbackItem::LinearVelocity,
    FeedbackItem::DifferentialWheelVelocity,
    FeedbackItem::RightFrontPosition,
    FeedbackItem::LeftFrontPosition,
    FeedbackItem::RightRearPosition,
    FeedbackItem::LeftRearPosition,
    FeedbackItem::LinearPosition,
    FeedbackItem::FramTrackWidth,
];

/// How many stored limits the driver writes ([`RmpBaseConfig::base_settings`]).
pub const BASE_SETTINGS: usize = 6;

/// The base's stored accelerations are this many times the driver's limiter's
/// ([`RmpBaseConfig::base_settings`]).
pub const ACCEL_HEADROOM: f32 = 2.0;

/// The forced-configuration feedback item that echoes a stored float setting (items 76.. in
/// parameter-id order, 2014 numbering).
pub fn echo_item(setting: NvmFloat) -> FeedbackItem {
    let index = NvmFloat::ALL
        .iter()
        .position(|p| *p == setting)
        .unwrap_or(0);
    FeedbackItem::from_index(FeedbackItem::FORCED_CONFIG_FIRST as usize + index)
        .unwrap_or(FeedbackItem::FORCED_CONFIG_FIRST)
}

/// True when `read` is `written` up to float rounding (the value travels as an f32 bit
/// pattern both ways, so a base that stored it reports it exactly; a few ulps are allowed for a
/// firmware that converts).
pub fn same_setting(written: f32, read: f32) -> bool {
    (written - read).abs() <= 4.0 * f32::EPSILON * written.abs().max(read.abs()).max(1.0)
}

/// Modes the driver can ask for.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum BaseMode {
    /// Powered, wheels not driven.
    Standby,
    /// Driving: the only mode in which motion commands move the base.
    Tractor,
    /// Drive disabled.
    Disable,
}

impl BaseMode {
    pub(super) fn request(self) -> ModeRequest {
        match self {
            BaseMode::Standby => ModeRequest::Standby,
            BaseMode::Tractor => ModeRequest::Tractor,
            BaseMode::Disable => ModeRequest::Disable,
        }
    }

    pub(super) fn reported_as(self) -> OperationalState {
        match self {
            BaseMode::Standby => OperationalState::Standby,
            BaseMode::Tractor => OperationalState::Tractor,
            BaseMode::Disable => OperationalState::DisablePower,
        }
    }
}

/// Driver settings. `Default` is what an RMP 210/220/440 with factory NVM needs at 50 Hz.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RmpBaseConfig {
    /// Configuration-command numbering of the base's firmware.
    pub profile: FirmwareProfile,
    /// Period at which the caller calls [`crate::RmpBase::tick`]; the limiter assumes it when the
    /// measured period is implausible. 20 ms (50 Hz, the design's base rate).
    pub command_period: Duration,
    /// Velocity targets older than this are stale and the base is ramped to zero. 100 ms.
    pub input_timeout: Duration,
    /// No feedback frame for this long means the base stopped answering; frames without a
    /// complete readable set for this long mean its feedback is unreadable. 250 ms (the
    /// base answers every command, so this is about 12 missed replies at 50 Hz and well inside
    /// the base's own 0.5 s loss-of-command timeout).
    pub response_timeout: Duration,
    /// Resend a mode request this often until the base reports the mode. 100 ms.
    pub mode_resend: Duration,
    /// Give up on a mode request after this long. 2 s.
    pub mode_timeout: Duration,
    /// Speed and acceleration limits applied before normalisation.
    pub limits: TwistLimits,
    /// Feedback items to ask for; written to the base at start-up (NVM may hold anything).
    /// Must include the operational state and the fault words. Default:
    /// [`DRIVER_FEEDBACK_ITEMS`]; `FeedbackBitmaps::DEFAULT` gives the factory set (`rmp.dbc`).
    pub feedback: FeedbackBitmaps,
    /// Skip writing the feedback bitmaps (when the base is known to hold `feedback`).
    pub assume_feedback_configured: bool,
    /// +1 when the base's positive yaw (command and differential wheel velocity) is
    /// counter-clockwise, -1 when clockwise (sources disagree, reference §1.9 item 4).
    pub yaw_sign: f64,
    /// Velocity limit used to normalise commands until the base reports its own, m/s
    /// (factory NVM: 2.2352).
    pub fallback_velocity_limit_mps: f32,
    /// A measured speed (feedback item `LinearVelocity`) more than this above the speed
    /// commanded (an envelope that falls no faster than `limits.max_decel_mps2`, so the base
    /// may lag a slowing command) stops and disarms the driver: [`crate::BaseError::Overspeed`].
    /// 0.15 m/s.
    pub overspeed_tolerance_mps: f32,
    /// The same for the measured yaw rate (`DifferentialWheelVelocity`), against an envelope
    /// that falls at `limits.max_yaw_accel_radps2`. 0.3 rad/s.
    pub overspeed_tolerance_radps: f32,
    /// Yaw-rate limit used to normalise until the base reports its own, rad/s (factory: 3.0).
    pub fallback_yaw_rate_limit_radps: f32,
    /// Track width for heading from wheel positions until the base reports its own, m.
    pub fallback_track_width_m: f64,
    /// Deceleration of a safety stop ([`crate::RmpBase::safety_stop`]), m/s^2: at least
    /// `limits.max_decel_mps2`, at most the base's highest settable deceleration (7.848). Also
    /// written into the base's stored deceleration limits, so that the base itself may follow
    /// the ramp and slews to zero at this rate when our commands stop. Default: the factory
    /// deceleration limit, 3.923.
    pub emergency_decel_mps2: f32,
    /// Replays of logs recorded before the driver kept the robot's limits in the base: the
    /// speed and yaw-rate limits the base echoes at start-up are taken as verified (commands
    /// are normalised by them) and nothing is written. Never on a robot: a base with other
    /// stored limits would then be driven. Default: false.
    pub adopt_stored_limits: bool,
}

impl Default for RmpBaseConfig {
    fn default() -> Self {
        Self {
            profile: FirmwareProfile::SegwayInc2014,
            command_period: Duration::from_millis(20),
            input_timeout: Duration::from_millis(100),
            response_timeout: Duration::from_millis(250),
            mode_resend: Duration::from_millis(100),
            mode_timeout: Duration::from_secs(2),
            limits: TwistLimits::default(),
            feedback: FeedbackBitmaps::from_items(&DRIVER_FEEDBACK_ITEMS),
            assume_feedback_configured: false,
            yaw_sign: 1.0,
            fallback_velocity_limit_mps: NvmFloat::MaxVelocityMps.default_value(),
            overspeed_tolerance_mps: 0.15,
            overspeed_tolerance_radps: 0.3,
            fallback_yaw_rate_limit_radps: NvmFloat::MaxTurnRateRadps.default_value(),
            fallback_track_width_m: NvmFloat::TrackWidthM.default_value() as f64,
            emergency_decel_mps2: NvmFloat::MaxDecelerationMps2.default_value(),
            adopt_stored_limits: false,
        }
    }
}

/// Why a configuration was refused.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum ConfigError {
    /// A limit is negative or not finite.
    #[error("rmp-base limits: {0}")]
    Limits(#[from] LimitsError),
    /// A duration is zero where it must not be; names the field.
    #[error("rmp-base config: {0} must be greater than zero")]
    ZeroDuration(&'static str),
    /// `yaw_sign` is not +1 or -1.
    #[error("rmp-base config: yaw_sign must be +1 or -1, got {0}")]
    YawSign(f64),
    /// A fallback limit, track width or overspeed tolerance is not a positive finite number;
    /// names the field.
    #[error("rmp-base config: {0} must be finite and > 0")]
    Fallback(&'static str),
    /// A limit the driver writes into the base's stored settings lies outside what the base
    /// accepts.
    #[error("rmp-base config: the base's {setting:?} would be {value}, it accepts ({min}, {max}]")]
    BaseSetting {
        /// The stored setting.
        setting: NvmFloat,
        /// The value the configuration gives it.
        value: f32,
        /// Lowest value (exclusive).
        min: f32,
        /// Highest value.
        max: f32,
    },
    /// `emergency_decel_mps2` is below the comfort deceleration `limits.max_decel_mps2`.
    #[error(
        "rmp-base config: emergency_decel_mps2 {emergency} is below limits.max_decel_mps2 {comfort}"
    )]
    EmergencyDecel {
        /// The emergency deceleration.
        emergency: f32,
        /// The comfort deceleration.
        comfort: f32,
    },
    /// The feedback selection lacks an item the driver needs.
    #[error("rmp-base config: feedback bitmaps must include {0:?}")]
    MissingFeedback(FeedbackItem),
    /// The firmware has fewer feedback bitmaps than the selection uses.
    #[error(
        "rmp-base config: firmware {profile:?} has {available} feedback bitmaps, bitmap {used} is used"
    )]
    FeedbackBitmapUnavailable {
        /// The profile.
        profile: FirmwareProfile,
        /// Bitmaps it has.
        available: u8,
        /// 1-based bitmap that is used.
        used: u8,
    },
}

impl RmpBaseConfig {
    /// The base's stored limits as the driver writes them at start-up, in parameter order:
    /// velocity (the larger of the forward and reverse limits), acceleration, deceleration and
    /// decel-to-zero rate (both `emergency_decel_mps2`: the base ramps no faster than its
    /// stored deceleration, so a safety stop needs it; the comfort deceleration is the
    /// driver's own ramp), yaw rate, yaw acceleration. Commands are normalised by the verified
    /// velocity and yaw-rate values.
    ///
    /// The accelerations are written [`ACCEL_HEADROOM`] times the limiter's (at most what the
    /// base takes): the driver's limiter is the ramp, the base's setting the ceiling behind it.
    /// Equal values made the base trail every ramp by a period, and the heading lag put the
    /// closed-loop mission's base into a chair.
    pub fn base_settings(&self) -> [(NvmFloat, f32); BASE_SETTINGS] {
        let l = &self.limits;
        let ceiling =
            |setting: NvmFloat, v: f32| (v * ACCEL_HEADROOM).min(setting.range().1).max(v);
        [
            (
                NvmFloat::MaxVelocityMps,
                l.max_forward_mps.max(l.max_reverse_mps),
            ),
            (
                NvmFloat::MaxAccelerationMps2,
                ceiling(NvmFloat::MaxAccelerationMps2, l.max_accel_mps2),
            ),
            (NvmFloat::MaxDecelerationMps2, self.emergency_decel_mps2),
            (NvmFloat::MaxDtzDecelMps2, self.emergency_decel_mps2),
            (NvmFloat::MaxTurnRateRadps, l.max_yaw_rate_radps),
            (
                NvmFloat::MaxTurnAccelerationRadps2,
                ceiling(NvmFloat::MaxTurnAccelerationRadps2, l.max_yaw_accel_radps2),
            ),
        ]
    }

    /// Checks every field.
    pub fn validate(&self) -> Result<(), ConfigError> {
        self.limits.validate()?;
        for (name, d) in [
            ("command_period", self.command_period),
            ("input_timeout", self.input_timeout),
            ("response_timeout", self.response_timeout),
            ("mode_resend", self.mode_resend),
            ("mode_timeout", self.mode_timeout),
        ] {
            if d.is_zero() {
                return Err(ConfigError::ZeroDuration(name));
            }
        }
        if self.yaw_sign != 1.0 && self.yaw_sign != -1.0 {
            return Err(ConfigError::YawSign(self.yaw_sign));
        }
        let positive = |v: f64| v.is_finite() && v > 0.0;
        if !positive(self.fallback_velocity_limit_mps as f64) {
            return Err(ConfigError::Fallback("fallback_velocity_limit_mps"));
        }
        if !positive(self.fallback_yaw_rate_limit_radps as f64) {
            return Err(ConfigError::Fallback("fallback_yaw_rate_limit_radps"));
        }
        if !positive(self.fallback_track_width_m) {
            return Err(ConfigError::Fallback("fallback_track_width_m"));
        }
        if !positive(self.overspeed_tolerance_mps as f64) {
            return Err(ConfigError::Fallback("overspeed_tolerance_mps"));
        }
        if !positive(self.overspeed_tolerance_radps as f64) {
            return Err(ConfigError::Fallback("overspeed_tolerance_radps"));
        }
        if !positive(self.emergency_decel_mps2 as f64) {
            return Err(ConfigError::Fallback("emergency_decel_mps2"));
        }
        if self.emergency_decel_mps2 < self.limits.max_decel_mps2 {
            return Err(ConfigError::EmergencyDecel {
                emergency: self.emergency_decel_mps2,
                comfort: self.limits.max_decel_mps2,
            });
        }
        // The robot's own accelerations within what the base takes (the settings below add
        // headroom, capped at the base's maximum).
        for (setting, value) in [
            (NvmFloat::MaxAccelerationMps2, self.limits.max_accel_mps2),
            (
                NvmFloat::MaxTurnAccelerationRadps2,
                self.limits.max_yaw_accel_radps2,
            ),
        ]
        .into_iter()
        .chain(self.base_settings())
        {
            let (_, max) = setting.range();
            // Zero is a stored value the base takes, but the driver divides by the speed and
            // yaw-rate limits and a base that may not accelerate cannot drive: all > 0.
            if !(value > 0.0 && value <= max) {
                return Err(ConfigError::BaseSetting {
                    setting,
                    value,
                    min: 0.0,
                    max,
                });
            }
        }
        for item in [
            FeedbackItem::OperationalState,
            FeedbackItem::FaultStatusWord1,
            FeedbackItem::FaultStatusWord2,
            FeedbackItem::FaultStatusWord3,
            FeedbackItem::FaultStatusWord4,
        ] {
            if !self.feedback.contains(item) {
                return Err(ConfigError::MissingFeedback(item));
            }
        }
        let available = self.profile.feedback_bitmap_count();
        if let Some(used) = (0..4u8)
            .rev()
            .find(|i| self.feedback.words()[*i as usize] != 0)
            && used >= available
        {
            return Err(ConfigError::FeedbackBitmapUnavailable {
                profile: self.profile,
                available,
                used: used + 1,
            });
        }
        Ok(())
    }
}
