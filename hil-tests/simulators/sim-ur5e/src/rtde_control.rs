//! ur_rtde's control script served natively: the register command loop of
//! `rtde_control.script` (ur_rtde 1.6), run by the controller itself once per cycle instead of
//! interpreting the uploaded URScript line by line.
//!
//! The protocol, as the script defines it (offsets 0 or 24 for the upper register range):
//!
//! - `input_int_register_0`: the command; `0` means none. `input_int_register_1..7` and
//!   `input_double_register_0..17`: its arguments.
//! - `output_int_register_0`: the script's state, `1` ready for a command, `2` done with it.
//!   ur_rtde sends a command, waits for `2`, sends `0`, waits for `1`.
//! - `output_int_register_1`, `output_double_register_0..5`: results (kinematics, checks).
//! - `output_int_register_2`: async progress, `op_id << 24 | wr_count << 16 | running << 15 |
//!   progress` (the script's `write_async_progress_register`).
//! - Real-time commands (servo, speed, force) are applied every cycle they are present and
//!   answered with `1`; the others run once per command (`executing_cmd`), and a synchronous
//!   move holds the loop until the arm is at rest, as the script's blocking `movej` does.
//!
//! Every motion runs on the simulated arm's own motion model ([`super::RobotModel`]), with its
//! joint limits and protective stop; stepped by the control thread or by the HIL world, so it
//! is lock-step whenever the simulator is.

use super::{
    Joints, MAX_JOINT_SPEED_RADPS, Motion, PI, PROGRAM_STOP_DECEL_RADPS2, Program, RobotModel,
    RtdeControlScript, Running, Statement, Target, WatchdogAction, iso_to_pose, pose_to_iso,
    robot_mode,
};
use crate::inputs::InputTable;
use crate::urscript::PathStep;
use ur5e::rtde::RtdeValue;

/// Name the control script runs under (`programState`, text messages).
pub const RTDE_CONTROL_PROGRAM: &str = "rtde_control";

/// The command codes of ur_rtde 1.6's control script (`input_int_register_0`).
pub mod commands {
    /// No command (the loop signals ready).
    pub const NO_CMD: i32 = 0;
    /// `moveJ(q, speed, acceleration, async)`.
    pub const MOVEJ: i32 = 1;
    /// `moveJ_IK(pose, ..)`.
    pub const MOVEJ_IK: i32 = 2;
    /// `moveL(pose, ..)`.
    pub const MOVEL: i32 = 3;
    /// `moveL_FK(q, ..)`.
    pub const MOVEL_FK: i32 = 4;
    /// `forceMode(..)` (not emulated).
    pub const FORCE_MODE: i32 = 6;
    /// `speedJ(qd, acceleration, time)`.
    pub const SPEEDJ: i32 = 9;
    /// `speedL(xd, acceleration, time)`.
    pub const SPEEDL: i32 = 10;
    /// `servoJ(q, speed, acceleration, time, lookahead, gain)`.
    pub const SERVOJ: i32 = 11;
    /// `speedStop(deceleration)`.
    pub const SPEED_STOP: i32 = 15;
    /// `servoStop(deceleration)`.
    pub const SERVO_STOP: i32 = 16;
    /// `setPayload(mass, cog)`.
    pub const SET_PAYLOAD: i32 = 17;
    /// `servoL(pose, ..)`.
    pub const SERVOL: i32 = 24;
    /// `setTcp(pose)`.
    pub const SET_TCP: i32 = 29;
    /// `getInverseKinematics(pose, qnear, ..)`.
    pub const GET_INVERSE_KIN_ARGS: i32 = 30;
    /// `triggerProtectiveStop()`.
    pub const PROTECTIVE_STOP: i32 = 31;
    /// `stopL(deceleration, async)`.
    pub const STOPL: i32 = 33;
    /// `stopJ(deceleration, async)`.
    pub const STOPJ: i32 = 34;
    /// `setWatchdog(min_frequency)`.
    pub const SET_WATCHDOG: i32 = 35;
    /// `isPoseWithinSafetyLimits(pose)`.
    pub const IS_POSE_WITHIN_SAFETY_LIMITS: i32 = 36;
    /// `isJointsWithinSafetyLimits(q)`.
    pub const IS_JOINTS_WITHIN_SAFETY_LIMITS: i32 = 37;
    /// `poseTrans(p_from, p_from_to)`.
    pub const POSE_TRANS: i32 = 39;
    /// `getTCPOffset()`.
    pub const GET_TCP_OFFSET: i32 = 40;
    /// `getForwardKinematics()`.
    pub const GET_FORWARD_KIN_DEFAULT: i32 = 43;
    /// `getForwardKinematics(q, tcp_offset)`.
    pub const GET_FORWARD_KIN_ARGS: i32 = 44;
    /// `moveJ(path)`, `moveL(path)`, `movePath(path)`: runs the injected path.
    pub const MOVE_PATH: i32 = 45;
    /// `getInverseKinematics(pose)`.
    pub const GET_INVERSE_KIN_DEFAULT: i32 = 46;
    /// `isSteady()`.
    pub const IS_STEADY: i32 = 47;
    /// `stopScript()`: the script ends.
    pub const STOP_SCRIPT: i32 = 255;
    /// Commands the script's loop treats as real-time: applied every cycle, answered `ready`.
    pub const REALTIME: [i32; 16] = [24, 11, 9, 10, 6, 25, 26, 27, 38, 58, 66, 67, 68, 69, 70, 71];
}

use commands as cmd;

/// Script state in `output_int_register_0`.
const READY: i32 = 1;
const DONE: i32 = 2;

/// Steps of a move (or stop) the loop or an async "thread" is running.
#[derive(Debug, Clone, PartialEq)]
struct Sequence {
    steps: Vec<PathStep>,
    next: usize,
    /// The current step's motion has begun; the next step waits until the arm is at rest.
    waiting: bool,
}

enum SeqState {
    Running,
    Done,
    /// A runtime error ended the program.
    Failed,
}

impl Sequence {
    fn new(steps: Vec<PathStep>) -> Self {
        Self {
            steps,
            next: 0,
            waiting: false,
        }
    }

    fn one(s: Statement) -> Self {
        Self::new(vec![PathStep::Move(s)])
    }
}

/// The state of the script's command loop.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct ControlLoop {
    script: RtdeControlScript,
    /// Slots of `input_int_register_{offset + 0..8}`.
    in_int: [usize; 8],
    /// Slots of `input_double_register_{offset + 0..18}`.
    in_f: [usize; 18],
    started: bool,
    executing_cmd: bool,
    /// A synchronous command's motion: the loop waits for it.
    blocking: Option<Sequence>,
    /// An async move or stop (the script's `move_thread` / `stop_thread`).
    async_op: Option<Sequence>,
    async_wr_count: i32,
    async_op_id: i32,
    /// Last speed command was `speedL` (`speedStop` then stops with `stopl`).
    speed_is_linear: bool,
    /// Commands already reported as not emulated (logged once each).
    logged: Vec<i32>,
}

impl ControlLoop {
    fn new(script: RtdeControlScript, inputs: &InputTable) -> Option<Self> {
        let slot = |kind: &str, i: usize, offset: usize| {
            inputs.index_of(&format!("input_{kind}_register_{}", offset + i))
        };
        let mut in_int = [0; 8];
        for (i, s) in in_int.iter_mut().enumerate() {
            *s = slot("int", i, script.int_offset)?;
        }
        let mut in_f = [0; 18];
        for (i, s) in in_f.iter_mut().enumerate() {
            *s = slot("double", i, script.float_offset)?;
        }
        Some(Self {
            script,
            in_int,
            in_f,
            started: false,
            executing_cmd: false,
            blocking: None,
            async_op: None,
            async_wr_count: 0,
            async_op_id: 0,
            speed_is_linear: false,
            logged: Vec::new(),
        })
    }

    fn int(&self, inputs: &InputTable, i: usize) -> i32 {
        match inputs.value(self.in_int[i]) {
            RtdeValue::Int32(v) => v,
            _ => 0,
        }
    }

    fn f(&self, inputs: &InputTable, i: usize) -> f64 {
        match inputs.value(self.in_f[i]) {
            RtdeValue::Double(v) => v,
            _ => 0.0,
        }
    }

    fn six(&self, inputs: &InputTable, base: usize) -> [f64; 6] {
        core::array::from_fn(|i| self.f(inputs, base + i))
    }
}

/// Joint position limits of the UR5e: +-2 pi, the elbow +-pi.
fn within_joint_limits(q: &Joints) -> bool {
    q.iter().all(|v| v.is_finite() && v.abs() <= 2.0 * PI) && q[2].abs() <= PI
}

impl RobotModel {
    /// Starts ur_rtde's control script: its command loop runs from the next cycle on, in
    /// place of a statement program (it replaces the running program, G-SCRIPT).
    pub fn load_rtde_control(&mut self, script: RtdeControlScript, inputs: &InputTable) {
        if self.robot_mode != robot_mode::RUNNING || self.safety_mode != 1 {
            self.log(
                1,
                format!("program {RTDE_CONTROL_PROGRAM} refused: robot is not running"),
            );
            return;
        }
        let Some(control) = ControlLoop::new(script, inputs) else {
            self.log(0, "rtde_control: register offset out of range".into());
            return;
        };
        if self.running.is_some() {
            self.log(
                3,
                format!("program {RTDE_CONTROL_PROGRAM} replaces the running program"),
            );
        }
        self.watchdog = None;
        self.running = Some(Running {
            program: Program {
                name: RTDE_CONTROL_PROGRAM.into(),
                secondary: false,
                statements: Vec::new(),
            },
            pc: 0,
            current: None,
            paused: false,
            control: Some(Box::new(control)),
            external: None,
        });
        self.motion = if self.moving() {
            Motion::Stop {
                decel: PROGRAM_STOP_DECEL_RADPS2,
            }
        } else {
            Motion::Idle
        };
    }

    /// The RTDE output registers as the control loop last wrote them (int, double).
    pub fn output_registers(&self) -> (&[i32], &[f64]) {
        (&self.out_int, &self.out_double)
    }

    /// One cycle of the control script's loop.
    pub(super) fn control_step(&mut self, inputs: &InputTable) {
        let Some(r) = &mut self.running else { return };
        if r.paused {
            return;
        }
        let Some(mut c) = r.control.take() else {
            return;
        };
        let keep = self.control_cycle(&mut c, inputs);
        match &mut self.running {
            Some(r) if keep && r.control.is_none() && r.program.name == RTDE_CONTROL_PROGRAM => {
                r.control = Some(c);
            }
            Some(r) if !keep && r.program.name == RTDE_CONTROL_PROGRAM => {
                self.running = None;
                self.watchdog = None;
                self.log(
                    3,
                    format!(
                        "program {RTDE_CONTROL_PROGRAM} finished (RTDE Control Script Terminated)"
                    ),
                );
            }
            _ => {}
        }
    }

    fn set_out_int(&mut self, c: &ControlLoop, i: usize, v: i32) {
        self.out_int[c.script.int_offset + i] = v;
    }

    fn set_out_double(&mut self, c: &ControlLoop, i: usize, v: &[f64; 6]) {
        let base = c.script.float_offset + i;
        self.out_double[base..base + 6].copy_from_slice(v);
    }

    /// The script's `write_async_progress_register`.
    fn write_async(&mut self, c: &mut ControlLoop, value: i32) {
        c.async_wr_count += 1;
        if c.async_wr_count > 127 {
            c.async_wr_count = 0;
        }
        if value == 0 {
            c.async_op_id += 1;
            if c.async_op_id > 127 {
                c.async_op_id = 0;
            }
        }
        let mut reg = c.async_wr_count * 65536 + c.async_op_id * 16_777_216;
        if value >= 0 {
            reg += value.min(32767) + 32768;
        }
        self.set_out_int(c, 2, reg);
    }

    /// Runs a sequence as far as it goes this cycle.
    fn run_sequence(
        &mut self,
        seq: &mut Sequence,
        c: &mut ControlLoop,
        inputs: &InputTable,
    ) -> SeqState {
        loop {
            if seq.waiting {
                if !self.motion_done() {
                    return SeqState::Running;
                }
                seq.waiting = false;
            }
            match seq.steps.get(seq.next).cloned() {
                None => return SeqState::Done,
                Some(PathStep::Progress(n)) => {
                    seq.next += 1;
                    self.write_async(c, n);
                }
                Some(PathStep::Move(s)) => {
                    seq.next += 1;
                    if !self.begin_motion(&s, inputs) {
                        return SeqState::Failed;
                    }
                    seq.waiting = true;
                }
            }
        }
    }

    /// The script's `stop_async_move`: kills the async move, reports it finished.
    fn stop_async(&mut self, c: &mut ControlLoop) {
        if c.async_op.take().is_some() {
            self.write_async(c, -1);
            self.motion = if self.moving() {
                Motion::Stop {
                    decel: PROGRAM_STOP_DECEL_RADPS2,
                }
            } else {
                Motion::Idle
            };
        }
    }

    /// Starts a move: blocking (the loop waits) or async (progress in register 2).
    fn start_sequence(
        &mut self,
        c: &mut ControlLoop,
        mut seq: Sequence,
        is_async: bool,
        inputs: &InputTable,
    ) {
        if is_async {
            self.write_async(c, 0);
            match self.run_sequence(&mut seq, c, inputs) {
                SeqState::Running => c.async_op = Some(seq),
                SeqState::Done => self.write_async(c, -1),
                SeqState::Failed => {}
            }
        } else {
            match self.run_sequence(&mut seq, c, inputs) {
                SeqState::Running => c.blocking = Some(seq),
                SeqState::Done | SeqState::Failed => {}
            }
        }
    }

    /// One pass of the script's `while keep_running` loop; false when the script ends.
    fn control_cycle(&mut self, c: &mut ControlLoop, inputs: &InputTable) -> bool {
        if !c.started {
            c.started = true;
            self.log(3, "RTDE Control Script Loaded (served natively)".into());
            self.write_async(c, -1);
            self.set_out_int(c, 0, READY);
            return true;
        }
        // The async move or stop "thread".
        if let Some(mut seq) = c.async_op.take() {
            match self.run_sequence(&mut seq, c, inputs) {
                SeqState::Running => c.async_op = Some(seq),
                SeqState::Done => self.write_async(c, -1),
                SeqState::Failed => return false,
            }
        }
        // A synchronous command still moving.
        if let Some(mut seq) = c.blocking.take() {
            match self.run_sequence(&mut seq, c, inputs) {
                SeqState::Running => c.blocking = Some(seq),
                SeqState::Done => {
                    self.set_out_int(c, 0, DONE);
                    c.executing_cmd = true;
                }
                SeqState::Failed => return false,
            }
            return self.running.is_some();
        }
        let command = c.int(inputs, 0);
        if cmd::REALTIME.contains(&command) {
            let keep = self.process(c, command, inputs);
            self.set_out_int(c, 0, READY);
            return keep && self.running.is_some();
        }
        if command == cmd::NO_CMD {
            c.executing_cmd = false;
            self.set_out_int(c, 0, READY);
            return true;
        }
        if !c.executing_cmd {
            if !self.process(c, command, inputs) {
                return false;
            }
            if c.blocking.is_none() {
                self.set_out_int(c, 0, DONE);
            }
        }
        c.executing_cmd = true;
        self.running.is_some()
    }

    /// The script's `process_cmd`; false for `stopScript`.
    #[allow(clippy::too_many_lines, reason = "one arm per ur_rtde command")]
    fn process(&mut self, c: &mut ControlLoop, command: i32, inputs: &InputTable) -> bool {
        let positive = |v: f64| v.is_finite() && v > 0.0;
        match command {
            cmd::MOVEJ | cmd::MOVEJ_IK | cmd::MOVEL | cmd::MOVEL_FK => {
                let x = c.six(inputs, 0);
                let (speed, accel) = (c.f(inputs, 6), c.f(inputs, 7));
                let is_async = c.int(inputs, 1) == 1;
                self.stop_async(c);
                if !positive(speed) || !positive(accel) {
                    self.runtime_error("move: speed and acceleration must be positive");
                    return true;
                }
                let s = match command {
                    cmd::MOVEJ => Statement::MoveJ {
                        target: Target::Joints(x),
                        accel,
                        speed,
                    },
                    cmd::MOVEJ_IK => Statement::MoveJ {
                        target: Target::Pose(x),
                        accel,
                        speed,
                    },
                    cmd::MOVEL => Statement::MoveL {
                        target: Target::Pose(x),
                        accel,
                        speed,
                    },
                    _ => Statement::MoveL {
                        target: Target::Joints(x),
                        accel,
                        speed,
                    },
                };
                self.start_sequence(c, Sequence::one(s), is_async, inputs);
            }
            cmd::MOVE_PATH => {
                let is_async = c.int(inputs, 1) == 1;
                self.stop_async(c);
                let seq = Sequence::new(c.script.path.clone());
                self.start_sequence(c, seq, is_async, inputs);
            }
            cmd::SPEEDJ => {
                let qd = c.six(inputs, 0);
                let accel = c.f(inputs, 6);
                c.speed_is_linear = false;
                if !positive(accel) {
                    self.runtime_error("speedj: acceleration must be positive");
                    return true;
                }
                match &mut self.motion {
                    Motion::Speed {
                        qd: target,
                        accel: a,
                        remaining_s: None,
                    } if qd.iter().all(|v| v.abs() <= MAX_JOINT_SPEED_RADPS) => {
                        *target = qd;
                        *a = accel;
                    }
                    _ => {
                        let s = Statement::SpeedJ {
                            qd,
                            accel,
                            time_s: None,
                        };
                        self.begin_motion(&s, inputs);
                    }
                }
            }
            cmd::SPEEDL => {
                let xd = c.six(inputs, 0);
                let accel = c.f(inputs, 6);
                c.speed_is_linear = true;
                if !positive(accel) || xd.iter().any(|v| !v.is_finite()) {
                    self.runtime_error("speedl: acceleration must be positive");
                    return true;
                }
                match &mut self.motion {
                    Motion::SpeedL {
                        xd: target,
                        accel: a,
                        ..
                    } => {
                        *target = xd;
                        *a = accel;
                    }
                    _ => {
                        self.motion = Motion::SpeedL {
                            xd,
                            accel,
                            v: [0.0; 6],
                        }
                    }
                }
            }
            cmd::SERVOJ | cmd::SERVOL => {
                let x = c.six(inputs, 0);
                let time_s = c.f(inputs, 8);
                let target = if command == cmd::SERVOJ {
                    x
                } else {
                    let flange = pose_to_iso(&x) * self.tcp_offset.inverse();
                    match self.nearest_ik(&flange) {
                        Some(q) => q,
                        None => {
                            self.runtime_error("servol: pose not reachable");
                            return true;
                        }
                    }
                };
                if target.iter().any(|v| !v.is_finite()) {
                    self.runtime_error("servoj: target is not a number");
                    return true;
                }
                let time_s = if time_s.is_finite() && time_s > 0.0 {
                    time_s
                } else {
                    0.008
                };
                self.motion = Motion::Servo { target, time_s };
            }
            cmd::SPEED_STOP | cmd::SERVO_STOP => {
                let decel = c.f(inputs, 0);
                let decel = if positive(decel) { decel } else { 10.0 };
                let s = if command == cmd::SPEED_STOP && !c.speed_is_linear {
                    Statement::StopJ { decel }
                } else {
                    Statement::StopL { decel }
                };
                self.start_sequence(c, Sequence::one(s), false, inputs);
            }
            cmd::STOPJ | cmd::STOPL => {
                let decel = c.f(inputs, 0);
                let decel = if positive(decel) { decel } else { 2.0 };
                let is_async = c.int(inputs, 1) == 1;
                self.stop_async(c);
                let s = if command == cmd::STOPJ {
                    Statement::StopJ { decel }
                } else {
                    Statement::StopL { decel }
                };
                self.start_sequence(c, Sequence::one(s), is_async, inputs);
            }
            cmd::SET_WATCHDOG => {
                let f = c.f(inputs, 0);
                let name = format!("input_int_register_{}", c.script.int_offset);
                self.start_watchdog(inputs, &name, f, WatchdogAction::Stop);
            }
            cmd::SET_TCP => {
                let p = c.six(inputs, 0);
                self.instant(&Statement::SetTcp(p));
            }
            cmd::SET_PAYLOAD => {
                self.log(
                    3,
                    format!(
                        "set_payload: mass {} kg (no effect on the motion model)",
                        c.f(inputs, 0)
                    ),
                );
            }
            cmd::POSE_TRANS => {
                let p =
                    iso_to_pose(&(pose_to_iso(&c.six(inputs, 0)) * pose_to_iso(&c.six(inputs, 6))));
                self.set_out_double(c, 0, &p);
            }
            cmd::GET_TCP_OFFSET => {
                let p = self.tcp_offset_p;
                self.set_out_double(c, 0, &p);
            }
            cmd::GET_FORWARD_KIN_DEFAULT => {
                let p = iso_to_pose(&(self.flange(&self.q) * self.tcp_offset));
                self.set_out_double(c, 0, &p);
            }
            cmd::GET_FORWARD_KIN_ARGS => {
                let q = c.six(inputs, 0);
                let tcp = c.six(inputs, 6);
                let p = iso_to_pose(&(self.flange(&q) * pose_to_iso(&tcp)));
                self.set_out_double(c, 0, &p);
            }
            cmd::GET_INVERSE_KIN_DEFAULT | cmd::GET_INVERSE_KIN_ARGS => {
                let pose = c.six(inputs, 0);
                let near = if command == cmd::GET_INVERSE_KIN_ARGS {
                    c.six(inputs, 6)
                } else {
                    self.q
                };
                let flange = pose_to_iso(&pose) * self.tcp_offset.inverse();
                match self.nearest_ik_to(&flange, &near) {
                    Some(q) => self.set_out_double(c, 0, &q),
                    None => {
                        self.runtime_error("get_inverse_kin: no solution");
                        return true;
                    }
                }
            }
            cmd::IS_STEADY => {
                let steady = self.motion_done() && !self.moving();
                self.set_out_int(c, 1, i32::from(steady));
            }
            cmd::IS_JOINTS_WITHIN_SAFETY_LIMITS => {
                let q = c.six(inputs, 0);
                self.set_out_int(c, 1, i32::from(within_joint_limits(&q)));
            }
            cmd::IS_POSE_WITHIN_SAFETY_LIMITS => {
                let pose = c.six(inputs, 0);
                let flange = pose_to_iso(&pose) * self.tcp_offset.inverse();
                let ok = self.nearest_ik(&flange).is_some();
                self.set_out_int(c, 1, i32::from(ok));
            }
            cmd::PROTECTIVE_STOP => {
                self.protective_stop("protective_stop() called by the control script")
            }
            cmd::STOP_SCRIPT => {
                self.log(3, "Received stop script!".into());
                return false;
            }
            other => {
                if !c.logged.contains(&other) {
                    c.logged.push(other);
                    self.log(
                        2,
                        format!("ur_rtde command {other} is not emulated by this simulator; acknowledged without effect"),
                    );
                }
            }
        }
        true
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::robot::{RobotInit, runtime_state};
    use crate::urscript::parse_rtde_control;

    const DT: f64 = 0.002;

    /// ur_rtde's control script as ur_rtde 1.6 sends it, cut to the lines the simulator reads
    /// (the offsets ur_rtde injects after the comment, and an injected path).
    pub(crate) fn control_script(offset: usize, path: &str) -> String {
        format!(
            "def rtde_control():\n# HEADER_BEGIN\n    global reg_offset_float = # float register offset\n{offset}    \
             global reg_offset_int = # int register offset\n{offset}    global force_mode_type = 2\n    \
             def exec_move_path():\n        textmsg(\"exec_move_path\")\n        # inject move path\n{path}    end\n    \
             def signal_ready():\n        write_output_integer_reg(0, 1)\n    end\n    \
             def process_cmd(cmd):\n        if cmd == 1:\n            textmsg(\"movej\")\n        end\n    end\n\
             # HEADER_END\n# NODE_CONTROL_LOOP_BEGINS\n        signal_ready()\n# NODE_CONTROL_LOOP_ENDS\nend\n"
        )
    }

    struct Rig {
        m: RobotModel,
        inputs: InputTable,
        offset: usize,
    }

    impl Rig {
        fn new(offset: usize, path: &str) -> Self {
            let inputs = InputTable::new();
            let mut m = RobotModel::new(RobotInit::default());
            let script = parse_rtde_control(&control_script(offset, path)).unwrap();
            assert_eq!((script.int_offset, script.float_offset), (offset, offset));
            m.load_rtde_control(script, &inputs);
            let mut rig = Self { m, inputs, offset };
            rig.step();
            assert_eq!(rig.state(), READY, "ready after the first cycle");
            rig
        }

        fn step(&mut self) {
            self.m.step(DT, &self.inputs);
        }

        fn steps(&mut self, n: usize) {
            for _ in 0..n {
                self.step();
            }
        }

        fn out_int(&self, i: usize) -> i32 {
            self.m.snapshot().output_int_registers[self.offset + i]
        }

        fn out_double(&self, i: usize) -> f64 {
            self.m.snapshot().output_double_registers[self.offset + i]
        }

        fn state(&self) -> i32 {
            self.out_int(0)
        }

        /// Writes a command and its arguments as one RTDE input package would.
        fn send(&mut self, command: i32, ints: &[i32], doubles: &[f64]) {
            let now = self.m.time_s();
            let mut put = |name: String, v: RtdeValue| {
                let i = self.inputs.index_of(&name).unwrap();
                self.inputs.write(i, v, now);
            };
            put(
                format!("input_int_register_{}", self.offset),
                RtdeValue::Int32(command),
            );
            for (k, &v) in ints.iter().enumerate() {
                put(
                    format!("input_int_register_{}", self.offset + 1 + k),
                    RtdeValue::Int32(v),
                );
            }
            for (k, &v) in doubles.iter().enumerate() {
                put(
                    format!("input_double_register_{}", self.offset + k),
                    RtdeValue::Double(v),
                );
            }
        }

        /// ur_rtde's `sendCommand` for a non-real-time command: send, wait for done, clear,
        /// wait for ready. Returns the cycles until done.
        fn command(&mut self, command: i32, ints: &[i32], doubles: &[f64], limit: usize) -> usize {
            assert_eq!(self.state(), READY);
            self.send(command, ints, doubles);
            let mut n = 0;
            while self.state() != DONE {
                self.step();
                n += 1;
                assert!(n < limit, "command {command} not done in {limit} cycles");
            }
            self.send(cmd::NO_CMD, &[], &[]);
            self.step();
            assert_eq!(self.state(), READY, "ready again after the clear");
            n
        }

        fn q(&self) -> Joints {
            self.m.q()
        }
    }

    fn close(a: &[f64], b: &[f64], tol: f64) -> bool {
        a.iter().zip(b).all(|(x, y)| (x - y).abs() <= tol)
    }

    const GOAL: Joints = [0.6, -1.2, 1.3, -1.6, -1.4, 0.3];

    fn args(q: &Joints, v: f64, a: f64) -> Vec<f64> {
        let mut d = q.to_vec();
        d.extend([v, a]);
        d
    }

    #[test]
    fn movej_blocks_until_the_arm_is_at_its_target() {
        let mut r = Rig::new(0, "");
        assert_eq!(r.m.runtime_state(), runtime_state::PLAYING);
        assert_eq!(r.m.program_name(), Some(RTDE_CONTROL_PROGRAM));
        r.send(cmd::MOVEJ, &[0], &args(&GOAL, 1.05, 1.4));
        r.steps(50);
        assert_eq!(r.state(), READY, "still moving: not done");
        assert!(r.m.snapshot().qd.iter().any(|v| v.abs() > 0.05));
        let mut n = 50;
        while r.state() != DONE {
            r.step();
            n += 1;
            assert!(n < 5000);
        }
        assert!(close(&r.q(), &GOAL, 1e-9), "{:?}", r.q());
        assert!(r.m.snapshot().qd.iter().all(|v| v.abs() < 1e-9));
        // The command stays latched: done is not repeated as a new move.
        r.steps(10);
        assert_eq!(r.state(), DONE);
        r.send(cmd::NO_CMD, &[], &[]);
        r.step();
        assert_eq!(r.state(), READY);
    }

    #[test]
    fn movel_keeps_a_straight_tool_line_to_its_pose() {
        let mut r = Rig::new(0, "");
        let start = r.m.snapshot().tcp_pose;
        let mut goal = start;
        goal[0] += 0.1;
        goal[2] -= 0.05;
        r.command(cmd::MOVEL, &[0], &args(&goal, 0.25, 1.2), 5000);
        let end = r.m.snapshot().tcp_pose;
        assert!(close(&end, &goal, 1e-6), "{end:?} vs {goal:?}");
    }

    #[test]
    fn async_movej_reports_progress_and_its_end() {
        let mut r = Rig::new(0, "");
        let idle = r.out_int(2);
        assert_eq!(idle & 0x8000, 0, "no async operation at start");
        let n = r.command(cmd::MOVEJ, &[1], &args(&GOAL, 1.05, 1.4), 10);
        assert!(n <= 2, "async returns at once, took {n} cycles");
        let running = r.out_int(2);
        assert_ne!(
            running & 0x8000,
            0,
            "running bit while moving: {running:#x}"
        );
        assert_eq!(running & 0x7fff, 0, "progress 0");
        let mut cycles = 0;
        while r.out_int(2) & 0x8000 != 0 {
            r.step();
            cycles += 1;
            assert!(cycles < 5000);
        }
        assert!(close(&r.q(), &GOAL, 1e-9));
        assert_ne!(
            r.out_int(2) >> 16 & 0x7f,
            running >> 16 & 0x7f,
            "write counter advanced"
        );
    }

    #[test]
    fn a_move_path_reports_each_waypoint() {
        let a: Joints = [0.3, -1.4, 1.4, -1.5, -1.5, 0.1];
        let b: Joints = [0.6, -1.2, 1.2, -1.5, -1.4, 0.2];
        let line = |q: &Joints| {
            format!(
                "\tmovej([{},{},{},{},{},{}],a=1.4,v=1.05,r=0)\n",
                q[0], q[1], q[2], q[3], q[4], q[5]
            )
        };
        let path = format!(
            "\tsignal_async_progress(0)\n{}\tsignal_async_progress(1)\n{}",
            line(&a),
            line(&b)
        );
        let mut r = Rig::new(0, &path);
        r.command(cmd::MOVE_PATH, &[1], &[], 10);
        let mut seen = Vec::new();
        let mut cycles = 0;
        while cycles == 0 || r.out_int(2) & 0x8000 != 0 {
            let reg = r.out_int(2);
            if reg & 0x8000 != 0 && seen.last() != Some(&(reg & 0x7fff)) {
                seen.push(reg & 0x7fff);
                if reg & 0x7fff == 1 {
                    // Written as the move to b starts: one cycle after reaching a.
                    assert!(close(&r.q(), &a, 1e-3), "waypoint 0 reached first");
                }
            }
            r.step();
            cycles += 1;
            assert!(cycles < 10_000);
        }
        assert_eq!(seen, [0, 1]);
        assert!(close(&r.q(), &b, 1e-9));
    }

    #[test]
    fn speedj_runs_until_speed_stop_brings_it_to_rest() {
        let mut r = Rig::new(0, "");
        let mut d = vec![0.2, -0.1, 0.0, 0.0, 0.0, 0.0];
        d.extend([1.0, 0.008]);
        r.send(cmd::SPEEDJ, &[], &d);
        r.steps(500);
        assert_eq!(r.state(), READY, "real-time commands answer ready");
        let qd = r.m.snapshot().qd;
        assert!(
            (qd[0] - 0.2).abs() < 1e-6 && (qd[1] + 0.1).abs() < 1e-6,
            "{qd:?}"
        );
        r.send(cmd::NO_CMD, &[], &[]);
        r.step();
        r.command(cmd::SPEED_STOP, &[], &[10.0], 200);
        assert!(r.m.snapshot().qd.iter().all(|v| v.abs() < 1e-9));
    }

    #[test]
    fn speedl_moves_the_tool_along_its_twist() {
        let mut r = Rig::new(0, "");
        let p0 = r.m.snapshot().tcp_pose;
        r.send(
            cmd::SPEEDL,
            &[],
            &[0.05, 0.0, 0.0, 0.0, 0.0, 0.0, 0.5, 0.008],
        );
        r.steps(500);
        let p1 = r.m.snapshot().tcp_pose;
        let v = r.m.snapshot().tcp_speed;
        assert!((v[0] - 0.05).abs() < 1e-4, "{v:?}");
        assert!((p1[1] - p0[1]).abs() < 1e-6 && (p1[2] - p0[2]).abs() < 1e-6);
        // 0.1 s ramp at 0.5 m/s^2, then 0.05 m/s: 0.0025 + 0.9 * 0.05 m.
        assert!((p1[0] - p0[0] - 0.0475).abs() < 1e-3, "{}", p1[0] - p0[0]);
        r.send(cmd::NO_CMD, &[], &[]);
        r.step();
        r.command(cmd::SPEED_STOP, &[], &[10.0], 200);
        assert!(r.m.snapshot().qd.iter().all(|v| v.abs() < 1e-9));
    }

    #[test]
    fn servoj_tracks_streamed_targets_and_servo_stop_holds() {
        let mut r = Rig::new(0, "");
        let q0 = r.q();
        let mut last = q0;
        for k in 0..1000 {
            // A smooth 0.2 rad excursion of joint 0, back to rest at the end.
            let s = k as f64 / 999.0;
            let mut q = q0;
            q[0] += 0.2 * (0.5 - 0.5 * (s * PI).cos());
            let mut d = q.to_vec();
            d.extend([0.5, 0.5, DT, 0.1, 300.0]);
            r.send(cmd::SERVOJ, &[], &d);
            r.step();
            assert_eq!(r.state(), READY);
            assert!(close(&r.q(), &q, 1e-12), "cycle {k}");
            last = q;
        }
        r.command(cmd::SERVO_STOP, &[], &[10.0], 200);
        assert!(close(&r.q(), &last, 1e-6), "{:?} vs {last:?}", r.q());
    }

    #[test]
    fn a_servo_target_past_the_joint_limit_is_a_protective_stop() {
        let mut r = Rig::new(0, "");
        let mut q = r.q();
        q[2] = 3.3; // the elbow's limit is pi
        let mut d = q.to_vec();
        d.extend([0.5, 0.5, 0.5, 0.1, 300.0]);
        r.send(cmd::SERVOJ, &[], &d);
        r.steps(1000);
        assert_eq!(r.m.safety_mode(), 3);
        assert_eq!(r.m.runtime_state(), runtime_state::STOPPED);
    }

    #[test]
    fn stop_script_ends_the_program() {
        let mut r = Rig::new(0, "");
        r.send(cmd::STOP_SCRIPT, &[], &[]);
        r.step();
        assert_eq!(r.m.runtime_state(), runtime_state::STOPPED);
        assert_eq!(r.m.program_name(), None);
    }

    #[test]
    fn the_watchdog_stops_the_script_when_commands_stop_coming() {
        let mut r = Rig::new(0, "");
        r.command(cmd::SET_WATCHDOG, &[], &[10.0], 10);
        for _ in 0..100 {
            r.send(cmd::NO_CMD, &[], &[]);
            r.step();
        }
        assert_eq!(r.m.runtime_state(), runtime_state::PLAYING, "fed");
        r.steps(60);
        assert_eq!(r.m.runtime_state(), runtime_state::STOPPED, "starved");
    }

    #[test]
    fn upper_range_registers_and_kinematics_queries() {
        let mut r = Rig::new(24, "");
        r.command(cmd::GET_FORWARD_KIN_DEFAULT, &[], &[], 10);
        let pose: Vec<f64> = (0..6).map(|i| r.out_double(i)).collect();
        assert!(close(&pose, &r.m.snapshot().tcp_pose, 1e-12));
        assert_eq!(
            r.m.snapshot().output_int_registers[0],
            0,
            "lower range untouched"
        );
        let mut d = pose.clone();
        d.extend(r.q());
        r.command(cmd::GET_INVERSE_KIN_ARGS, &[], &d, 10);
        let q: Vec<f64> = (0..6).map(|i| r.out_double(i)).collect();
        assert!(close(&q, &r.q(), 1e-6), "{q:?}");
        let mut d = vec![0.1, 0.0, 0.0, 0.0, 0.0, PI / 2.0];
        d.extend([0.0, 0.2, 0.0, 0.0, 0.0, 0.0]);
        r.command(cmd::POSE_TRANS, &[], &d, 10);
        let p: Vec<f64> = (0..6).map(|i| r.out_double(i)).collect();
        // (0.1, 0, 0) turned a quarter about z, then 0.2 along its y: (-0.1, 0, 0).
        assert!(
            close(&p, &[-0.1, 0.0, 0.0, 0.0, 0.0, PI / 2.0], 1e-12),
            "{p:?}"
        );
        r.command(cmd::IS_STEADY, &[], &[], 10);
        assert_eq!(r.out_int(1), 1);
        let mut bad = r.q();
        bad[0] = 7.0;
        r.command(cmd::IS_JOINTS_WITHIN_SAFETY_LIMITS, &[], &bad, 10);
        assert_eq!(r.out_int(1), 0);
    }

    #[test]
    fn an_unknown_command_is_acknowledged_without_effect() {
        let mut r = Rig::new(0, "");
        let q = r.q();
        r.command(cmd::FORCE_MODE + 1, &[], &[], 10);
        assert_eq!(r.q(), q);
        assert_eq!(r.m.runtime_state(), runtime_state::PLAYING);
    }
}

#[cfg(test)]
mod parse_tests {
    use super::tests::control_script;
    use crate::urscript::{ScriptParseError, is_rtde_control, parse_rtde_control};

    #[test]
    fn a_path_with_movep_is_rejected_naming_its_line() {
        let text = control_script(0, "\tmovep(p[0.1,0.2,0.3,0,3.14,0],a=1.2,v=0.25,r=0)\n");
        match parse_rtde_control(&text) {
            Err(ScriptParseError::Statement { line, text, .. }) => {
                assert!(text.starts_with("movep("), "{text}");
                assert!(line > 1);
            }
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn only_urrtde_s_script_is_recognised() {
        assert!(is_rtde_control(&control_script(0, "")));
        assert!(!is_rtde_control("def rtde_control():\n  sleep(1)\nend\n"));
        let bad = control_script(0, "").replace(
            "reg_offset_int = # int register offset\n0",
            "reg_offset_int = 7",
        );
        assert!(
            parse_rtde_control(&bad)
                .unwrap_err()
                .to_string()
                .contains("reg_offset_int")
        );
    }
}
