//! Simulated Segway RMP v3 base (Segway Inc 2014 firmware numbering by default) for
//! hardware-in-the-loop tests: it answers every 0x500 / 0x501 with one feedback set in the
//! layout its feedback bitmaps select, changes modes on request, holds the last motion command
//! for 0.5 s and then ramps to zero at the NVM deceleration limit, reports and acts on injected
//! faults, and moves as a unicycle under its NVM acceleration limits.
//!
//! Two ways to run it:
//! * in-process on any `can_bus::CanBus` (e.g. `MemoryBus`) with a simulated clock:
//!   [`SimRmpNode::poll`] after every driver tick; deterministic and fast;
//! * as its own process on the iceoryx2 virtual bus: the `sim-rmp` binary
//!   (`sim-rmp --bus hil`), controlled through stdin (see `docs/rmp.md`).
//!
//! ```
//! use std::time::Duration;
//! use can_bus::MemoryBus;
//! use sim_rmp::{SimConfig, SimRmp, SimRmpNode};
//!
//! let bus = MemoryBus::new();
//! let mut base = SimRmpNode::new(bus.join(), SimRmp::new(SimConfig::default()));
//! let replies = base.poll(Duration::from_millis(20))?; // answers whatever the host sent
//! assert_eq!(replies, 0);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

use std::time::Duration;

use can_bus::{CanBus, CanFrame, CanId, RecvError, SendError};
use log::{debug, info};
use motion_control::limiter::slew;
use planar::{Pose2, wrap_angle};
use rmp_codec::RawFrame;
use rmp_codec::faults::{self, FaultBit, FaultStatus};
use rmp_codec::feedback::{FeedbackBitmaps, FeedbackItem, FeedbackLayout, FeedbackSet};
use rmp_codec::v3::{
    self, ConfigCommand, DecodeError, FirmwareProfile, HostCommand, ModeRequest, NvmFloat,
    OperationalState,
};

/// Build id the simulator reports in `sp_sw_build_id` ("SIM" + version 1).
pub const SIM_BUILD_ID: u32 = 0x5349_4D01;

/// Simulator settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SimConfig {
    /// Command numbering the simulated firmware speaks.
    pub profile: FirmwareProfile,
    /// Silence after which the last command is dropped and the base ramps to zero. 0.5 s
    /// (reference §2.3, FORUM2).
    pub loss_of_command_timeout: Duration,
    /// Time from a mode request to the new operational state. 50 ms.
    pub mode_change_delay: Duration,
    /// +1: a positive normalised yaw command and a positive differential wheel velocity are
    /// counter-clockwise; -1: clockwise.
    pub yaw_sign: f64,
    /// State at power-on. Standby (3), as the sources report.
    pub initial_state: OperationalState,
    /// Feedback bitmaps in NVM at power-on.
    pub initial_bitmaps: FeedbackBitmaps,
    /// Integration step of the kinematics. 1 ms.
    pub physics_step: Duration,
}

impl Default for SimConfig {
    fn default() -> Self {
        Self {
            profile: FirmwareProfile::SegwayInc2014,
            loss_of_command_timeout: Duration::from_millis(500),
            mode_change_delay: Duration::from_millis(50),
            yaw_sign: 1.0,
            initial_state: OperationalState::Standby,
            initial_bitmaps: FeedbackBitmaps::DEFAULT,
            physics_step: Duration::from_millis(1),
        }
    }
}

/// Counters for tests and logs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct SimStats {
    /// Valid motion commands received.
    pub motion_commands: u64,
    /// Valid configuration commands received.
    pub config_commands: u64,
    /// Frames addressed to the base that did not decode.
    pub bad_frames: u64,
    /// Feedback sets sent.
    pub replies: u64,
    /// Times the loss-of-command timeout fired.
    pub command_losses: u64,
    /// Times the base was pushed back by an obstacle ([`SimRmp::block`]).
    pub blocks: u64,
}

/// Where the base and its wheels are: what [`SimRmp::block`] puts back.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Kinematics {
    pose: Pose2,
    linear_position_m: f64,
    wheel_positions_m: [f64; 4],
}

impl Kinematics {
    /// The pose.
    pub fn pose(&self) -> Pose2 {
        self.pose
    }
}

/// The simulated base: protocol state machine plus kinematics, on an external clock.
#[derive(Debug, Clone)]
pub struct SimRmp {
    config: SimConfig,
    nvm: [f32; 11],
    input_config_bitmap: u32,
    ethernet: [u32; 4],
    bitmaps: FeedbackBitmaps,
    forced_config: bool,
    state: OperationalState,
    pending_mode: Option<(OperationalState, Duration)>,
    powering_down: bool,
    faults: FaultStatus,
    /// Normalised command as last received.
    command: (f32, f32),
    last_command_at: Option<Duration>,
    command_lost: bool,
    /// Actual forward speed (m/s) and counter-clockwise yaw rate (rad/s).
    speed_mps: f32,
    yaw_rate_radps: f32,
    linear_accel_mps2: f32,
    pose: Pose2,
    linear_position_m: f64,
    /// Right-front, left-front, right-rear, left-rear wheel positions, m.
    wheel_positions_m: [f64; 4],
    time: Duration,
    silent: bool,
    stats: SimStats,
}

fn nvm_index(p: NvmFloat) -> usize {
    NvmFloat::ALL.iter().position(|q| *q == p).unwrap_or(0)
}

impl SimRmp {
    /// A base that just powered on (time zero, standby, factory NVM).
    pub fn new(config: SimConfig) -> Self {
        Self {
            nvm: NvmFloat::ALL.map(NvmFloat::default_value),
            input_config_bitmap: 0,
            ethernet: [0xC0A8_0028, 8080, 0xFFFF_FF00, 0xC0A8_0001],
            bitmaps: config.initial_bitmaps,
            forced_config: false,
            state: config.initial_state,
            pending_mode: None,
            powering_down: false,
            faults: FaultStatus::CLEAR,
            command: (0.0, 0.0),
            last_command_at: None,
            command_lost: true,
            speed_mps: 0.0,
            yaw_rate_radps: 0.0,
            linear_accel_mps2: 0.0,
            pose: Pose2::default(),
            linear_position_m: 0.0,
            wheel_positions_m: [0.0; 4],
            time: Duration::ZERO,
            silent: false,
            stats: SimStats::default(),
            config,
        }
    }

    /// The settings.
    pub fn config(&self) -> &SimConfig {
        &self.config
    }

    /// One NVM float.
    pub fn nvm(&self, p: NvmFloat) -> f32 {
        self.nvm[nvm_index(p)]
    }

    /// Writes one NVM float as a service tool would, behind the host's back (fault injection:
    /// a limit that changes after the driver verified it). Values outside the parameter's
    /// range are refused, as the firmware refuses them.
    pub fn set_nvm(&mut self, p: NvmFloat, value: f32) -> bool {
        let (min, max) = p.range();
        if !(value.is_finite() && (min..=max).contains(&value)) {
            return false;
        }
        info!("sim-rmp: {p:?} set to {value} behind the host's back");
        self.nvm[nvm_index(p)] = value;
        true
    }

    /// Power-cycles the base: what the F-RAM holds survives (the float parameters, the input
    /// configuration and feedback bitmaps, the Ethernet settings: reference §2.5), everything
    /// else starts over as at power-on (initial state, no faults, no command, at rest, wheel
    /// and linear integrators zero, user feedback). The base stays where it is.
    pub fn power_cycle(&mut self) {
        info!("sim-rmp: power cycle (NVM kept: {:?})", self.nvm);
        let kept = (
            self.nvm,
            self.input_config_bitmap,
            self.ethernet,
            self.bitmaps,
            self.pose,
            self.time,
            self.stats,
        );
        *self = SimRmp::new(self.config);
        (
            self.nvm,
            self.input_config_bitmap,
            self.ethernet,
            self.bitmaps,
            self.pose,
            self.time,
            self.stats,
        ) = kept;
    }

    /// Operational state.
    pub fn state(&self) -> OperationalState {
        self.state
    }

    /// Ground-truth pose.
    pub fn pose(&self) -> Pose2 {
        self.pose
    }

    /// Where the base and its wheels are now.
    pub fn kinematics(&self) -> Kinematics {
        Kinematics {
            pose: self.pose,
            linear_position_m: self.linear_position_m,
            wheel_positions_m: self.wheel_positions_m,
        }
    }

    /// The base ran into something: it is back where it was (`at`, before the step that went
    /// into the obstacle), its drives stalled (speed and yaw rate zero, the wheels did not
    /// turn). The next physics step accelerates again from rest toward the command, so a base
    /// that keeps pushing stays against the obstacle with its measured velocity near zero: what
    /// a real base's current-limited motors do.
    pub fn block(&mut self, at: Kinematics) {
        self.pose = at.pose;
        self.linear_position_m = at.linear_position_m;
        self.wheel_positions_m = at.wheel_positions_m;
        self.speed_mps = 0.0;
        self.yaw_rate_radps = 0.0;
        self.linear_accel_mps2 = 0.0;
        self.stats.blocks += 1;
    }

    /// Actual forward speed (m/s) and counter-clockwise yaw rate (rad/s).
    pub fn velocity(&self) -> (f32, f32) {
        (self.speed_mps, self.yaw_rate_radps)
    }

    /// Current fault words.
    pub fn faults(&self) -> FaultStatus {
        self.faults
    }

    /// Counters.
    pub fn stats(&self) -> SimStats {
        self.stats
    }

    /// Simulated time.
    pub fn time(&self) -> Duration {
        self.time
    }

    /// True while the loss-of-command timeout holds the base at (or ramping to) zero.
    pub fn command_lost(&self) -> bool {
        self.command_lost
    }

    /// Sets or clears a fault bit (fault injection). A fault that stops motion brings the base
    /// to rest at the decel-to-zero rate and refuses tractor requests while present.
    pub fn set_fault(&mut self, fault: FaultBit, active: bool) {
        if active {
            info!("sim-rmp: fault injected: {}", fault.name);
            self.faults.set(fault);
        } else {
            info!("sim-rmp: fault cleared: {}", fault.name);
            self.faults.clear(fault);
        }
    }

    /// Makes the base stop answering (it keeps moving per its own timeout rules).
    pub fn set_silent(&mut self, silent: bool) {
        self.silent = silent;
    }

    /// True while the base does not answer.
    pub fn is_silent(&self) -> bool {
        self.silent
    }

    /// Layout of the next feedback set.
    pub fn layout(&self) -> FeedbackLayout {
        if self.forced_config {
            FeedbackLayout::ForcedConfig
        } else {
            FeedbackLayout::User(self.bitmaps)
        }
    }

    /// Handles one received frame at `now`; returns the feedback set to send, if any. Frames
    /// that are not 0x500 / 0x501 are ignored (other traffic on the bus).
    pub fn handle_frame(&mut self, frame: &RawFrame, now: Duration) -> Option<FeedbackSet> {
        if frame.id() != v3::MOTION_ID && frame.id() != v3::CONFIG_ID {
            return None;
        }
        self.advance(now);
        match HostCommand::decode(self.config.profile, frame) {
            Ok(HostCommand::Motion(m)) => {
                self.stats.motion_commands += 1;
                self.faults.clear(faults::BAD_MOTION_COMMAND);
                self.command = (m.velocity(), m.yaw_rate());
                self.keep_alive();
            }
            Ok(HostCommand::Config(c)) => {
                self.stats.config_commands += 1;
                self.faults.clear(faults::UNKNOWN_COMMAND);
                self.configure(c);
                self.keep_alive();
            }
            Err(e) => {
                self.stats.bad_frames += 1;
                debug!("sim-rmp: bad frame {frame:?}: {e}");
                // The firmware flags it; a rejected frame does not count as a keep-alive.
                match e {
                    DecodeError::UnknownCommand { .. } | DecodeError::BadParameter { .. } => {
                        self.faults.set(faults::UNKNOWN_COMMAND)
                    }
                    _ => self.faults.set(faults::BAD_MOTION_COMMAND),
                }
            }
        }
        if self.silent {
            return None;
        }
        self.stats.replies += 1;
        Some(self.feedback())
    }

    fn keep_alive(&mut self) {
        self.last_command_at = Some(self.time);
        if self.command_lost {
            self.command_lost = false;
        }
    }

    fn configure(&mut self, c: ConfigCommand) {
        match c {
            ConfigCommand::None | ConfigCommand::Audio(_) | ConfigCommand::SendFaultLog(_) => {}
            ConfigCommand::SetFloat(p, v) => self.nvm[nvm_index(p)] = v,
            ConfigCommand::SetInputConfigBitmap(b) => self.input_config_bitmap = b,
            ConfigCommand::SetEthernet(field, v) => {
                let i = match field {
                    v3::EthernetField::Ip => 0,
                    v3::EthernetField::Port => 1,
                    v3::EthernetField::Subnet => 2,
                    v3::EthernetField::Gateway => 3,
                };
                self.ethernet[i] = v;
            }
            ConfigCommand::SetFeedbackBitmap { index, bitmap } => {
                let mut words = self.bitmaps.words();
                words[index as usize] = bitmap;
                match FeedbackBitmaps::new(words) {
                    Ok(b) => self.bitmaps = b,
                    Err(_) => self.faults.set(faults::UNKNOWN_COMMAND),
                }
            }
            ConfigCommand::ForceConfigFeedback(on) => self.forced_config = on,
            ConfigCommand::SetOperationalMode(request) => self.request_mode(request),
            ConfigCommand::ResetIntegrators(mask) => {
                if mask & v3::reset::LINEAR_POSITION != 0 {
                    self.linear_position_m = 0.0;
                }
                for (bit, wheel) in [
                    (v3::reset::RIGHT_FRONT, 0),
                    (v3::reset::LEFT_FRONT, 1),
                    (v3::reset::RIGHT_REAR, 2),
                    (v3::reset::LEFT_REAR, 3),
                ] {
                    if mask & bit != 0 {
                        self.wheel_positions_m[wheel] = 0.0;
                    }
                }
            }
            ConfigCommand::ResetParametersToDefault => {
                self.nvm = NvmFloat::ALL.map(NvmFloat::default_value);
            }
            _ => self.faults.set(faults::UNKNOWN_COMMAND),
        }
    }

    fn request_mode(&mut self, request: ModeRequest) {
        let due = self.time + self.config.mode_change_delay;
        let target = match request {
            ModeRequest::Tractor if self.faults.stops_motion() => {
                info!("sim-rmp: tractor refused while faulted");
                return;
            }
            ModeRequest::Tractor => OperationalState::Tractor,
            ModeRequest::Standby | ModeRequest::DecelToZero => OperationalState::Standby,
            ModeRequest::Disable => OperationalState::DisablePower,
            ModeRequest::PowerDown => {
                self.powering_down = true;
                OperationalState::DisablePower
            }
            // A statically stable base has no balance mode.
            ModeRequest::Balance => return,
        };
        self.pending_mode = Some((target, due));
    }

    /// Advances time to `now` (no-op if `now` is not later).
    pub fn advance(&mut self, now: Duration) {
        let step = self.config.physics_step.max(Duration::from_micros(100));
        while self.time < now {
            let dt = step.min(now - self.time);
            self.time += dt;
            self.physics(dt.as_secs_f64());
        }
    }

    fn physics(&mut self, dt: f64) {
        if let Some((target, due)) = self.pending_mode
            && self.time >= due
        {
            info!("sim-rmp: {:?} -> {:?}", self.state, target);
            self.state = target;
            self.pending_mode = None;
            if self.powering_down {
                self.silent = true;
            }
        }
        let lost = self
            .last_command_at
            .is_none_or(|t| self.time - t > self.config.loss_of_command_timeout);
        if lost && !self.command_lost {
            info!(
                "sim-rmp: no command for {:?}: ramping to zero",
                self.config.loss_of_command_timeout
            );
            self.command_lost = true;
            self.stats.command_losses += 1;
        }
        let faulted = self.faults.stops_motion();
        let driving = self.state == OperationalState::Tractor && !faulted && !self.command_lost;
        let (v_target, w_target) = if driving {
            (
                self.command.0 * self.nvm(NvmFloat::MaxVelocityMps),
                self.config.yaw_sign as f32 * self.command.1 * self.nvm(NvmFloat::MaxTurnRateRadps),
            )
        } else {
            (0.0, 0.0)
        };
        // Loss of command slews at the NVM deceleration (FORUM2); faults and leaving tractor
        // use the decel-to-zero rate.
        let decel = if driving || self.command_lost {
            self.nvm(NvmFloat::MaxDecelerationMps2)
        } else {
            self.nvm(NvmFloat::MaxDtzDecelMps2)
        };
        let yaw_accel = self.nvm(NvmFloat::MaxTurnAccelerationRadps2);
        let dt32 = dt as f32;
        let before = self.speed_mps;
        self.speed_mps = slew(
            self.speed_mps,
            v_target,
            self.nvm(NvmFloat::MaxAccelerationMps2),
            decel,
            dt32,
        );
        self.yaw_rate_radps = slew(self.yaw_rate_radps, w_target, yaw_accel, yaw_accel, dt32);
        self.linear_accel_mps2 = if dt32 > 0.0 {
            (self.speed_mps - before) / dt32
        } else {
            0.0
        };

        // Unicycle, exact arc over the step.
        let v = self.speed_mps as f64;
        let w = self.yaw_rate_radps as f64;
        let dtheta = w * dt;
        let chord = if dtheta.abs() < 1e-9 {
            v * dt
        } else {
            2.0 * v / w * (dtheta / 2.0).sin()
        };
        let mid = self.pose.yaw_rad + dtheta / 2.0;
        self.pose.x_m += chord * mid.cos();
        self.pose.y_m += chord * mid.sin();
        self.pose.yaw_rad = wrap_angle(self.pose.yaw_rad + dtheta);
        self.linear_position_m += v * dt;
        let half_track = self.nvm(NvmFloat::TrackWidthM) as f64 / 2.0;
        let right = (v + w * half_track) * dt;
        let left = (v - w * half_track) * dt;
        self.wheel_positions_m[0] += right;
        self.wheel_positions_m[1] += left;
        self.wheel_positions_m[2] += right;
        self.wheel_positions_m[3] += left;
    }

    /// The feedback set for the current state.
    pub fn feedback(&self) -> FeedbackSet {
        FeedbackSet::from_fn(self.layout(), |item| self.item_value(item))
    }

    fn item_value(&self, item: FeedbackItem) -> u32 {
        use FeedbackItem as I;
        let f = |x: f32| x.to_bits();
        let half_track = self.nvm(NvmFloat::TrackWidthM) / 2.0;
        let right_v = self.speed_mps + self.yaw_rate_radps * half_track;
        let left_v = self.speed_mps - self.yaw_rate_radps * half_track;
        let sign = self.config.yaw_sign as f32;
        let fault_words = self.faults.words();
        match item {
            I::FaultStatusWord1 => fault_words[0],
            I::FaultStatusWord2 => fault_words[1],
            I::FaultStatusWord3 => fault_words[2],
            I::FaultStatusWord4 => fault_words[3],
            I::OperationalTime => f(self.time.as_secs_f32()),
            I::OperationalState => self.state.to_word(),
            I::MinPropulsionBattSoc | I::AuxBattSoc => f(80.0),
            I::InertialZRate => f(self.yaw_rate_radps),
            I::PseYawRate => f(sign * self.yaw_rate_radps.to_degrees()),
            I::PseDataIsValid => 0x3,
            I::YawRateLimit => f(self.nvm(NvmFloat::MaxTurnRateRadps)),
            I::VelocityLimit => f(self.nvm(NvmFloat::MaxVelocityMps)),
            I::LinearAccel => f(self.linear_accel_mps2),
            I::LinearVelocity => f(self.speed_mps),
            I::DifferentialWheelVelocity => f(sign * self.yaw_rate_radps),
            I::RightFrontVelocity | I::RightRearVelocity => f(right_v),
            I::LeftFrontVelocity | I::LeftRearVelocity => f(left_v),
            I::RightFrontPosition => f(self.wheel_positions_m[0] as f32),
            I::LeftFrontPosition => f(self.wheel_positions_m[1] as f32),
            I::RightRearPosition => f(self.wheel_positions_m[2] as f32),
            I::LeftRearPosition => f(self.wheel_positions_m[3] as f32),
            I::LinearPosition => f(self.linear_position_m as f32),
            I::FrontBaseBatt1Soc
            | I::FrontBaseBatt2Soc
            | I::RearBaseBatt1Soc
            | I::RearBaseBatt2Soc => f(80.0),
            I::FrontBaseBatt1Temp
            | I::FrontBaseBatt2Temp
            | I::RearBaseBatt1Temp
            | I::RearBaseBatt2Temp
            | I::AuxBattTemp => f(25.0),
            I::VelocityTarget => f(self.command.0 * self.nvm(NvmFloat::MaxVelocityMps)),
            I::YawRateTarget => f(self.command.1 * self.nvm(NvmFloat::MaxTurnRateRadps)),
            I::AuxBattVoltage => f(12.8),
            I::SevenP2VBattVoltage => f(7.2),
            I::SpSwBuildId | I::UipSwBuildId => SIM_BUILD_ID,
            I::FramVelocityLimit => f(self.nvm[0]),
            I::FramAccelLimit => f(self.nvm[1]),
            I::FramDecelLimit => f(self.nvm[2]),
            I::FramDtzDecelLimit => f(self.nvm[3]),
            I::FramCoastDownAccel => f(self.nvm[4]),
            I::FramYawRateLimit => f(self.nvm[5]),
            I::FramYawAccelLimit => f(self.nvm[6]),
            I::FramTireDiameter => f(self.nvm[7]),
            I::FramWheelBase => f(self.nvm[8]),
            I::FramTrackWidth => f(self.nvm[9]),
            I::FramTransmissionRatio => f(self.nvm[10]),
            I::FramConfigBitmap => self.input_config_bitmap,
            I::FramEthIp => self.ethernet[0],
            I::FramEthPort => self.ethernet[1],
            I::FramEthSubnet => self.ethernet[2],
            I::FramEthGateway => self.ethernet[3],
            I::UserFeedbackBitmap1 => self.bitmaps.words()[0],
            I::UserFeedbackBitmap2 => self.bitmaps.words()[1],
            I::UserFeedbackBitmap3 => self.bitmaps.words()[2],
            I::UserFeedbackBitmap4 => self.bitmaps.words()[3],
            // Attitude, currents, energy and the rest: zero on a level, unloaded simulation.
            _ => 0,
        }
    }
}

/// Why the simulator's bus node failed.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SimNodeError {
    /// Sending a feedback frame failed.
    #[error("sim-rmp: sending feedback failed: {0}")]
    Send(#[from] SendError),
    /// Receiving failed.
    #[error("sim-rmp: receiving failed: {0}")]
    Recv(#[from] RecvError),
}

/// The simulator on a bus node.
pub struct SimRmpNode<B> {
    bus: B,
    sim: SimRmp,
}

impl<B: CanBus> SimRmpNode<B> {
    /// Puts `sim` on `bus`.
    pub fn new(bus: B, sim: SimRmp) -> Self {
        Self { bus, sim }
    }

    /// The simulator.
    pub fn sim(&self) -> &SimRmp {
        &self.sim
    }

    /// The simulator, for fault injection.
    pub fn sim_mut(&mut self) -> &mut SimRmp {
        &mut self.sim
    }

    /// The bus node.
    pub fn bus_mut(&mut self) -> &mut B {
        &mut self.bus
    }

    /// Handles every frame waiting, answering each command, then advances to `now`.
    /// Returns the number of feedback sets sent.
    pub fn poll(&mut self, now: Duration) -> Result<usize, SimNodeError> {
        let mut replies = 0;
        while let Some(frame) = self.bus.try_recv()? {
            replies += self.handle(&frame, now)?;
        }
        self.sim.advance(now);
        Ok(replies)
    }

    /// Waits up to `timeout` for one frame and answers it (the process loop).
    pub fn poll_blocking(
        &mut self,
        timeout: Duration,
        clock: impl Fn() -> Duration,
    ) -> Result<usize, SimNodeError> {
        let replies = match self.bus.recv_timeout(timeout)? {
            Some(frame) => self.handle(&frame, clock())?,
            None => 0,
        };
        self.sim.advance(clock());
        Ok(replies)
    }

    fn handle(&mut self, frame: &CanFrame, now: Duration) -> Result<usize, SimNodeError> {
        let CanId::Standard(id) = frame.id() else {
            return Ok(0);
        };
        let Ok(raw) = RawFrame::new(id, frame.data()) else {
            return Ok(0);
        };
        let Some(set) = self.sim.handle_frame(&raw, now) else {
            return Ok(0);
        };
        for f in set.frames() {
            // RawFrame ids and lengths are always valid CAN.
            if let Ok(out) = CanFrame::new(CanId::Standard(f.id()), f.data()) {
                self.bus.send(&out)?;
            }
        }
        Ok(1)
    }
}

/// Parses a fault name used on the simulator's control input (`kill`, `disable`,
/// `velocity-control`, `decel-switch`).
pub fn fault_by_name(name: &str) -> Option<FaultBit> {
    Some(match name {
        "kill" => faults::KILL_SWITCH_ACTIVE,
        "disable" => faults::COMMANDED_DISABLE,
        "shutdown" => faults::COMMANDED_SAFETY_SHUTDOWN,
        "velocity-control" => faults::VELOCITY_CONTROL_FAILED,
        "decel-switch" => faults::DECEL_SWITCH_ACTIVE,
        _ => return None,
    })
}

#[cfg(test)]
mod tests;
