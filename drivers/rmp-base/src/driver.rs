//! The RMP v3 base driver: one [`RmpBase::tick`] per command period.

use std::time::Duration;

use log::{debug, info, warn};
use motion_control::Twist;
use motion_control::limiter::{LimitsError, TwistLimiter, TwistLimits};
use motion_control::mode::{ModeSequencer, ModeStep};
use motion_control::watchdog::Watchdog;
use rmp_codec::faults::FaultStatus;
use rmp_codec::feedback::{
    self, FeedbackAssembler, FeedbackBitmaps, FeedbackError, FeedbackItem, FeedbackLayout,
    FeedbackSet,
};
use rmp_codec::v3::{
    CONFIG_ID, ConfigCommand, FirmwareProfile, MOTION_ID, ModeRequest, MotionCommand, NvmFloat,
    OperationalState,
};

use crate::link::{LinkError, RmpLink};
use crate::odometry::{DeadReckoning, Integrators, Odometry};

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
    fn request(self) -> ModeRequest {
        match self {
            BaseMode::Standby => ModeRequest::Standby,
            BaseMode::Tractor => ModeRequest::Tractor,
            BaseMode::Disable => ModeRequest::Disable,
        }
    }

    fn reported_as(self) -> OperationalState {
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
    /// Period at which the caller calls [`RmpBase::tick`]; the limiter assumes it when the
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
    /// may lag a slowing command) stops and disarms the driver: [`BaseError::Overspeed`].
    /// 0.15 m/s.
    pub overspeed_tolerance_mps: f32,
    /// The same for the measured yaw rate (`DifferentialWheelVelocity`), against an envelope
    /// that falls at `limits.max_yaw_accel_radps2`. 0.3 rad/s.
    pub overspeed_tolerance_radps: f32,
    /// Yaw-rate limit used to normalise until the base reports its own, rad/s (factory: 3.0).
    pub fallback_yaw_rate_limit_radps: f32,
    /// Track width for heading from wheel positions until the base reports its own, m.
    pub fallback_track_width_m: f64,
    /// Deceleration of a safety stop ([`RmpBase::safety_stop`]), m/s^2: at least
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

/// Why a tick reports trouble. The driver has still done its safe action for the tick
/// (commanded zero where the variant says so); the condition is re-reported every tick while
/// it lasts.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum BaseError {
    /// No feedback at all from the base for longer than the response timeout. Motion commands
    /// are zero until it answers again.
    #[error(
        "RMP base not answering: no feedback for {silent_for:?} (timeout {timeout:?}); commanding zero velocity"
    )]
    Silent {
        /// Time since the last complete feedback set (or since start).
        silent_for: Duration,
        /// The response timeout.
        timeout: Duration,
    },
    /// Frames arrive but no complete feedback set could be read for longer than the response
    /// timeout (feedback layout changed behind the driver's back, corrupted frames). Motion
    /// commands are zero.
    #[error(
        "RMP base feedback unreadable for {silent_for:?} (last error: {last_error:?}, expected {expected_frames} frames per set); commanding zero velocity"
    )]
    FeedbackUnreadable {
        /// Time since the last complete set.
        silent_for: Duration,
        /// The last assembly error, if any (partial sets alone leave none).
        last_error: Option<FeedbackError>,
        /// Frames per set in the layout the driver expects.
        expected_frames: usize,
    },
    /// At start-up the base did not take the feedback bitmaps: the forced configuration
    /// feedback echoed other bitmaps. The driver starts over (rewrites them).
    #[error(
        "RMP base kept feedback bitmaps {echoed:08x?} after {attempts} writes of {wanted:08x?}"
    )]
    FeedbackConfigRejected {
        /// Bitmaps written.
        wanted: [u32; 4],
        /// Bitmaps the base reports.
        echoed: [u32; 4],
        /// Write-and-verify rounds done.
        attempts: u8,
    },
    /// The base did not report the requested mode in time.
    #[error("RMP base did not enter {wanted:?} within {timeout:?} (it reports {reported:?})")]
    ModeTimeout {
        /// The mode asked for.
        wanted: BaseMode,
        /// The last reported operational state.
        reported: Option<OperationalState>,
        /// The mode timeout.
        timeout: Duration,
    },
    /// The base reports faults that stop motion.
    #[error("RMP base faulted ({}): motion is stopped", describe(.faults))]
    Faulted {
        /// Fault status words 1..4.
        faults: FaultStatus,
    },
    /// The base moved faster than commanded (beyond the configured tolerance): the driver
    /// commands zero and stays disarmed until [`RmpBase::rearm`]. Re-reported every tick
    /// until then.
    #[error(
        "RMP base faster than commanded: {measured_mps} m/s (allowed {allowed_mps}), {measured_yaw_radps} rad/s (allowed {allowed_yaw_radps}); stopped until re-armed"
    )]
    Overspeed {
        /// Measured speed, m/s.
        measured_mps: f32,
        /// Commanded envelope plus tolerance, m/s.
        allowed_mps: f32,
        /// Measured yaw rate, rad/s.
        measured_yaw_radps: f32,
        /// Commanded yaw envelope plus tolerance, rad/s.
        allowed_yaw_radps: f32,
    },
    /// Another host sends motion (0x500) or configuration (0x501) commands on the bus: the
    /// base obeys whichever command came last, so nobody is in control. The driver commands
    /// zero and stays disarmed until [`RmpBase::rearm`]; re-reported every tick until then.
    /// (A host never receives its own frames: SocketCAN does not loop them back to the
    /// sending socket, nor does the virtual bus.)
    #[error(
        "a second commander on the RMP bus: {frames} command frames not sent by this driver (last id {last_id:#05x}); stopped until re-armed"
    )]
    SecondCommander {
        /// Foreign command frames seen since start.
        frames: u64,
        /// Id of the last one.
        last_id: u16,
    },
    /// At start-up the base did not keep a limit the driver wrote into its stored settings
    /// (after the write-and-verify rounds): the driver stays disarmed, commanding zero, and
    /// reports this every tick. Nothing clears it but a new driver on a base that keeps the
    /// value.
    #[error(
        "RMP base did not take its {setting:?} setting: wrote {written}, read back {}; refusing to drive",
        read_back(.read)
    )]
    LimitNotTaken {
        /// The stored setting.
        setting: NvmFloat,
        /// The value written (from the robot file's limits).
        written: f32,
        /// The value the base reports (`None`: it reports none).
        read: Option<f32>,
    },
    /// After the limits were verified the base reported a different speed or yaw-rate limit:
    /// its normalised commands would now mean other speeds. The driver commands zero and stays
    /// disarmed until [`RmpBase::rearm`] (and disarms again while the report differs).
    #[error(
        "RMP base reports its {setting:?} as {reported}, verified at start-up as {verified}; stopped until re-armed"
    )]
    LimitChanged {
        /// The stored setting.
        setting: NvmFloat,
        /// The value verified at start-up.
        verified: f32,
        /// The value reported now.
        reported: f32,
    },
    /// The link refused a frame.
    #[error("RMP link: {0}")]
    Link(#[from] LinkError),
}

/// The speed and yaw-rate limits a forced-configuration echo holds (both finite and > 0).
fn echoed_limits(echo: &FeedbackSet) -> Option<VerifiedLimits> {
    let positive = |v: Option<f32>| v.filter(|x| x.is_finite() && *x > 0.0);
    Some(VerifiedLimits {
        velocity_mps: positive(echo.get_f32(echo_item(NvmFloat::MaxVelocityMps)))?,
        yaw_rate_radps: positive(echo.get_f32(echo_item(NvmFloat::MaxTurnRateRadps)))?,
    })
}

fn read_back(read: &Option<f32>) -> String {
    match read {
        Some(v) => v.to_string(),
        None => "nothing (not in the feedback)".to_owned(),
    }
}

/// Why the driver disarmed itself. Disarmed, it commands zero velocity whatever the input,
/// until [`RmpBase::rearm`] is called, even after the cause has cleared.
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub enum DisarmCause {
    /// The base stopped answering (or its feedback became unreadable) after it had answered.
    LinkLost,
    /// The base reported a fault that stops motion.
    Faulted {
        /// Fault status words 1..4 when it was seen.
        faults: FaultStatus,
    },
    /// The base moved faster than commanded ([`BaseError::Overspeed`]).
    Overspeed {
        /// Measured speed, m/s.
        measured_mps: f32,
        /// Commanded envelope plus tolerance, m/s.
        allowed_mps: f32,
        /// Measured yaw rate, rad/s.
        measured_yaw_radps: f32,
        /// Commanded yaw envelope plus tolerance, rad/s.
        allowed_yaw_radps: f32,
    },
    /// Another host sends motion or configuration commands on the bus
    /// ([`BaseError::SecondCommander`]).
    SecondCommander,
    /// The base did not keep a limit written at start-up ([`BaseError::LimitNotTaken`]).
    LimitNotTaken {
        /// The stored setting.
        setting: NvmFloat,
        /// The value written.
        written: f32,
        /// The value read back, if any.
        read: Option<f32>,
    },
    /// The base reported a limit other than the one verified ([`BaseError::LimitChanged`]).
    LimitChanged {
        /// The stored setting.
        setting: NvmFloat,
        /// The verified value.
        verified: f32,
        /// The value reported.
        reported: f32,
    },
}

fn describe(faults: &FaultStatus) -> String {
    let names: Vec<&str> = faults.active().map(|b| b.name).collect();
    if names.is_empty() {
        format!("fault words {:08x?}", faults.words())
    } else {
        names.join(", ")
    }
}

/// The base as last reported.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BaseStatus {
    /// Operational state, once a set arrived.
    pub state: Option<OperationalState>,
    /// Fault words.
    pub faults: FaultStatus,
    /// Minimum propulsion battery state of charge, %, if reported.
    pub battery_soc_pct: Option<f32>,
    /// Velocity limit the base last reported, m/s (the fallback until it reports one). The
    /// driver divides its commands by the limit verified at start-up
    /// ([`RmpBase::verified_limits`]) and disarms when a report differs from it.
    pub velocity_limit_mps: f32,
    /// Yaw-rate limit the base last reported, rad/s (the fallback until it reports one).
    pub yaw_rate_limit_radps: f32,
    /// Clock time of the last complete feedback set.
    pub last_feedback: Option<Duration>,
    /// Complete feedback sets received.
    pub feedback_sets: u64,
    /// Feedback frames that could not be assembled.
    pub feedback_errors: u64,
    /// Frames from the link that were neither feedback nor ignorable.
    pub receive_errors: u64,
}

/// What one tick did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tick {
    /// The velocity commanded this tick (after limits), SI units.
    pub commanded: Twist,
    /// True when the velocity target was stale (or never set) and the driver ramped to zero.
    pub input_stale: bool,
    /// Complete feedback sets taken in this tick.
    pub feedback_sets: u32,
    /// A mode request was confirmed this tick.
    pub mode_reached: Option<BaseMode>,
    /// False while the driver is disarmed ([`RmpBase::disarmed`]): it commands zero.
    pub armed: bool,
}

/// Start-up: write the feedback bitmaps one per tick, read them and the stored limits
/// ([`RmpBaseConfig::base_settings`]) back through the forced configuration feedback (as the
/// Segway library does); where the limits differ, write them one per tick and read back again;
/// then drop one tick of replies. (Older firmware: the limits are written at once and checked
/// in the user feedback.)
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Startup {
    WriteBitmap(u8),
    WriteLimit(u8),
    ForceConfig,
    Verify,
    Settle,
    Running,
}

/// Write-and-verify rounds before start-up reports [`BaseError::FeedbackConfigRejected`].
const FEEDBACK_CONFIG_ATTEMPTS: u8 = 3;

/// The speed and yaw-rate limits the base reported back after the driver wrote them: what a
/// normalised command of 1.0 means.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VerifiedLimits {
    /// Stored velocity limit, m/s.
    pub velocity_mps: f32,
    /// Stored yaw-rate limit, rad/s.
    pub yaw_rate_radps: f32,
}

/// The driver. Owns the link; the caller owns the clock and calls [`tick`](Self::tick) once per
/// command period with the current monotonic time. Nothing allocates after construction.
pub struct RmpBase<L> {
    link: L,
    config: RmpBaseConfig,
    startup: Startup,
    limiter: TwistLimiter,
    target: Twist,
    input_watchdog: Watchdog,
    modes: ModeSequencer<OperationalState>,
    mode_target: Option<BaseMode>,
    assembler: FeedbackAssembler,
    last_feedback_error: Option<FeedbackError>,
    started_at: Option<Duration>,
    running_since: Duration,
    last_heard: Option<Duration>,
    forced_echo: Option<FeedbackSet>,
    config_rounds: u8,
    /// Rounds of writing the stored limits so far.
    limit_writes: u8,
    last_tick: Option<Duration>,
    status: BaseStatus,
    track_width_m: f64,
    odometry: DeadReckoning,
    disarmed: Option<DisarmCause>,
    /// What the base may be doing on the commands sent so far: |commanded|, falling no faster
    /// than the limiter's deceleration (speed, yaw rate).
    envelope: (f32, f32),
    /// The base's speed and yaw-rate limits as read back after the write (`None` until then:
    /// the driver does not drive).
    verified: Option<VerifiedLimits>,
    /// Speed and yaw-rate limits in the last feedback set (`None`: not in it).
    reported_limits: (Option<f32>, Option<f32>),
    /// The limit the base did not take at start-up (latched for the driver's life).
    limit_refused: Option<DisarmCause>,
    /// A safety stop is latched ([`RmpBase::safety_stop`]).
    safety_stop: bool,
    /// The limiter of a safety stop: the comfort limits with the emergency deceleration.
    emergency: TwistLimiter,
    /// Command frames (0x500/0x501) received from another host, and the last one's id.
    foreign_commands: (u64, u16),
    /// Foreign commands seen since the last tick.
    foreign_this_tick: bool,
}

fn us(d: Duration) -> u64 {
    u64::try_from(d.as_micros()).unwrap_or(u64::MAX)
}

impl<L: RmpLink> RmpBase<L> {
    /// A driver on `link`; validates the configuration. Sends nothing until the first tick.
    pub fn new(link: L, config: RmpBaseConfig) -> Result<Self, ConfigError> {
        config.validate()?;
        let layout = FeedbackLayout::User(config.feedback);
        Ok(Self {
            link,
            startup: if config.assume_feedback_configured {
                Self::read_or_write_limits(config.profile)
            } else {
                Startup::WriteBitmap(0)
            },
            limiter: TwistLimiter::new(config.limits),
            target: Twist::ZERO,
            input_watchdog: Watchdog::new(us(config.input_timeout)),
            modes: ModeSequencer::new(us(config.mode_resend), us(config.mode_timeout)),
            mode_target: None,
            assembler: FeedbackAssembler::new(layout),
            last_feedback_error: None,
            started_at: None,
            running_since: Duration::ZERO,
            last_heard: None,
            foreign_commands: (0, 0),
            foreign_this_tick: false,
            forced_echo: None,
            config_rounds: 0,
            limit_writes: 0,
            last_tick: None,
            status: BaseStatus {
                state: None,
                faults: FaultStatus::CLEAR,
                battery_soc_pct: None,
                velocity_limit_mps: config.fallback_velocity_limit_mps,
                yaw_rate_limit_radps: config.fallback_yaw_rate_limit_radps,
                last_feedback: None,
                feedback_sets: 0,
                feedback_errors: 0,
                receive_errors: 0,
            },
            track_width_m: config.fallback_track_width_m,
            odometry: DeadReckoning::default(),
            disarmed: None,
            envelope: (0.0, 0.0),
            verified: None,
            reported_limits: (None, None),
            limit_refused: None,
            safety_stop: false,
            emergency: TwistLimiter::new(TwistLimits {
                max_decel_mps2: config.emergency_decel_mps2,
                ..config.limits
            }),
            config,
        })
    }

    /// Sets the velocity target (SI, counter-clockwise yaw) and marks the input fresh at `now`.
    /// Non-finite values count as a stop.
    pub fn set_velocity(&mut self, target: Twist, now: Duration) {
        self.target = target;
        self.input_watchdog.feed(us(now));
    }

    /// Asks for a mode; [`tick`](Self::tick) sends and resends the request and reports the
    /// outcome ([`Tick::mode_reached`] or [`BaseError::ModeTimeout`]).
    pub fn request_mode(&mut self, mode: BaseMode, now: Duration) {
        self.mode_target = Some(mode);
        self.modes.request(mode.reported_as(), us(now));
    }

    /// Why the driver is disarmed, if it is. A new driver is armed (constructing it and asking
    /// for tractor is the operator's intent); a lost link (silence or unreadable feedback
    /// after the base had answered), a stopping fault or an overspeed disarms it, and it then
    /// commands zero until [`Self::rearm`].
    pub fn disarmed(&self) -> Option<DisarmCause> {
        self.disarmed
    }

    /// Re-arms after a lost link, a fault or an overspeed: the explicit acknowledgement
    /// without which motion does not resume. Returns the cause that is cleared. Call it when
    /// the cause is gone and the base is at rest (e.g. when a mission starts); if the cause
    /// persists, the next tick disarms again. Velocity ramps up from zero afterwards.
    pub fn rearm(&mut self) -> Option<DisarmCause> {
        if std::mem::take(&mut self.safety_stop) {
            info!("RMP driver: safety stop released");
        }
        let cause = self.disarmed.take();
        if let Some(c) = cause {
            info!("RMP driver re-armed (was disarmed: {c:?})");
        }
        self.envelope = (0.0, 0.0);
        self.limiter.reset_to(Twist::ZERO);
        cause
    }

    /// Latches a safety stop: from the next tick the driver ramps its command to zero at
    /// [`RmpBaseConfig::emergency_decel_mps2`] (yaw at the yaw-acceleration limit) instead of
    /// the comfort deceleration, whatever [`Self::set_velocity`] asks, and commands zero until
    /// [`Self::rearm`]. For the executive's latched stops (e-stop, kill switch, UR safety
    /// stops...). Disarming causes (a lost link, a fault) still command zero at once: the base
    /// then slews at its stored deceleration, which the driver set to the same rate.
    pub fn safety_stop(&mut self) {
        if !self.safety_stop {
            warn!(
                "RMP driver: safety stop, ramping to zero at {} m/s^2",
                self.config.emergency_decel_mps2
            );
            self.safety_stop = true;
        }
    }

    /// True while a safety stop is latched.
    pub fn safety_stopping(&self) -> bool {
        self.safety_stop
    }

    /// The speed and yaw-rate limits the base reported back after start-up wrote them (`None`
    /// before, or when it did not keep them: then the driver does not drive).
    pub fn verified_limits(&self) -> Option<VerifiedLimits> {
        self.verified
    }

    /// After the bitmaps: the read-back round first where the base echoes its stored limits
    /// (they are written only when they differ: a base configured by an earlier start keeps
    /// them in F-RAM), else write them at once (older firmware: read back from user feedback).
    fn after_bitmaps(&self) -> Startup {
        Self::read_or_write_limits(self.config.profile)
    }

    fn read_or_write_limits(profile: FirmwareProfile) -> Startup {
        if profile == FirmwareProfile::SegwayInc2014 {
            Startup::ForceConfig
        } else {
            Startup::WriteLimit(0)
        }
    }

    fn disarm(&mut self, cause: DisarmCause) {
        if self.disarmed.is_none() {
            warn!("RMP driver disarmed: {cause:?}; commanding zero until re-armed");
            self.disarmed = Some(cause);
        }
    }

    /// The measured velocity against the commanded envelope; `Some` when it is above.
    fn overspeed(&self) -> Option<DisarmCause> {
        let o = &self.odometry.odometry;
        let (measured_mps, measured_yaw_radps) = (o.speed_mps as f32, o.yaw_rate_radps as f32);
        let allowed_mps = self.envelope.0 + self.config.overspeed_tolerance_mps;
        let allowed_yaw_radps = self.envelope.1 + self.config.overspeed_tolerance_radps;
        (measured_mps.abs() > allowed_mps || measured_yaw_radps.abs() > allowed_yaw_radps)
            .then_some(DisarmCause::Overspeed {
                measured_mps,
                allowed_mps,
                measured_yaw_radps,
                allowed_yaw_radps,
            })
    }

    /// The base's status as last reported.
    pub fn status(&self) -> &BaseStatus {
        &self.status
    }

    /// Dead-reckoned pose and reported velocity.
    pub fn odometry(&self) -> &Odometry {
        &self.odometry.odometry
    }

    /// The configuration.
    pub fn config(&self) -> &RmpBaseConfig {
        &self.config
    }

    /// The link (for statistics or to shut it down).
    pub fn link_mut(&mut self) -> &mut L {
        &mut self.link
    }

    /// True once the start-up configuration is written and the base is in tractor mode.
    pub fn is_driving(&self) -> bool {
        self.startup == Startup::Running && self.status.state == Some(OperationalState::Tractor)
    }

    /// One command period: read feedback, advance the mode sequence, send one command.
    #[allow(
        clippy::too_many_lines,
        reason = "the driver's one tick in the order the base sees it: start-up, feedback checks, disarm causes, the command"
    )]
    pub fn tick(&mut self, now: Duration) -> Result<Tick, BaseError> {
        let started_at = *self.started_at.get_or_insert(now);
        let period = self.config.command_period;
        // Our own loop stalled longer than the base waits for us: the base has stopped on its
        // own loss-of-command timeout (or is about to), and anything it reported before the
        // gap is stale. That is a lost link, whoever caused it.
        let gap = self
            .last_tick
            .map_or(Duration::ZERO, |t| now.saturating_sub(t));
        let stalled = gap > self.config.response_timeout;
        let dt = match self.last_tick {
            Some(_) => gap.min(4 * period),
            None => period,
        };
        self.last_tick = Some(now);

        let feedback_sets = self.drain_feedback(now);

        let mut mode_reached = None;
        let mut mode_error = None;
        let mut sent_config = false;
        match self.startup {
            Startup::WriteBitmap(index) => {
                let bitmap = self.config.feedback.words()[index as usize];
                self.send_config(ConfigCommand::SetFeedbackBitmap { index, bitmap })?;
                sent_config = true;
                self.startup = if index + 1 < self.config.profile.feedback_bitmap_count() {
                    Startup::WriteBitmap(index + 1)
                } else {
                    self.after_bitmaps()
                };
            }
            Startup::WriteLimit(index) => {
                if index == 0 {
                    self.limit_writes = self.limit_writes.saturating_add(1);
                }
                let settings = self.config.base_settings();
                let (setting, value) = settings[usize::from(index)];
                self.send_config(ConfigCommand::SetFloat(setting, value))?;
                sent_config = true;
                self.startup = if usize::from(index) + 1 < settings.len() {
                    Startup::WriteLimit(index + 1)
                } else if self.config.profile == FirmwareProfile::SegwayInc2014 {
                    Startup::ForceConfig
                } else {
                    // The forced-feedback layout of the older firmware is not documented: its
                    // speed and yaw-rate limits are checked in the first user feedback set.
                    Startup::Settle
                };
            }
            Startup::ForceConfig => {
                // Replies to the writes came in during the last period and were dropped.
                self.assembler.set_layout(FeedbackLayout::ForcedConfig);
                self.forced_echo = None;
                self.config_rounds += 1;
                self.send_config(ConfigCommand::ForceConfigFeedback(true))?;
                sent_config = true;
                self.startup = Startup::Verify;
            }
            Startup::Verify => {
                sent_config = true;
                match self.forced_echo.take() {
                    None => self.send_config(ConfigCommand::None)?, // prompt a reply
                    Some(echo) => {
                        let wanted = self.config.feedback.words();
                        let echoed = [
                            FeedbackItem::UserFeedbackBitmap1,
                            FeedbackItem::UserFeedbackBitmap2,
                            FeedbackItem::UserFeedbackBitmap3,
                            FeedbackItem::UserFeedbackBitmap4,
                        ]
                        .map(|item| echo.get(item).unwrap_or(u32::MAX));
                        self.send_config(ConfigCommand::ForceConfigFeedback(false))?;
                        let limit_mismatch = self.check_echoed_limits(&echo);
                        if echoed == wanted && limit_mismatch.is_none() {
                            info!("RMP feedback bitmaps verified: {wanted:08x?}");
                            info!("RMP stored limits verified: {:?}", self.verified);
                            self.config_rounds = 0;
                            self.startup = Startup::Settle;
                        } else if let (true, Some(_), true) = (
                            echoed == wanted,
                            limit_mismatch,
                            self.config.adopt_stored_limits,
                        ) {
                            // A replay of a driver that did not write them: as it did.
                            self.verified = echoed_limits(&echo);
                            info!("RMP stored limits adopted (replay): {:?}", self.verified);
                            self.config_rounds = 0;
                            self.startup = Startup::Settle;
                        } else if let (true, Some(cause)) = (echoed == wanted, limit_mismatch) {
                            // The first round reads what the base holds; each later one
                            // follows a write.
                            if self.limit_writes > 0 {
                                warn!("RMP base did not take a limit: {cause:?}");
                            } else {
                                info!("RMP base holds other limits ({cause:?}): writing them");
                            }
                            if self.limit_writes >= FEEDBACK_CONFIG_ATTEMPTS {
                                // Refuse to drive: run on (keep-alive, status) disarmed.
                                self.limit_refused = Some(cause);
                                self.config_rounds = 0;
                                self.startup = Startup::Settle;
                            } else {
                                self.startup = Startup::WriteLimit(0);
                            }
                        } else {
                            warn!("RMP feedback bitmaps {echoed:08x?}, wanted {wanted:08x?}");
                            self.startup = Startup::WriteBitmap(0);
                            if self.config_rounds >= FEEDBACK_CONFIG_ATTEMPTS {
                                mode_error = Some(BaseError::FeedbackConfigRejected {
                                    wanted,
                                    echoed,
                                    attempts: self.config_rounds,
                                });
                                self.config_rounds = 0;
                            }
                        }
                    }
                }
            }
            Startup::Settle => {
                // Replies sent before the layout change may be in either layout: drop them.
                self.assembler
                    .set_layout(FeedbackLayout::User(self.config.feedback));
                self.status.last_feedback = None;
                self.running_since = now;
                self.startup = Startup::Running;
            }
            Startup::Running => match self.modes.poll(us(now)) {
                ModeStep::Send(_) => {
                    if let Some(mode) = self.mode_target {
                        self.send_config(ConfigCommand::SetOperationalMode(mode.request()))?;
                        sent_config = true;
                    }
                }
                ModeStep::Reached(_) => {
                    mode_reached = self.mode_target.take();
                    info!("RMP base reports {:?}", mode_reached);
                }
                ModeStep::TimedOut { reported, .. } => {
                    if let Some(wanted) = self.mode_target.take() {
                        mode_error = Some(BaseError::ModeTimeout {
                            wanted,
                            reported,
                            timeout: self.config.mode_timeout,
                        });
                    }
                }
                ModeStep::Idle | ModeStep::Waiting => {}
            },
        }

        // Silent: no feedback frame at all. Unreadable: frames, but no complete readable set.
        let heard_for = now.saturating_sub(self.last_heard.unwrap_or(started_at));
        let (base_silent, heard_for) = if stalled && self.startup == Startup::Running {
            (true, gap)
        } else {
            (heard_for > self.config.response_timeout, heard_for)
        };
        let unread_for =
            now.saturating_sub(self.status.last_feedback.unwrap_or(self.running_since));
        let unreadable = !base_silent
            && self.startup == Startup::Running
            && unread_for > self.config.response_timeout;
        let silent = base_silent || unreadable;

        // Decide the velocity: zero unless the driver is armed, the input is fresh, the base
        // answers, drives, and reports no stopping fault.
        let input_stale = self.input_watchdog.is_stale(us(now));
        let faulted = self.status.faults.stops_motion();
        if std::mem::take(&mut self.foreign_this_tick) {
            self.disarm(DisarmCause::SecondCommander);
        }
        if let Some(cause) = self.limit_refused {
            self.disarm(cause);
        }
        if let Some(cause) = self.limit_changed() {
            self.disarm(cause);
        }
        if faulted {
            self.disarm(DisarmCause::Faulted {
                faults: self.status.faults,
            });
        } else if silent && self.status.feedback_sets > 0 {
            self.disarm(DisarmCause::LinkLost);
        } else if self.disarmed.is_none() && feedback_sets > 0 && !silent && self.is_driving() {
            // This tick's feedback against what was commanded before it.
            if let Some(cause) = self.overspeed() {
                self.disarm(cause);
            }
        }
        let armed = self.disarmed.is_none();
        let may_drive =
            armed && !silent && !faulted && self.is_driving() && self.verified.is_some();
        let wanted = if input_stale || !may_drive || self.safety_stop {
            Twist::ZERO
        } else {
            self.target
        };
        if silent {
            // The base may have restarted meanwhile: do not difference across the gap.
            self.odometry.rebase();
        }
        if !may_drive {
            // Not driving: the base is not moving on our commands, so restart ramps from rest.
            self.limiter.reset_to(Twist::ZERO);
        }
        let commanded = if self.safety_stop {
            // The emergency ramp, from wherever the comfort ramp was.
            self.emergency.reset_to(self.limiter.output());
            let c = self.emergency.step(Twist::ZERO, dt.as_secs_f32());
            self.limiter.reset_to(c);
            c
        } else {
            self.limiter.step(wanted, dt.as_secs_f32())
        };
        let dt_s = dt.as_secs_f32();
        let limits = &self.config.limits;
        self.envelope = (
            commanded
                .speed_mps
                .abs()
                .max(self.envelope.0 - limits.max_decel_mps2 * dt_s),
            commanded
                .yaw_rate_radps
                .abs()
                .max(self.envelope.1 - limits.max_yaw_accel_radps2 * dt_s),
        );

        if !sent_config {
            // The motion frame is also the keep-alive and the prompt for feedback. The base
            // multiplies it by its stored limit: the driver wrote the robot's limits there and
            // divides by what the base reported back (a later report that differs disarms).
            // Before that the command is zero whatever the divisor.
            let (v_scale, w_scale) = match self.verified {
                Some(v) => (v.velocity_mps, v.yaw_rate_radps),
                None => (
                    self.config.fallback_velocity_limit_mps,
                    self.config.fallback_yaw_rate_limit_radps,
                ),
            };
            let v = (commanded.speed_mps / v_scale).clamp(-1.0, 1.0);
            let w =
                (self.config.yaw_sign as f32 * commanded.yaw_rate_radps / w_scale).clamp(-1.0, 1.0);
            let motion = MotionCommand::new(v, w).unwrap_or(MotionCommand::ZERO);
            self.link.send(&motion.encode())?;
        }

        if let Some(e) = mode_error {
            return Err(e);
        }
        if base_silent {
            return Err(BaseError::Silent {
                silent_for: heard_for,
                timeout: self.config.response_timeout,
            });
        }
        if unreadable {
            return Err(BaseError::FeedbackUnreadable {
                silent_for: unread_for,
                last_error: self.last_feedback_error,
                expected_frames: self.assembler.layout().frame_count(),
            });
        }
        if faulted {
            return Err(BaseError::Faulted {
                faults: self.status.faults,
            });
        }
        if self.disarmed == Some(DisarmCause::SecondCommander) {
            return Err(BaseError::SecondCommander {
                frames: self.foreign_commands.0,
                last_id: self.foreign_commands.1,
            });
        }
        if let Some(DisarmCause::LimitNotTaken {
            setting,
            written,
            read,
        }) = self.disarmed
        {
            return Err(BaseError::LimitNotTaken {
                setting,
                written,
                read,
            });
        }
        if let Some(DisarmCause::LimitChanged {
            setting,
            verified,
            reported,
        }) = self.disarmed
        {
            return Err(BaseError::LimitChanged {
                setting,
                verified,
                reported,
            });
        }
        if let Some(DisarmCause::Overspeed {
            measured_mps,
            allowed_mps,
            measured_yaw_radps,
            allowed_yaw_radps,
        }) = self.disarmed
        {
            return Err(BaseError::Overspeed {
                measured_mps,
                allowed_mps,
                measured_yaw_radps,
                allowed_yaw_radps,
            });
        }
        Ok(Tick {
            commanded,
            input_stale,
            feedback_sets,
            mode_reached,
            armed,
        })
    }

    /// Compares the forced configuration echo with the limits written; sets the verified
    /// limits when all match, returns the first mismatch otherwise.
    fn check_echoed_limits(&mut self, echo: &FeedbackSet) -> Option<DisarmCause> {
        for (setting, written) in self.config.base_settings() {
            let read = echo.get_f32(echo_item(setting));
            if !read.is_some_and(|r| same_setting(written, r)) {
                return Some(DisarmCause::LimitNotTaken {
                    setting,
                    written,
                    read,
                });
            }
        }
        self.verified = self.written_limits();
        None
    }

    /// The speed and yaw-rate limits as written.
    fn written_limits(&self) -> Option<VerifiedLimits> {
        let settings = self.config.base_settings();
        Some(VerifiedLimits {
            velocity_mps: settings[0].1,
            yaw_rate_radps: settings[4].1,
        })
    }

    /// A reported speed or yaw-rate limit other than the verified one, if the last set had one.
    fn limit_changed(&self) -> Option<DisarmCause> {
        let verified = self.verified?;
        [
            (
                NvmFloat::MaxVelocityMps,
                verified.velocity_mps,
                self.reported_limits.0,
            ),
            (
                NvmFloat::MaxTurnRateRadps,
                verified.yaw_rate_radps,
                self.reported_limits.1,
            ),
        ]
        .into_iter()
        .find_map(|(setting, verified, reported)| {
            let reported = reported?;
            (!same_setting(verified, reported)).then_some(DisarmCause::LimitChanged {
                setting,
                verified,
                reported,
            })
        })
    }

    /// Older firmware: no forced configuration feedback, so the speed and yaw-rate limits are
    /// read back from the user feedback (the accelerations cannot be).
    fn verify_from_user_feedback(&mut self) {
        if self.verified.is_none()
            && self.limit_refused.is_none()
            && self.config.profile != FirmwareProfile::SegwayInc2014
        {
            let written = self.written_limits();
            if let Some(w) = written {
                let pairs = [
                    (
                        NvmFloat::MaxVelocityMps,
                        w.velocity_mps,
                        self.reported_limits.0,
                    ),
                    (
                        NvmFloat::MaxTurnRateRadps,
                        w.yaw_rate_radps,
                        self.reported_limits.1,
                    ),
                ];
                match pairs
                    .into_iter()
                    .find(|(_, written, read)| !read.is_some_and(|r| same_setting(*written, r)))
                {
                    None => self.verified = written,
                    Some((setting, written, read)) => {
                        self.limit_refused = Some(DisarmCause::LimitNotTaken {
                            setting,
                            written,
                            read,
                        })
                    }
                }
            }
        }
    }

    fn send_config(&mut self, command: ConfigCommand) -> Result<(), BaseError> {
        // Every command the driver builds is valid for its profile (validated config).
        match command.encode(self.config.profile) {
            Ok(frame) => Ok(self.link.send(&frame)?),
            Err(e) => {
                warn!("RMP command {command:?} not encodable: {e}");
                Ok(())
            }
        }
    }

    /// Reads everything waiting; returns the number of complete sets taken.
    ///
    /// Sets carry no header, so a base whose layout is larger than the expected one produces
    /// "complete" sets of the wrong items followed by frames beyond the layout. A set is
    /// therefore taken only at the end of the drain, and dropped when such frames follow it.
    fn drain_feedback(&mut self, now: Duration) -> u32 {
        let mut sets = 0;
        let mut pending: Option<FeedbackSet> = None;
        // Bounded: at most a few sets' worth per tick, so a babbling bus cannot stall the loop.
        for _ in 0..4 * feedback::MAX_FRAMES {
            let frame = match self.link.try_recv() {
                Ok(Some(frame)) => frame,
                Ok(None) => break,
                Err(e) => {
                    self.status.receive_errors += 1;
                    debug!("RMP link receive: {e}");
                    break;
                }
            };
            if frame.id() == MOTION_ID || frame.id() == CONFIG_ID {
                // Never our own (see BaseError::SecondCommander): another host commands the base.
                self.foreign_commands.0 += 1;
                self.foreign_commands.1 = frame.id();
                self.foreign_this_tick = true;
                continue;
            }
            if !feedback::is_feedback_id(frame.id()) {
                continue; // other devices
            }
            self.last_heard = Some(now);
            if !matches!(self.startup, Startup::Running | Startup::Verify) {
                continue; // replies in a layout being changed
            }
            match self.assembler.push(&frame) {
                Ok(Some(set)) => {
                    if let Some(previous) = pending.replace(set) {
                        sets += self.accept(previous, now);
                    }
                }
                Ok(None) => {}
                Err(e) => {
                    if matches!(e, FeedbackError::BeyondLayout { .. }) && pending.take().is_some() {
                        warn!("RMP feedback longer than the configured layout: set dropped");
                    }
                    self.status.feedback_errors += 1;
                    self.last_feedback_error = Some(e);
                    debug!("RMP feedback: {e}");
                }
            }
        }
        if let Some(set) = pending {
            sets += self.accept(set, now);
        }
        sets
    }

    fn accept(&mut self, set: FeedbackSet, now: Duration) -> u32 {
        if self.startup == Startup::Verify {
            self.forced_echo = Some(set);
            return 0;
        }
        self.last_feedback_error = None;
        self.take_feedback(&set, now);
        1
    }

    fn take_feedback(&mut self, set: &FeedbackSet, now: Duration) {
        let s = &mut self.status;
        s.last_feedback = Some(now);
        s.feedback_sets += 1;
        if let Some(state) = set.operational_state() {
            if s.state != Some(state) {
                info!("RMP base state {:?} -> {:?}", s.state, state);
            }
            s.state = Some(state);
            self.modes.on_reported(state);
        }
        if let Some(faults) = set.fault_status() {
            if faults != s.faults && faults.stops_motion() {
                warn!("RMP base faulted: {}", describe(&faults));
            }
            s.faults = faults;
        }
        let positive = |v: Option<f32>| v.filter(|x| x.is_finite() && *x > 0.0);
        // The stored limits as reported now (any value, NaN too: it is compared with the
        // verified one, and anything else disarms).
        self.reported_limits = (
            set.get_f32(FeedbackItem::VelocityLimit),
            set.get_f32(FeedbackItem::YawRateLimit),
        );
        if let Some(v) = positive(self.reported_limits.0) {
            s.velocity_limit_mps = v;
        }
        if let Some(w) = positive(self.reported_limits.1) {
            s.yaw_rate_limit_radps = w;
        }
        if let Some(t) = positive(set.get_f32(FeedbackItem::FramTrackWidth)) {
            self.track_width_m = t as f64;
        }
        s.battery_soc_pct = set
            .get_f32(FeedbackItem::MinPropulsionBattSoc)
            .filter(|v| v.is_finite());

        let yaw_sign = self.config.yaw_sign;
        let f = |item| set.get_f32(item).map(f64::from).filter(|v| v.is_finite());
        let o = &mut self.odometry.odometry;
        let previous_stamp = o.stamp;
        o.stamp = now;
        o.speed_mps = f(FeedbackItem::LinearVelocity).unwrap_or(0.0);
        o.yaw_rate_radps = yaw_sign * f(FeedbackItem::DifferentialWheelVelocity).unwrap_or(0.0);
        let first_set = s.feedback_sets == 1;
        let wheels = (
            f(FeedbackItem::LinearPosition),
            f(FeedbackItem::RightFrontPosition),
            f(FeedbackItem::LeftFrontPosition),
            f(FeedbackItem::RightRearPosition),
            f(FeedbackItem::LeftRearPosition),
        );
        if let (Some(linear_m), Some(rf), Some(lf), Some(rr), Some(lr)) = wheels {
            self.odometry.update(
                Integrators {
                    linear_m,
                    right_m: (rf + rr) / 2.0,
                    left_m: (lf + lr) / 2.0,
                },
                self.track_width_m,
            );
        } else if !first_set {
            // No integrators in the selected feedback: integrate the reported velocities.
            let dt = now.saturating_sub(previous_stamp).as_secs_f64();
            self.odometry.integrate_velocity(dt);
        }
        self.verify_from_user_feedback();
    }
}
