//! The base's hardware seam, beside [`super::ArmDevice`]: what the executive's shell needs of a
//! mobile base. The RMP driver over any CAN bus implements it; [`RecordingBase`] wraps any
//! device and keeps what it did, and [`ScriptedBase`] stands in for a base in tests of the
//! shell (no CAN, no simulator).

use std::time::Duration;

use motion_control::Twist;
use rmp_base::{BaseError, BaseMode, BaseStatus, Odometry, RmpBase, RmpLink, Tick};

/// A mobile base as the executive drives it: one velocity target and one tick per base cycle.
pub trait BaseDevice {
    /// Asks for a mode (the device sends and re-sends the request on its ticks).
    fn request_mode(&mut self, mode: BaseMode, now: Duration);
    /// The explicit acknowledgement after which a disarmed driver may move again (it also
    /// releases a [`safety_stop`](Self::safety_stop)).
    fn rearm(&mut self);
    /// A latched safety stop: ramp to zero at the robot file's emergency deceleration (not the
    /// comfort one) and command zero until [`rearm`](Self::rearm).
    fn safety_stop(&mut self);
    /// Sets the velocity target and marks it fresh at `now`.
    fn set_velocity(&mut self, target: Twist, now: Duration);
    /// One command period: read feedback, send one command.
    fn tick(&mut self, now: Duration) -> Result<Tick, BaseError>;
    /// Dead-reckoned pose and measured velocity as of the last tick.
    fn odometry(&self) -> Odometry;
    /// The base's status as last reported.
    fn status(&self) -> BaseStatus;
    /// Start-up done and in a driving mode.
    fn is_driving(&self) -> bool;
}

impl<L: RmpLink> BaseDevice for RmpBase<L> {
    fn request_mode(&mut self, mode: BaseMode, now: Duration) {
        RmpBase::request_mode(self, mode, now);
    }

    fn rearm(&mut self) {
        RmpBase::rearm(self);
    }

    fn safety_stop(&mut self) {
        RmpBase::safety_stop(self);
    }

    fn set_velocity(&mut self, target: Twist, now: Duration) {
        RmpBase::set_velocity(self, target, now);
    }

    fn tick(&mut self, now: Duration) -> Result<Tick, BaseError> {
        RmpBase::tick(self, now)
    }

    fn odometry(&self) -> Odometry {
        *RmpBase::odometry(self)
    }

    fn status(&self) -> BaseStatus {
        *RmpBase::status(self)
    }

    fn is_driving(&self) -> bool {
        RmpBase::is_driving(self)
    }
}

/// One call the shell made on a base.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum BaseCall {
    /// `request_mode`.
    RequestMode(BaseMode),
    /// `rearm`.
    Rearm,
    /// `safety_stop`.
    SafetyStop,
    /// `set_velocity` with this target.
    SetVelocity(Twist),
    /// `tick`; whether it returned an error.
    Tick {
        /// The tick failed.
        failed: bool,
    },
}

/// A base that records every call (time and call) into a list allocated once, for tests and
/// reports of what the executive commanded; calls past the capacity are counted.
pub struct RecordingBase<D: BaseDevice> {
    inner: D,
    calls: Vec<(Duration, BaseCall)>,
    dropped: u64,
}

impl<D: BaseDevice> RecordingBase<D> {
    /// Wraps `inner`, keeping up to `capacity` calls.
    pub fn new(inner: D, capacity: usize) -> Self {
        Self {
            inner,
            calls: Vec::with_capacity(capacity),
            dropped: 0,
        }
    }

    /// The calls recorded, in order.
    pub fn calls(&self) -> &[(Duration, BaseCall)] {
        &self.calls
    }

    /// Calls that did not fit.
    pub fn dropped(&self) -> u64 {
        self.dropped
    }

    /// The wrapped device.
    pub fn inner(&self) -> &D {
        &self.inner
    }

    /// The wrapped device, mutably (tests change what it reports).
    pub fn inner_mut(&mut self) -> &mut D {
        &mut self.inner
    }

    fn record(&mut self, now: Duration, call: BaseCall) {
        if self.calls.len() < self.calls.capacity() {
            self.calls.push((now, call));
        } else {
            self.dropped += 1;
        }
    }
}

impl<D: BaseDevice> BaseDevice for RecordingBase<D> {
    fn request_mode(&mut self, mode: BaseMode, now: Duration) {
        self.record(now, BaseCall::RequestMode(mode));
        self.inner.request_mode(mode, now);
    }

    fn rearm(&mut self) {
        let at = self.inner.odometry().stamp;
        self.record(at, BaseCall::Rearm);
        self.inner.rearm();
    }

    fn safety_stop(&mut self) {
        let at = self.inner.odometry().stamp;
        self.record(at, BaseCall::SafetyStop);
        self.inner.safety_stop();
    }

    fn set_velocity(&mut self, target: Twist, now: Duration) {
        self.record(now, BaseCall::SetVelocity(target));
        self.inner.set_velocity(target, now);
    }

    fn tick(&mut self, now: Duration) -> Result<Tick, BaseError> {
        let result = self.inner.tick(now);
        self.record(
            now,
            BaseCall::Tick {
                failed: result.is_err(),
            },
        );
        result
    }

    fn odometry(&self) -> Odometry {
        self.inner.odometry()
    }

    fn status(&self) -> BaseStatus {
        self.inner.status()
    }

    fn is_driving(&self) -> bool {
        self.inner.is_driving()
    }
}

/// A base whose answers a test sets: it integrates the commanded velocity exactly (unicycle,
/// no limits: the core's and the driver's limits are tested elsewhere), drives once asked for
/// tractor, and fails its ticks with the error a test puts in [`ScriptedBase::fail_with`].
#[derive(Debug)]
pub struct ScriptedBase {
    odometry: Odometry,
    status: BaseStatus,
    target: Twist,
    driving: bool,
    last_tick: Option<Duration>,
    /// The next ticks fail with a lost link while set.
    pub fail_silent: bool,
    /// Ticks so far.
    pub ticks: u64,
    /// The last velocity a tick sent.
    pub sent: Twist,
    /// A safety stop is latched: ticks send zero until `rearm`.
    pub safety_stopped: bool,
}

impl Default for ScriptedBase {
    fn default() -> Self {
        Self::new()
    }
}

impl ScriptedBase {
    /// A base at the origin, standing still, in standby.
    pub fn new() -> Self {
        Self {
            odometry: Odometry::default(),
            status: BaseStatus {
                state: None,
                faults: rmp_codec::faults::FaultStatus::CLEAR,
                battery_soc_pct: None,
                velocity_limit_mps: 0.0,
                yaw_rate_limit_radps: 0.0,
                last_feedback: None,
                feedback_sets: 0,
                feedback_errors: 0,
                receive_errors: 0,
            },
            target: Twist::ZERO,
            driving: false,
            last_tick: None,
            fail_silent: false,
            ticks: 0,
            sent: Twist::ZERO,
            safety_stopped: false,
        }
    }

    /// Makes the next tick fail as a silent base would.
    pub fn fail_with_silence(&mut self) {
        self.fail_silent = true;
    }
}

impl BaseDevice for ScriptedBase {
    fn request_mode(&mut self, mode: BaseMode, _now: Duration) {
        self.driving = mode == BaseMode::Tractor;
        self.status.state = Some(if self.driving {
            rmp_codec::v3::OperationalState::Tractor
        } else {
            rmp_codec::v3::OperationalState::Standby
        });
    }

    fn rearm(&mut self) {
        self.safety_stopped = false;
    }

    fn safety_stop(&mut self) {
        self.safety_stopped = true;
    }

    fn set_velocity(&mut self, target: Twist, _now: Duration) {
        self.target = target;
    }

    fn tick(&mut self, now: Duration) -> Result<Tick, BaseError> {
        self.ticks += 1;
        let dt = self
            .last_tick
            .map_or(0.0, |t| now.saturating_sub(t).as_secs_f64());
        self.last_tick = Some(now);
        if self.fail_silent {
            self.sent = Twist::ZERO;
            self.odometry.speed_mps = 0.0;
            self.odometry.yaw_rate_radps = 0.0;
            return Err(BaseError::Silent {
                silent_for: Duration::from_secs(1),
                timeout: Duration::from_millis(200),
            });
        }
        if self.safety_stopped {
            self.target = Twist::ZERO;
        }
        self.sent = self.target;
        let (v, w) = (
            f64::from(self.target.speed_mps),
            f64::from(self.target.yaw_rate_radps),
        );
        let o = &mut self.odometry;
        o.x_m += v * o.yaw_rad.cos() * dt;
        o.y_m += v * o.yaw_rad.sin() * dt;
        o.yaw_rad = planar::wrap_angle(o.yaw_rad + w * dt);
        o.speed_mps = v;
        o.yaw_rate_radps = w;
        o.stamp = now;
        Ok(Tick {
            commanded: self.target,
            input_stale: false,
            feedback_sets: 1,
            mode_reached: None,
            armed: true,
        })
    }

    fn odometry(&self) -> Odometry {
        self.odometry
    }

    fn status(&self) -> BaseStatus {
        self.status
    }

    fn is_driving(&self) -> bool {
        self.driving
    }
}
