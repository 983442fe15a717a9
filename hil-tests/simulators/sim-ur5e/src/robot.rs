//! The simulated arm: modes, safety, program execution and motion, stepped at the control rate.
//!
//! Deterministic: [`RobotModel::step`] advances by a fixed `dt` and depends on nothing else
//! (the servers call it from a 500 Hz thread, unit tests call it directly).
//!
//! Motion model: `movej` is a synchronised trapezoidal profile in joint space (the leading
//! joint runs at `v`/`a`, capped at the UR5e's pi rad/s); `movel` follows a straight line with
//! slerped orientation under a trapezoidal profile, solved each cycle with the closed-form IK
//! of `ur5e-kin` (solution nearest the current joints) and slowed down (speed scaling) so no
//! joint exceeds pi rad/s; `stopj`/`stopl` and program stops decelerate all joints along their
//! current direction. The TCP pose is `Ur5e::forward(q)` composed with the TCP offset.

use std::f64::consts::PI;

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use planar::wrap_angle;
use ur5e_kin::{Joints, Ur5e};

use crate::gripper::GripperModel;
use crate::inputs::InputTable;
use crate::urscript::{Program, RtdeControlScript, Statement, Target, WatchdogAction};

#[path = "rtde_control.rs"]
mod rtde_control;
use rtde_control::ControlLoop;
pub use rtde_control::{RTDE_CONTROL_PROGRAM, commands as rtde_commands};

#[path = "ext_loop.rs"]
mod ext_loop;
pub use ext_loop::EXTERNAL_CONTROL_PROGRAM;
use ext_loop::ExtLoop;

/// Number of RTDE output int and double registers (0..=47).
pub const OUTPUT_REGISTERS: usize = 48;

/// UR5e joint speed limit (rad/s), reference §5.2.
pub const MAX_JOINT_SPEED_RADPS: f64 = PI;
/// Largest joint acceleration the simulator accepts (rad/s^2; ur_rtde's client-side limit).
pub const MAX_JOINT_ACCEL_RADPS2: f64 = 40.0;
/// Deceleration used when a program is stopped from outside (rad/s^2).
pub const PROGRAM_STOP_DECEL_RADPS2: f64 = 4.0;
/// Deceleration of a protective stop (rad/s^2): a quick category-2 stop.
pub const PROTECTIVE_STOP_DECEL_RADPS2: f64 = 20.0;

/// `robot_mode` values (reference §2.7).
pub mod robot_mode {
    /// Power off.
    pub const POWER_OFF: i32 = 3;
    /// Powering on.
    pub const POWER_ON: i32 = 4;
    /// Powered, brakes on.
    pub const IDLE: i32 = 5;
    /// Brakes released, ready.
    pub const RUNNING: i32 = 7;
}

/// `runtime_state` values.
pub mod runtime_state {
    /// No program.
    pub const STOPPED: u32 = 1;
    /// Program running.
    pub const PLAYING: u32 = 2;
    /// Program paused.
    pub const PAUSED: u32 = 4;
}

/// Seconds the power-on and brake-release sequences take.
const POWER_ON_S: f64 = 0.3;
const BRAKE_RELEASE_S: f64 = 0.3;

/// Trapezoidal velocity profile over a path length.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Trapezoid {
    distance: f64,
    speed: f64,
    accel: f64,
    t_acc: f64,
    total_s: f64,
}

impl Trapezoid {
    /// Profile covering `distance` with peak `speed` and `accel`, starting and ending at rest.
    pub fn new(distance: f64, speed: f64, accel: f64) -> Self {
        let distance = distance.abs();
        if distance <= 0.0 || speed <= 0.0 || accel <= 0.0 {
            return Self {
                distance: 0.0,
                speed: 0.0,
                accel: 1.0,
                t_acc: 0.0,
                total_s: 0.0,
            };
        }
        let mut t_acc = speed / accel;
        let mut speed = speed;
        let d_acc = 0.5 * accel * t_acc * t_acc;
        let t_flat = if 2.0 * d_acc >= distance {
            // Triangle: never reaches the peak speed.
            t_acc = (distance / accel).sqrt();
            speed = accel * t_acc;
            0.0
        } else {
            (distance - 2.0 * d_acc) / speed
        };
        Self {
            distance,
            speed,
            accel,
            t_acc,
            total_s: 2.0 * t_acc + t_flat,
        }
    }

    /// Duration (s).
    pub fn total_s(&self) -> f64 {
        self.total_s
    }

    /// Distance covered at time `t` (clamped to the profile).
    pub fn position(&self, t: f64) -> f64 {
        if self.total_s <= 0.0 {
            return self.distance;
        }
        let t = t.clamp(0.0, self.total_s);
        let a = self.accel;
        if t < self.t_acc {
            0.5 * a * t * t
        } else if t <= self.total_s - self.t_acc {
            0.5 * a * self.t_acc * self.t_acc + self.speed * (t - self.t_acc)
        } else {
            let r = self.total_s - t;
            self.distance - 0.5 * a * r * r
        }
    }
}

#[derive(Debug, Clone, PartialEq)]
enum Motion {
    /// At rest, nothing commanded.
    Idle,
    /// `movej`.
    Joint {
        start: Joints,
        delta: Joints,
        leading: f64,
        profile: Trapezoid,
        t: f64,
    },
    /// `movel`: tool path from `start` to `goal` (flange poses), path time `t`.
    Linear {
        start: Isometry3<f64>,
        goal: Isometry3<f64>,
        profile: Trapezoid,
        t: f64,
    },
    /// Decelerate to rest along the current direction.
    Stop { decel: f64 },
    /// `speedj`.
    Speed {
        qd: Joints,
        accel: f64,
        remaining_s: Option<f64>,
    },
    /// `sleep`.
    Sleep { remaining_s: f64 },
    /// `sync`.
    Sync,
    /// `servoj`: track `target`, reaching it in `time_s` when the joint speed limit allows.
    Servo { target: Joints, time_s: f64 },
    /// A joint spline `start + c1 t + .. + c5 t^5` over `total_s`.
    Spline {
        start: Joints,
        coeffs: [Joints; 5],
        t: f64,
        total_s: f64,
    },
    /// `speedl`: tool speed `xd` (base frame, m/s and rad/s) reached with `accel`; `v` is the
    /// tool speed commanded now.
    SpeedL {
        xd: [f64; 6],
        accel: f64,
        v: [f64; 6],
    },
}

#[derive(Debug, Clone, PartialEq)]
struct Watchdog {
    input: usize,
    name: String,
    min_frequency_hz: f64,
    action: WatchdogAction,
    armed_at_s: f64,
}

#[derive(Debug, Clone, PartialEq)]
struct Running {
    program: Program,
    /// Index of the next statement to execute.
    pc: usize,
    /// Index of the statement whose motion is in progress (re-run on resume).
    current: Option<usize>,
    paused: bool,
    /// ur_rtde's control script: its command loop, served natively instead of statements.
    control: Option<Box<ControlLoop>>,
    /// An External Control session (URCL), served natively.
    external: Option<Box<ExtLoop>>,
}

/// A log line from the controller (text messages on RTDE and the primary port).
#[derive(Debug, Clone, PartialEq)]
pub struct ControllerMessage {
    /// Controller time (s).
    pub time_s: f64,
    /// Text.
    pub text: String,
    /// Severity: 0 exception .. 3 info (RTDE levels).
    pub level: u8,
}

/// Everything the output interfaces publish, copied once per cycle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Snapshot {
    /// Controller time (s).
    pub time_s: f64,
    /// Cycle counter.
    pub cycle: u64,
    /// Actual joints (rad).
    pub q: Joints,
    /// Actual joint speeds (rad/s).
    pub qd: Joints,
    /// Joint accelerations (rad/s^2).
    pub qdd: Joints,
    /// Target joints: the same as actual (perfect tracking).
    pub target_q: Joints,
    /// TCP pose `p[x, y, z, rx, ry, rz]`.
    pub tcp_pose: [f64; 6],
    /// TCP speed (linear m/s, angular rad/s).
    pub tcp_speed: [f64; 6],
    /// TCP offset `p[..]`.
    pub tcp_offset: [f64; 6],
    /// Elbow (frame 3 origin) position (m).
    pub elbow_position: [f64; 3],
    /// Robot mode.
    pub robot_mode: i32,
    /// Safety mode (1 normal, 3 protective stop, 7 robot emergency stop).
    pub safety_mode: i32,
    /// Runtime state.
    pub runtime_state: u32,
    /// Speed scaling (0..1).
    pub speed_scaling: f64,
    /// Speed slider (0..1).
    pub target_speed_fraction: f64,
    /// Standard digital outputs (bits 0..7), configurable (8..15), tool (16..17).
    pub digital_output_bits: u64,
    /// Gripper finger gap (m).
    pub gripper_opening_m: f64,
    /// RTDE `output_int_register_0..47` (written by ur_rtde's control loop).
    pub output_int_registers: [i32; OUTPUT_REGISTERS],
    /// RTDE `output_double_register_0..47`.
    pub output_double_registers: [f64; OUTPUT_REGISTERS],
}

impl Snapshot {
    /// `robot_status_bits`: bit 0 power on, bit 1 program running.
    pub fn robot_status_bits(&self) -> u32 {
        let power = u32::from(self.robot_mode >= robot_mode::POWER_ON);
        let running = u32::from(self.runtime_state == runtime_state::PLAYING);
        power | (running << 1)
    }

    /// `safety_status_bits`: bit 0 normal, bit 2 protective stop, bit 4 safeguard stop, bits 6 and 7 robot
    /// emergency stop / emergency stopped.
    pub fn safety_status_bits(&self) -> u32 {
        match self.safety_mode {
            3 => 1 << 2,
            5 => 1 << 4,
            7 => (1 << 6) | (1 << 7),
            _ => 1,
        }
    }

    /// `joint_mode` (253 running, 255 idle, 239 power off).
    pub fn joint_mode(&self) -> i32 {
        match self.robot_mode {
            robot_mode::RUNNING => 253,
            robot_mode::IDLE | robot_mode::POWER_ON => 255,
            _ => 239,
        }
    }
}

/// Initial state of the simulated robot.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RobotInit {
    /// Joints at start (rad).
    pub q: Joints,
    /// Powered with brakes released (`RUNNING`) or powered off.
    pub powered: bool,
    /// A TCP below this height (base frame, m) triggers a protective stop, like hitting the
    /// table; `None` disables it.
    pub floor_z_m: Option<f64>,
}

impl Default for RobotInit {
    fn default() -> Self {
        Self {
            // A tucked, collision-free home with the tool pointing down.
            q: [0.0, -PI / 2.0, PI / 2.0, -PI / 2.0, -PI / 2.0, 0.0],
            powered: true,
            floor_z_m: None,
        }
    }
}

/// The simulated arm and its controller state.
#[derive(Debug, Clone)]
pub struct RobotModel {
    kin: Ur5e,
    time_s: f64,
    cycle: u64,
    q: Joints,
    qd: Joints,
    qdd: Joints,
    tcp_offset: Isometry3<f64>,
    tcp_offset_p: [f64; 6],
    robot_mode: i32,
    mode_timer_s: f64,
    safety_mode: i32,
    motion: Motion,
    running: Option<Running>,
    last_program: Option<Program>,
    watchdog: Option<Watchdog>,
    speed_scaling: f64,
    speed_fraction: f64,
    digital_output_bits: u64,
    floor_z_m: Option<f64>,
    /// The gripper on the flange.
    pub gripper: GripperModel,
    messages: Vec<ControllerMessage>,
    out_int: [i32; OUTPUT_REGISTERS],
    out_double: [f64; OUTPUT_REGISTERS],
    next_session: u64,
    stops_asked: StopsAsked,
}

/// Stops asked of the controller from outside, counted as they arrive (whether or not the
/// controller could act on them): what a test reads to tell the onboard reaction from the
/// controller's own.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct StopsAsked {
    /// Programs with a `stopj` / `stopl` (the driver's stop).
    pub stop_programs: u64,
    /// Dashboard `stop` commands.
    pub dashboard: u64,
}

fn pose_to_iso(p: &[f64; 6]) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::new(p[0], p[1], p[2]),
        UnitQuaternion::from_scaled_axis(Vector3::new(p[3], p[4], p[5])),
    )
}

fn iso_to_pose(iso: &Isometry3<f64>) -> [f64; 6] {
    let t = iso.translation.vector;
    let r = iso.rotation.scaled_axis();
    [t.x, t.y, t.z, r.x, r.y, r.z]
}

impl RobotModel {
    /// A robot in the given initial state.
    pub fn new(init: RobotInit) -> Self {
        Self {
            kin: Ur5e::default(),
            time_s: 0.0,
            cycle: 0,
            q: init.q,
            qd: [0.0; 6],
            qdd: [0.0; 6],
            tcp_offset: Isometry3::identity(),
            tcp_offset_p: [0.0; 6],
            robot_mode: if init.powered {
                robot_mode::RUNNING
            } else {
                robot_mode::POWER_OFF
            },
            mode_timer_s: 0.0,
            safety_mode: 1,
            motion: Motion::Idle,
            running: None,
            last_program: None,
            stops_asked: StopsAsked::default(),
            watchdog: None,
            speed_scaling: 1.0,
            speed_fraction: 1.0,
            digital_output_bits: 0,
            floor_z_m: init.floor_z_m,
            gripper: GripperModel::default(),
            messages: Vec::new(),
            out_int: [0; OUTPUT_REGISTERS],
            out_double: [0.0; OUTPUT_REGISTERS],
            next_session: 0,
        }
    }

    /// Controller time (s).
    pub fn time_s(&self) -> f64 {
        self.time_s
    }

    /// Actual joints.
    pub fn q(&self) -> Joints {
        self.q
    }

    /// Robot mode.
    pub fn robot_mode(&self) -> i32 {
        self.robot_mode
    }

    /// Safety mode.
    pub fn safety_mode(&self) -> i32 {
        self.safety_mode
    }

    /// Runtime state.
    pub fn runtime_state(&self) -> u32 {
        match &self.running {
            None => runtime_state::STOPPED,
            Some(r) if r.paused => runtime_state::PAUSED,
            Some(_) => runtime_state::PLAYING,
        }
    }

    /// Name of the running (or paused) program.
    pub fn program_name(&self) -> Option<&str> {
        self.running.as_ref().map(|r| r.program.name.as_str())
    }

    /// Name of the last program received.
    pub fn last_program_name(&self) -> Option<&str> {
        self.last_program.as_ref().map(|p| p.name.as_str())
    }

    /// Takes the log lines produced since the last call.
    pub fn take_messages(&mut self) -> Vec<ControllerMessage> {
        std::mem::take(&mut self.messages)
    }

    fn log(&mut self, level: u8, text: String) {
        match level {
            0 | 1 => log::error!("sim-ur5e: {text}"),
            2 => log::warn!("sim-ur5e: {text}"),
            _ => log::info!("sim-ur5e: {text}"),
        }
        // Bounded: nobody may be reading.
        if self.messages.len() < 256 {
            self.messages.push(ControllerMessage {
                time_s: self.time_s,
                text,
                level,
            });
        }
    }

    /// Sets the speed slider (0..1), as the RTDE `speed_slider_fraction` input does.
    pub fn set_speed_fraction(&mut self, fraction: f64) {
        if fraction.is_finite() {
            self.speed_fraction = fraction.clamp(0.0, 1.0);
        }
    }

    /// Sets digital outputs under a mask (`bits` in the layout of `actual_digital_output_bits`).
    pub fn set_digital_outputs(&mut self, mask: u64, bits: u64) {
        self.digital_output_bits = (self.digital_output_bits & !mask) | (bits & mask);
    }

    /// Starts a program received on a script port; it replaces the running one (G-SCRIPT).
    pub fn load_program(&mut self, program: Program) {
        if program
            .statements
            .iter()
            .any(|s| matches!(s, Statement::StopJ { .. } | Statement::StopL { .. }))
        {
            self.stops_asked.stop_programs += 1;
        }
        if program.secondary {
            // `sec` programs run beside the main program: apply their instant statements now.
            for s in &program.statements {
                self.instant(s);
            }
            return;
        }
        self.last_program = Some(program.clone());
        if self.robot_mode != robot_mode::RUNNING || self.safety_mode != 1 {
            self.log(
                1,
                format!("program {} refused: robot is not running", program.name),
            );
            return;
        }
        if self.running.is_some() {
            self.log(
                3,
                format!("program {} replaces the running program", program.name),
            );
        }
        self.watchdog = None;
        let starts_with_stop = matches!(
            program.statements.first(),
            Some(Statement::StopJ { .. } | Statement::StopL { .. })
        );
        self.running = Some(Running {
            program,
            pc: 0,
            current: None,
            paused: false,
            control: None,
            external: None,
        });
        // A moving arm first comes to rest, unless the new program does exactly that itself.
        self.motion = if self.moving() && !starts_with_stop {
            Motion::Stop {
                decel: PROGRAM_STOP_DECEL_RADPS2,
            }
        } else {
            Motion::Idle
        };
    }

    /// Dashboard `play`: resumes a paused program or replays the last one. False if neither.
    pub fn play(&mut self) -> bool {
        if self.robot_mode != robot_mode::RUNNING || self.safety_mode != 1 {
            return false;
        }
        match &mut self.running {
            Some(r) if r.paused => {
                r.paused = false;
                // Re-run the interrupted statement from where the arm is now.
                if let Some(c) = r.current.take() {
                    r.pc = c;
                }
                true
            }
            Some(_) => true,
            None => match self.last_program.clone() {
                Some(p) => {
                    self.load_program(p);
                    true
                }
                None => false,
            },
        }
    }

    /// Dashboard `pause`. False if nothing runs.
    pub fn pause(&mut self) -> bool {
        match &mut self.running {
            Some(r) if !r.paused => {
                r.paused = true;
                self.motion = Motion::Stop {
                    decel: PROGRAM_STOP_DECEL_RADPS2,
                };
                true
            }
            _ => false,
        }
    }

    /// The stops asked from outside so far.
    pub fn stops_asked(&self) -> StopsAsked {
        self.stops_asked
    }

    /// Dashboard `stop`: counted, then [`Self::stop_program`].
    pub fn dashboard_stop(&mut self) {
        self.stops_asked.dashboard += 1;
        self.stop_program("dashboard stop");
    }

    /// Dashboard `stop` (and the watchdog's stop action): ends the program, decelerates.
    pub fn stop_program(&mut self, reason: &str) {
        if let Some(r) = self.running.take() {
            self.log(2, format!("program {} stopped: {reason}", r.program.name));
        }
        self.watchdog = None;
        self.motion = if self.moving() {
            Motion::Stop {
                decel: PROGRAM_STOP_DECEL_RADPS2,
            }
        } else {
            Motion::Idle
        };
    }

    /// Protective stop: the program stops, the arm brakes hard, motion is refused until unlock.
    pub fn protective_stop(&mut self, reason: &str) {
        self.safety_stop(3, "protective stop", reason);
    }

    /// Enters safety mode `mode`: the program stops, the arm brakes hard.
    fn safety_stop(&mut self, mode: i32, what: &str, reason: &str) {
        if self.safety_mode == mode {
            return;
        }
        self.log(1, format!("{what}: {reason}"));
        self.running = None;
        self.watchdog = None;
        self.safety_mode = mode;
        self.motion = Motion::Stop {
            decel: PROTECTIVE_STOP_DECEL_RADPS2,
        };
    }

    /// Emergency stop (category 1: brake hard, then power off the joints): the program stops,
    /// motion is refused until the stop is released and the arm powered on again.
    pub fn emergency_stop(&mut self, reason: &str) {
        self.safety_stop(7, "emergency stop", reason);
    }

    /// Safeguard stop (the safeguard input opened: a light curtain or an area scanner sees a
    /// person): the program stops and the arm brakes as in a protective stop; motion is
    /// refused while the input is open.
    pub fn safeguard_stop(&mut self, reason: &str) {
        self.safety_stop(5, "safeguard stop", reason);
    }

    /// The safeguard input closed again (automatic reset): normal mode.
    pub fn safeguard_release(&mut self) {
        if self.safety_mode == 5 {
            self.safety_mode = 1;
            self.log(3, "safeguard stop released".into());
        }
    }

    /// The emergency stop released (the button pulled out, the reset pressed): normal safety
    /// mode, the arm powered off, as a real controller leaves it.
    pub fn release_emergency_stop(&mut self) {
        if self.safety_mode == 7 {
            self.safety_mode = 1;
            self.power_off();
            self.log(3, "emergency stop released; power off".into());
        }
    }

    /// Dashboard `unlock protective stop`.
    pub fn unlock_protective_stop(&mut self) {
        if self.safety_mode == 3 {
            self.safety_mode = 1;
            self.log(3, "protective stop released".into());
        }
    }

    /// Dashboard `power on`.
    pub fn power_on(&mut self) {
        if self.robot_mode == robot_mode::POWER_OFF {
            self.robot_mode = robot_mode::POWER_ON;
            self.mode_timer_s = POWER_ON_S;
        }
    }

    /// Dashboard `power off`.
    pub fn power_off(&mut self) {
        self.running = None;
        self.watchdog = None;
        self.motion = Motion::Idle;
        self.qd = [0.0; 6];
        self.robot_mode = robot_mode::POWER_OFF;
    }

    /// Dashboard `brake release`.
    pub fn brake_release(&mut self) {
        if self.robot_mode == robot_mode::IDLE {
            self.mode_timer_s = BRAKE_RELEASE_S;
        }
    }

    fn moving(&self) -> bool {
        self.qd.iter().any(|v| v.abs() > 1e-9)
    }

    /// Executes a statement that takes no time; false if it is a motion statement.
    fn instant(&mut self, s: &Statement) -> bool {
        match s {
            Statement::TextMsg(t) => self.log(3, t.clone()),
            Statement::SetTcp(p) => {
                self.tcp_offset_p = *p;
                self.tcp_offset = pose_to_iso(p);
            }
            Statement::SetStandardDigitalOut { index, on } => {
                let bit = 1u64 << index;
                self.set_digital_outputs(bit, if *on { bit } else { 0 });
            }
            Statement::SetToolDigitalOut { index, on } => {
                let bit = 1u64 << (16 + index);
                self.set_digital_outputs(bit, if *on { bit } else { 0 });
            }
            Statement::RtdeWatchdog { .. } => {}
            _ => return false,
        }
        true
    }

    fn start_watchdog(
        &mut self,
        inputs: &InputTable,
        input: &str,
        min_frequency_hz: f64,
        action: WatchdogAction,
    ) {
        if min_frequency_hz <= 0.0 {
            self.watchdog = None;
            return;
        }
        match inputs.index_of(input) {
            Some(index) => {
                self.watchdog = Some(Watchdog {
                    input: index,
                    name: input.to_string(),
                    min_frequency_hz,
                    action,
                    armed_at_s: self.time_s,
                })
            }
            None => {
                self.log(0, format!("rtde_set_watchdog: unknown input {input:?}"));
                self.stop_program("runtime exception");
            }
        }
    }

    /// Joint target for a pose target: the IK solution nearest the current joints.
    fn nearest_ik(&self, flange: &Isometry3<f64>) -> Option<Joints> {
        self.nearest_ik_to(flange, &self.q)
    }

    /// Joint target for a flange pose: the IK solution nearest `near`.
    fn nearest_ik_to(&self, flange: &Isometry3<f64>, near: &Joints) -> Option<Joints> {
        let r = flange.rotation.to_rotation_matrix().into_inner();
        let p = flange.translation.vector;
        let mut best: Option<(f64, Joints)> = None;
        self.kin.inverse_matrix(&r, &p, near[5], |sol| {
            // Each joint's representative nearest the reference angle (the short way round).
            let cand: Joints = core::array::from_fn(|i| near[i] + wrap_angle(sol[i] - near[i]));
            let within = cand.iter().all(|v| v.abs() <= 2.0 * PI) && cand[2].abs() <= PI;
            if within {
                let cost = cand
                    .iter()
                    .zip(near)
                    .fold(0.0_f64, |m, (a, b)| m.max((a - b).abs()));
                if best.is_none_or(|(c, _)| cost < c) {
                    best = Some((cost, cand));
                }
            }
            true
        });
        best.map(|(_, q)| q)
    }

    fn flange(&self, q: &Joints) -> Isometry3<f64> {
        self.kin.forward(q)
    }

    /// Starts the motion of statement `s`; returns false (and stops the program) on a
    /// runtime error.
    fn begin_motion(&mut self, s: &Statement, inputs: &InputTable) -> bool {
        match s {
            Statement::MoveJ {
                target,
                accel,
                speed,
            } => {
                let goal = match target {
                    Target::Joints(q) => *q,
                    Target::Pose(p) => {
                        let flange = pose_to_iso(p) * self.tcp_offset.inverse();
                        match self.nearest_ik(&flange) {
                            Some(q) => q,
                            None => return self.runtime_error("movej: pose not reachable"),
                        }
                    }
                };
                if goal.iter().any(|v| v.abs() > 2.0 * PI) || goal[2].abs() > PI {
                    return self.runtime_error("movej: target outside the joint limits");
                }
                let delta: Joints = core::array::from_fn(|i| goal[i] - self.q[i]);
                let leading = delta.iter().fold(0.0_f64, |m, d| m.max(d.abs()));
                self.motion = Motion::Joint {
                    start: self.q,
                    delta,
                    leading,
                    profile: Trapezoid::new(
                        leading,
                        speed.min(MAX_JOINT_SPEED_RADPS),
                        accel.min(MAX_JOINT_ACCEL_RADPS2),
                    ),
                    t: 0.0,
                };
            }
            Statement::MoveL {
                target,
                accel,
                speed,
            } => {
                let goal_tool = match target {
                    Target::Pose(p) => pose_to_iso(p),
                    Target::Joints(q) => self.flange(q) * self.tcp_offset,
                };
                let goal = goal_tool * self.tcp_offset.inverse();
                if self.nearest_ik(&goal).is_none() {
                    return self.runtime_error("movel: target pose not reachable");
                }
                let start = self.flange(&self.q);
                let start_tool = start * self.tcp_offset;
                let dist = (goal_tool.translation.vector - start_tool.translation.vector).norm();
                let angle = start_tool.rotation.angle_to(&goal_tool.rotation);
                // The path parameter is the tool distance; a pure rotation uses the angle.
                let length = if dist > 1e-6 { dist } else { angle };
                self.motion = Motion::Linear {
                    start,
                    goal,
                    profile: Trapezoid::new(length, *speed, *accel),
                    t: 0.0,
                };
            }
            Statement::StopJ { decel } => self.motion = Motion::Stop { decel: *decel },
            // A tool deceleration of a m/s^2 is about a / 0.5 rad/s^2 for joints at UR5e scale.
            Statement::StopL { decel } => self.motion = Motion::Stop { decel: decel / 0.5 },
            Statement::SpeedJ { qd, accel, time_s } => {
                if qd.iter().any(|v| v.abs() > MAX_JOINT_SPEED_RADPS) {
                    return self.runtime_error("speedj: speed above the joint limit");
                }
                self.motion = Motion::Speed {
                    qd: *qd,
                    accel: *accel,
                    remaining_s: *time_s,
                };
            }
            Statement::Sleep { time_s } => {
                self.motion = Motion::Sleep {
                    remaining_s: *time_s,
                }
            }
            Statement::Sync => self.motion = Motion::Sync,
            Statement::RtdeWatchdog {
                input,
                min_frequency_hz,
                action,
            } => {
                let input = input.clone();
                self.start_watchdog(inputs, &input, *min_frequency_hz, *action);
            }
            other => {
                self.instant(other);
            }
        }
        true
    }

    fn runtime_error(&mut self, text: &str) -> bool {
        self.log(0, text.to_string());
        self.stop_program("runtime exception");
        false
    }

    /// Advances the controller by `dt` seconds, the control period: the same every call.
    ///
    /// Time is `cycle * dt`, not a running sum, so after n steps the controller time (RTDE
    /// `timestamp`) is exactly `n * dt` as the stepping world computes it, with no rounding
    /// drift between the two clocks.
    pub fn step(&mut self, dt: f64, inputs: &InputTable) {
        self.cycle += 1;
        self.time_s = self.cycle as f64 * dt;
        self.gripper.step(dt);
        self.step_modes(dt);
        if self.robot_mode != robot_mode::RUNNING {
            self.qd = [0.0; 6];
            self.qdd = [0.0; 6];
            return;
        }
        self.check_watchdog(inputs);
        self.advance_program(inputs);
        let q_before = self.q;
        let qd_before = self.qd;
        self.integrate(dt);
        for i in 0..6 {
            self.qd[i] = (self.q[i] - q_before[i]) / dt;
            self.qdd[i] = (self.qd[i] - qd_before[i]) / dt;
        }
        self.check_safety();
    }

    fn step_modes(&mut self, dt: f64) {
        if self.mode_timer_s > 0.0 {
            self.mode_timer_s -= dt;
            if self.mode_timer_s <= 0.0 {
                self.mode_timer_s = 0.0;
                self.robot_mode = match self.robot_mode {
                    robot_mode::POWER_ON => robot_mode::IDLE,
                    robot_mode::IDLE => robot_mode::RUNNING,
                    other => other,
                };
            }
        }
    }

    fn check_watchdog(&mut self, inputs: &InputTable) {
        let Some(w) = &self.watchdog else { return };
        let last = inputs
            .updated_at_s(w.input)
            .unwrap_or(f64::NEG_INFINITY)
            .max(w.armed_at_s);
        if self.time_s - last > 1.0 / w.min_frequency_hz {
            let (name, action) = (w.name.clone(), w.action);
            let text = format!(
                "RTDE watchdog: input {name} not updated for {:.3} s",
                self.time_s - last
            );
            match action {
                WatchdogAction::Ignore => {
                    self.log(2, text);
                    self.watchdog = None;
                }
                WatchdogAction::Pause => {
                    self.log(1, text);
                    self.pause();
                }
                WatchdogAction::Stop => {
                    self.log(1, text);
                    self.stop_program("RTDE watchdog");
                }
            }
        }
    }

    fn motion_done(&self) -> bool {
        matches!(self.motion, Motion::Idle)
    }

    fn advance_program(&mut self, inputs: &InputTable) {
        // Instant statements run in the same cycle; stop at the first one that takes time.
        if self.running.as_ref().is_some_and(|r| r.control.is_some()) {
            self.control_step(inputs);
            return;
        }
        if self.running.as_ref().is_some_and(|r| r.external.is_some()) {
            self.external_step(inputs);
            return;
        }
        for _ in 0..64 {
            let Some(r) = &self.running else { return };
            if r.paused || !self.motion_done() {
                return;
            }
            let Some(stmt) = r.program.statements.get(r.pc).cloned() else {
                let name = r.program.name.clone();
                self.running = None;
                self.watchdog = None;
                self.log(3, format!("program {name} finished"));
                return;
            };
            let pc = r.pc;
            if let Some(r) = &mut self.running {
                r.pc += 1;
                r.current = Some(pc);
            }
            if !self.begin_motion(&stmt, inputs) {
                return;
            }
        }
    }

    #[allow(
        clippy::too_many_lines,
        reason = "the controller model's one step: modes, motion kinds, limits, in the controller's order"
    )]
    fn integrate(&mut self, dt: f64) {
        let scale = self.speed_fraction;
        self.speed_scaling = 1.0;
        let mut motion = std::mem::replace(&mut self.motion, Motion::Idle);
        // `finished`: the motion is over and `self.motion` stays as set meanwhile (Idle, or
        // Stop after a runtime error).
        let finished = match &mut motion {
            Motion::Idle => true,
            Motion::Joint {
                start,
                delta,
                leading,
                profile,
                t,
            } => {
                *t += dt * scale;
                let s = if *leading > 0.0 {
                    profile.position(*t) / *leading
                } else {
                    1.0
                };
                self.q = core::array::from_fn(|i| start[i] + delta[i] * s);
                *t >= profile.total_s()
            }
            Motion::Linear {
                start,
                goal,
                profile,
                t,
            } => {
                let mut step = dt * scale;
                let mut next = None;
                let total = profile.total_s();
                // Speed scaling: shrink the step until no joint exceeds its speed limit.
                for _ in 0..12 {
                    let tau = (*t + step).min(total);
                    let u = if total > 0.0 {
                        profile.position(tau) / profile.position(total)
                    } else {
                        1.0
                    };
                    let pose = start.lerp_slerp(goal, u);
                    let Some(q) = self.nearest_ik(&pose) else {
                        break;
                    };
                    let worst = q
                        .iter()
                        .zip(&self.q)
                        .fold(0.0_f64, |m, (a, b)| m.max((a - b).abs()))
                        / dt;
                    if worst <= MAX_JOINT_SPEED_RADPS * 1.0001 {
                        next = Some((tau, q));
                        break;
                    }
                    step *= 0.5;
                }
                match next {
                    Some((tau, q)) => {
                        self.speed_scaling = ((tau - *t) / (dt * scale).max(1e-12)).min(1.0);
                        *t = tau;
                        self.q = q;
                        tau >= total
                    }
                    None => {
                        self.runtime_error(
                            "movel: path passes a singularity or leaves the workspace",
                        );
                        return;
                    }
                }
            }
            Motion::Stop { decel } => {
                let fastest = self.qd.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
                if fastest <= *decel * dt {
                    true
                } else {
                    let k = (fastest - *decel * dt) / fastest;
                    self.q = core::array::from_fn(|i| self.q[i] + self.qd[i] * k * dt);
                    false
                }
            }
            Motion::Speed {
                qd,
                accel,
                remaining_s,
            } => {
                let (target, accel) = (*qd, *accel);
                let mut done = false;
                if let Some(r) = remaining_s {
                    *r -= dt;
                    done = *r <= 0.0;
                }
                let new_qd: Joints = core::array::from_fn(|i| {
                    let d = (target[i] * scale - self.qd[i]).clamp(-accel * dt, accel * dt);
                    self.qd[i] + d
                });
                self.q = core::array::from_fn(|i| self.q[i] + new_qd[i] * dt);
                if done {
                    motion = Motion::Stop { decel: accel };
                }
                false
            }
            Motion::Sleep { remaining_s } => {
                *remaining_s -= dt;
                *remaining_s <= 0.0
            }
            Motion::Sync => true,
            Motion::Servo { target, time_s } => {
                let frac = (dt / time_s.max(dt)).min(1.0);
                let mut step: Joints = core::array::from_fn(|i| (target[i] - self.q[i]) * frac);
                let worst = step.iter().fold(0.0_f64, |m, d| m.max(d.abs())) / dt;
                if worst > MAX_JOINT_SPEED_RADPS {
                    let k = MAX_JOINT_SPEED_RADPS / worst;
                    step.iter_mut().for_each(|d| *d *= k);
                }
                self.q = core::array::from_fn(|i| self.q[i] + step[i]);
                false
            }
            Motion::Spline {
                start,
                coeffs,
                t,
                total_s,
            } => {
                *t = (*t + dt * scale).min(*total_s);
                let tt = *t;
                let q: Joints = core::array::from_fn(|i| {
                    let mut x = 0.0;
                    for c in coeffs.iter().rev() {
                        x = (x + c[i]) * tt;
                    }
                    start[i] + x
                });
                let worst = q
                    .iter()
                    .zip(&self.q)
                    .fold(0.0_f64, |m, (a, b)| m.max((a - b).abs()))
                    / dt;
                if worst > MAX_JOINT_SPEED_RADPS * 1.0001 {
                    self.protective_stop("spline: a joint would exceed its speed limit");
                    return;
                }
                self.q = q;
                tt >= *total_s
            }
            Motion::SpeedL { xd, accel, v } => {
                for i in 0..6 {
                    v[i] += (xd[i] * scale - v[i]).clamp(-*accel * dt, *accel * dt);
                }
                let tool = self.flange(&self.q) * self.tcp_offset;
                let lin = Vector3::new(v[0], v[1], v[2]) * dt;
                let ang = Vector3::new(v[3], v[4], v[5]) * dt;
                let next = Isometry3::from_parts(
                    Translation3::from(tool.translation.vector + lin),
                    UnitQuaternion::from_scaled_axis(ang) * tool.rotation,
                );
                match self.nearest_ik(&(next * self.tcp_offset.inverse())) {
                    Some(q) => {
                        let worst = q
                            .iter()
                            .zip(&self.q)
                            .fold(0.0_f64, |m, (a, b)| m.max((a - b).abs()))
                            / dt;
                        if worst > MAX_JOINT_SPEED_RADPS * 1.0001 {
                            self.protective_stop("speedl: a joint would exceed its speed limit");
                            return;
                        }
                        self.q = q;
                    }
                    None => {
                        self.runtime_error(
                            "speedl: path passes a singularity or leaves the workspace",
                        );
                        return;
                    }
                }
                false
            }
        };
        if !finished {
            self.motion = motion;
        }
    }

    fn check_safety(&mut self) {
        if self.q.iter().any(|v| v.abs() > 2.0 * PI) || self.q[2].abs() > PI {
            self.protective_stop("joint position limit");
        }
        if let Some(floor) = self.floor_z_m {
            let tool = self.flange(&self.q) * self.tcp_offset;
            if tool.translation.vector.z < floor {
                self.protective_stop("tool below the configured floor plane (collision)");
            }
        }
    }

    /// The values every output interface publishes for this cycle.
    pub fn snapshot(&self) -> Snapshot {
        let frames = self.kin.frames(&self.q);
        let flange = frames.flange();
        let tool = flange * self.tcp_offset;
        // TCP speed by finite difference over one cycle at the current joint speed.
        let dt = 0.002;
        let q_next: Joints = core::array::from_fn(|i| self.q[i] + self.qd[i] * dt);
        let tool_next = self.flange(&q_next) * self.tcp_offset;
        let lin = (tool_next.translation.vector - tool.translation.vector) / dt;
        let ang = (tool_next.rotation * tool.rotation.inverse()).scaled_axis() / dt;
        let elbow = frames.origin(2);
        Snapshot {
            time_s: self.time_s,
            cycle: self.cycle,
            q: self.q,
            qd: self.qd,
            qdd: self.qdd,
            target_q: self.q,
            tcp_pose: iso_to_pose(&tool),
            tcp_speed: [lin.x, lin.y, lin.z, ang.x, ang.y, ang.z],
            tcp_offset: self.tcp_offset_p,
            elbow_position: [elbow.x, elbow.y, elbow.z],
            robot_mode: self.robot_mode,
            safety_mode: self.safety_mode,
            runtime_state: self.runtime_state(),
            speed_scaling: self.speed_scaling,
            target_speed_fraction: self.speed_fraction,
            digital_output_bits: self.digital_output_bits,
            gripper_opening_m: self.gripper.opening_m(),
            output_int_registers: self.out_int,
            output_double_registers: self.out_double,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::urscript::parse_program;

    const DT: f64 = 0.002;

    fn run(model: &mut RobotModel, inputs: &InputTable, seconds: f64) -> f64 {
        let mut max_speed = 0.0_f64;
        for _ in 0..(seconds / DT) as usize {
            model.step(DT, inputs);
            max_speed = model.qd.iter().fold(max_speed, |m, v| m.max(v.abs()));
        }
        max_speed
    }

    #[test]
    fn trapezoid_covers_its_distance_and_respects_speed() {
        for (d, v, a) in [(1.0, 1.0, 2.0), (0.01, 3.0, 1.0), (2.0, 0.5, 40.0)] {
            let p = Trapezoid::new(d, v, a);
            assert!((p.position(p.total_s()) - d).abs() < 1e-12);
            assert!((p.position(p.total_s() + 1.0) - d).abs() < 1e-12);
            let mut prev = 0.0;
            let n = 1000;
            for k in 1..=n {
                let t = p.total_s() * k as f64 / n as f64;
                let x = p.position(t);
                assert!(x + 1e-12 >= prev, "monotone");
                assert!((x - prev) / (p.total_s() / n as f64) <= v + 1e-6, "speed");
                prev = x;
            }
        }
    }

    #[test]
    fn movej_reaches_its_goal_within_the_joint_speed_limit() {
        let inputs = InputTable::new();
        let mut m = RobotModel::new(RobotInit::default());
        let goal = [1.0, -1.2, 1.4, -1.0, -1.57, 0.5];
        m.load_program(parse_program(&format!("movej({goal:?}, a=10, v=10)")).unwrap());
        assert_eq!(m.runtime_state(), runtime_state::PLAYING);
        let top = run(&mut m, &inputs, 3.0);
        assert!(top <= MAX_JOINT_SPEED_RADPS + 1e-6, "speed {top}");
        assert!(top > 2.0, "it should run near the limit, got {top}");
        for (a, b) in m.q().iter().zip(goal) {
            assert!((a - b).abs() < 1e-9);
        }
        assert_eq!(m.runtime_state(), runtime_state::STOPPED);
    }

    #[test]
    fn movel_keeps_the_tool_on_a_straight_line() {
        let inputs = InputTable::new();
        let mut m = RobotModel::new(RobotInit::default());
        let start = m.snapshot().tcp_pose;
        let mut goal = start;
        goal[0] += 0.2;
        goal[1] -= 0.1;
        let text = format!(
            "movel(p[{}, {}, {}, {}, {}, {}], a=1.2, v=0.25)",
            goal[0], goal[1], goal[2], goal[3], goal[4], goal[5]
        );
        m.load_program(parse_program(&text).unwrap());
        let dir =
            Vector3::new(goal[0] - start[0], goal[1] - start[1], goal[2] - start[2]).normalize();
        for _ in 0..1000 {
            m.step(DT, &inputs);
            let p = m.snapshot().tcp_pose;
            let off = Vector3::new(p[0] - start[0], p[1] - start[1], p[2] - start[2]);
            let across = (off - dir * off.dot(&dir)).norm();
            assert!(across < 1e-6, "off the line by {across}");
        }
        let end = m.snapshot().tcp_pose;
        for i in 0..3 {
            assert!((end[i] - goal[i]).abs() < 1e-6);
        }
        assert_eq!(m.runtime_state(), runtime_state::STOPPED);
    }

    #[test]
    fn stopj_brings_a_moving_arm_to_rest() {
        let inputs = InputTable::new();
        let mut m = RobotModel::new(RobotInit::default());
        m.load_program(
            parse_program("movej([2, -1.57, 1.57, -1.57, -1.57, 0], a=3, v=3)").unwrap(),
        );
        run(&mut m, &inputs, 0.5);
        assert!(m.snapshot().qd[0] > 1.0);
        m.load_program(parse_program("stopj(4)").unwrap());
        run(&mut m, &inputs, 1.0);
        assert!(m.snapshot().qd.iter().all(|v| v.abs() < 1e-9));
        assert!(m.q()[0] < 1.9, "stopped before the goal");
    }

    #[test]
    fn watchdog_stops_the_program_when_its_input_goes_stale() {
        let mut inputs = InputTable::new();
        let reg = inputs.index_of("input_int_register_24").unwrap();
        let mut m = RobotModel::new(RobotInit::default());
        let text = "def p():\n  rtde_set_watchdog(\"input_int_register_24\", 10, \"stop\")\n  \
                    movej([2, -1.57, 1.57, -1.57, -1.57, 0], a=1, v=1)\nend\n";
        m.load_program(parse_program(text).unwrap());
        for _ in 0..200 {
            inputs.mark_updated(reg, m.time_s());
            m.step(DT, &inputs);
        }
        assert_eq!(
            m.runtime_state(),
            runtime_state::PLAYING,
            "fed watchdog keeps it running"
        );
        run(&mut m, &inputs, 0.2);
        assert_eq!(
            m.runtime_state(),
            runtime_state::STOPPED,
            "stale input stops it"
        );
        run(&mut m, &inputs, 1.0);
        assert!(m.snapshot().qd.iter().all(|v| v.abs() < 1e-9));
    }

    #[test]
    fn floor_contact_is_a_protective_stop_and_needs_unlock() {
        let inputs = InputTable::new();
        let init = RobotInit {
            floor_z_m: Some(0.2),
            ..RobotInit::default()
        };
        let mut m = RobotModel::new(init);
        // Shoulder down: the tool sweeps towards the floor.
        m.load_program(parse_program("movej([0, 0, 0, -1.57, -1.57, 0], a=2, v=1)").unwrap());
        run(&mut m, &inputs, 3.0);
        assert_eq!(m.safety_mode(), 3);
        assert_eq!(m.runtime_state(), runtime_state::STOPPED);
        m.load_program(parse_program("movej([0, -1.57, 1.57, -1.57, -1.57, 0])").unwrap());
        assert_eq!(
            m.runtime_state(),
            runtime_state::STOPPED,
            "refused while stopped"
        );
        m.unlock_protective_stop();
        assert_eq!(m.safety_mode(), 1);
    }

    #[test]
    fn speedj_ramps_to_its_speed_then_stops_after_its_time() {
        let inputs = InputTable::new();
        let mut m = RobotModel::new(RobotInit::default());
        m.load_program(parse_program("speedj([0.5, 0, 0, 0, 0, 0], 2.0, 1.0)").unwrap());
        run(&mut m, &inputs, 0.5);
        assert!(
            (m.snapshot().qd[0] - 0.5).abs() < 1e-6,
            "at speed after the 0.25 s ramp"
        );
        run(&mut m, &inputs, 1.5);
        assert!(m.snapshot().qd[0].abs() < 1e-9, "stopped after t");
        assert_eq!(m.runtime_state(), runtime_state::STOPPED);
        assert!(m.q()[0] > 0.35 && m.q()[0] < 0.6, "q0 = {}", m.q()[0]);
    }

    #[test]
    fn power_sequence_reaches_running() {
        let inputs = InputTable::new();
        let mut m = RobotModel::new(RobotInit {
            powered: false,
            ..RobotInit::default()
        });
        assert_eq!(m.robot_mode(), robot_mode::POWER_OFF);
        m.power_on();
        run(&mut m, &inputs, 0.5);
        assert_eq!(m.robot_mode(), robot_mode::IDLE);
        m.brake_release();
        run(&mut m, &inputs, 0.5);
        assert_eq!(m.robot_mode(), robot_mode::RUNNING);
    }
}
