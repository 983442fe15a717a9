//! The skills as state machines the caller advances: `start_*`, then [`Ur5eArm::poll`] once per
//! cycle, every timeout on the caller's clock.

use std::time::Duration;

use super::{JOINT_LIMIT_RAD, Joints, MAX_JOINT_SPEED_RADPS, MoveReport, SkillError, Ur5eArm};
use crate::dashboard::RobotMode;
use crate::gripper::{GripOutcome, GripperJob, GripperProgress, RobotiqGripper};
use crate::pose::TcpPose;
use crate::script::{ScriptCommand, UrScriptProgram, WatchdogAction};

/// What [`Ur5eArm::start_gripper`] does.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum GripperAction {
    /// Activate if not active (STA != 3); nothing moves otherwise.
    Activate,
    /// Activate if needed, then open fully.
    Open,
    /// Activate if needed, then close fully with moderate force.
    Close,
}

impl GripperAction {
    /// The gripper job that does it, each phase within `timeout` from `now` (caller's clock).
    pub fn job(self, timeout: Duration, now: Duration) -> GripperJob {
        match self {
            GripperAction::Activate => GripperJob::activate(timeout, now),
            GripperAction::Open => GripperJob::activate_and_move_to(0, 255, 128, timeout, now),
            GripperAction::Close => GripperJob::activate_and_move_to(255, 255, 128, timeout, now),
        }
    }
}

/// What a finished skill achieved.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SkillOutcome {
    /// A `start_move_joints` / `start_move_linear` reached its goal and settled.
    Moved(MoveReport),
    /// A `start_stop` brought the arm to rest.
    Stopped,
    /// `GripperAction::Activate` finished.
    GripperActivated,
    /// `GripperAction::Open` / `Close` finished; [`GripOutcome::ObjectWhileClosing`] = held.
    Gripper(GripOutcome),
}

/// Where the skill stands after [`Ur5eArm::poll`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SkillProgress {
    /// No skill is in progress.
    Idle,
    /// In progress: `update_at` and `poll` again next cycle.
    Running,
    /// Finished this cycle; the arm is idle again.
    Done(SkillOutcome),
}

/// Longest wait, after a motion timed out and `stopj` was sent, for the arm to come to rest
/// before the timeout is reported (the blocking skills always waited this long, 2 s).
const STOP_AFTER_TIMEOUT_WAIT: Duration = Duration::from_secs(2);

#[derive(Debug, Clone, Copy)]
pub(super) enum Goal {
    Joints(Joints),
    Pose(TcpPose),
}

/// The skill in progress, as a state machine advanced by [`Ur5eArm::poll`].
#[derive(Debug)]
pub(super) enum Skill {
    Idle,
    Motion {
        name: &'static str,
        goal: Goal,
        timeout: Duration,
        phase: MotionPhase,
    },
    Stop {
        timeout: Duration,
        sent_at: Duration,
    },
    Gripper(GripperJob),
}

impl Skill {
    pub(super) fn name(&self) -> Option<&'static str> {
        match self {
            Skill::Idle => None,
            Skill::Motion { name, .. } => Some(name),
            Skill::Stop { .. } => Some("stop"),
            Skill::Gripper(_) => Some("gripper"),
        }
    }
}

#[derive(Debug)]
pub(super) enum MotionPhase {
    /// Another program still runs; ours is sent once it ends (so the next program seen
    /// running is ours), or `Busy` after `program_start_timeout`.
    WaitIdle {
        program: UrScriptProgram,
        since: Duration,
    },
    /// Sent; judged every cycle.
    Sent {
        sent_at: Duration,
        first_cycle: u64,
        seen_running: bool,
    },
    /// Timed out; `stopj` sent; the timeout is reported once the arm rests.
    StopAfterTimeout { since: Duration },
}

impl Ur5eArm {
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

    fn ensure_no_skill(&self) -> Result<(), SkillError> {
        match self.skill.name() {
            Some(active) => Err(SkillError::SkillInProgress { active }),
            None => Ok(()),
        }
    }

    /// Starts a motion: checks the state of the last cycle, builds the program (this may
    /// allocate) and sends it now if no program runs, or once the running one ends.
    fn start_motion(
        &mut self,
        name: &'static str,
        motion: ScriptCommand,
        goal: Goal,
        timeout: Duration,
        now: Duration,
    ) -> Result<(), SkillError> {
        self.ensure_no_skill()?;
        self.check_safety()?;
        let program = self.motion_program(motion);
        let phase = if self.state.program_running() {
            MotionPhase::WaitIdle {
                program,
                since: now,
            }
        } else {
            self.send_program(&program)?;
            MotionPhase::Sent {
                sent_at: now,
                first_cycle: self.cycles,
                seen_running: false,
            }
        };
        self.skill = Skill::Motion {
            name,
            goal,
            timeout,
            phase,
        };
        Ok(())
    }

    /// Starts `movej` to `q_rad` (speed rad/s, accel rad/s^2); done when the arm rests there.
    /// The motion must end within `timeout` of sending, on the caller's clock; `now` is the
    /// caller's time. Progress: [`Self::poll`] every cycle after [`Self::update_at`].
    pub fn start_move_joints(
        &mut self,
        q_rad: Joints,
        speed_radps: f64,
        accel_radps2: f64,
        timeout: Duration,
        now: Duration,
    ) -> Result<(), SkillError> {
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
        self.start_motion("move_joints", motion, Goal::Joints(q_rad), timeout, now)
    }

    /// Starts `movel` to `pose` (straight tool line, m/s, m/s^2); as [`Self::start_move_joints`].
    pub fn start_move_linear(
        &mut self,
        pose: TcpPose,
        speed_mps: f64,
        accel_mps2: f64,
        timeout: Duration,
        now: Duration,
    ) -> Result<(), SkillError> {
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
        self.start_motion("move_linear", motion, Goal::Pose(pose), timeout, now)
    }

    /// Sends `stopj` (replacing the running program) and replaces any skill in progress; done
    /// when the arm rests, [`SkillError::Timeout`] if not within `timeout` (caller's clock).
    pub fn start_stop(
        &mut self,
        decel_radps2: f64,
        timeout: Duration,
        now: Duration,
    ) -> Result<(), SkillError> {
        self.skill = Skill::Idle;
        self.send_stopj(decel_radps2)?;
        self.skill = Skill::Stop {
            timeout,
            sent_at: now,
        };
        Ok(())
    }

    /// Starts a gripper activation, opening or closing: one request/reply on the URCap socket
    /// per [`Self::poll`], each phase (activation, motion) within `timeout` on the caller's clock.
    pub fn start_gripper(
        &mut self,
        action: GripperAction,
        timeout: Duration,
        now: Duration,
    ) -> Result<(), SkillError> {
        self.ensure_no_skill()?;
        if self.gripper.is_none() {
            return Err(SkillError::NoGripper);
        }
        self.skill = Skill::Gripper(action.job(timeout, now));
        Ok(())
    }

    /// Takes the gripper's connection out of the arm (to drive it from another thread with
    /// [`GripperJob`]s); the arm's own gripper skill then answers [`SkillError::NoGripper`].
    pub fn take_gripper(&mut self) -> Option<RobotiqGripper> {
        self.gripper.take()
    }

    /// Judges the skill in progress on the state of the last [`Self::update_at`], at caller
    /// time `now`: `Running`, `Done` (the arm is idle again), or the error that ended it (the
    /// arm is idle again; on a motion timeout `stopj` was sent and the arm came to rest first).
    /// Checks are those of the blocking skills: protective stop -> `ProtectiveStop`; program
    /// seen running then ended: at the goal and settled -> `Done`, else `StoppedShort`; never
    /// seen running within `program_start_timeout` and not at the goal -> `ProgramNotStarted`;
    /// past the timeout -> `stopj`, then `Timeout`. No state for `stale_after` -> `ConnectionLost`.
    /// Does not allocate while a motion runs.
    pub fn poll(&mut self, now: Duration) -> Result<SkillProgress, SkillError> {
        let skill = std::mem::replace(&mut self.skill, Skill::Idle);
        if matches!(skill, Skill::Idle) {
            return Ok(SkillProgress::Idle);
        }
        if let Some(t) = self.received_at {
            let silent = now.saturating_sub(t);
            if silent > self.cfg.stale_after {
                return Err(self.connection_lost(format!(
                    "no RTDE state for {silent:?} (caller clock), limit {:?}",
                    self.cfg.stale_after
                )));
            }
        }
        // On error the skill stays Idle: it has ended.
        let (next, progress) = self.advance(skill, now)?;
        self.skill = next;
        Ok(progress)
    }

    #[allow(
        clippy::too_many_lines,
        reason = "the skill state machine: one arm per skill and phase"
    )]
    fn advance(
        &mut self,
        skill: Skill,
        now: Duration,
    ) -> Result<(Skill, SkillProgress), SkillError> {
        const RUNNING: SkillProgress = SkillProgress::Running;
        match skill {
            Skill::Idle => Ok((Skill::Idle, SkillProgress::Idle)),
            Skill::Stop { timeout, sent_at } => {
                if self.state.at_rest(self.cfg.settled_speed_radps) {
                    return Ok((Skill::Idle, SkillProgress::Done(SkillOutcome::Stopped)));
                }
                if now.saturating_sub(sent_at) > timeout {
                    return Err(SkillError::Timeout {
                        skill: "stop",
                        timeout,
                    });
                }
                Ok((Skill::Stop { timeout, sent_at }, RUNNING))
            }
            Skill::Gripper(mut job) => {
                let Some(g) = self.gripper.as_mut() else {
                    return Err(SkillError::NoGripper);
                };
                Ok(match job.poll(g, now)? {
                    GripperProgress::Pending => (Skill::Gripper(job), RUNNING),
                    GripperProgress::Activated => (
                        Skill::Idle,
                        SkillProgress::Done(SkillOutcome::GripperActivated),
                    ),
                    GripperProgress::Moved(o) => {
                        (Skill::Idle, SkillProgress::Done(SkillOutcome::Gripper(o)))
                    }
                })
            }
            Skill::Motion {
                name,
                goal,
                timeout,
                phase,
            } => {
                let phase = match phase {
                    MotionPhase::WaitIdle { program, since } => {
                        self.check_safety()?;
                        if !self.state.program_running() {
                            self.send_program(&program)?;
                            MotionPhase::Sent {
                                sent_at: now,
                                first_cycle: self.cycles,
                                seen_running: false,
                            }
                        } else if now.saturating_sub(since) > self.cfg.program_start_timeout {
                            return Err(SkillError::Busy);
                        } else {
                            MotionPhase::WaitIdle { program, since }
                        }
                    }
                    MotionPhase::Sent {
                        sent_at,
                        first_cycle,
                        seen_running,
                    } => {
                        self.check_safety()?;
                        let running = self.state.program_running();
                        let seen_running = seen_running || running;
                        let elapsed = now.saturating_sub(sent_at);
                        let report = MoveReport {
                            duration_s: elapsed.as_secs_f64(),
                            final_error: self.goal_error(&goal),
                            cycles: self.cycles - first_cycle,
                        };
                        if seen_running && !running {
                            if self.at_goal(&goal) {
                                let done = SkillProgress::Done(SkillOutcome::Moved(report));
                                return Ok((Skill::Idle, done));
                            }
                            return Err(SkillError::StoppedShort {
                                skill: name,
                                remaining: report.final_error,
                            });
                        }
                        if !seen_running && elapsed > self.cfg.program_start_timeout {
                            // A move to where the arm already is may run between two samples.
                            if self.at_goal(&goal) {
                                let done = SkillProgress::Done(SkillOutcome::Moved(report));
                                return Ok((Skill::Idle, done));
                            }
                            return Err(SkillError::ProgramNotStarted {
                                skill: name,
                                waited: elapsed,
                            });
                        }
                        if elapsed > timeout {
                            self.send_stopj(self.cfg.stop_decel_radps2)?;
                            MotionPhase::StopAfterTimeout { since: now }
                        } else {
                            MotionPhase::Sent {
                                sent_at,
                                first_cycle,
                                seen_running,
                            }
                        }
                    }
                    MotionPhase::StopAfterTimeout { since } => {
                        if self.state.at_rest(self.cfg.settled_speed_radps)
                            || now.saturating_sub(since) > STOP_AFTER_TIMEOUT_WAIT
                        {
                            return Err(SkillError::Timeout {
                                skill: name,
                                timeout,
                            });
                        }
                        MotionPhase::StopAfterTimeout { since }
                    }
                };
                Ok((
                    Skill::Motion {
                        name,
                        goal,
                        timeout,
                        phase,
                    },
                    RUNNING,
                ))
            }
        }
    }
}
