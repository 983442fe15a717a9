//! The arm's calls as messages: [`RecordingArm`] wraps any [`ArmDevice`] and publishes every
//! call and its answer on `arm/io` (what the mission log keeps of the RTDE samples the executive
//! acted on); [`ArmIoMsg`] converts back into the answer, so a replay can stand in for the arm.

use std::time::Duration;

use grop_ipc::{
    ARM_FLAG_CLOSE, ARM_FLAG_EMERGENCY_STOP, ARM_FLAG_PROGRAM_RUNNING, ARM_FLAG_PROTECTIVE_STOP,
    ARM_SAFETY_MODE_SHIFT, ARM_STATUS_DONE, ARM_STATUS_DONE_HOLDING, ARM_STATUS_RUNNING, ArmCall,
    ArmIoMsg, ArmOutcome, IpcNode, PortError, TopicPublisher,
};
use ur5e_kin::Joints;

use super::unload::{ArmFault, ArmPort, SkillStatus};
use super::{ArmDevice, ArmSnapshot};

use grop_clock::duration_ns as ns;

/// The wire code of a fault.
pub fn outcome_of(result: Result<(), ArmFault>) -> ArmOutcome {
    match result {
        Ok(()) => ArmOutcome::Ok,
        Err(ArmFault::LinkLost) => ArmOutcome::LinkLost,
        Err(ArmFault::ProtectiveStop) => ArmOutcome::ProtectiveStop,
        Err(ArmFault::EmergencyStop) => ArmOutcome::EmergencyStop,
        Err(ArmFault::SkillFailed) => ArmOutcome::SkillFailed,
        Err(ArmFault::GripperFault) => ArmOutcome::GripperFault,
    }
}

/// The fault of a wire code (`Ok` for success).
pub fn fault_of(outcome: ArmOutcome) -> Result<(), ArmFault> {
    match outcome {
        ArmOutcome::Ok => Ok(()),
        ArmOutcome::LinkLost => Err(ArmFault::LinkLost),
        ArmOutcome::ProtectiveStop => Err(ArmFault::ProtectiveStop),
        ArmOutcome::EmergencyStop => Err(ArmFault::EmergencyStop),
        ArmOutcome::SkillFailed => Err(ArmFault::SkillFailed),
        ArmOutcome::GripperFault => Err(ArmFault::GripperFault),
    }
}

/// Fills `m` with the answer of an `update`.
pub fn put_snapshot(m: &mut ArmIoMsg, s: &ArmSnapshot) {
    m.joints_rad = s.q_rad;
    m.joint_speeds_radps = s.qd_radps;
    m.flange_pose = s.flange_pose;
    m.robot_mode = s.robot_mode;
    let flag = |on: bool, bit: u32| if on { bit } else { 0 };
    m.flags = flag(s.program_running, ARM_FLAG_PROGRAM_RUNNING)
        | flag(s.protective_stop, ARM_FLAG_PROTECTIVE_STOP)
        | flag(s.emergency_stop, ARM_FLAG_EMERGENCY_STOP)
        | (u32::try_from(s.safety_mode).unwrap_or(0) & 0xff) << ARM_SAFETY_MODE_SHIFT;
}

/// The answer of an `update` recorded in `m`.
pub fn snapshot_of(m: &ArmIoMsg) -> ArmSnapshot {
    ArmSnapshot {
        q_rad: m.joints_rad,
        qd_radps: m.joint_speeds_radps,
        flange_pose: m.flange_pose,
        program_running: m.flags & ARM_FLAG_PROGRAM_RUNNING != 0,
        robot_mode: m.robot_mode,
        protective_stop: m.flags & ARM_FLAG_PROTECTIVE_STOP != 0,
        emergency_stop: m.flags & ARM_FLAG_EMERGENCY_STOP != 0,
        safety_mode: ((m.flags >> ARM_SAFETY_MODE_SHIFT) & 0xff) as i32,
    }
}

/// The wire code of a skill status.
pub fn status_code(status: SkillStatus) -> u32 {
    match status {
        SkillStatus::Running => ARM_STATUS_RUNNING,
        SkillStatus::Done { object_held: false } => ARM_STATUS_DONE,
        SkillStatus::Done { object_held: true } => ARM_STATUS_DONE_HOLDING,
    }
}

/// The skill status of a wire code (unknown codes read as running: the caller's timeout acts).
pub fn status_of(code: u32) -> SkillStatus {
    match code {
        ARM_STATUS_DONE => SkillStatus::Done { object_held: false },
        ARM_STATUS_DONE_HOLDING => SkillStatus::Done { object_held: true },
        _ => SkillStatus::Running,
    }
}

/// An [`ArmDevice`] that publishes every call on `arm/io` (publishing never blocks; a failed
/// publish is counted, the call goes through regardless).
pub struct RecordingArm<A: ArmDevice> {
    inner: A,
    out: TopicPublisher<ArmIoMsg>,
    seq: u64,
    published: u64,
    failed: u64,
}

impl<A: ArmDevice> RecordingArm<A> {
    /// Wraps `inner`, publishing in `node`.
    pub fn new(inner: A, node: &IpcNode) -> Result<Self, PortError> {
        Ok(Self {
            inner,
            out: node.publisher()?,
            seq: 0,
            published: 0,
            failed: 0,
        })
    }

    /// Messages published so far, and publishes that failed.
    pub fn published(&self) -> (u64, u64) {
        (self.published, self.failed)
    }

    /// The wrapped device.
    pub fn inner(&self) -> &A {
        &self.inner
    }

    fn emit(&mut self, call: ArmCall, now: Duration, fill: impl FnOnce(&mut ArmIoMsg)) {
        self.seq += 1;
        let seq = self.seq;
        match self.out.publish_with(|m| {
            m.seq = seq;
            m.stamp_ns = ns(now);
            m.call = call as u32;
            fill(m);
        }) {
            Ok(_) => self.published += 1,
            Err(_) => self.failed += 1,
        }
    }
}

impl<A: ArmDevice> ArmPort for RecordingArm<A> {
    fn start_move_joints(&mut self, q: &Joints, now: Duration) -> Result<(), ArmFault> {
        let result = self.inner.start_move_joints(q, now);
        self.emit(ArmCall::StartMoveJoints, now, |m| {
            m.joints_rad = *q;
            m.outcome = outcome_of(result) as u32;
        });
        result
    }

    fn start_gripper(&mut self, close: bool, now: Duration) -> Result<(), ArmFault> {
        let result = self.inner.start_gripper(close, now);
        self.emit(ArmCall::StartGripper, now, |m| {
            m.flags = if close { ARM_FLAG_CLOSE } else { 0 };
            m.outcome = outcome_of(result) as u32;
        });
        result
    }

    fn poll(&mut self, now: Duration) -> Result<SkillStatus, ArmFault> {
        let result = self.inner.poll(now);
        self.emit(ArmCall::Poll, now, |m| match result {
            Ok(status) => m.status = status_code(status),
            Err(f) => m.outcome = outcome_of(Err(f)) as u32,
        });
        result
    }
}

impl<A: ArmDevice> ArmDevice for RecordingArm<A> {
    fn update(&mut self, now: Duration) -> Result<ArmSnapshot, ArmFault> {
        let result = self.inner.update(now);
        self.emit(ArmCall::Update, now, |m| match &result {
            Ok(s) => put_snapshot(m, s),
            Err(f) => m.outcome = outcome_of(Err(*f)) as u32,
        });
        result
    }

    fn stop(&mut self, now: Duration) {
        self.inner.stop(now);
        self.emit(ArmCall::Stop, now, |_| {});
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn answers_survive_the_wire() {
        for f in [
            Ok(()),
            Err(ArmFault::LinkLost),
            Err(ArmFault::ProtectiveStop),
            Err(ArmFault::EmergencyStop),
            Err(ArmFault::SkillFailed),
            Err(ArmFault::GripperFault),
        ] {
            assert_eq!(fault_of(outcome_of(f)), f);
        }
        for s in [
            SkillStatus::Running,
            SkillStatus::Done { object_held: false },
            SkillStatus::Done { object_held: true },
        ] {
            assert_eq!(status_of(status_code(s)), s);
        }
        let snap = ArmSnapshot {
            q_rad: [0.1, 0.2, 0.3, 0.4, 0.5, 0.6],
            qd_radps: [1.0; 6],
            flange_pose: [0.3, 0.2, 0.1, 0.0, 3.1, 0.0],
            program_running: true,
            robot_mode: 7,
            protective_stop: false,
            emergency_stop: true,
            safety_mode: 5,
        };
        let mut m = ArmIoMsg::default();
        put_snapshot(&mut m, &snap);
        assert_eq!(snapshot_of(&m), snap);
    }
}
