//! The arm's state as the RTDE stream reports it, decoded from each data package.

use std::time::Duration;

use super::{Joints, RUNTIME_PLAYING, Ur5eArm};
use crate::dashboard::{RobotMode, SafetyMode};
use crate::pose::TcpPose;
use crate::rtde::RtdeValue;

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

    /// Motion may be commanded: robot mode RUNNING, no protective or emergency stop.
    pub fn ready_for_motion(&self) -> bool {
        self.robot_mode == RobotMode::Running.code()
            && !self.protective_stopped()
            && !self.emergency_stopped()
    }

    /// Largest joint distance to `q_rad` (rad).
    pub fn max_joint_error_rad(&self, q_rad: &Joints) -> f64 {
        self.q_rad
            .iter()
            .zip(q_rad)
            .fold(0.0_f64, |m, (a, b)| m.max((a - b).abs()))
    }

    /// No program runs and every joint is slower than `settled_speed_radps`.
    pub fn at_rest(&self, settled_speed_radps: f64) -> bool {
        !self.program_running() && self.max_joint_speed_radps() < settled_speed_radps
    }

    /// Controller time as a [`Duration`] (zero if the timestamp is not a finite, non-negative
    /// number).
    pub fn controller_time(&self) -> Duration {
        Duration::try_from_secs_f64(self.timestamp_s).unwrap_or(Duration::ZERO)
    }
}

fn vec6(v: &RtdeValue) -> [f64; 6] {
    match v {
        RtdeValue::Vector6d(x) => *x,
        _ => [f64::NAN; 6],
    }
}

impl Ur5eArm {
    pub(super) fn decode_state(&mut self) {
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
}
