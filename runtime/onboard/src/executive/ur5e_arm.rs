//! The executive's arm on the real driver: [`ArmDevice`] over `ur5e::Ur5eArm`'s non-blocking
//! skills (one RTDE state per cycle, one skill polled per cycle, timeouts on the runtime clock).

use std::time::Duration;

use ur5e::{GripOutcome, GripperAction, SkillError, SkillOutcome, SkillProgress, Ur5eArm};
use ur5e_kin::Joints;

use super::unload::{ArmFault, ArmPort, SkillStatus};
use super::{ArmDevice, ArmSnapshot};

/// Speeds and timeouts of the unload skills.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ArmMotionSettings {
    /// Joint speed of `movej`, rad/s.
    pub joint_speed_radps: f64,
    /// Joint acceleration, rad/s^2.
    pub joint_accel_radps2: f64,
    /// A move must end within this.
    pub move_timeout: Duration,
    /// A gripper phase must end within this.
    pub gripper_timeout: Duration,
    /// Deceleration of a stop, rad/s^2.
    pub stop_decel_radps2: f64,
}

impl Default for ArmMotionSettings {
    fn default() -> Self {
        Self {
            joint_speed_radps: 1.5,
            joint_accel_radps2: 3.0,
            move_timeout: Duration::from_secs(15),
            gripper_timeout: Duration::from_secs(3),
            stop_decel_radps2: 4.0,
        }
    }
}

/// The UR5e through its driver.
pub struct Ur5eDevice {
    arm: Ur5eArm,
    settings: ArmMotionSettings,
}

impl Ur5eDevice {
    /// Wraps a connected arm.
    pub fn new(arm: Ur5eArm, settings: ArmMotionSettings) -> Self {
        Self { arm, settings }
    }
}

fn fault(e: &SkillError) -> ArmFault {
    match e {
        SkillError::ConnectionLost { .. } => ArmFault::LinkLost,
        SkillError::ProtectiveStop { .. } => ArmFault::ProtectiveStop,
        SkillError::EmergencyStop { .. } => ArmFault::EmergencyStop,
        SkillError::Gripper(_) | SkillError::NoGripper => ArmFault::GripperFault,
        _ => ArmFault::SkillFailed,
    }
}

impl ArmPort for Ur5eDevice {
    fn start_move_joints(&mut self, q: &Joints, now: Duration) -> Result<(), ArmFault> {
        let s = self.settings;
        self.arm
            .start_move_joints(
                *q,
                s.joint_speed_radps,
                s.joint_accel_radps2,
                s.move_timeout,
                now,
            )
            .map_err(|e| {
                log::warn!("arm: move refused: {e}");
                fault(&e)
            })
    }

    fn start_gripper(&mut self, close: bool, now: Duration) -> Result<(), ArmFault> {
        let action = if close {
            GripperAction::Close
        } else {
            GripperAction::Open
        };
        self.arm
            .start_gripper(action, self.settings.gripper_timeout, now)
            .map_err(|e| {
                log::warn!("arm: gripper refused: {e}");
                fault(&e)
            })
    }

    fn poll(&mut self, now: Duration) -> Result<SkillStatus, ArmFault> {
        match self.arm.poll(now) {
            Ok(SkillProgress::Running) => Ok(SkillStatus::Running),
            Ok(SkillProgress::Idle) => Ok(SkillStatus::Done { object_held: false }),
            Ok(SkillProgress::Done(outcome)) => Ok(SkillStatus::Done {
                object_held: matches!(
                    outcome,
                    SkillOutcome::Gripper(GripOutcome::ObjectWhileClosing)
                ),
            }),
            Err(e) => {
                log::warn!("arm: skill failed: {e}");
                Err(fault(&e))
            }
        }
    }
}

impl ArmDevice for Ur5eDevice {
    fn update(&mut self, now: Duration) -> Result<ArmSnapshot, ArmFault> {
        match self.arm.update_at(now) {
            Ok(s) => Ok(ArmSnapshot {
                q_rad: s.q_rad,
                qd_radps: s.qd_radps,
                flange_pose: s.tcp_pose.as_array(),
                program_running: s.program_running(),
                robot_mode: s.robot_mode,
                protective_stop: s.protective_stopped(),
                emergency_stop: s.emergency_stopped(),
                safety_mode: s.safety_mode,
            }),
            Err(e) => Err(fault(&e)),
        }
    }

    fn stop(&mut self, now: Duration) {
        // Best effort; on a lost link the driver has already sent stopj by every channel left.
        if let Err(e) =
            self.arm
                .start_stop(self.settings.stop_decel_radps2, Duration::from_secs(2), now)
        {
            log::warn!("arm: stop: {e}");
        }
    }
}
