//! UR5e drivers: RTDE client, dashboard client, URScript sender, Robotiq gripper, unload skills.
//!
//! The onboard executive talks to the arm through [`Ur5eArm`], whose skills detect completion,
//! time out, and return protective stops and lost connections as [`SkillError`]s:
//!
//! ```no_run
//! use std::time::Duration;
//! use ur5e::{ArmConfig, Ur5eArm};
//!
//! let mut arm = Ur5eArm::connect(ArmConfig::default())?;
//! arm.open_gripper(Duration::from_secs(3))?;
//! arm.move_joints([0.0, -1.57, 1.57, -1.57, -1.57, 0.0], 1.05, 1.4, Duration::from_secs(10))?;
//! arm.close_gripper(Duration::from_secs(3))?;
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! The lower layers are usable on their own: [`rtde::RtdeClient`] (protocol 2, recipes decoded
//! by the types the controller returns, newest package wins, text messages logged),
//! [`dashboard::DashboardClient`] (port 29999, exact reply strings), [`script::ScriptSender`]
//! (URScript on 30002) and [`gripper::RobotiqGripper`] (Robotiq URCap socket, 63352).
//! Protocol facts and their sources: `docs/ur5e.md`.

pub mod arm;
pub mod dashboard;
pub mod gripper;
mod line_link;
pub mod pose;
pub mod rtde;
pub mod script;
pub mod transport;

pub use arm::{
    ArmConfig, ArmConnectError, ArmState, GripperAction, Joints, MoveReport, SkillError,
    SkillOutcome, SkillProgress, Ur5eArm,
};
pub use gripper::GripOutcome;
pub use line_link::MAX_LINE_LEN;
pub use pose::TcpPose;
