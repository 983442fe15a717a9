//! The mission core: every decision of the executive, as one pure function of what the shell
//! read in a cycle.
//!
//! [`MissionCore::update`] takes [`CycleInputs`] (time, the base's reading and its last tick,
//! the arm's state and the result of the skill in flight, pose fixes, plans, planner heartbeats,
//! the planning worker's answer, and the scan, collision-monitor and operator-enable slots the
//! lidar and safety work fill in) and writes [`CycleOutputs`] (one velocity, one arm command,
//! at most one worker job, at most one plan request, the events in a bounded list, the abort).
//! It opens no port, calls no device and allocates nothing: tests drive it cycle by cycle with
//! plain values ([`super::shell`] is the process around it, like ros2_control's read / update /
//! write). Leg phases (path, follow, align, settle, dock, back out) live in [`super::legs`].

use std::sync::Arc;
use std::time::Duration;

use grop_ipc::{
    EventKind, EventMsg, LoadRequestMsg, PoseFixKind, ProcessRole, ReplanReason, ReplanRequestMsg,
    TaskStep, TaskStepKind,
};
use motion_control::Twist;
use motion_control::follower::PathFollower;
use planar::Pose2;
use rmp_base::{BaseError, BaseMode, Tick};
use ur5e_kin::Joints;
use world::nav::OccupancyGrid;

use super::cycle::{ArmCommand, CycleInputs, CycleOutputs, MonitorMode};
use super::unload::{
    ArmFault, ArmPort, SkillStatus, TrayGeometry, UnloadFailure, UnloadProgress, UnloadSequence,
};
use super::worker::{Answer, Job, MAX_PATH_POINTS};
use super::{AbortReason, ExecutiveConfig, MAX_TRAY_SLOTS, MissionState};
use crate::localisation::{FixOutcome, Localiser};
pub(super) use grop_clock::duration_ns as ns;

/// The arm must reach its carry pose within this.
const PARKING_TIMEOUT: Duration = Duration::from_secs(20);

/// Where the arm is on its way to the carry pose.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Parking {
    /// Not asked yet.
    NotStarted,
    /// Moving since then.
    Moving { since: Duration },
    /// In the carry pose.
    Parked,
}

/// Most mission phases one base cycle runs through.
const MAX_PHASES_PER_UPDATE: usize = 8;

/// Counters the core keeps.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct CoreStats {
    /// Unloads that succeeded.
    pub unloads_ok: u32,
    /// Unloads that failed.
    pub unloads_failed: u32,
    /// Plans accepted.
    pub plans: u32,
    /// Times the collision monitor held the base (stop zone or stale scan).
    pub monitor_holds: u32,
    /// Stalls (motion sent, none measured).
    pub stalls: u32,
    /// Scan-to-map alignments taken into the estimate.
    pub alignments: u32,
    /// Velocities the core's own laws produced outside what the robot can do (not finite, or
    /// above the robot file's speed or yaw rate: nonsense in an input) and that were cut to it.
    pub bounded: u32,
    /// Pose fixes refused for a pose off the map.
    pub off_map_fixes: u32,
}

/// `robot` with its footprint grown by `margin_m` on every side.
/// Step progress.
#[derive(Debug, Clone)]
pub(super) enum Phase {
    /// Asked for the path of this leg.
    PathRequested { id: u64, since: Duration },
    /// Following the path.
    Following { deadline: Duration },
    /// Turning to the goal heading.
    Aligning { deadline: Duration },
    /// Standing still before the step counts as reached.
    Settling { until: Duration },
    /// Waiting for the objects to be loaded.
    Loading { until: Duration },
    /// At the table, waiting for a table-relative fix.
    AwaitTableFix { since: Duration },
    /// Backing straight out from the table before the next leg.
    Reversing {
        start: Pose2,
        distance_m: f64,
        deadline: Duration,
    },
    /// The worker plans the unload's arm motions.
    PlanningArm {
        id: u64,
        since: Duration,
        slot: usize,
    },
    /// Arm at work (the sequence lives in `MissionCore::unload`, allocated once).
    Unloading,
}

/// The arm as the unload sequence sees it inside an update: a start becomes the cycle's
/// [`ArmCommand`]; a poll reads the skill result the shell passed in.
struct CommandArm<'a> {
    skill: Option<Result<SkillStatus, ArmFault>>,
    command: &'a mut ArmCommand,
}

impl ArmPort for CommandArm<'_> {
    fn start_move_joints(&mut self, q: &Joints, _now: Duration) -> Result<(), ArmFault> {
        *self.command = ArmCommand::MoveJoints(*q);
        self.skill = None;
        Ok(())
    }

    fn start_gripper(&mut self, close: bool, _now: Duration) -> Result<(), ArmFault> {
        *self.command = ArmCommand::Gripper(close);
        self.skill = None;
        Ok(())
    }

    fn poll(&mut self, _now: Duration) -> Result<SkillStatus, ArmFault> {
        // No result yet: the skill was started this cycle or the shell has not polled it.
        self.skill.take().unwrap_or(Ok(SkillStatus::Running))
    }
}

/// Writes a short event text without allocating.
pub(super) fn text(
    args: std::fmt::Arguments<'_>,
) -> heapless::String<{ grop_ipc::EVENT_DETAIL_CAPACITY }> {
    use std::fmt::Write;
    let mut s = heapless::String::new();
    // Too long: cut (the message would be cut to the capacity anyway).
    let _ = s.write_fmt(args);
    s
}

/// The executive's decisions.
pub struct MissionCore {
    pub(super) config: ExecutiveConfig,
    pub(super) grid: Arc<OccupancyGrid>,
    pub(super) tray: TrayGeometry,
    pub(super) localiser: Localiser,
    pub(super) follower: PathFollower<MAX_PATH_POINTS>,
    /// While driving to a pre-goal: the goal the base then docks at, straight ahead.
    pub(super) dock: Option<[f64; 4]>,
    /// The last step done was at the table: back out before the next leg.
    pub(super) at_table: bool,
    /// The arm's way to its carry pose (once, while the first plan is asked for, before the
    /// base first drives).
    pub(super) parking: Parking,
    /// Legs failed in a row.
    pub(super) failed_legs: u32,
    /// Plans refused in a row.
    pub(super) plans_refused: u32,
    /// The unload in progress (in place: a new one overwrites it, nothing is allocated).
    pub(super) unload: Option<UnloadSequence>,
    pub(super) steps: Vec<TaskStep>,
    pub(super) plan_id: u64,
    pub(super) step_index: usize,
    pub(super) phase: Option<Phase>,
    pub(super) state: MissionState,
    request_id: u64,
    /// Load requests sent (`load/request`), the last one's id.
    load_request_id: u64,
    pub(super) request_sent: Option<Duration>,
    pub(super) last_request: ReplanRequestMsg,
    /// Standing still after a localisation jump until then.
    jump_hold_until: Option<Duration>,
    /// Objects not yet placed (or given up), bit i = object i.
    remaining: u64,
    /// The task's objects, bit i = object i.
    pub(super) task_objects: u64,
    /// Tray slot -> object.
    pub(super) slots: [Option<u32>; MAX_TRAY_SLOTS],
    planner_seen: Option<Duration>,
    pub(super) next_job_id: u64,
    pub(super) velocity: Twist,
    stale_reported: bool,
    arm_stopped_sent: bool,
    mode_requested: bool,
    /// The newest skill result not yet consumed (parking reads it on base cycles).
    skill_result: Option<Result<SkillStatus, ArmFault>>,
    event_seq: u64,
    /// When the last global fix was taken in.
    global_fix_received: Option<Duration>,
    /// Fixes refused for a stamp in the future.
    future_fixes: u64,
    /// The goal of the docking stretch being driven and how near it the monitor uses its
    /// docking shape: `[x, y, range]`.
    pub(super) dock_goal: Option<[f64; 3]>,
    /// Since when the way in to the standing spot has been seen blocked at the pre-goal.
    pub(super) dock_blocked_since: Option<Duration>,
    /// The map's docking geometry: a goal the scan moves must have a free line in on the map.
    pub(super) docking: crate::docking::Docking,
    /// Since when the collision monitor has held the base (motion asked, none let through).
    pub(super) monitor_hold_since: Option<Duration>,
    /// The hold was reported.
    pub(super) hold_reported: bool,
    /// A turn in place the monitor held goes the other way round (the sign of the yaw rate)
    /// until the base drives on.
    pub(super) forced_turn: Option<f32>,
    /// Since when motion is sent and none measured.
    pub(super) stall_since: Option<Duration>,
    /// The operator's enable was taken since the executive started (nothing is armed before).
    pub(super) enabled: bool,
    /// The wait for the enable was reported.
    enable_wait_reported: bool,
    /// A latched safety stop that pauses the mission (a UR safeguard stop).
    pub(super) latch: Option<Latch>,
    /// The arm has reported robot mode RUNNING.
    pub(super) arm_running_seen: bool,
    pub(super) stats: CoreStats,
}

/// A latched safety stop that pauses the mission.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Latch {
    /// The safety mode that latched it.
    pub safety_mode: i32,
    /// When it latched.
    pub since: Duration,
    /// Its cause has cleared (the arm is back in normal mode); an enable now releases it.
    pub cleared: bool,
}

impl MissionCore {
    /// A core for `objects` objects (bits of `remaining`) on the map `grid`, with the tray
    /// solved beforehand. Allocates its step list once.
    pub fn new(
        config: ExecutiveConfig,
        grid: Arc<OccupancyGrid>,
        scene: Arc<world::Scene>,
        tray: TrayGeometry,
        objects: usize,
    ) -> Self {
        let docking = crate::docking::Docking::new(scene.as_ref().clone(), &config.robot);
        let remaining = if objects >= 64 {
            u64::MAX
        } else {
            (1u64 << objects) - 1
        };
        Self {
            localiser: Localiser::new(config.localiser),
            follower: PathFollower::new(config.follower),
            steps: Vec::with_capacity(grop_ipc::MAX_TASK_STEPS),
            config,
            grid,
            tray,
            dock: None,
            at_table: false,
            parking: Parking::NotStarted,
            failed_legs: 0,
            plans_refused: 0,
            unload: None,
            plan_id: 0,
            step_index: 0,
            phase: None,
            state: MissionState::Starting,
            request_id: 0,
            load_request_id: 0,
            request_sent: None,
            last_request: zero_request(),
            jump_hold_until: None,
            remaining,
            task_objects: remaining,
            slots: [None; MAX_TRAY_SLOTS],
            planner_seen: None,
            next_job_id: 1,
            velocity: Twist::ZERO,
            stale_reported: false,
            arm_stopped_sent: false,
            mode_requested: false,
            skill_result: None,
            event_seq: 0,
            global_fix_received: None,
            future_fixes: 0,
            dock_goal: None,
            dock_blocked_since: None,
            docking,
            monitor_hold_since: None,
            hold_reported: false,
            forced_turn: None,
            stall_since: None,
            enabled: false,
            enable_wait_reported: false,
            latch: None,
            arm_running_seen: false,
            stats: CoreStats::default(),
        }
    }

    /// The mission state.
    pub fn state(&self) -> MissionState {
        self.state
    }

    /// Counters.
    pub fn stats(&self) -> CoreStats {
        self.stats
    }

    /// The localisation estimate.
    pub fn estimate(&self) -> Pose2 {
        self.localiser.estimate()
    }

    /// The base's footprint (the robot file's).
    pub fn footprint(&self) -> world::BaseFootprint {
        self.config.robot.footprint
    }

    /// The velocity the core commands now.
    pub fn velocity(&self) -> Twist {
        self.velocity
    }

    /// The request the core is waiting on (0: none yet).
    pub fn request_id(&self) -> u64 {
        self.request_id
    }

    /// One update: reads `inputs`, decides, writes `outputs` (which the caller cleared).
    pub fn update(&mut self, inputs: &CycleInputs<'_>, outputs: &mut CycleOutputs) {
        let now = inputs.now;
        if inputs.shutdown {
            self.abort(AbortReason::Shutdown, now, outputs);
        } else if inputs.clock_lost {
            self.abort(AbortReason::ClockLost, now, outputs);
        }
        self.arm_reading(inputs, outputs);
        if inputs.operator_enable {
            self.operator_enable(now, outputs);
        }
        if let Some(tick) = inputs.base_tick {
            self.base_tick(tick, now, outputs);
        }
        if inputs.base_cycle {
            self.watch_motion(inputs, outputs);
            self.base_loop(inputs, outputs);
            self.turn_the_other_way();
        } else if !inputs.plans.is_empty() {
            self.plan_between_base_cycles(inputs, outputs);
        }
        self.velocity = self.within_limits(self.velocity);
        outputs.velocity = self.velocity;
        outputs.monitor_mode = if self.docking() {
            MonitorMode::Docking
        } else {
            MonitorMode::Normal
        };
    }

    /// `v` within what the robot can do: zero when not finite, cut to the robot file's speed
    /// and yaw rate. The laws stay within them on sane inputs; this is the last check against
    /// nonsense (an odometry of 1e308 m once made the follower command a NaN yaw rate).
    fn within_limits(&mut self, v: Twist) -> Twist {
        let speed = self.config.robot.speed_mps as f32;
        let yaw = self.config.robot.yaw_rate_radps as f32;
        let bounded = if v.is_finite() {
            Twist::new(
                v.speed_mps.clamp(-speed, speed),
                v.yaw_rate_radps.clamp(-yaw, yaw),
            )
        } else {
            Twist::ZERO
        };
        if bounded != v {
            self.stats.bounded = self.stats.bounded.saturating_add(1);
        }
        bounded
    }

    fn arm_reading(&mut self, inputs: &CycleInputs<'_>, outputs: &mut CycleOutputs) {
        let now = inputs.now;
        match inputs.arm {
            Ok(snapshot) => self.arm_modes(&snapshot, now, outputs),
            Err(ArmFault::LinkLost) => self.abort(AbortReason::ArmLinkLost, now, outputs),
            Err(ArmFault::ProtectiveStop | ArmFault::EmergencyStop) => {
                self.abort(AbortReason::ArmStopped, now, outputs)
            }
            Err(_) => {}
        }
        if inputs.skill.is_some() {
            self.skill_result = inputs.skill;
        }
        if let (Some(Phase::Unloading), Some(seq)) = (&self.phase, &mut self.unload) {
            if matches!(self.state, MissionState::Running) && self.latch.is_none() {
                let mut arm = CommandArm {
                    skill: self.skill_result.take(),
                    command: &mut outputs.arm,
                };
                let progress = seq.poll(&mut arm, &self.tray, now);
                match progress {
                    UnloadProgress::Busy(_) => {}
                    UnloadProgress::Placed => self.unload_done(now, None, outputs),
                    UnloadProgress::Failed(f) => self.unload_done(now, Some(f), outputs),
                }
            }
        }
    }

    fn base_tick(
        &mut self,
        tick: &Result<Tick, BaseError>,
        now: Duration,
        outputs: &mut CycleOutputs,
    ) {
        match tick {
            // Unreadable feedback disarms the driver like silence does: no mission goes on
            // with a base that only ever gets zero.
            Err(BaseError::Silent { .. } | BaseError::FeedbackUnreadable { .. }) => {
                self.abort(AbortReason::BaseLinkLost, now, outputs)
            }
            Err(BaseError::Faulted { .. } | BaseError::Overspeed { .. }) => {
                self.abort(AbortReason::BaseFault, now, outputs)
            }
            Err(BaseError::SecondCommander { .. }) => {
                self.abort(AbortReason::SecondCommander, now, outputs)
            }
            // The base's stored limits are not the robot's (never taken, or changed behind the
            // driver's back): its normalised commands would mean other speeds.
            Err(BaseError::LimitNotTaken { .. } | BaseError::LimitChanged { .. }) => {
                self.abort(AbortReason::BaseFault, now, outputs)
            }
            _ => {}
        }
    }

    #[allow(
        clippy::too_many_lines,
        reason = "one match over the mission's steps, every phase that is ready run in one cycle"
    )]
    fn base_loop(&mut self, inputs: &CycleInputs<'_>, outputs: &mut CycleOutputs) {
        let now = inputs.now;
        // Localisation: odometry, then fixes.
        let odo = inputs.base.odometry;
        self.localiser.on_odometry(odo.pose());
        for fix in inputs.fixes {
            if fix.stamp_ns > ns(now.saturating_add(self.config.fix_future_tolerance)) {
                self.future_fixes += 1;
                if self.future_fixes == 1 {
                    self.event(
                        EventKind::StaleInput,
                        now,
                        format_args!(
                            "pose fix stamped {:.3} s in the future refused",
                            Duration::from_nanos(fix.stamp_ns.saturating_sub(ns(now)))
                                .as_secs_f64()
                        ),
                        outputs,
                    );
                }
                continue;
            }
            let Ok(pose) = fix.pose() else { continue };
            if self.grid.cell_of(pose[0], pose[1]).is_none() {
                // Off the map: nonsense whatever its stamp (the estimate would follow it there).
                self.stats.off_map_fixes += 1;
                if self.stats.off_map_fixes == 1 {
                    self.event(
                        EventKind::StaleInput,
                        now,
                        format_args!(
                            "pose fix at ({:.3e}, {:.3e}) m off the map refused",
                            pose[0], pose[1]
                        ),
                        outputs,
                    );
                }
                continue;
            }
            let pose = Pose2::new(pose[0], pose[1], pose[2]);
            let outcome = match fix.kind() {
                Ok(PoseFixKind::Global) => {
                    let outcome = self.localiser.on_global_fix(pose, fix.stamp_ns);
                    if outcome != FixOutcome::Rejected {
                        self.global_fix_received = Some(now);
                    }
                    outcome
                }
                Ok(PoseFixKind::TableRelative) => self.localiser.on_table_fix(pose, fix.stamp_ns),
                Err(_) => FixOutcome::Rejected,
            };
            if let FixOutcome::Jumped { by_m } = outcome {
                if by_m > self.config.localiser.jump_m {
                    // Which pose is right is unknown until the next fixes agree: stand still
                    // meanwhile instead of steering hard towards either.
                    self.jump_hold_until = Some(now + self.config.jump_hold);
                    self.event(
                        EventKind::StaleInput,
                        now,
                        format_args!("localisation jumped {by_m:.2} m"),
                        outputs,
                    );
                }
            }
        }
        // The range sensor's scan aligned to the map (the shell's worker).
        if let Some((pose, odom)) = inputs.aligned
            && self.localiser.on_aligned(pose, odom, ns(now)) != FixOutcome::Rejected
        {
            self.stats.alignments += 1;
        }
        // Peers.
        if inputs.planner_heartbeats > 0 {
            self.planner_seen = Some(now);
        }
        if let Some(seen) = self.planner_seen {
            if now.saturating_sub(seen) > self.config.planner_timeout
                && matches!(self.state, MissionState::Starting | MissionState::Running)
            {
                self.event(
                    EventKind::PeerLost,
                    now,
                    format_args!("planner heartbeats missing for {:?}", now - seen),
                    outputs,
                );
                self.abort(AbortReason::PlannerLost, now, outputs);
            }
        }
        // Plans.
        for plan in inputs.plans {
            if plan.answers_request == self.request_id && self.request_id != 0 {
                self.take_plan(plan, now, outputs);
            }
        }

        self.velocity = Twist::ZERO;
        match self.state {
            MissionState::Starting if !self.enabled => {
                // A start (or a restart) is not an enable: nothing is armed before the
                // operator's enable.
                if !self.enable_wait_reported {
                    self.enable_wait_reported = true;
                    self.event(
                        EventKind::Enable,
                        now,
                        format_args!("waiting for the operator's enable before arming the base"),
                        outputs,
                    );
                }
            }
            MissionState::Starting => {
                if !self.mode_requested {
                    self.mode_requested = true;
                    outputs.base_mode = Some(BaseMode::Tractor);
                    // The one explicit re-arm of the RMP driver: at mission start. After a lost
                    // link, a base fault or an overspeed the driver disarms itself and the
                    // mission aborts; nothing here re-arms it again.
                    outputs.rearm_base = true;
                }
                if inputs.base.driving && self.localiser.is_initialised() {
                    self.state = MissionState::Running;
                    self.request_plan(ReplanReason::MissionStart, now, None, outputs);
                    // The arm goes to its carry pose while the plan is worked out.
                    self.park_arm(now, outputs);
                }
            }
            MissionState::Running if self.latch.is_some() => {}
            MissionState::Running if !inputs.base.driving => {
                // Out of tractor mode without being asked and without a fault word: the driver
                // would drive again when tractor returns. A safety stop.
                self.abort(AbortReason::BaseModeLost, now, outputs);
            }
            MissionState::Running => self.mission_step(inputs, outputs),
            MissionState::Finished | MissionState::Aborted(_) => {}
        }
        if self.jump_hold_until.is_some_and(|until| now < until) {
            self.velocity = Twist::ZERO;
        } else {
            self.jump_hold_until = None;
        }
        let stale = self.localisation_stale(now);
        if matches!(self.state, MissionState::Running) && self.velocity != Twist::ZERO && stale {
            // No fixes: do not drive on odometry alone.
            self.velocity = Twist::ZERO;
            if !self.stale_reported {
                self.stale_reported = true;
                self.event(
                    EventKind::StaleInput,
                    now,
                    format_args!("no localisation fix: holding"),
                    outputs,
                );
            }
        } else if !stale {
            self.stale_reported = false;
        }
        // A request nobody answered (the planner joined late): ask again.
        if let Some(sent) = self.request_sent {
            if now.saturating_sub(sent) > self.config.plan_request_retry {
                self.request_sent = Some(now);
                self.last_request.stamp_ns = ns(now);
                outputs.request = Some(self.last_request);
            }
        }
        if matches!(self.state, MissionState::Aborted(_)) {
            self.velocity = Twist::ZERO;
        }
    }

    /// A plan that came in on an arm cycle (the shell reads plans every cycle): taken at once,
    /// as the next base cycle would, and the phases that are then ready run (plan taken -> path
    /// asked), so the path search starts up to one base period earlier. Nothing else of the
    /// base loop runs here, and the velocity stays as it is (zero: the base holds while a plan
    /// is awaited); the first velocity is commanded on the base cycle that takes the path.
    fn plan_between_base_cycles(&mut self, inputs: &CycleInputs<'_>, outputs: &mut CycleOutputs) {
        let now = inputs.now;
        let taken = self.stats.plans;
        for plan in inputs.plans {
            if plan.answers_request == self.request_id && self.request_id != 0 {
                self.take_plan(plan, now, outputs);
            }
        }
        let ready = self.stats.plans != taken
            && matches!(self.state, MissionState::Running)
            && self.latch.is_none()
            && inputs.base.driving;
        if ready {
            let velocity = self.velocity;
            // Answers are the base cycle's to take.
            let inputs = CycleInputs {
                answer: None,
                ..*inputs
            };
            self.mission_step(&inputs, outputs);
            self.velocity = velocity;
        }
    }

    /// No global fix for the stale time, counted from its stamp and from when it was received
    /// (a stamp alone can lie).
    fn localisation_stale(&self, now: Duration) -> bool {
        let by_receipt = self.global_fix_received.is_none_or(|t| {
            now.saturating_sub(t) > Duration::from_nanos(self.config.localiser.stale_after_ns)
        });
        self.localiser.is_stale(ns(now)) || by_receipt
    }

    /// Pose fixes refused for a stamp in the future.
    pub fn future_fixes(&self) -> u64 {
        self.future_fixes
    }

    pub(super) fn on_board(&self) -> u64 {
        self.slots
            .iter()
            .flatten()
            .fold(0u64, |m, &o| m | (1u64 << o.min(63)))
    }

    pub(super) fn request_plan(
        &mut self,
        reason: ReplanReason,
        now: Duration,
        failed: Option<&TaskStep>,
        outputs: &mut CycleOutputs,
    ) {
        self.request_id += 1;
        let est = self.localiser.estimate();
        let mut req = zero_request();
        req.request_id = self.request_id;
        req.stamp_ns = ns(now);
        req.set_reason(reason);
        req.remaining_mask = self.remaining;
        req.on_board_mask = self.on_board();
        req.pose = [est.x_m, est.y_m, est.yaw_rad];
        if self.at_table {
            // The plan's first leg backs out (the planner works out how far).
            req.flags |= grop_ipc::REQUEST_AT_TABLE;
        }
        // The plan's loads go into the slots free now (the planner assigns them).
        req.tray = crate::tray_plan::tray_to_wire(&self.slots);
        if let Some(step) = failed {
            req.failed_object = step.object_index;
            req.failed_side = step.side;
            req.failed_goal_m = [step.x_m, step.y_m];
        }
        self.last_request = req;
        self.request_sent = Some(now);
        self.steps.clear();
        self.phase = None;
        outputs.request = Some(req);
        let id = self.request_id;
        self.event(
            EventKind::ReplanRequested,
            now,
            format_args!("request {id} ({reason:?})"),
            outputs,
        );
    }

    pub(super) fn current_step(&self) -> Option<TaskStep> {
        self.steps.get(self.step_index).copied()
    }

    pub(super) fn next_step(&mut self, now: Duration, outputs: &mut CycleOutputs) {
        self.step_index += 1;
        self.phase = None;
        if self.step_index >= self.steps.len() && self.request_sent.is_none() {
            self.state = MissionState::Finished;
            let (plan, ok, failed) = (
                self.plan_id,
                self.stats.unloads_ok,
                self.stats.unloads_failed,
            );
            self.event(
                EventKind::PlanFinished,
                now,
                format_args!("plan {plan} finished: {ok} placed, {failed} failed"),
                outputs,
            );
        }
    }

    /// Runs every phase that is ready in this base cycle: a phase that ends hands over to the
    /// next at once (plan taken -> arm parked -> path asked; path answered -> first velocity),
    /// until one waits on the world (a job, an arm command, a request, a velocity) or none
    /// changes. So a plan reaches the first motion command one path search after it arrives,
    /// not one base cycle per phase.
    fn mission_step(&mut self, inputs: &CycleInputs<'_>, outputs: &mut CycleOutputs) {
        for _ in 0..MAX_PHASES_PER_UPDATE {
            let before = self.phase.as_ref().map(std::mem::discriminant);
            let index = self.step_index;
            self.mission_pass(inputs, outputs);
            let progressed = before != self.phase.as_ref().map(std::mem::discriminant)
                || index != self.step_index;
            let waits = outputs.job.is_some()
                || outputs.arm != ArmCommand::None
                || outputs.request.is_some()
                || self.velocity != Twist::ZERO
                || !matches!(self.state, MissionState::Running);
            if !progressed || waits {
                break;
            }
        }
    }

    fn mission_pass(&mut self, inputs: &CycleInputs<'_>, outputs: &mut CycleOutputs) {
        let now = inputs.now;
        if !self.park_arm(now, outputs) {
            return; // the arm on its way to the carry pose: the base holds still
        }
        if self.request_sent.is_some() {
            return; // waiting for a plan: hold still
        }
        let Some(step) = self.current_step() else {
            if self.steps.is_empty() && self.stats.plans > 0 {
                self.state = MissionState::Finished;
                self.event(
                    EventKind::PlanFinished,
                    now,
                    format_args!("nothing left to do"),
                    outputs,
                );
            }
            return;
        };
        let kind = step.kind();
        let pose = self.localiser.estimate();
        let phase = self.phase.take();
        self.phase = match (kind, phase) {
            (Ok(TaskStepKind::Load), None) => {
                self.request_load(&step, now, outputs);
                Some(Phase::Loading {
                    until: now + self.config.load_wait,
                })
            }
            (Ok(TaskStepKind::Unload), None) => Some(Phase::AwaitTableFix { since: now }),
            (Ok(_), Some(Phase::Loading { until })) => {
                if now >= until {
                    self.load(&step, now, outputs);
                    // The station is next to the loading table: leave it as a table, straight
                    // back first, then turn.
                    self.at_table = true;
                    None
                } else {
                    Some(Phase::Loading { until })
                }
            }
            (Ok(_), Some(Phase::AwaitTableFix { since })) => {
                if let Some(fix) = self.localiser.table_pose(ns(since)) {
                    self.start_unload(&step, fix, now, outputs)
                } else if now.saturating_sub(since) > self.config.table_fix_wait {
                    // No table fix: fall back to the global estimate (less precise).
                    self.start_unload(&step, pose, now, outputs)
                } else {
                    Some(Phase::AwaitTableFix { since })
                }
            }
            (Ok(_), Some(Phase::PlanningArm { id, since, slot })) => match inputs.answer {
                Some(Answer::Unload(answer_id, planned)) if *answer_id == id => match planned {
                    Ok(plan) => {
                        self.unload = Some(UnloadSequence::new(slot, plan.clone()));
                        Some(Phase::Unloading)
                    }
                    Err(f) => {
                        self.finish_failed_unload(&step, now, *f, outputs);
                        None
                    }
                },
                _ if now.saturating_sub(since) > Duration::from_secs(10) => {
                    self.finish_failed_unload(&step, now, UnloadFailure::NoArmPath, outputs);
                    None
                }
                _ => Some(Phase::PlanningArm { id, since, slot }),
            },
            (Ok(_), Some(Phase::Unloading)) => Some(Phase::Unloading), // the arm cycle drives it
            // Every step is "be at (x, y, yaw)" first: the leg phases.
            (Ok(_), phase) => self.leg(&step, pose, phase, inputs, outputs),
            (Err(_), _) => {
                let index = self.step_index;
                self.event(
                    EventKind::StaleInput,
                    now,
                    format_args!("step {index} has no known kind: skipped"),
                    outputs,
                );
                self.next_step(now, outputs);
                None
            }
        };
    }

    /// Moves the arm to its carry pose once, before the base first drives; true once it is
    /// there. It starts as soon as the mission runs, so it overlaps the wait for the first plan.
    fn park_arm(&mut self, now: Duration, outputs: &mut CycleOutputs) -> bool {
        match self.parking {
            Parking::Parked => true,
            Parking::NotStarted => {
                outputs.arm = ArmCommand::MoveJoints(self.tray.carry);
                self.skill_result = None;
                self.parking = Parking::Moving { since: now };
                false
            }
            Parking::Moving { since } => match self.skill_result.take() {
                Some(Ok(SkillStatus::Done { .. })) => {
                    self.parking = Parking::Parked;
                    true
                }
                Some(Ok(SkillStatus::Running)) | None
                    if now.saturating_sub(since) < PARKING_TIMEOUT =>
                {
                    false
                }
                Some(Err(_)) | Some(Ok(SkillStatus::Running)) | None => {
                    self.abort(AbortReason::ArmStopped, now, outputs);
                    false
                }
            },
        }
    }

    /// Asks the station for the load step's objects (`load/request`, once per load step): what
    /// the robot's display shows the people there. The station loads exactly this mask.
    fn request_load(&mut self, step: &TaskStep, now: Duration, outputs: &mut CycleOutputs) {
        self.load_request_id += 1;
        let mut request = LoadRequestMsg::new(
            self.load_request_id,
            ns(now),
            self.plan_id,
            u32::try_from(self.step_index).unwrap_or(u32::MAX),
            step.load_mask,
            [step.x_m, step.y_m],
        );
        // Where each object goes, as the plan says (the robot's display shows it).
        let pairs = crate::tray_plan::load_pairs(step.load_mask, step.tray_slot, &self.slots);
        for (object, slot) in pairs.iter().flatten() {
            request.slots[*slot] = u8::try_from(object + 1).unwrap_or(0);
        }
        outputs.load_request = Some(request);
        let id = self.load_request_id;
        self.event(
            EventKind::LoadRequested,
            now,
            format_args!("load request {id}: objects {:#x} asked for", step.load_mask),
            outputs,
        );
    }

    fn load(&mut self, step: &TaskStep, now: Duration, outputs: &mut CycleOutputs) {
        // Into the slots the plan gives them (checked when the plan was taken in).
        let pairs = crate::tray_plan::load_pairs(step.load_mask, step.tray_slot, &self.slots);
        for (object, slot) in pairs.iter().flatten() {
            self.slots[*slot] = Some(*object);
        }
        self.event(
            EventKind::Loaded,
            now,
            format_args!("objects {:#x} on the tray", step.load_mask),
            outputs,
        );
        self.next_step(now, outputs);
    }

    /// Hands the unload's arm planning (IK at the measured pose, RRT-Connect transits) to the
    /// worker.
    fn start_unload(
        &mut self,
        step: &TaskStep,
        at: Pose2,
        now: Duration,
        outputs: &mut CycleOutputs,
    ) -> Option<Phase> {
        let object = step.object_index;
        // From the slot the plan names, if the object is there as far as the executive knows
        // (a tray mismatch found earlier forgets it).
        let slot = step.tray_slot as usize;
        if self.slots.get(slot) != Some(&Some(object)) {
            self.finish_failed_unload(step, now, UnloadFailure::NothingInSlot, outputs);
            return None;
        }
        let id = self.next_job_id;
        self.next_job_id += 1;
        outputs.job = Some(Job::Unload {
            id,
            base: at,
            target: step.target_m,
            from_slot: self.tray.pick_above[slot.min(self.tray.pick_above.len() - 1)],
            carry: self.tray.carry,
            seed: self.plan_id ^ (u64::from(object) << 32) ^ id,
        });
        Some(Phase::PlanningArm {
            id,
            since: now,
            slot,
        })
    }

    fn unload_done(
        &mut self,
        now: Duration,
        failure: Option<UnloadFailure>,
        outputs: &mut CycleOutputs,
    ) {
        let Some(step) = self.current_step() else {
            return;
        };
        match failure {
            None => {
                self.stats.unloads_ok += 1;
                let object = step.object_index;
                for s in self.slots.iter_mut() {
                    if *s == Some(object) {
                        *s = None;
                    }
                }
                self.remaining &= !(1u64 << object.min(63));
                self.at_table = true;
                self.event(
                    EventKind::UnloadSucceeded,
                    now,
                    format_args!("object {object} released on its target"),
                    outputs,
                );
                self.next_step(now, outputs);
            }
            Some(UnloadFailure::Arm(fault)) => {
                let reason = match fault {
                    ArmFault::LinkLost => AbortReason::ArmLinkLost,
                    ArmFault::ProtectiveStop | ArmFault::EmergencyStop => AbortReason::ArmStopped,
                    ArmFault::SkillFailed | ArmFault::GripperFault => {
                        self.finish_failed_unload(&step, now, UnloadFailure::Arm(fault), outputs);
                        return;
                    }
                };
                self.abort(reason, now, outputs);
            }
            Some(UnloadFailure::NothingInSlot) => {
                // The gripper's object check: the slot believed to hold the object is empty.
                // Not placed; the belief is corrected, the planner decides what follows.
                let object = step.object_index;
                let slot = self.slots.iter().position(|s| *s == Some(object));
                if let Some(k) = slot {
                    self.slots[k] = None;
                }
                self.event(
                    EventKind::TrayMismatch,
                    now,
                    format_args!(
                        "object {object}: the gripper closed on nothing in slot {}, believed to hold it",
                        slot.map_or(-1, |k| k as i64)
                    ),
                    outputs,
                );
                self.finish_failed_unload(&step, now, UnloadFailure::NothingInSlot, outputs);
            }
            Some(f) => self.finish_failed_unload(&step, now, f, outputs),
        }
    }

    pub(super) fn finish_failed_unload(
        &mut self,
        step: &TaskStep,
        now: Duration,
        failure: UnloadFailure,
        outputs: &mut CycleOutputs,
    ) {
        self.stats.unloads_failed += 1;
        self.at_table = true;
        self.event(
            EventKind::UnloadFailed,
            now,
            format_args!("object {}: {failure:?}", step.object_index),
            outputs,
        );
        self.request_plan(ReplanReason::UnloadFailed, now, Some(step), outputs);
    }

    /// Stops everything: zero velocity from now on, the arm stopped once, the mission ended.
    pub(super) fn abort(&mut self, reason: AbortReason, now: Duration, outputs: &mut CycleOutputs) {
        self.velocity = Twist::ZERO;
        outputs.velocity = Twist::ZERO;
        // Every abort but the operator's own shutdown and refused plans is a safety stop: the
        // base ramps at the emergency deceleration.
        if !matches!(reason, AbortReason::Shutdown | AbortReason::PlansRefused) {
            outputs.safety_stop = true;
        }
        if !self.arm_stopped_sent {
            self.arm_stopped_sent = true;
            outputs.arm = ArmCommand::Stop;
        }
        if matches!(self.state, MissionState::Aborted(_)) {
            return;
        }
        self.state = MissionState::Aborted(reason);
        outputs.abort = Some(reason);
        self.phase = None;
        self.request_sent = None;
        let kind = match reason {
            AbortReason::BaseLinkLost | AbortReason::ArmLinkLost => EventKind::LinkLost,
            AbortReason::BaseFault | AbortReason::SecondCommander | AbortReason::BaseModeLost => {
                EventKind::BaseFault
            }
            AbortReason::ArmStopped | AbortReason::ArmUnsafe => EventKind::ArmStopped,
            AbortReason::PlannerLost => EventKind::PeerLost,
            AbortReason::ClockLost
            | AbortReason::Shutdown
            | AbortReason::Stuck
            | AbortReason::PlansRefused => EventKind::MissionAborted,
        };
        if kind != EventKind::MissionAborted {
            self.event(
                kind,
                now,
                format_args!("{reason:?}: base to zero, arm stopped"),
                outputs,
            );
        }
        self.event(
            EventKind::MissionAborted,
            now,
            format_args!(
                "{reason:?}; a new mission needs a restart of the executive and the operator's enable"
            ),
            outputs,
        );
    }

    pub(super) fn event(
        &mut self,
        kind: EventKind,
        now: Duration,
        args: std::fmt::Arguments<'_>,
        outputs: &mut CycleOutputs,
    ) {
        self.event_seq += 1;
        let detail = text(args);
        log::info!("event {kind:?} step {}: {detail}", self.step_index);
        let mut msg = EventMsg::new(kind, ns(now), &detail).with_source(ProcessRole::Executive);
        msg.seq = self.event_seq;
        msg.plan_id = self.plan_id;
        msg.step_index = u32::try_from(self.step_index).unwrap_or(u32::MAX);
        if outputs.events.push(msg).is_err() {
            outputs.events_dropped += 1;
        }
    }
}

fn zero_request() -> ReplanRequestMsg {
    ReplanRequestMsg {
        request_id: 0,
        stamp_ns: 0,
        reason: 0,
        failed_object: 0,
        remaining_mask: 0,
        on_board_mask: 0,
        pose: [0.0; 3],
        failed_side: 0,
        flags: 0,
        tray: [0; grop_ipc::MAX_TRAY_SLOTS],
        failed_goal_m: [0.0; 2],
    }
}

#[cfg(test)]
#[path = "mission_tests.rs"]
mod tests;
