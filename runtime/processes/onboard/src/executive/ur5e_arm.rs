//! The executive's arm on the real driver: [`ArmDevice`] over `ur5e::Ur5eArm`'s non-blocking
//! skills, with every socket call off the cycle's thread (#25 item 5).
//!
//! Two [`IoWorker`]s own the connections: one the RTDE, URScript and dashboard sockets (a
//! state read and the skill's judgement each cycle, moves and stops), one the gripper's URCap
//! socket (one request per poll). The cycle hands each call over and waits for the answer only
//! up to [`ArmIoSettings::wait`]; what misses it is taken in a later cycle. So a gripper that
//! does not answer for 2 s, or a lost RTDE link whose dashboard `stop` waits 2 s for its reply,
//! no longer holds up the 50 Hz base loop that runs in the same thread. The cycle judges the
//! silence itself, on its own clock: no arm state for [`ArmIoSettings::stale_after`] is a lost
//! link (the executive stops the base), and a gripper job unanswered past its deadline is a
//! gripper fault.
//!
//! On a simulated clock the wait is long ([`ArmIoSettings::for_clock`]): nothing advances the
//! clock while the cycle waits, so every call is answered within it and a run is the same as
//! with the calls made in the cycle (the closed-loop tests and the replays rely on that).

use std::time::Duration;

use ur5e::gripper::{GripperJob, GripperProgress, RobotiqGripper};
use ur5e::{GripOutcome, GripperAction, SkillError, SkillOutcome, SkillProgress, Ur5eArm};
use ur5e_kin::Joints;

use super::io_worker::{Call, IoWorker};
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

/// How the cycle waits for the arm's I/O threads.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ArmIoSettings {
    /// Longest wait of the cycle for one answer (wall time).
    pub wait: Duration,
    /// No arm state for this long (cycle clock) is a lost link.
    pub stale_after: Duration,
    /// A gripper job with no final answer this long after it started (cycle clock) has failed:
    /// the job's own phases end within two gripper timeouts, a reply within the socket's
    /// timeout, so this is only reached when the gripper's thread is stuck.
    pub gripper_deadline: Duration,
}

impl ArmIoSettings {
    /// The settings for a cycle on a simulated clock or not: on the wall clock a wait of 1 ms
    /// (half the 2 ms cycle); on a simulated clock 10 s (time stands while the cycle waits, so
    /// waiting costs nothing and keeps runs reproducible). `stale_after` is the driver's own,
    /// `io_timeout` its sockets' reply timeout.
    pub fn for_clock(
        simulated: bool,
        stale_after: Duration,
        motion: &ArmMotionSettings,
        io_timeout: Duration,
    ) -> Self {
        Self {
            wait: if simulated {
                Duration::from_secs(10)
            } else {
                Duration::from_millis(1)
            },
            stale_after,
            gripper_deadline: 2 * motion.gripper_timeout + io_timeout + Duration::from_millis(500),
        }
    }
}

/// A request to the RTDE / URScript / dashboard thread. `generation` ties a skill's answers to
/// the skill that asked.
#[derive(Debug, Clone, Copy)]
enum ArmRequest {
    /// Read the newest state; judge the skill in progress if `poll`.
    Cycle {
        now: Duration,
        poll: bool,
        generation: u32,
    },
    /// Start a joint move.
    Move {
        q: Joints,
        now: Duration,
        generation: u32,
    },
    /// Stop the arm.
    Stop { now: Duration },
}

#[derive(Debug, Clone, Copy)]
enum ArmAnswer {
    Cycle {
        now: Duration,
        state: Result<ArmSnapshot, ArmFault>,
        skill: Option<(u32, Result<SkillStatus, ArmFault>)>,
    },
    Started(u32, Result<(), ArmFault>),
    Stopped,
}

#[derive(Debug, Clone, Copy)]
enum GripperRequest {
    Start {
        close: bool,
        now: Duration,
        generation: u32,
    },
    Poll {
        now: Duration,
    },
}

/// An answer of the gripper's thread (to a start, or to the job's poll), with the skill's
/// generation (`None`: no job to poll).
#[derive(Debug, Clone, Copy)]
struct GripperAnswer(Option<u32>, Result<SkillStatus, ArmFault>);

/// The skill the cycle believes runs.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Active {
    Idle,
    Arm,
    Gripper { started: Duration },
}

/// The UR5e through its driver, every socket call on the arm's own threads.
pub struct Ur5eDevice {
    arm: IoWorker<ArmRequest, ArmAnswer>,
    gripper: IoWorker<GripperRequest, GripperAnswer>,
    io: ArmIoSettings,
    /// The newest state (before the first: the default, robot mode 0).
    snapshot: ArmSnapshot,
    /// Cycle time of the newest state answered, or of the first cycle before any.
    fresh_at: Option<Duration>,
    /// The driver's last state read failed so (a lost link: the driver repeats it).
    read_fault: Option<ArmFault>,
    active: Active,
    /// Generation of the skill in `active` (answers of older skills are dropped).
    generation: u32,
    /// A result for the skill in `active`, not yet given to `poll`.
    result: Option<Result<SkillStatus, ArmFault>>,
    /// A move or stop not yet handed over (the thread was busy); a stop replaces a move.
    queued: Option<ArmRequest>,
    /// A gripper start not yet handed over.
    gripper_queued: Option<GripperRequest>,
    /// Calls whose answer missed the wait, per thread (arm, gripper).
    late: (u64, u64),
}

impl std::fmt::Debug for Ur5eDevice {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Ur5eDevice")
            .field("active", &self.active)
            .field("late", &self.late)
            .finish_non_exhaustive()
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

fn read_state(arm: &mut Ur5eArm, now: Duration) -> Result<ArmSnapshot, ArmFault> {
    match arm.update_at(now) {
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

fn status_of(progress: SkillProgress) -> SkillStatus {
    match progress {
        SkillProgress::Running => SkillStatus::Running,
        SkillProgress::Idle => SkillStatus::Done { object_held: false },
        SkillProgress::Done(outcome) => SkillStatus::Done {
            object_held: matches!(
                outcome,
                SkillOutcome::Gripper(GripOutcome::ObjectWhileClosing)
            ),
        },
    }
}

/// The RTDE / URScript / dashboard thread's service.
fn serve_arm(arm: &mut Ur5eArm, s: &ArmMotionSettings, request: ArmRequest) -> ArmAnswer {
    match request {
        ArmRequest::Cycle {
            now,
            poll,
            generation,
        } => {
            let state = read_state(arm, now);
            let skill = poll.then(|| {
                let judged = arm.poll(now).map(status_of).map_err(|e| {
                    log::warn!("arm: skill failed: {e}");
                    fault(&e)
                });
                (generation, judged)
            });
            ArmAnswer::Cycle { now, state, skill }
        }
        ArmRequest::Move { q, now, generation } => ArmAnswer::Started(
            generation,
            arm.start_move_joints(
                q,
                s.joint_speed_radps,
                s.joint_accel_radps2,
                s.move_timeout,
                now,
            )
            .map_err(|e| {
                log::warn!("arm: move refused: {e}");
                fault(&e)
            }),
        ),
        ArmRequest::Stop { now } => {
            // Best effort; on a lost link the driver has already sent stopj by every channel.
            if let Err(e) = arm.start_stop(s.stop_decel_radps2, Duration::from_secs(2), now) {
                log::warn!("arm: stop: {e}");
            }
            ArmAnswer::Stopped
        }
    }
}

/// The gripper thread's state: the connection and the job in progress.
struct GripperService {
    gripper: Option<RobotiqGripper>,
    job: Option<(u32, GripperJob)>,
    timeout: Duration,
}

impl GripperService {
    fn serve(&mut self, request: GripperRequest) -> GripperAnswer {
        match request {
            GripperRequest::Start {
                close,
                now,
                generation,
            } => {
                if self.gripper.is_none() {
                    return GripperAnswer(Some(generation), Err(ArmFault::GripperFault));
                }
                let action = if close {
                    GripperAction::Close
                } else {
                    GripperAction::Open
                };
                self.job = Some((generation, action.job(self.timeout, now)));
                GripperAnswer(Some(generation), Ok(SkillStatus::Running))
            }
            GripperRequest::Poll { now } => {
                let (Some(g), Some((generation, job))) = (self.gripper.as_mut(), self.job.as_mut())
                else {
                    return GripperAnswer(None, Err(ArmFault::GripperFault));
                };
                let generation = *generation;
                let status = match job.poll(g, now) {
                    Ok(GripperProgress::Pending) => {
                        return GripperAnswer(Some(generation), Ok(SkillStatus::Running));
                    }
                    Ok(GripperProgress::Activated) => Ok(SkillStatus::Done { object_held: false }),
                    Ok(GripperProgress::Moved(o)) => Ok(SkillStatus::Done {
                        object_held: o == GripOutcome::ObjectWhileClosing,
                    }),
                    Err(e) => {
                        log::warn!("arm: gripper failed: {e}");
                        Err(ArmFault::GripperFault)
                    }
                };
                self.job = None;
                GripperAnswer(Some(generation), status)
            }
        }
    }
}

impl Ur5eDevice {
    /// Moves a connected arm onto its I/O threads (`ur5e-arm-io` and `ur5e-gripper-io`).
    pub fn new(
        mut arm: Ur5eArm,
        settings: ArmMotionSettings,
        io: ArmIoSettings,
    ) -> std::io::Result<Self> {
        let mut gripper = GripperService {
            gripper: arm.take_gripper(),
            job: None,
            timeout: settings.gripper_timeout,
        };
        let arm_worker = IoWorker::spawn("ur5e-arm-io", io.wait, move |r| {
            serve_arm(&mut arm, &settings, r)
        })?;
        let gripper_worker =
            IoWorker::spawn("ur5e-gripper-io", io.wait, move |r| gripper.serve(r))?;
        Ok(Self {
            arm: arm_worker,
            gripper: gripper_worker,
            io,
            snapshot: ArmSnapshot::default(),
            fresh_at: None,
            read_fault: None,
            active: Active::Idle,
            generation: 0,
            result: None,
            queued: None,
            gripper_queued: None,
            late: (0, 0),
        })
    }

    /// Calls whose answer missed the cycle's wait so far (arm thread, gripper thread).
    pub fn late_answers(&self) -> (u64, u64) {
        self.late
    }

    fn take_arm(&mut self, answer: ArmAnswer) {
        let ours =
            |generation: u32, me: &Self| generation == me.generation && me.active == Active::Arm;
        match answer {
            ArmAnswer::Cycle { now, state, skill } => {
                match state {
                    Ok(s) => {
                        self.snapshot = s;
                        self.fresh_at = Some(now);
                        self.read_fault = None;
                    }
                    Err(f) => self.read_fault = Some(f),
                }
                if let Some((generation, judged)) = skill
                    && ours(generation, self)
                {
                    self.result = Some(judged);
                }
            }
            ArmAnswer::Started(generation, Err(f)) if ours(generation, self) => {
                self.result = Some(Err(f));
            }
            ArmAnswer::Started(..) | ArmAnswer::Stopped => {}
        }
    }

    fn take_gripper(&mut self, GripperAnswer(generation, status): GripperAnswer) {
        let ours =
            generation == Some(self.generation) && matches!(self.active, Active::Gripper { .. });
        // A start's `Running` says only that the job was taken.
        if ours && status != Ok(SkillStatus::Running) {
            self.result = Some(status);
        }
    }

    /// Hands `request` to the arm thread, or keeps it for when the thread is free.
    fn send_arm(&mut self, request: ArmRequest) -> Option<ArmAnswer> {
        match self.arm.call(request) {
            Call::Answered(a) => Some(a),
            Call::Pending => {
                self.late.0 += 1;
                None
            }
            // A cycle's read the busy thread cannot take is not kept: the next cycle asks.
            Call::Busy(ArmRequest::Cycle { .. }) => None,
            Call::Busy(r) => {
                self.queued = Some(r);
                None
            }
        }
    }

    fn send_gripper(&mut self, request: GripperRequest) {
        match self.gripper.call(request) {
            Call::Answered(a) => self.take_gripper(a),
            Call::Pending => self.late.1 += 1,
            Call::Busy(r @ GripperRequest::Start { .. }) => self.gripper_queued = Some(r),
            // A poll the thread cannot take now is asked again next cycle.
            Call::Busy(GripperRequest::Poll { .. }) => {}
        }
    }

    /// Ends the skill the cycle believes runs (answers to it are dropped from now on).
    fn new_skill(&mut self, active: Active) {
        self.generation = self.generation.wrapping_add(1);
        self.active = active;
        self.result = None;
    }
}

impl ArmPort for Ur5eDevice {
    fn start_move_joints(&mut self, q: &Joints, now: Duration) -> Result<(), ArmFault> {
        if matches!(self.active, Active::Gripper { .. }) {
            // As the driver: one skill at a time.
            return Err(ArmFault::SkillFailed);
        }
        self.new_skill(Active::Arm);
        let generation = self.generation;
        match self.send_arm(ArmRequest::Move {
            q: *q,
            now,
            generation,
        }) {
            Some(ArmAnswer::Started(_, Err(f))) => {
                self.new_skill(Active::Idle);
                Err(f)
            }
            Some(other) => {
                self.take_arm(other);
                Ok(())
            }
            // Taken later: a refusal comes back through `poll`.
            None => Ok(()),
        }
    }

    fn start_gripper(&mut self, close: bool, now: Duration) -> Result<(), ArmFault> {
        if self.active == Active::Arm {
            return Err(ArmFault::SkillFailed);
        }
        self.new_skill(Active::Gripper { started: now });
        let generation = self.generation;
        self.send_gripper(GripperRequest::Start {
            close,
            now,
            generation,
        });
        if let Some(Err(f)) = self.result {
            self.new_skill(Active::Idle);
            return Err(f);
        }
        Ok(())
    }

    fn poll(&mut self, now: Duration) -> Result<SkillStatus, ArmFault> {
        if let Active::Gripper { started } = self.active {
            if let Some(a) = self.gripper.late_answer() {
                self.take_gripper(a);
            }
            if let Some(start) = self.gripper_queued.take() {
                self.send_gripper(start);
            } else if self.result.is_none() {
                self.send_gripper(GripperRequest::Poll { now });
            }
            if self.result.is_none() && now.saturating_sub(started) > self.io.gripper_deadline {
                log::warn!(
                    "arm: the gripper has not answered for {:?}: gripper fault",
                    now.saturating_sub(started)
                );
                self.result = Some(Err(ArmFault::GripperFault));
            }
        }
        match self.active {
            Active::Idle => Ok(SkillStatus::Done { object_held: false }),
            _ => match self.result.take() {
                None | Some(Ok(SkillStatus::Running)) => Ok(SkillStatus::Running),
                Some(done) => {
                    self.new_skill(Active::Idle);
                    done
                }
            },
        }
    }
}

impl ArmDevice for Ur5eDevice {
    fn update(&mut self, now: Duration) -> Result<ArmSnapshot, ArmFault> {
        self.fresh_at.get_or_insert(now);
        if let Some(a) = self.arm.late_answer() {
            self.take_arm(a);
        }
        if let Some(request) = self.queued.take()
            && let Some(a) = self.send_arm(request)
        {
            self.take_arm(a);
        }
        if self.queued.is_none() && !self.arm.is_busy() {
            let request = ArmRequest::Cycle {
                now,
                poll: self.active == Active::Arm && self.result.is_none(),
                generation: self.generation,
            };
            if let Some(a) = self.send_arm(request) {
                self.take_arm(a);
            }
        }
        if let Some(f) = self.read_fault {
            return Err(f);
        }
        let silent = now.saturating_sub(self.fresh_at.unwrap_or(now));
        if silent > self.io.stale_after || self.arm.is_gone() {
            log::error!(
                "arm: no state from the arm's I/O thread for {silent:?} (limit {:?}): link lost",
                self.io.stale_after
            );
            self.read_fault = Some(ArmFault::LinkLost);
            return Err(ArmFault::LinkLost);
        }
        Ok(self.snapshot)
    }

    fn stop(&mut self, now: Duration) {
        self.new_skill(Active::Idle);
        self.gripper_queued = None;
        // Replaces a move not yet handed over.
        self.queued = None;
        if let Some(a) = self.send_arm(ArmRequest::Stop { now }) {
            self.take_arm(a);
        }
    }
}
