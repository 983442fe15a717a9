//! The RMP v3 base driver: one [`RmpBase::tick`] per command period.

use std::time::Duration;

use log::{debug, info, warn};
use motion_control::Twist;
use motion_control::limiter::{TwistLimiter, TwistLimits};
use motion_control::mode::{ModeSequencer, ModeStep};
use motion_control::watchdog::Watchdog;
use rmp_codec::faults::FaultStatus;
use rmp_codec::feedback::{
    self, FeedbackAssembler, FeedbackError, FeedbackItem, FeedbackLayout, FeedbackSet,
};
use rmp_codec::v3::{
    CONFIG_ID, ConfigCommand, FirmwareProfile, MOTION_ID, MotionCommand, NvmFloat, OperationalState,
};

use crate::link::RmpLink;
use crate::odometry::{DeadReckoning, Integrators, Odometry};

mod config;
mod errors;

pub use config::*;
use errors::describe;
pub use errors::*;

/// The speed and yaw-rate limits a forced-configuration echo holds (both finite and > 0).
fn echoed_limits(echo: &FeedbackSet) -> Option<VerifiedLimits> {
    let positive = |v: Option<f32>| v.filter(|x| x.is_finite() && *x > 0.0);
    Some(VerifiedLimits {
        velocity_mps: positive(echo.get_f32(echo_item(NvmFloat::MaxVelocityMps)))?,
        yaw_rate_radps: positive(echo.get_f32(echo_item(NvmFloat::MaxTurnRateRadps)))?,
    })
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
