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

use std::net::{IpAddr, Ipv4Addr, SocketAddr};
use std::time::{Duration, Instant};

use thiserror::Error;

use crate::dashboard::{DashboardClient, DashboardError, RobotMode, SafetyMode};
use crate::gripper::{GripOutcome, GripperError, RobotiqGripper};
use crate::pose::TcpPose;
use crate::rtde::{
    DataPackage, InputRecipe, RtdeClient, RtdeConnectError, RtdeReceiveError, RtdeRequestError,
    RtdeSendError, RtdeSetupError, RtdeTimeouts, RtdeType, RtdeValue,
};
use crate::script::{ScriptCommand, ScriptError, ScriptSender, UrScriptProgram, WatchdogAction};

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
    /// No state for this long = lost connection.
    pub stale_after: Duration,
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

/// The arm state of one RTDE cycle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ArmState {
    /// Controller time (s).
    pub timestamp_s: f64,
    /// Actual joints (rad).
    pub q_rad: Joints,
    /// Actual joint speeds (rad/s).
    pub qd_radps: Joints,
    /// Target joints (rad).
    pub target_q_rad: Joints,
    /// Actual TCP pose.
    pub tcp_pose: TcpPose,
    /// `robot_mode` (7 = running).
    pub robot_mode: i32,
    /// `safety_mode` (1 = normal, 3 = protective stop).
    pub safety_mode: i32,
    /// `safety_status_bits`.
    pub safety_status_bits: u32,
    /// `runtime_state` (2 = playing).
    pub runtime_state: u32,
    /// `robot_status_bits`.
    pub robot_status_bits: u32,
    /// Packages dropped since the previous cycle (newest wins).
    pub skipped: u32,
}

impl ArmState {
    /// Protective stop: safety status bit 2 or safety mode 3.
    pub fn protective_stopped(&self) -> bool {
        self.safety_status_bits & (1 << 2) != 0
            || self.safety_mode == SafetyMode::ProtectiveStop.code()
    }

    /// Emergency stop (system, robot or either): safety status bits 5, 6, 7.
    pub fn emergency_stopped(&self) -> bool {
        self.safety_status_bits & (0b111 << 5) != 0
    }

    /// A program is running.
    pub fn program_running(&self) -> bool {
        self.runtime_state == RUNTIME_PLAYING
    }

    /// Fastest joint (rad/s).
    pub fn max_joint_speed_radps(&self) -> f64 {
        self.qd_radps.iter().fold(0.0_f64, |m, v| m.max(v.abs()))
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

/// How a finished move ended.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MoveReport {
    /// Wall time from sending to done (s).
    pub duration_s: f64,
    /// Remaining error at the end (rad for joints, m for linear).
    pub final_error: f64,
    /// State cycles observed.
    pub cycles: u64,
}

enum Goal {
    Joints(Joints),
    Pose(TcpPose),
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
}

impl core::fmt::Debug for Ur5eArm {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("Ur5eArm")
            .field("rtde", &self.rtde.peer())
            .field("state", &self.state)
            .finish_non_exhaustive()
    }
}

fn vec6(v: &RtdeValue) -> [f64; 6] {
    match v {
        RtdeValue::Vector6d(x) => *x,
        _ => [f64::NAN; 6],
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

    /// The dashboard connection (recovery, power, modes).
    pub fn dashboard(&mut self) -> &mut DashboardClient {
        &mut self.dashboard
    }

    fn decode_state(&mut self) {
        let v = &self.package.values;
        let int = |i: usize| match v[i] {
            RtdeValue::Int32(x) => x,
            _ => i32::MIN,
        };
        let uint = |i: usize| match v[i] {
            RtdeValue::Uint32(x) => x,
            _ => 0,
        };
        self.state = ArmState {
            timestamp_s: v[0].as_f64().unwrap_or(f64::NAN),
            q_rad: vec6(&v[1]),
            qd_radps: vec6(&v[2]),
            target_q_rad: vec6(&v[3]),
            tcp_pose: TcpPose::from_array(vec6(&v[4])),
            robot_mode: int(5),
            safety_mode: int(6),
            safety_status_bits: uint(7),
            runtime_state: uint(8),
            robot_status_bits: uint(9),
            skipped: self.package.skipped,
        };
    }

    /// One cycle: waits for the newest state (at most [`ArmConfig::stale_after`]) and feeds the
    /// controller-side watchdog. Any failure here means the link is gone.
    pub fn update(&mut self) -> Result<&ArmState, SkillError> {
        if let Err(e) = self
            .rtde
            .receive_latest(&mut self.package, self.cfg.stale_after)
        {
            return Err(self.connection_lost(e.to_string()));
        }
        self.decode_state();
        self.cycles += 1;
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
        Ok(&self.state)
    }

    /// The link is gone: try every other channel to stop the arm, then report.
    fn connection_lost(&mut self, cause: String) -> SkillError {
        log::error!("UR5e link lost: {cause}; stopping the arm");
        let stop = UrScriptProgram::new(
            "grop_stop",
            vec![ScriptCommand::StopJ {
                decel_radps2: self.cfg.stop_decel_radps2,
            }],
        );
        let by_script = self.script.send(&stop).is_ok();
        let by_dashboard = self.dashboard.stop().is_ok();
        SkillError::ConnectionLost {
            cause,
            stop_sent: by_script || by_dashboard,
        }
    }

    fn check_safety(&self) -> Result<(), SkillError> {
        let s = &self.state;
        if s.emergency_stopped() {
            return Err(SkillError::EmergencyStop {
                safety_status_bits: s.safety_status_bits,
            });
        }
        if s.protective_stopped() {
            return Err(SkillError::ProtectiveStop { q_rad: s.q_rad });
        }
        if s.robot_mode != RobotMode::Running.code() {
            return Err(SkillError::NotReady {
                robot_mode: s.robot_mode,
            });
        }
        Ok(())
    }

    fn motion_program(&self, motion: ScriptCommand) -> UrScriptProgram {
        let mut commands = vec![ScriptCommand::RtdeWatchdog {
            input: format!("input_int_register_{}", self.cfg.watchdog_register),
            min_frequency_hz: self.cfg.watchdog_min_hz,
            action: WatchdogAction::Stop,
        }];
        if let Some(tcp) = self.cfg.tcp_offset {
            commands.push(ScriptCommand::SetTcp(tcp));
        }
        commands.push(motion);
        UrScriptProgram::new("grop_motion", commands)
    }

    fn goal_error(&self, goal: &Goal) -> f64 {
        match goal {
            Goal::Joints(q) => self
                .state
                .q_rad
                .iter()
                .zip(q)
                .fold(0.0_f64, |m, (a, b)| m.max((a - b).abs())),
            Goal::Pose(p) => self.state.tcp_pose.position_distance_m(p),
        }
    }

    fn at_goal(&self, goal: &Goal) -> bool {
        let settled = self.state.max_joint_speed_radps() < self.cfg.settled_speed_radps;
        let close = match goal {
            Goal::Joints(_) => self.goal_error(goal) <= self.cfg.joint_tolerance_rad,
            Goal::Pose(p) => {
                self.state.tcp_pose.position_distance_m(p) <= self.cfg.position_tolerance_m
                    && self.state.tcp_pose.orientation_distance_rad(p)
                        <= self.cfg.orientation_tolerance_rad
            }
        };
        settled && close
    }

    /// Waits (bounded) until no program runs, so the next one is ours when seen running.
    fn wait_idle(&mut self) -> Result<(), SkillError> {
        let started = Instant::now();
        loop {
            self.update()?;
            self.check_safety()?;
            if !self.state.program_running() {
                return Ok(());
            }
            if started.elapsed() > self.cfg.program_start_timeout {
                return Err(SkillError::Busy);
            }
        }
    }

    fn run_motion(
        &mut self,
        skill: &'static str,
        motion: ScriptCommand,
        goal: Goal,
        timeout: Duration,
    ) -> Result<MoveReport, SkillError> {
        self.wait_idle()?;
        let program = self.motion_program(motion);
        if let Err(e) = self.script.send(&program) {
            return Err(match e {
                ScriptError::Io { .. } | ScriptError::Closed { .. } => {
                    self.connection_lost(e.to_string())
                }
                other => other.into(),
            });
        }
        let sent = Instant::now();
        let first_cycle = self.cycles;
        let mut seen_running = false;
        loop {
            self.update()?;
            self.check_safety()?;
            let running = self.state.program_running();
            seen_running |= running;
            let elapsed = sent.elapsed();
            let report = |arm: &Self| MoveReport {
                duration_s: elapsed.as_secs_f64(),
                final_error: arm.goal_error(&goal),
                cycles: arm.cycles - first_cycle,
            };
            if seen_running && !running {
                if self.at_goal(&goal) {
                    return Ok(report(self));
                }
                return Err(SkillError::StoppedShort {
                    skill,
                    remaining: self.goal_error(&goal),
                });
            }
            if !seen_running && elapsed > self.cfg.program_start_timeout {
                // A move to where the arm already is may run between two samples.
                if self.at_goal(&goal) {
                    return Ok(report(self));
                }
                return Err(SkillError::ProgramNotStarted {
                    skill,
                    waited: elapsed,
                });
            }
            if elapsed > timeout {
                self.stop(self.cfg.stop_decel_radps2, Duration::from_secs(2))?;
                return Err(SkillError::Timeout { skill, timeout });
            }
        }
    }

    /// `movej` to `q_rad` and waits until the arm rests there.
    pub fn move_joints(
        &mut self,
        q_rad: Joints,
        speed_radps: f64,
        accel_radps2: f64,
        timeout: Duration,
    ) -> Result<MoveReport, SkillError> {
        if q_rad.iter().any(|q| !q.is_finite()) {
            return Err(SkillError::InvalidTarget {
                reason: "joint target not finite",
            });
        }
        if q_rad.iter().any(|q| q.abs() > JOINT_LIMIT_RAD) {
            return Err(SkillError::InvalidTarget {
                reason: "joint target outside +-2 pi",
            });
        }
        if !(speed_radps > 0.0 && speed_radps <= MAX_JOINT_SPEED_RADPS) {
            return Err(SkillError::InvalidTarget {
                reason: "joint speed must be in (0, pi] rad/s",
            });
        }
        let motion = ScriptCommand::MoveJ {
            q_rad,
            accel_radps2,
            speed_radps,
        };
        self.run_motion("move_joints", motion, Goal::Joints(q_rad), timeout)
    }

    /// `movel` to `pose` (straight tool line) and waits until the arm rests there.
    pub fn move_linear(
        &mut self,
        pose: TcpPose,
        speed_mps: f64,
        accel_mps2: f64,
        timeout: Duration,
    ) -> Result<MoveReport, SkillError> {
        if pose.as_array().iter().any(|x| !x.is_finite()) {
            return Err(SkillError::InvalidTarget {
                reason: "pose not finite",
            });
        }
        let motion = ScriptCommand::MoveL {
            pose,
            accel_mps2,
            speed_mps,
        };
        self.run_motion("move_linear", motion, Goal::Pose(pose), timeout)
    }

    /// Stops any motion (`stopj`, replacing the running program) and waits until the arm rests.
    pub fn stop(&mut self, decel_radps2: f64, timeout: Duration) -> Result<(), SkillError> {
        let program =
            UrScriptProgram::new("grop_stop", vec![ScriptCommand::StopJ { decel_radps2 }]);
        if let Err(e) = self.script.send(&program) {
            return Err(match e {
                ScriptError::Io { .. } | ScriptError::Closed { .. } => {
                    self.connection_lost(e.to_string())
                }
                other => other.into(),
            });
        }
        let sent = Instant::now();
        loop {
            self.update()?;
            if self.state.max_joint_speed_radps() < self.cfg.settled_speed_radps
                && !self.state.program_running()
            {
                return Ok(());
            }
            if sent.elapsed() > timeout {
                return Err(SkillError::Timeout {
                    skill: "stop",
                    timeout,
                });
            }
        }
    }

    /// Opens the gripper.
    pub fn open_gripper(&mut self, timeout: Duration) -> Result<GripOutcome, SkillError> {
        let g = self.gripper.as_mut().ok_or(SkillError::NoGripper)?;
        g.activate(timeout)?;
        Ok(g.open(timeout)?)
    }

    /// Closes the gripper; [`GripOutcome::ObjectWhileClosing`] means an object is held.
    pub fn close_gripper(&mut self, timeout: Duration) -> Result<GripOutcome, SkillError> {
        let g = self.gripper.as_mut().ok_or(SkillError::NoGripper)?;
        g.activate(timeout)?;
        Ok(g.close(timeout)?)
    }

    /// After a protective stop: `unlock protective stop` and wait until the robot runs again.
    pub fn recover_protective_stop(&mut self, timeout: Duration) -> Result<(), SkillError> {
        self.dashboard.close_safety_popup()?;
        self.dashboard.unlock_protective_stop()?;
        let started = Instant::now();
        loop {
            self.update()?;
            if !self.state.protective_stopped()
                && self.state.robot_mode == RobotMode::Running.code()
            {
                return Ok(());
            }
            if started.elapsed() > timeout {
                return Err(SkillError::Timeout {
                    skill: "recover_protective_stop",
                    timeout,
                });
            }
        }
    }
}
