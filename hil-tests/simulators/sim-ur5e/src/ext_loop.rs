//! The External Control program's command loop (module [`crate::external_control`]), served
//! natively on the arm's motion model: the server's socket threads hand each reverse message,
//! trajectory point and script command to [`RobotModel`]; the loop runs once per control cycle.

use std::collections::VecDeque;

use super::{
    Joints, MAX_JOINT_SPEED_RADPS, Motion, Program, RobotModel, Running, Statement, Target,
    Trapezoid, pose_to_iso, robot_mode,
};
use crate::external_control::{
    ExternalControlScript, REVERSE_MESSAGE_INTS, SCRIPT_COMMAND_INTS, TRAJECTORY_POINT_INTS, mode,
    motion, result, trajectory_action,
};
use crate::inputs::InputTable;

/// Name the External Control program runs under.
pub const EXTERNAL_CONTROL_PROGRAM: &str = "external_control";

/// Deceleration of the program's `stopj` (`STOPJ_ACCELERATION`).
const STOPJ_ACCELERATION: f64 = 4.0;
/// The script ignores targets that need more than this joint speed (`JOINT_IGNORE_SPEED`).
const JOINT_IGNORE_SPEED: f64 = 20.0;
/// Seconds the trajectory thread waits for a point before it fails.
const POINT_TIMEOUT_S: f64 = 0.5;

/// Trajectory points kept that arrived before their start message.
const EARLY_POINTS_MAX: usize = 64;
/// The program's `steptime` on an e-Series controller (s).
const STEPTIME_S: f64 = 0.002;

/// State of one External Control session.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct ExtLoop {
    session: u64,
    mult_joint: f64,
    mult_time: f64,
    mode: i32,
    /// Keep-alive: seconds a reverse message may take (0: the next read blocks).
    read_timeout_s: f64,
    last_message_s: f64,
    servo_target: Option<Joints>,
    speed: Joints,
    twist: [f64; 6],
    /// Trajectory forwarding.
    points_left: i32,
    queue: VecDeque<[i32; TRAJECTORY_POINT_INTS]>,
    trajectory_running: bool,
    waiting_motion: bool,
    waiting_point_since_s: f64,
    spline_qd: Joints,
    spline_qdd: Joints,
    results: Vec<i32>,
    logged: Vec<i32>,
}

impl RobotModel {
    /// Starts an External Control session (the program connected its sockets); returns its id,
    /// or `None` when the robot refuses programs (not running, stopped by safety).
    pub fn load_external_control(&mut self, script: &ExternalControlScript) -> Option<u64> {
        if self.robot_mode != robot_mode::RUNNING || self.safety_mode != 1 {
            self.log(
                1,
                format!("program {EXTERNAL_CONTROL_PROGRAM} refused: robot is not running"),
            );
            return None;
        }
        self.next_session += 1;
        let session = self.next_session;
        if self.running.is_some() {
            self.log(
                3,
                format!("program {EXTERNAL_CONTROL_PROGRAM} replaces the running program"),
            );
        }
        self.watchdog = None;
        self.running = Some(Running {
            program: Program {
                name: EXTERNAL_CONTROL_PROGRAM.into(),
                secondary: false,
                statements: Vec::new(),
            },
            pc: 0,
            current: None,
            paused: false,
            control: None,
            external: Some(Box::new(ExtLoop {
                session,
                mult_joint: script.mult_jointstate,
                mult_time: script.mult_time,
                mode: mode::UNINITIALIZED,
                read_timeout_s: 0.0,
                last_message_s: self.time_s,
                servo_target: None,
                speed: [0.0; 6],
                twist: [0.0; 6],
                points_left: 0,
                queue: VecDeque::new(),
                trajectory_running: false,
                waiting_motion: false,
                waiting_point_since_s: self.time_s,
                spline_qd: [0.0; 6],
                spline_qdd: [0.0; 6],
                results: Vec::new(),
                logged: Vec::new(),
            })),
        });
        self.motion = if self.moving() {
            Motion::Stop {
                decel: STOPJ_ACCELERATION,
            }
        } else {
            Motion::Idle
        };
        self.log(3, "ExternalControl: External control active".into());
        Some(session)
    }

    fn ext(&mut self, session: u64) -> Option<&mut ExtLoop> {
        self.running
            .as_mut()
            .and_then(|r| r.external.as_deref_mut())
            .filter(|e| e.session == session)
    }

    /// Whether session `session` still runs.
    pub fn external_active(&self, session: u64) -> bool {
        self.running
            .as_ref()
            .and_then(|r| r.external.as_deref())
            .is_some_and(|e| e.session == session)
    }

    /// Takes the trajectory results to send; `None` when the session has ended (the server then
    /// closes its sockets).
    pub fn external_take_results(&mut self, session: u64) -> Option<Vec<i32>> {
        self.ext(session).map(|e| std::mem::take(&mut e.results))
    }

    /// One reverse-socket message `[read_timeout_ms, v0..v5, mode]`.
    pub fn external_reverse(&mut self, session: u64, msg: &[i32; REVERSE_MESSAGE_INTS]) {
        let now = self.time_s;
        let q_now = self.q;
        let Some(e) = self.ext(session) else { return };
        e.last_message_s = now;
        e.read_timeout_s = f64::from(msg[0].max(0)) / 1000.0;
        let m = e.mult_joint;
        let v: [f64; 6] = core::array::from_fn(|i| f64::from(msg[1 + i]) / m);
        let new_mode = msg[7];
        let old_mode = e.mode;
        let mut cancel = false;
        if new_mode != old_mode {
            if old_mode == mode::FORWARD && e.trajectory_running {
                cancel = true;
            }
            e.mode = new_mode;
            e.servo_target = None;
        }
        let action = (new_mode == mode::FORWARD).then_some((msg[1], msg[2]));
        match new_mode {
            mode::SERVOJ => {
                // The script ignores targets that would need more than 20 rad/s.
                let from = e.servo_target.unwrap_or(q_now);
                let ok = v
                    .iter()
                    .zip(from)
                    .all(|(a, b)| (a - b).abs() / STEPTIME_S <= JOINT_IGNORE_SPEED);
                if ok {
                    e.servo_target = Some(v);
                }
            }
            mode::SPEEDJ => e.speed = v,
            mode::SPEEDL => e.twist = v,
            _ => {}
        }
        if cancel {
            self.external_cancel(session);
        }
        if new_mode == mode::POSE {
            let flange = pose_to_iso(&v) * self.tcp_offset.inverse();
            let near = self
                .ext(session)
                .and_then(|e| e.servo_target)
                .unwrap_or(self.q);
            let q = self.nearest_ik_to(&flange, &near);
            if let (Some(q), Some(e)) = (q, self.ext(session)) {
                e.servo_target = Some(q);
            }
        }
        if let Some((a, n)) = action {
            match a {
                trajectory_action::RECEIVE => {
                    let now = self.time_s;
                    if let Some(e) = self.ext(session) {
                        e.queue.truncate(n.max(0) as usize);
                        e.points_left = n.max(0);
                        e.trajectory_running = n > 0;
                        e.waiting_motion = false;
                        e.waiting_point_since_s = now;
                        e.spline_qd = [0.0; 6];
                        e.spline_qdd = [0.0; 6];
                    }
                    if n <= 0 {
                        self.ext_push_result(session, result::SUCCESS);
                    }
                }
                trajectory_action::CANCEL => {
                    self.log(3, "ExternalControl: cancel received".into());
                    self.external_cancel(session);
                }
                _ => {}
            }
        }
    }

    /// One trajectory point (21 `i32`).
    pub fn external_trajectory_point(
        &mut self,
        session: u64,
        point: &[i32; TRAJECTORY_POINT_INTS],
    ) {
        if let Some(e) = self.ext(session) {
            // Points beyond the announced count are drained, as the script's cleanup does.
            // Points read before the start message (the two arrive on different sockets, and
            // a loaded host may deliver them in either order) wait, as a real controller's
            // socket buffer keeps them until the script reads; the start keeps its count.
            let room = if e.trajectory_running {
                e.points_left.max(0) as usize
            } else {
                EARLY_POINTS_MAX
            };
            if e.queue.len() < room {
                e.queue.push_back(*point);
            }
        }
    }

    /// One script command (28 `i32`): `set_tcp` and `set_payload` are applied; the others are
    /// logged once as not emulated.
    pub fn external_script_command(&mut self, session: u64, cmd: &[i32; SCRIPT_COMMAND_INTS]) {
        let Some(e) = self.ext(session) else { return };
        let m = e.mult_joint;
        let command = cmd[0];
        match command {
            // SET_TCP_OFFSET
            10 => {
                let p: [f64; 6] = core::array::from_fn(|i| f64::from(cmd[1 + i]) / m);
                self.instant(&Statement::SetTcp(p));
            }
            // SET_PAYLOAD
            1 => self.log(
                3,
                format!(
                    "ExternalControl: set_payload({} kg) (no effect on the motion model)",
                    f64::from(cmd[1]) / m
                ),
            ),
            other => {
                if !e.logged.contains(&other) {
                    e.logged.push(other);
                    self.log(
                        2,
                        format!("ExternalControl: script command {other} is not emulated by this simulator"),
                    );
                }
            }
        }
    }

    fn ext_push_result(&mut self, session: u64, r: i32) {
        let name = match r {
            result::SUCCESS => "SUCCESS",
            result::CANCELED => "CANCELED",
            _ => "FAILURE",
        };
        if let Some(e) = self.ext(session) {
            e.results.push(r);
        }
        self.log(
            3,
            format!("ExternalControl: trajectory finished with result {name}"),
        );
    }

    fn external_cancel(&mut self, session: u64) {
        let running = self.ext(session).is_some_and(|e| e.trajectory_running);
        if let Some(e) = self.ext(session) {
            e.trajectory_running = false;
            e.points_left = 0;
            e.queue.clear();
            e.waiting_motion = false;
        }
        self.motion = Motion::Stop {
            decel: STOPJ_ACCELERATION,
        };
        if running {
            self.ext_push_result(session, result::CANCELED);
        }
    }

    /// One cycle of the External Control loop (called with the session's `Running`).
    pub(super) fn external_step(&mut self, inputs: &InputTable) {
        let Some(e) = self.running.as_ref().and_then(|r| r.external.as_deref()) else {
            return;
        };
        if self.running.as_ref().is_some_and(|r| r.paused) {
            return;
        }
        let session = e.session;
        let (timeout, last, m) = (e.read_timeout_s, e.last_message_s, e.mode);
        if m == mode::STOPPED {
            self.external_end("ExternalControl: Stopping communication and control");
            return;
        }
        if timeout > 0.0 && self.time_s - last > timeout {
            self.external_end(
                "Socket timed out waiting for command on reverse_socket. The script will exit now.",
            );
            return;
        }
        match m {
            mode::SERVOJ | mode::POSE => {
                let target = self.ext(session).and_then(|e| e.servo_target);
                if let Some(target) = target {
                    self.motion = Motion::Servo {
                        target,
                        time_s: STEPTIME_S,
                    };
                }
            }
            mode::SPEEDJ => {
                let qd = self.ext(session).map_or([0.0; 6], |e| e.speed);
                if qd.iter().any(|v| v.abs() > MAX_JOINT_SPEED_RADPS) {
                    self.protective_stop("speedj: a joint speed above its limit");
                    return;
                }
                self.motion = Motion::Speed {
                    qd,
                    accel: 40.0,
                    remaining_s: None,
                };
            }
            mode::SPEEDL => {
                let xd = self.ext(session).map_or([0.0; 6], |e| e.twist);
                match &mut self.motion {
                    Motion::SpeedL { xd: t, .. } => *t = xd,
                    _ => {
                        self.motion = Motion::SpeedL {
                            xd,
                            accel: 40.0,
                            v: [0.0; 6],
                        }
                    }
                }
            }
            mode::FORWARD => self.external_trajectory(session, inputs),
            mode::IDLE | mode::UNINITIALIZED => {
                if matches!(
                    self.motion,
                    Motion::Servo { .. } | Motion::Speed { .. } | Motion::SpeedL { .. }
                ) {
                    self.motion = Motion::Stop {
                        decel: STOPJ_ACCELERATION,
                    };
                }
            }
            other => {
                let first = self
                    .ext(session)
                    .is_some_and(|e| !e.logged.contains(&(1000 + other)));
                if first {
                    if let Some(e) = self.ext(session) {
                        e.logged.push(1000 + other);
                    }
                    self.log(
                        2,
                        format!("ExternalControl: control mode {other} is not emulated by this simulator"),
                    );
                }
            }
        }
    }

    fn external_end(&mut self, text: &str) {
        self.log(2, text.into());
        self.running = None;
        self.motion = if self.moving() {
            Motion::Stop {
                decel: STOPJ_ACCELERATION,
            }
        } else {
            Motion::Idle
        };
    }

    /// The trajectory thread: one point at a time, each started when the previous one ended.
    #[allow(
        clippy::too_many_lines,
        reason = "one arm per mode of the URCap external-control protocol"
    )]
    fn external_trajectory(&mut self, session: u64, inputs: &InputTable) {
        enum Next {
            Wait,
            Finished,
            TimedOut,
            Point(Box<[i32; TRAJECTORY_POINT_INTS]>, f64, f64, Joints, Joints),
        }
        let now = self.time_s;
        let done = self.motion_done();
        let next = {
            let Some(e) = self.ext(session) else { return };
            if !e.trajectory_running {
                return;
            }
            if e.waiting_motion {
                if !done {
                    return;
                }
                e.waiting_motion = false;
                e.waiting_point_since_s = now;
            }
            if e.points_left <= 0 {
                e.trajectory_running = false;
                Next::Finished
            } else {
                match e.queue.pop_front() {
                    Some(p) => {
                        e.points_left -= 1;
                        Next::Point(
                            Box::new(p),
                            e.mult_joint,
                            e.mult_time,
                            e.spline_qd,
                            e.spline_qdd,
                        )
                    }
                    None if now - e.waiting_point_since_s > POINT_TIMEOUT_S => {
                        e.trajectory_running = false;
                        e.points_left = 0;
                        Next::TimedOut
                    }
                    None => Next::Wait,
                }
            }
        };
        let (point, mj, mt, start_qd, start_qdd) = match next {
            Next::Wait => return,
            Next::Finished => {
                self.motion = Motion::Stop {
                    decel: STOPJ_ACCELERATION,
                };
                self.ext_push_result(session, result::SUCCESS);
                return;
            }
            Next::TimedOut => {
                self.log(
                    1,
                    "ExternalControl: receiving trajectory point failed".into(),
                );
                self.motion = Motion::Stop {
                    decel: STOPJ_ACCELERATION,
                };
                self.ext_push_result(session, result::FAILURE);
                return;
            }
            Next::Point(p, mj, mt, qd, qdd) => (*p, mj, mt, qd, qdd),
        };
        let block =
            |k: usize| -> [f64; 6] { core::array::from_fn(|i| f64::from(point[6 * k + i]) / mj) };
        let (q, b2, b3) = (block(0), block(1), block(2));
        let time_s = f64::from(point[18]) / mt;
        let kind = point[20];
        let (speed, accel) = (b3[0], b3[1]);
        let ok = match kind {
            motion::SPLINE | motion::SPLINE_LEGACY => {
                let spline_type = point[19];
                let (end_qd, end_qdd) = match spline_type {
                    motion::SPLINE_CUBIC => (b2, [0.0; 6]),
                    motion::SPLINE_QUINTIC => (b2, b3),
                    _ => {
                        self.ext_fail(session, "ExternalControl: unknown spline type");
                        return;
                    }
                };
                if time_s <= 0.0 {
                    self.ext_cancel_point(
                        session,
                        "Spline time shouldn't be zero as it would require infinite velocity to reach the target. Canceling motion.",
                    );
                    return;
                }
                let start = self.q;
                if (0..6).any(|i| (q[i] - start[i]).abs() / time_s > JOINT_IGNORE_SPEED) {
                    self.ext_cancel_point(
                        session,
                        "ExternalControl: spline point exceeds the joint velocity limits",
                    );
                    return;
                }
                let quintic = spline_type == motion::SPLINE_QUINTIC;
                let coeffs = spline_coefficients(
                    &start, &start_qd, &start_qdd, &q, &end_qd, &end_qdd, time_s, quintic,
                );
                if let Some(e) = self.ext(session) {
                    e.spline_qd = end_qd;
                    e.spline_qdd = if quintic { end_qdd } else { [0.0; 6] };
                }
                self.motion = Motion::Spline {
                    start,
                    coeffs,
                    t: 0.0,
                    total_s: time_s,
                };
                true
            }
            motion::MOVEJ | motion::MOVEJ_POSE | motion::MOVEL | motion::MOVEL_JOINT => {
                if let Some(e) = self.ext(session) {
                    e.spline_qd = [0.0; 6];
                    e.spline_qdd = [0.0; 6];
                }
                let target = if matches!(kind, motion::MOVEJ | motion::MOVEL_JOINT) {
                    Target::Joints(q)
                } else {
                    Target::Pose(q)
                };
                let joint_move = matches!(kind, motion::MOVEJ | motion::MOVEJ_POSE);
                if joint_move && time_s > 0.0 {
                    self.begin_timed_movej(target, time_s)
                } else {
                    let (a, v) = match (accel > 0.0, speed > 0.0, joint_move) {
                        (true, true, _) => (accel, speed),
                        (_, _, true) => (1.4, 1.05),
                        (_, _, false) => (1.2, 0.25),
                    };
                    let s = if joint_move {
                        Statement::MoveJ {
                            target,
                            accel: a,
                            speed: v,
                        }
                    } else {
                        Statement::MoveL {
                            target,
                            accel: a,
                            speed: v,
                        }
                    };
                    self.begin_motion(&s, inputs)
                }
            }
            other => {
                self.ext_fail(
                    session,
                    &format!("ExternalControl: trajectory point type {other} is not emulated by this simulator"),
                );
                return;
            }
        };
        if !ok {
            // A runtime error ended the program.
            return;
        }
        if let Some(e) = self.ext(session) {
            e.waiting_motion = true;
        }
    }

    fn ext_fail(&mut self, session: u64, text: &str) {
        self.log(1, text.into());
        if let Some(e) = self.ext(session) {
            e.trajectory_running = false;
            e.points_left = 0;
            e.queue.clear();
        }
        self.motion = Motion::Stop {
            decel: STOPJ_ACCELERATION,
        };
        self.ext_push_result(session, result::FAILURE);
    }

    fn ext_cancel_point(&mut self, session: u64, text: &str) {
        self.log(1, text.into());
        if let Some(e) = self.ext(session) {
            e.trajectory_running = false;
            e.points_left = 0;
            e.queue.clear();
        }
        self.motion = Motion::Stop {
            decel: STOPJ_ACCELERATION,
        };
        self.ext_push_result(session, result::CANCELED);
    }

    /// `movej(q, t=time_s)`: a synchronised joint move that takes `time_s` (a quarter of it
    /// accelerating, a quarter braking), slower when the joint speed limit needs it.
    fn begin_timed_movej(&mut self, target: Target, time_s: f64) -> bool {
        let goal = match target {
            Target::Joints(q) => q,
            Target::Pose(p) => {
                let flange = pose_to_iso(&p) * self.tcp_offset.inverse();
                match self.nearest_ik(&flange) {
                    Some(q) => q,
                    None => return self.runtime_error("movej: pose not reachable"),
                }
            }
        };
        if goal.iter().any(|v| v.abs() > 2.0 * std::f64::consts::PI)
            || goal[2].abs() > std::f64::consts::PI
        {
            return self.runtime_error("movej: target outside the joint limits");
        }
        let delta: Joints = core::array::from_fn(|i| goal[i] - self.q[i]);
        let leading = delta.iter().fold(0.0_f64, |m, d| m.max(d.abs()));
        let t_acc = time_s / 4.0;
        let mut speed = leading / (time_s - t_acc);
        if speed > MAX_JOINT_SPEED_RADPS {
            self.log(
                2,
                format!(
                    "movej: {time_s} s needs {speed:.2} rad/s; slowed to the joint speed limit"
                ),
            );
            speed = MAX_JOINT_SPEED_RADPS;
        }
        let accel = speed / t_acc;
        self.motion = Motion::Joint {
            start: self.q,
            delta,
            leading,
            profile: Trapezoid::new(leading, speed, accel),
            t: 0.0,
        };
        true
    }
}

/// Polynomial coefficients `c1..c5` of a joint spline from `(q0, qd0, qdd0)` to `(q1, qd1,
/// qdd1)` in `t` seconds: cubic (Hermite: position and speed at both ends) or quintic (also
/// acceleration). Position: `q0 + c1 t + c2 t^2 + c3 t^3 + c4 t^4 + c5 t^5`.
#[allow(clippy::too_many_arguments)]
pub(super) fn spline_coefficients(
    q0: &Joints,
    qd0: &Joints,
    qdd0: &Joints,
    q1: &Joints,
    qd1: &Joints,
    qdd1: &Joints,
    t: f64,
    quintic: bool,
) -> [Joints; 5] {
    let mut c = [[0.0; 6]; 5];
    for i in 0..6 {
        let d = q1[i] - q0[i];
        if quintic {
            let t2 = t * t;
            c[0][i] = qd0[i];
            c[1][i] = 0.5 * qdd0[i];
            c[2][i] =
                (20.0 * d - (8.0 * qd1[i] + 12.0 * qd0[i]) * t - (3.0 * qdd0[i] - qdd1[i]) * t2)
                    / (2.0 * t2 * t);
            c[3][i] = (-30.0 * d
                + (14.0 * qd1[i] + 16.0 * qd0[i]) * t
                + (3.0 * qdd0[i] - 2.0 * qdd1[i]) * t2)
                / (2.0 * t2 * t2);
            c[4][i] = (12.0 * d - 6.0 * (qd1[i] + qd0[i]) * t - (qdd0[i] - qdd1[i]) * t2)
                / (2.0 * t2 * t2 * t);
        } else {
            c[0][i] = qd0[i];
            c[1][i] = (3.0 * d - (2.0 * qd0[i] + qd1[i]) * t) / (t * t);
            c[2][i] = (-2.0 * d + (qd0[i] + qd1[i]) * t) / (t * t * t);
        }
    }
    c
}
