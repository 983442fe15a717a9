//! `arm/io`: every call the executive made on the arm and what the arm answered, one message a
//! call. It is what the mission log keeps of the RTDE samples and skill results the executive
//! acted on, and what a replay feeds back in place of the arm.

use iceoryx2::prelude::*;

use crate::MessageError;

/// Which call of the executive's arm interface a message records.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u32)]
pub enum ArmCall {
    /// Read the newest controller state (every arm cycle).
    Update = 1,
    /// Start a joint move to `joints_rad`.
    StartMoveJoints = 2,
    /// Start the gripper (`close` says which way).
    StartGripper = 3,
    /// Progress of the running skill.
    Poll = 4,
    /// Stop any motion.
    Stop = 5,
}

/// What a call came back with.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u32)]
pub enum ArmOutcome {
    /// Success (for `Poll`: see [`ArmIoMsg::status`]).
    Ok = 0,
    /// The controller link is gone.
    LinkLost = 1,
    /// Protective stop.
    ProtectiveStop = 2,
    /// Emergency stop.
    EmergencyStop = 3,
    /// A skill did not finish in time or stopped short.
    SkillFailed = 4,
    /// The gripper did not answer or reported a fault.
    GripperFault = 5,
}

/// [`ArmIoMsg::status`] of a `Poll` that returned: still running.
pub const ARM_STATUS_RUNNING: u32 = 0;
/// ... done, nothing held.
pub const ARM_STATUS_DONE: u32 = 1;
/// ... done, the gripper holds an object.
pub const ARM_STATUS_DONE_HOLDING: u32 = 2;

/// [`ArmIoMsg::flags`]: a program runs on the controller.
pub const ARM_FLAG_PROGRAM_RUNNING: u32 = 1;
/// [`ArmIoMsg::flags`]: protective stop.
pub const ARM_FLAG_PROTECTIVE_STOP: u32 = 2;
/// [`ArmIoMsg::flags`]: emergency stop.
pub const ARM_FLAG_EMERGENCY_STOP: u32 = 4;
/// [`ArmIoMsg::flags`]: `StartGripper` closes (else opens).
pub const ARM_FLAG_CLOSE: u32 = 8;
/// [`ArmIoMsg::flags`]: the UR `safety_mode` in bits 8 to 15 (0: not reported; logs before
/// `log_format` 3 have 0 there).
pub const ARM_SAFETY_MODE_SHIFT: u32 = 8;

/// One call on the arm (`arm/io`).
#[derive(Clone, Copy, Debug, Default, PartialEq, ZeroCopySend)]
#[repr(C)]
#[type_name("grop_ipc::ArmIoMsg/v1")]
pub struct ArmIoMsg {
    /// Counter, increasing.
    pub seq: u64,
    /// Time of the call on the runtime clock, nanoseconds.
    pub stamp_ns: u64,
    /// [`ArmCall`] as an integer; read with [`ArmIoMsg::call`].
    pub call: u32,
    /// [`ArmOutcome`] as an integer; read with [`ArmIoMsg::outcome`].
    pub outcome: u32,
    /// For `Poll`: one of the `ARM_STATUS_*` values.
    pub status: u32,
    /// `ARM_FLAG_*` bits: the state of an `Update`, the direction of a `StartGripper`.
    pub flags: u32,
    /// Robot mode code of an `Update`.
    pub robot_mode: i32,
    /// Zero.
    pub reserved: u32,
    /// `Update`: joint positions read; `StartMoveJoints`: the target (rad).
    pub joints_rad: [f64; 6],
    /// `Update`: joint speeds (rad/s).
    pub joint_speeds_radps: [f64; 6],
    /// `Update`: flange pose in the arm base frame (x, y, z, rotation vector).
    pub flange_pose: [f64; 6],
}

impl ArmIoMsg {
    /// The call, checked.
    pub fn call(&self) -> Result<ArmCall, MessageError> {
        Ok(match self.call {
            1 => ArmCall::Update,
            2 => ArmCall::StartMoveJoints,
            3 => ArmCall::StartGripper,
            4 => ArmCall::Poll,
            5 => ArmCall::Stop,
            value => {
                return Err(MessageError::UnknownEnumValue {
                    message: "ArmIoMsg",
                    field: "call",
                    value,
                });
            }
        })
    }

    /// The outcome, checked.
    pub fn outcome(&self) -> Result<ArmOutcome, MessageError> {
        Ok(match self.outcome {
            0 => ArmOutcome::Ok,
            1 => ArmOutcome::LinkLost,
            2 => ArmOutcome::ProtectiveStop,
            3 => ArmOutcome::EmergencyStop,
            4 => ArmOutcome::SkillFailed,
            5 => ArmOutcome::GripperFault,
            value => {
                return Err(MessageError::UnknownEnumValue {
                    message: "ArmIoMsg",
                    field: "outcome",
                    value,
                });
            }
        })
    }

    /// Every number is finite.
    pub fn is_finite(&self) -> bool {
        self.joints_rad
            .iter()
            .chain(&self.joint_speeds_radps)
            .chain(&self.flange_pose)
            .all(|v| v.is_finite())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn layout_is_fixed_and_enums_are_checked() {
        assert_eq!(size_of::<ArmIoMsg>(), 40 + 3 * 48);
        let mut m = ArmIoMsg {
            seq: 1,
            stamp_ns: 2,
            call: 4,
            status: ARM_STATUS_DONE,
            robot_mode: 7,
            ..ArmIoMsg::default()
        };
        assert_eq!(m.call(), Ok(ArmCall::Poll));
        assert_eq!(m.outcome(), Ok(ArmOutcome::Ok));
        assert!(m.is_finite());
        m.call = 0;
        assert!(m.call().is_err());
        m.outcome = 6;
        assert!(m.outcome().is_err());
        m.flange_pose[3] = f64::INFINITY;
        assert!(!m.is_finite());
    }
}
