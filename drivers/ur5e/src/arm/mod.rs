//! Unload skills on a UR5e: move to joints, move linear, open/close the gripper, stop.
//!
//! [`Ur5eArm`] owns one RTDE connection (its state stream is the skill loop's clock), one
//! URScript connection (motions are short programs), the dashboard and optionally the gripper.
//! Every motion program starts with `rtde_set_watchdog` on an input register that
//! [`Ur5eArm::update`] writes every cycle, so if this computer or the link dies mid-move the
//! controller itself stops the arm. On this side, a state stream that goes stale for
//! [`ArmConfig::stale_after`] (default 100 ms) is a lost connection: the skill sends `stopj`
//! (and the dashboard `stop`) over whatever still works and returns
//! [`SkillError::ConnectionLost`].
//!
//! Two ways to run a skill, one logic:
//!
//! - **Blocking** (`move_joints`, `move_linear`, `stop`, `open_gripper`, `close_gripper`): the
//!   call returns when the skill is done, clocked by the RTDE stream and timed on the arm's own
//!   monotonic clock. For tools and tests.
//! - **Non-blocking**, for the cyclic executive: `start_*` sends what has to be sent and
//!   returns; then once per cycle [`Ur5eArm::update_at`] (never waits for long) and
//!   [`Ur5eArm::poll`] judge progress. Every timeout (program start, motion, stop, gripper,
//!   stale state) is measured on the caller's `now`, a monotonic [`Duration`] from the
//!   executive's clock: wall time on the robot, simulated time in HIL, so a lock-stepped world
//!   that stops also stops every timeout. Once a motion program is sent, `update_at` + `poll`
//!   do not allocate. The blocking skills are `start_*` + a loop of `update` + `poll`.
//!
//! ```no_run
//! # use std::time::Duration;
//! # fn cycle_time() -> Duration { Duration::ZERO }
//! # let mut arm = ur5e::Ur5eArm::connect(ur5e::ArmConfig::default())?;
//! let now = cycle_time();
//! arm.update_at(now)?;
//! arm.start_move_joints([0.0, -1.57, 1.57, -1.57, -1.57, 0.0], 1.05, 1.4,
//!     Duration::from_secs(10), now)?;
//! loop {
//!     let now = cycle_time(); // next cycle
//!     arm.update_at(now)?;
//!     match arm.poll(now)? {
//!         ur5e::SkillProgress::Done(outcome) => break,
//!         _ => {} // Running: come back next cycle
//!     }
//! }
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

use std::net::{IpAddr, Ipv4Addr, SocketAddr};
use std::time::{Duration, Instant};

use thiserror::Error;

use crate::dashboard::{DashboardClient, DashboardError};
use crate::gripper::{GripperError, RobotiqGripper};
use crate::pose::TcpPose;
use crate::rtde::{
    DataPackage, InputRecipe, RtdeClient, RtdeConnectError, RtdeReceiveError, RtdeRequestError,
    RtdeSendError, RtdeSetupError, RtdeTimeouts, RtdeType, RtdeValue,
};
use crate::script::{ScriptCommand, ScriptError, ScriptSender, UrScriptProgram};

mod blocking;
mod skills;
mod state;

pub use blocking::MoveReport;
use skills::Skill;
pub use skills::{GripperAction, SkillOutcome, SkillProgress};
pub use state::ArmState;

/// Joint positions (rad), base to wrist 3 (same layout as `ur5e_kin::Joints`).
pub type Joints = [f64; 6];

/// Output variables the arm reads every cycle, with the types the controller must return.
pub const ARM_OUTPUTS: [(&str, RtdeType); 10] = [
    ("timestamp", RtdeType::Double),
    ("actual_q", RtdeType::Vector6d),
    ("actual_qd", RtdeType::Vector6d),
    ("target_q", RtdeType::Vector6d),
    ("actual_TCP_pose", RtdeType::Vector6d),
    ("robot_mode", RtdeType::Int32),
    ("safety_mode", RtdeType::Int32),
    ("safety_status_bits", RtdeType::Uint32),
    ("runtime_state", RtdeType::Uint32),
    ("robot_status_bits", RtdeType::Uint32),
];

/// `runtime_state` value of a running program.
pub const RUNTIME_PLAYING: u32 = 2;
/// UR5e joint position limit (rad), all joints (reference §5.2).
pub const JOINT_LIMIT_RAD: f64 = 2.0 * std::f64::consts::PI;
/// UR5e maximum joint speed (rad/s), all joints (reference §5.2).
pub const MAX_JOINT_SPEED_RADPS: f64 = std::f64::consts::PI;

/// Connection and skill settings.
#[derive(Debug, Clone, PartialEq)]
pub struct ArmConfig {
    /// Controller address.
    pub host: IpAddr,
    /// RTDE port (30004).
    pub rtde_port: u16,
    /// Dashboard port (29999).
    pub dashboard_port: u16,
    /// URScript port (30002, secondary interface).
    pub script_port: u16,
    /// Robotiq URCap socket port (63352); `None` without a gripper.
    pub gripper_port: Option<u16>,
    /// RTDE output frequency (Hz); 500 on e-Series.
    pub frequency_hz: f64,
    /// No state for this long = lost connection (wall time in the blocking calls; the caller's
    /// clock in [`Ur5eArm::update_at`] and [`Ur5eArm::poll`]).
    pub stale_after: Duration,
    /// Longest wall time [`Ur5eArm::update_at`] waits for a package when none has arrived yet.
    /// Zero (default): take what is there and never block the executive's cycle; in lock-step
    /// HIL the cycle's package is already there when the world's step returns.
    pub receive_wait: Duration,
    /// Input int register fed every cycle as the controller-side watchdog (24..=47 are the
    /// external-client range).
    pub watchdog_register: u8,
    /// Minimum feed rate the controller demands before it stops the program (Hz).
    pub watchdog_min_hz: f64,
    /// A joint move is done when every joint is this close to the goal (rad).
    pub joint_tolerance_rad: f64,
    /// A linear move is done when the TCP is this close to the goal (m).
    pub position_tolerance_m: f64,
    /// ... and its orientation this close (rad).
    pub orientation_tolerance_rad: f64,
    /// ... and every joint slower than this (rad/s).
    pub settled_speed_radps: f64,
    /// A sent program must show up as running within this time.
    pub program_start_timeout: Duration,
    /// Deceleration used to stop the arm (rad/s^2).
    pub stop_decel_radps2: f64,
    /// Tool centre point relative to the flange, set by every motion program (`set_tcp`);
    /// `move_linear` poses and `ArmState::tcp_pose` refer to it. `None` leaves the
    /// controller's configured TCP alone.
    pub tcp_offset: Option<TcpPose>,
    /// TCP connect and reply timeouts.
    pub io_timeout: Duration,
}

impl Default for ArmConfig {
    fn default() -> Self {
        Self {
            host: IpAddr::V4(Ipv4Addr::LOCALHOST),
            rtde_port: crate::rtde::RTDE_PORT,
            dashboard_port: crate::dashboard::DASHBOARD_PORT,
            script_port: crate::script::SECONDARY_PORT,
            gripper_port: Some(crate::gripper::GRIPPER_PORT),
            frequency_hz: 500.0,
            stale_after: Duration::from_millis(100),
            receive_wait: Duration::ZERO,
            watchdog_register: 24,
            watchdog_min_hz: 10.0,
            joint_tolerance_rad: 0.002,
            position_tolerance_m: 0.001,
            orientation_tolerance_rad: 0.005,
            settled_speed_radps: 0.01,
            program_start_timeout: Duration::from_secs(1),
            stop_decel_radps2: 4.0,
            tcp_offset: None,
            io_timeout: Duration::from_secs(2),
        }
    }
}

/// Errors of [`Ur5eArm::connect`].
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum ArmConnectError {
    /// RTDE connect or protocol negotiation.
    #[error("RTDE connect: {0}")]
    Rtde(#[from] RtdeConnectError),
    /// RTDE recipe setup.
    #[error("RTDE recipe setup: {0}")]
    Setup(#[from] RtdeSetupError),
    /// RTDE start.
    #[error("RTDE start: {0}")]
    Start(#[from] RtdeRequestError),
    /// First state package.
    #[error("RTDE first state: {0}")]
    FirstState(#[from] RtdeReceiveError),
    /// The controller returned another type for a variable the arm reads.
    #[error("RTDE variable {name} has type {got:?}, expected {expected:?}")]
    FieldType {
        /// Variable.
        name: &'static str,
        /// Expected type.
        expected: RtdeType,
        /// Returned type.
        got: RtdeType,
    },
    /// URScript port.
    #[error("URScript connect: {0}")]
    Script(#[from] ScriptError),
    /// Dashboard.
    #[error("dashboard connect: {0}")]
    Dashboard(#[from] DashboardError),
    /// Gripper socket.
    #[error("gripper connect: {0}")]
    Gripper(#[from] GripperError),
}

/// Why a skill failed.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum SkillError {
    /// The state stream stopped or the socket failed; the arm was told to stop where possible.
    #[error("connection to the arm lost ({cause}); stop command {}", if *.stop_sent { "sent" } else { "could not be sent: the controller watchdog stops the arm" })]
    ConnectionLost {
        /// What failed.
        cause: String,
        /// Whether a stop program reached the controller over another socket.
        stop_sent: bool,
    },
    /// The controller is in protective stop (collision or limit); needs `unlock protective stop`.
    #[error("protective stop at q = {q_rad:?}")]
    ProtectiveStop {
        /// Joints when the stop was seen.
        q_rad: Joints,
    },
    /// Emergency stop pressed.
    #[error("emergency stop (safety status bits {safety_status_bits:#x})")]
    EmergencyStop {
        /// The bits.
        safety_status_bits: u32,
    },
    /// The robot is not powered with brakes released.
    #[error("robot not ready: robot mode {robot_mode}")]
    NotReady {
        /// `robot_mode`.
        robot_mode: i32,
    },
    /// The motion did not finish in time; the arm was stopped.
    #[error("{skill} did not finish within {timeout:?}; arm stopped")]
    Timeout {
        /// The skill.
        skill: &'static str,
        /// The timeout.
        timeout: Duration,
    },
    /// The program never showed up as running.
    #[error("{skill}: program did not start within {waited:?}")]
    ProgramNotStarted {
        /// The skill.
        skill: &'static str,
        /// Waited.
        waited: Duration,
    },
    /// The program ended (stopped, replaced, runtime error) before the goal was reached.
    #[error("{skill} ended {remaining:.4} short of the goal")]
    StoppedShort {
        /// The skill.
        skill: &'static str,
        /// Remaining error (rad for joints, m for linear).
        remaining: f64,
    },
    /// A program from elsewhere keeps running.
    #[error("another program is running on the controller")]
    Busy,
    /// A skill of this arm is still in progress: poll it to its end, or `start_stop`, which
    /// replaces any skill.
    #[error("skill {active} is still in progress")]
    SkillInProgress {
        /// The skill in progress.
        active: &'static str,
    },
    /// The target is not finite or outside the joint limits.
    #[error("invalid target: {reason}")]
    InvalidTarget {
        /// Why.
        reason: &'static str,
    },
    /// Building or sending the program failed (the socket error is also a lost connection).
    #[error("URScript: {0}")]
    Script(#[from] ScriptError),
    /// Gripper failure.
    #[error("gripper: {0}")]
    Gripper(#[from] GripperError),
    /// No gripper configured.
    #[error("no gripper configured")]
    NoGripper,
    /// Dashboard failure during recovery.
    #[error("dashboard: {0}")]
    Dashboard(#[from] DashboardError),
}

/// A connected UR5e with the unload skills.
pub struct Ur5eArm {
    cfg: ArmConfig,
    rtde: RtdeClient,
    package: DataPackage,
    heartbeat: InputRecipe,
    heartbeat_count: i32,
    heartbeat_value: [RtdeValue; 1],
    script: ScriptSender,
    dashboard: DashboardClient,
    gripper: Option<RobotiqGripper>,
    state: ArmState,
    cycles: u64,
    /// The blocking calls' clock.
    epoch: Instant,
    /// Caller time of the newest package taken by `update_at`.
    received_at: Option<Duration>,
    /// First caller time seen by `update_at`: the staleness reference before any package.
    clock_ref: Option<Duration>,
    skill: Skill,
    /// The first lost-link report: later calls repeat it instead of stopping and logging again.
    lost: Option<(String, bool)>,
}

impl core::fmt::Debug for Ur5eArm {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("Ur5eArm")
            .field("rtde", &self.rtde.peer())
            .field("state", &self.state)
            .finish_non_exhaustive()
    }
}

impl Ur5eArm {
    /// Connects RTDE (recipes checked against [`ARM_OUTPUTS`]), URScript, dashboard and gripper,
    /// and reads the first state.
    pub fn connect(cfg: ArmConfig) -> Result<Self, ArmConnectError> {
        let at = |port| SocketAddr::new(cfg.host, port);
        let timeouts = RtdeTimeouts {
            connect: cfg.io_timeout,
            reply: cfg.io_timeout,
            write: cfg.io_timeout,
        };
        let mut rtde = RtdeClient::connect(at(cfg.rtde_port), timeouts)?;
        match rtde.controller_version() {
            Ok(v) => log::info!("UR controller version {v}"),
            Err(e) => log::warn!("UR controller version unknown: {e}"),
        }
        let names: Vec<&str> = ARM_OUTPUTS.iter().map(|(n, _)| *n).collect();
        let recipe = rtde.setup_outputs(&names, cfg.frequency_hz)?.clone();
        // The recipe is ARM_OUTPUTS in order; check the controller agrees on every type.
        for (i, (name, expected)) in ARM_OUTPUTS.iter().enumerate() {
            let got = recipe.types[i];
            if got != *expected {
                return Err(ArmConnectError::FieldType {
                    name,
                    expected: *expected,
                    got,
                });
            }
        }
        let register = format!("input_int_register_{}", cfg.watchdog_register);
        let heartbeat = rtde.setup_inputs(&[register.as_str()])?;
        if heartbeat.types != [RtdeType::Int32] {
            return Err(ArmConnectError::FieldType {
                name: "input_int_register (watchdog)",
                expected: RtdeType::Int32,
                got: heartbeat.types.first().copied().unwrap_or(RtdeType::Uint8),
            });
        }
        rtde.start()?;
        let mut package = DataPackage::for_recipe(&recipe);
        rtde.receive_latest(&mut package, cfg.io_timeout)?;
        let script = ScriptSender::connect(at(cfg.script_port), cfg.io_timeout)?;
        let dashboard = DashboardClient::connect(at(cfg.dashboard_port), cfg.io_timeout)?;
        let gripper = match cfg.gripper_port {
            Some(port) => Some(RobotiqGripper::connect(at(port), cfg.io_timeout)?),
            None => None,
        };
        let mut arm = Self {
            cfg,
            rtde,
            package,
            heartbeat,
            heartbeat_count: 0,
            heartbeat_value: [RtdeValue::Int32(0)],
            script,
            dashboard,
            gripper,
            state: ArmState {
                timestamp_s: 0.0,
                q_rad: [0.0; 6],
                qd_radps: [0.0; 6],
                target_q_rad: [0.0; 6],
                tcp_pose: TcpPose::from_array([0.0; 6]),
                robot_mode: -1,
                safety_mode: 11,
                safety_status_bits: 0,
                runtime_state: 0,
                robot_status_bits: 0,
                skipped: 0,
            },
            cycles: 0,
            epoch: Instant::now(),
            received_at: None,
            clock_ref: None,
            skill: Skill::Idle,
            lost: None,
        };
        arm.decode_state();
        Ok(arm)
    }

    /// The settings.
    pub fn config(&self) -> &ArmConfig {
        &self.cfg
    }

    /// The state of the last cycle.
    pub fn state(&self) -> &ArmState {
        &self.state
    }

    /// The caller time (`now` of [`Self::update_at`]) at which the newest state arrived; `None`
    /// before `update_at` took a package, and after a blocking call (which runs on its own
    /// clock and restarts this bookkeeping).
    pub fn state_received_at(&self) -> Option<Duration> {
        self.received_at
    }

    /// The skill in progress, if any.
    pub fn active_skill(&self) -> Option<&'static str> {
        self.skill.name()
    }

    /// The dashboard connection (recovery, power, modes).
    pub fn dashboard(&mut self) -> &mut DashboardClient {
        &mut self.dashboard
    }

    /// One cycle: waits for the newest state (at most [`ArmConfig::stale_after`], wall time)
    /// and feeds the controller-side watchdog. Any failure here means the link is gone.
    pub fn update(&mut self) -> Result<&ArmState, SkillError> {
        if let Err(e) = self
            .rtde
            .receive_latest(&mut self.package, self.cfg.stale_after)
        {
            return Err(self.connection_lost(e.to_string()));
        }
        self.take_package();
        // This call runs on the arm's own clock: caller-clock bookkeeping starts afresh.
        self.received_at = None;
        self.clock_ref = None;
        self.feed_watchdog()?;
        Ok(&self.state)
    }

    /// One cycle of a cyclic executive at caller time `now`: takes the newest package that has
    /// arrived (waiting at most [`ArmConfig::receive_wait`], wall time, if none has) and feeds
    /// the controller-side watchdog. With no new package the previous state stays; only when
    /// no package arrived for longer than [`ArmConfig::stale_after`] on the caller's clock is
    /// the link lost (`stopj` attempted, [`SkillError::ConnectionLost`]). A closed or reset
    /// socket is lost at once. Does not allocate unless it fails.
    pub fn update_at(&mut self, now: Duration) -> Result<&ArmState, SkillError> {
        match self
            .rtde
            .receive_newest(&mut self.package, self.cfg.receive_wait)
        {
            Ok(true) => {
                self.take_package();
                self.received_at = Some(now);
            }
            Ok(false) => {}
            Err(e) => return Err(self.connection_lost(e.to_string())),
        }
        let reference = match self.received_at {
            Some(t) => t,
            None => *self.clock_ref.get_or_insert(now),
        };
        let silent = now.saturating_sub(reference);
        if silent > self.cfg.stale_after {
            return Err(self.connection_lost(format!(
                "no RTDE state for {silent:?} (caller clock), limit {:?}",
                self.cfg.stale_after
            )));
        }
        self.feed_watchdog()?;
        Ok(&self.state)
    }

    fn take_package(&mut self) {
        self.decode_state();
        self.cycles += 1;
    }

    /// Writes the next heartbeat count to the watchdog register.
    fn feed_watchdog(&mut self) -> Result<(), SkillError> {
        self.heartbeat_count = self.heartbeat_count.wrapping_add(1);
        self.heartbeat_value[0] = RtdeValue::Int32(self.heartbeat_count);
        if let Err(e) = self
            .rtde
            .send_inputs(&self.heartbeat, &self.heartbeat_value)
        {
            let cause = match e {
                RtdeSendError::Link(l) => l.to_string(),
                other => other.to_string(),
            };
            return Err(self.connection_lost(cause));
        }
        Ok(())
    }

    /// The link is gone: abandon the skill, try every other channel to stop the arm, then
    /// report. Once: later failures repeat the first report.
    fn connection_lost(&mut self, cause: String) -> SkillError {
        self.skill = Skill::Idle;
        if let Some((cause, stop_sent)) = &self.lost {
            return SkillError::ConnectionLost {
                cause: cause.clone(),
                stop_sent: *stop_sent,
            };
        }
        log::error!("UR5e link lost: {cause}; stopping the arm");
        let stop = UrScriptProgram::new(
            "grop_stop",
            vec![ScriptCommand::StopJ {
                decel_radps2: self.cfg.stop_decel_radps2,
            }],
        );
        let by_script = self.script.send(&stop).is_ok();
        let by_dashboard = self.dashboard.stop().is_ok();
        let stop_sent = by_script || by_dashboard;
        self.lost = Some((cause.clone(), stop_sent));
        SkillError::ConnectionLost { cause, stop_sent }
    }

    /// Sends a program; a socket failure is a lost link.
    fn send_program(&mut self, program: &UrScriptProgram) -> Result<(), SkillError> {
        match self.script.send(program) {
            Ok(()) => Ok(()),
            Err(e @ (ScriptError::Io { .. } | ScriptError::Closed { .. })) => {
                Err(self.connection_lost(e.to_string()))
            }
            Err(other) => Err(other.into()),
        }
    }

    fn send_stopj(&mut self, decel_radps2: f64) -> Result<(), SkillError> {
        let program =
            UrScriptProgram::new("grop_stop", vec![ScriptCommand::StopJ { decel_radps2 }]);
        self.send_program(&program)
    }

    /// The blocking calls' clock: time since connect.
    fn own_now(&self) -> Duration {
        self.epoch.elapsed()
    }
}
