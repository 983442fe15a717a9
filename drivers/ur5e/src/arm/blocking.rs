//! The blocking calls, for tools and tests: a skill started, then run to its end on the arm's
//! own clock, one RTDE cycle at a time.

use std::time::{Duration, Instant};

use super::{GripperAction, Joints, SkillError, SkillOutcome, SkillProgress, Ur5eArm};
use crate::dashboard::RobotMode;
use crate::gripper::GripOutcome;
use crate::pose::TcpPose;

/// How a finished move ended.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MoveReport {
    /// Time from sending the program to done (s), on the clock the skill was run on (the
    /// caller's for `start_*` + `poll`, the arm's own for the blocking calls).
    pub duration_s: f64,
    /// Remaining error at the end (rad for joints, m for linear).
    pub final_error: f64,
    /// State cycles observed.
    pub cycles: u64,
}

impl Ur5eArm {
    /// Runs the skill just started to its end on the arm's own clock, one RTDE cycle at a time.
    fn finish_blocking(&mut self) -> Result<SkillOutcome, SkillError> {
        loop {
            self.update()?;
            match self.poll(self.own_now())? {
                SkillProgress::Running => {}
                SkillProgress::Done(outcome) => return Ok(outcome),
                SkillProgress::Idle => {
                    unreachable!("finish_blocking is only called with a skill in progress")
                }
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
        self.update()?;
        self.start_move_joints(q_rad, speed_radps, accel_radps2, timeout, self.own_now())?;
        self.finish_move()
    }

    /// `movel` to `pose` (straight tool line) and waits until the arm rests there.
    pub fn move_linear(
        &mut self,
        pose: TcpPose,
        speed_mps: f64,
        accel_mps2: f64,
        timeout: Duration,
    ) -> Result<MoveReport, SkillError> {
        self.update()?;
        self.start_move_linear(pose, speed_mps, accel_mps2, timeout, self.own_now())?;
        self.finish_move()
    }

    fn finish_move(&mut self) -> Result<MoveReport, SkillError> {
        match self.finish_blocking()? {
            SkillOutcome::Moved(report) => Ok(report),
            other => unreachable!("a motion skill ended in {other:?}"),
        }
    }

    /// Stops any motion (`stopj`, replacing the running program) and waits until the arm rests.
    pub fn stop(&mut self, decel_radps2: f64, timeout: Duration) -> Result<(), SkillError> {
        self.start_stop(decel_radps2, timeout, self.own_now())?;
        self.finish_blocking().map(|_| ())
    }

    fn grip_blocking(
        &mut self,
        action: GripperAction,
        timeout: Duration,
    ) -> Result<GripOutcome, SkillError> {
        self.start_gripper(action, timeout, self.own_now())?;
        match self.finish_blocking()? {
            SkillOutcome::Gripper(outcome) => Ok(outcome),
            other => unreachable!("a gripper move ended in {other:?}"),
        }
    }

    /// Opens the gripper (activating it first if needed).
    pub fn open_gripper(&mut self, timeout: Duration) -> Result<GripOutcome, SkillError> {
        self.grip_blocking(GripperAction::Open, timeout)
    }

    /// Closes the gripper (activating it first if needed); [`GripOutcome::ObjectWhileClosing`]
    /// means an object is held.
    pub fn close_gripper(&mut self, timeout: Duration) -> Result<GripOutcome, SkillError> {
        self.grip_blocking(GripperAction::Close, timeout)
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
