//! The executive: a cyclic executive in its own process that runs the plan on the robot.
//!
//! One thread, a fixed minor cycle (2 ms, the UR5e's RTDE period) on absolute deadlines of the
//! runtime clock ([`grop_clock::Clock`]): every cycle the arm is updated and its skill polled;
//! every `base_every`-th cycle (20 ms, 50 Hz) the base loop runs: localisation fixes are fused
//! with odometry, the mission advances, and the RMP driver ticks once over its `CanBus`.
//! Everything the loop needs is allocated before the first cycle; planning work that allocates
//! (base paths, arm motions) runs in a worker thread behind bounded channels ([`worker`]). Overruns (a cycle
//! that starts after its deadline) are counted and reported in heartbeats and `base/state`.
//!
//! The mission: ask the planning node for a plan (`plan/request`), then per step: drive to the
//! goal (path from the navigation planner, pure pursuit within the robot file's limits, final
//! heading aligned to the table, settle), load at the station, or unload with inverse
//! kinematics solved at the pose the table-relative fix measured ([`unload`]). After a failed
//! unload it asks for a new plan for what is left: how (or whether) to retry is the planner's
//! decision. Every step is reported on `events`.
//!
//! Safety (DESIGN.md): a lost base (no feedback), a base fault or overspeed, a lost arm link, an
//! arm stop, a dead planner (heartbeats missing) or a lost clock abort the mission: the base is
//! commanded to zero (the driver ramps at its deceleration limit) and the arm is stopped. Aborted
//! is final: motion resumes only after the executive is restarted (re-armed) by an operator. The
//! RMP driver latches the same way on its own (a lost link, a fault or an overspeed disarm it);
//! the executive re-arms it once, at mission start, and never after a fault. Stale
//! localisation holds the base at zero until fixes return. If this process dies, the base's own
//! 0.5 s loss-of-command timeout and the arm controller's RTDE watchdog stop both.

pub mod arm_io;
pub mod unload;
pub mod ur5e_arm;
pub mod worker;

use std::sync::Arc;
use std::time::Duration;

use can_bus::CanBus;
use grop_clock::Clock;
use grop_ipc::{
    ArmSafety, ArmStateMsg, BaseMode as IpcBaseMode, BasePoseMsg, BaseStateMsg, EventKind,
    EventMsg, HeartbeatMsg, IpcNode, MAX_TASK_STEPS, PoseFixKind, ProcessRole, ReplanReason,
    ReplanRequestMsg, TaskPlanMsg, TaskStep, TaskStepKind, TopicPublisher, TopicSubscriber,
};
use motion_control::follower::{FollowStep, FollowerConfig, PathFollower};
use motion_control::{Pose2, Twist};
use rmp_base::{BaseError, BaseMode, CanLink, RmpBase};
use rmp_codec::v3::OperationalState;
use ur5e_kin::{BasePose, Joints};
use world::nav::OccupancyGrid;
use world::{RobotConfig, Scene};

use crate::localisation::{FixOutcome, Localiser, LocaliserConfig, PlanarPose, wrap};
use unload::{ArmFault, ArmPort, TrayGeometry, UnloadFailure, UnloadProgress, UnloadSequence};
use worker::{Answer, Job, MAX_PATH_POINTS, PathFailure, Worker};

/// What the executive needs of the arm besides the unload skills.
pub trait ArmDevice: ArmPort {
    /// Reads the newest controller state at `now` (non-blocking); an error means the arm can
    /// no longer be trusted to move.
    fn update(&mut self, now: Duration) -> Result<ArmSnapshot, ArmFault>;
    /// Stops any motion (best effort; the controller's watchdog is the last line).
    fn stop(&mut self, now: Duration);
}

/// The arm state the executive publishes.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ArmSnapshot {
    /// Joint positions, rad.
    pub q_rad: Joints,
    /// Joint speeds, rad/s.
    pub qd_radps: Joints,
    /// Flange pose in the arm base frame (x, y, z, rotation vector).
    pub flange_pose: [f64; 6],
    /// A program runs on the controller.
    pub program_running: bool,
    /// Robot mode code.
    pub robot_mode: i32,
    /// Protective stop.
    pub protective_stop: bool,
    /// Emergency stop.
    pub emergency_stop: bool,
}

/// Settings of the executive (the robot file's limits enter through [`ExecutiveConfig::for_robot`]).
#[derive(Debug, Clone)]
pub struct ExecutiveConfig {
    /// Minor cycle (the arm's cycle). 2 ms.
    pub cycle: Duration,
    /// The base loop runs every this many minor cycles (10: 50 Hz).
    pub base_every: u32,
    /// Path follower (speed, yaw rate and deceleration from the robot file).
    pub follower: FollowerConfig,
    /// Heading tolerance of the final alignment, rad.
    pub yaw_tolerance_rad: f64,
    /// Proportional gain of the final alignment, 1/s.
    pub align_gain: f64,
    /// Standing still after arriving before the step counts as reached.
    pub settle: Duration,
    /// How long loading at the station takes (people put objects on the tray).
    pub load_wait: Duration,
    /// A table-relative fix must arrive within this after the base stopped at the table.
    pub table_fix_wait: Duration,
    /// A leg may take this factor times its planned travel time plus `leg_slack`.
    pub leg_time_factor: f64,
    /// See `leg_time_factor`.
    pub leg_slack: Duration,
    /// Planner heartbeats missing this long: the planner is dead.
    pub planner_timeout: Duration,
    /// A plan request without an answer is sent again after this.
    pub plan_request_retry: Duration,
    /// After the localisation jumps (a fix far from the estimate), the base is commanded to
    /// stand still (through the deceleration ramp) this long, so that it never steers hard on
    /// one wrong fix (or on the jump back); then the leg goes on from the estimate.
    pub jump_hold: Duration,
    /// Heartbeat period.
    pub heartbeat_period: Duration,
    /// Localisation filter.
    pub localiser: LocaliserConfig,
    /// Tray slots, base frame (m).
    pub tray_slots: Vec<[f64; 3]>,
    /// Clearance kept from furniture by base paths where the map allows (m).
    pub path_clearance_m: f64,
    /// The robot file (limits, footprint, arm mount).
    pub robot: RobotConfig,
}

impl ExecutiveConfig {
    /// Settings for `robot` (speed, acceleration and yaw-rate limits from its file).
    pub fn for_robot(robot: &RobotConfig) -> Self {
        Self {
            cycle: Duration::from_millis(2),
            base_every: 10,
            follower: FollowerConfig {
                lookahead_m: 0.35,
                cruise_speed_mps: robot.speed_mps as f32,
                max_yaw_rate_radps: robot.yaw_rate_radps as f32,
                stop_decel_mps2: (0.8 * robot.accel_mps2) as f32,
                goal_tolerance_m: 0.02,
                turn_in_place_above_rad: 0.8,
            },
            yaw_tolerance_rad: 0.008,
            align_gain: 2.0,
            settle: Duration::from_millis(400),
            load_wait: Duration::from_secs(3),
            table_fix_wait: Duration::from_secs(2),
            leg_time_factor: 3.0,
            leg_slack: Duration::from_secs(20),
            planner_timeout: Duration::from_millis(500),
            plan_request_retry: Duration::from_secs(1),
            jump_hold: Duration::from_secs(1),
            heartbeat_period: Duration::from_millis(100),
            localiser: LocaliserConfig::default(),
            tray_slots: unload::default_tray_slots().to_vec(),
            path_clearance_m: 0.15,
            robot: robot.clone(),
        }
    }
}

/// Why the executive could not start.
#[derive(Debug, thiserror::Error)]
pub enum ExecutiveError {
    /// A topic could not be opened.
    #[error("executive IPC: {0}")]
    Ipc(String),
    /// The base driver refused its configuration.
    #[error("base driver configuration: {0}")]
    BaseConfig(String),
    /// The tray cannot be reached by the arm.
    #[error("tray: {0}")]
    Tray(String),
    /// The path worker could not start.
    #[error("path worker: {0}")]
    Worker(std::io::Error),
    /// The robot file's `carry_capacity` exceeds the tray's slots: plans would load objects the
    /// tray cannot hold.
    #[error(
        "robot file: carry_capacity = {carry_capacity} exceeds the {tray_slots} tray slots of the executive"
    )]
    CarryCapacity {
        /// The robot file's `carry_capacity`.
        carry_capacity: u32,
        /// Usable tray slots (`ExecutiveConfig::tray_slots`, at most [`MAX_TRAY_SLOTS`]).
        tray_slots: usize,
    },
}

/// Most tray slots the executive tracks.
pub const MAX_TRAY_SLOTS: usize = 8;

/// How the mission ended (or is going).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MissionState {
    /// Waiting for the base, the localiser and a plan.
    Starting,
    /// Running a plan.
    Running,
    /// Every step done.
    Finished,
    /// Stopped for safety; needs a restart (re-arm).
    Aborted(AbortReason),
}

/// Why a mission was aborted.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AbortReason {
    /// The base stopped answering on CAN.
    BaseLinkLost,
    /// The base reported a fault, or moved faster than commanded.
    BaseFault,
    /// Another host sends commands on the base's bus.
    SecondCommander,
    /// The arm link is gone.
    ArmLinkLost,
    /// The arm is in a protective or emergency stop.
    ArmStopped,
    /// The planning node died.
    PlannerLost,
    /// The clock is lost (the HIL world ended).
    ClockLost,
    /// Asked to stop (signal).
    Shutdown,
    /// Legs kept failing: no route from where the base stands.
    Stuck,
}

/// Counters for reports.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ExecutiveStats {
    /// Minor cycles run.
    pub cycles: u64,
    /// Cycles that started after their deadline.
    pub overruns: u64,
    /// Unloads the executive saw succeed.
    pub unloads_ok: u32,
    /// Unloads that failed.
    pub unloads_failed: u32,
    /// Plans received.
    pub plans: u32,
    /// Messages published (iceoryx2 0.10 allocates one small reference-counted block per
    /// loaned sample, upstream: the allocation test accounts for exactly these).
    pub published: u64,
}

/// Step progress.
#[derive(Debug, Clone)]
enum Phase {
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
        start: PlanarPose,
        distance_m: f64,
        deadline: Duration,
    },
    /// Moving the arm to its carry pose before the base first drives.
    ParkingArm { started: bool, since: Duration },
    /// The worker plans the unload's arm motions.
    PlanningArm {
        id: u64,
        since: Duration,
        slot: usize,
    },
    /// Arm at work.
    /// (the sequence lives in `Executive::unload`, allocated once).
    Unloading,
}

/// The topics of the executive.
struct Ports {
    base_state: TopicPublisher<BaseStateMsg>,
    arm_state: TopicPublisher<ArmStateMsg>,
    events: TopicPublisher<EventMsg>,
    requests: TopicPublisher<ReplanRequestMsg>,
    health: TopicPublisher<HeartbeatMsg>,
    plans: TopicSubscriber<TaskPlanMsg>,
    poses: TopicSubscriber<BasePoseMsg>,
    peers: TopicSubscriber<HeartbeatMsg>,
}

/// The executive process's state.
pub struct Executive<B: CanBus, A: ArmDevice> {
    config: ExecutiveConfig,
    clock: Arc<dyn Clock>,
    base: RmpBase<CanLink<B>>,
    arm: A,
    ports: Ports,
    worker: Worker,
    grid: Arc<OccupancyGrid>,
    /// While driving to a pre-goal: the goal the base then docks at, straight ahead.
    dock: Option<[f64; 3]>,
    /// The last step done was at the table: back out before the next leg.
    at_table: bool,
    /// The arm is in its carry pose (done once before the first leg).
    arm_parked: bool,
    /// Legs failed in a row.
    failed_legs: u32,
    /// The unload in progress (in place: a new one overwrites it, nothing is allocated).
    unload: Option<UnloadSequence>,
    tray: TrayGeometry,
    localiser: Localiser,
    follower: PathFollower<MAX_PATH_POINTS>,
    steps: Vec<TaskStep>,
    plan_id: u64,
    step_index: usize,
    phase: Option<Phase>,
    state: MissionState,
    request_id: u64,
    request_sent: Option<Duration>,
    last_request: ReplanRequestMsg,
    /// Standing still after a localisation jump until then.
    jump_hold_until: Option<Duration>,
    /// Objects not yet placed (or given up), bit i = object i.
    remaining: u64,
    /// Tray slot -> object.
    slots: [Option<u32>; MAX_TRAY_SLOTS],
    planner_seen: Option<Duration>,
    next_path_id: u64,
    velocity: Twist,
    stale_reported: bool,
    arm_snapshot: ArmSnapshot,
    arm_stopped_sent: bool,
    mode_requested: bool,
    base_seq: u64,
    arm_seq: u64,
    event_seq: u64,
    heartbeat_seq: u64,
    next_heartbeat: Duration,
    stats: ExecutiveStats,
    /// Wake-up lateness of the minor cycle (allocation-free histogram).
    loop_stats: grop_clock::rt::LoopStats,
}

/// Writes a short event text without allocating.
fn text(args: std::fmt::Arguments<'_>) -> heapless::String<{ grop_ipc::EVENT_DETAIL_CAPACITY }> {
    use std::fmt::Write;
    let mut s = heapless::String::new();
    // Too long: cut (the message would be cut to the capacity anyway).
    let _ = s.write_fmt(args);
    s
}

fn ns(d: Duration) -> u64 {
    u64::try_from(d.as_nanos()).unwrap_or(u64::MAX)
}

fn ipc_err(e: impl std::fmt::Display) -> ExecutiveError {
    ExecutiveError::Ipc(e.to_string())
}

impl<B: CanBus, A: ArmDevice> Executive<B, A> {
    /// Builds the executive: opens its topics in `node`, solves the tray, starts the path worker.
    /// `objects` is the number of objects of the task (bits of `remaining`).
    pub fn new(
        config: ExecutiveConfig,
        clock: Arc<dyn Clock>,
        bus: B,
        arm: A,
        node: &IpcNode,
        scene: Scene,
        objects: usize,
    ) -> Result<Self, ExecutiveError> {
        let tray_slots = config.tray_slots.len().min(MAX_TRAY_SLOTS);
        if config.robot.carry_capacity as usize > tray_slots {
            return Err(ExecutiveError::CarryCapacity {
                carry_capacity: config.robot.carry_capacity,
                tray_slots,
            });
        }
        let mut base_config = rmp_base::RmpBaseConfig {
            command_period: config.cycle * config.base_every,
            ..rmp_base::RmpBaseConfig::default()
        };
        // The robot file's limits bound every command the driver sends (the follower plans
        // within them; the driver's limiter enforces them).
        base_config.limits.max_forward_mps = config.robot.speed_mps as f32;
        base_config.limits.max_reverse_mps = (0.5 * config.robot.speed_mps) as f32;
        base_config.limits.max_yaw_rate_radps = config.robot.yaw_rate_radps as f32;
        base_config.limits.max_accel_mps2 = config.robot.accel_mps2 as f32;
        base_config.limits.max_decel_mps2 = config.robot.accel_mps2 as f32;
        base_config.limits.max_yaw_accel_radps2 = config.robot.yaw_accel_radps2 as f32;
        let base = RmpBase::new(CanLink::new(bus), base_config)
            .map_err(|e| ExecutiveError::BaseConfig(e.to_string()))?;
        let tray = unload::solve_tray(&config.robot.place, &config.tray_slots)
            .map_err(ExecutiveError::Tray)?;
        let grid = Arc::new(OccupancyGrid::from_scene(&scene, &config.robot));
        // Paths keep a margin from furniture where the map allows: the base follows its estimate,
        // which is off by the localisation error.
        let mut grids: Vec<Arc<OccupancyGrid>> = [1.0, 0.5]
            .iter()
            .filter(|_| config.path_clearance_m > 0.0)
            .map(|share| {
                let mut careful = config.robot.clone();
                careful.footprint.length_m += 2.0 * share * config.path_clearance_m;
                careful.footprint.width_m += 2.0 * share * config.path_clearance_m;
                Arc::new(OccupancyGrid::from_scene(&scene, &careful))
            })
            .collect();
        grids.push(Arc::clone(&grid));
        let worker = Worker::start(
            grids,
            scene.clone(),
            config.robot.clone(),
            Arc::clone(&clock),
        )
        .map_err(ExecutiveError::Worker)?;
        let ports = Ports {
            base_state: node.publisher().map_err(ipc_err)?,
            arm_state: node.publisher().map_err(ipc_err)?,
            events: node.publisher().map_err(ipc_err)?,
            requests: node.publisher().map_err(ipc_err)?,
            health: node.publisher().map_err(ipc_err)?,
            plans: node.subscriber().map_err(ipc_err)?,
            poses: node.subscriber().map_err(ipc_err)?,
            peers: node.subscriber().map_err(ipc_err)?,
        };
        let remaining = if objects >= 64 {
            u64::MAX
        } else {
            (1u64 << objects) - 1
        };
        let follower = PathFollower::new(config.follower);
        let config_cycle = config.cycle;
        Ok(Self {
            localiser: Localiser::new(config.localiser),
            follower,
            steps: Vec::with_capacity(MAX_TASK_STEPS),
            config,
            clock,
            base,
            arm,
            ports,
            worker,
            grid,
            dock: None,
            at_table: false,
            arm_parked: false,
            failed_legs: 0,
            unload: None,
            tray,
            plan_id: 0,
            step_index: 0,
            phase: None,
            state: MissionState::Starting,
            request_id: 0,
            request_sent: None,
            last_request: zero_request(),
            jump_hold_until: None,
            remaining,
            slots: [None; MAX_TRAY_SLOTS],
            planner_seen: None,
            next_path_id: 1,
            velocity: Twist::ZERO,
            stale_reported: false,
            arm_snapshot: ArmSnapshot::default(),
            arm_stopped_sent: false,
            mode_requested: false,
            base_seq: 0,
            arm_seq: 0,
            event_seq: 0,
            heartbeat_seq: 0,
            next_heartbeat: Duration::ZERO,
            stats: ExecutiveStats::default(),
            loop_stats: grop_clock::rt::LoopStats::new(config_cycle),
        })
    }

    /// The mission state.
    pub fn state(&self) -> MissionState {
        self.state
    }

    /// Counters.
    pub fn stats(&self) -> ExecutiveStats {
        self.stats
    }

    /// How late the minor cycle woke (p50 / p99 / max) and its overruns.
    pub fn loop_summary(&self) -> grop_clock::rt::LoopSummary {
        self.loop_stats.summary()
    }

    /// The base driver (tests inspect it).
    pub fn base(&self) -> &RmpBase<CanLink<B>> {
        &self.base
    }

    /// Runs cycles until `keep_going` says stop, the mission ends and `exit_when_done` is set,
    /// or the clock is lost. Returns the final state.
    pub fn run(&mut self, keep_going: &dyn Fn() -> bool, exit_when_done: bool) -> MissionState {
        self.clock.wait_turn();
        let mut deadline = self.clock.now();
        loop {
            if !keep_going() {
                self.abort(AbortReason::Shutdown, deadline);
                // A few more base periods so the zero command reaches the base.
                for _ in 0..5 * self.config.base_every {
                    deadline += self.config.cycle;
                    self.clock.sleep_until(deadline);
                    self.cycle(deadline);
                }
                return self.state;
            }
            if self.clock.is_lost() {
                self.abort(AbortReason::ClockLost, deadline);
                return self.state;
            }
            self.cycle(deadline);
            if exit_when_done
                && matches!(
                    self.state,
                    MissionState::Finished | MissionState::Aborted(_)
                )
            {
                return self.state;
            }
            deadline += self.config.cycle;
            if self.clock.now() > deadline {
                self.stats.overruns += 1;
                // Far behind: skip ahead rather than burst.
                let now = self.clock.now();
                if now > deadline + 5 * self.config.cycle {
                    deadline = now;
                }
            }
            self.clock.sleep_until(deadline);
            self.loop_stats.record(deadline, self.clock.now());
        }
    }

    /// One minor cycle at `now` (public so tests can step it).
    pub fn cycle(&mut self, now: Duration) {
        self.stats.cycles += 1;
        self.arm_cycle(now);
        if self.stats.cycles % u64::from(self.config.base_every.max(1)) == 1
            || self.config.base_every <= 1
        {
            self.base_cycle(now);
        }
        if now >= self.next_heartbeat {
            self.next_heartbeat = now + self.config.heartbeat_period;
            self.heartbeat_seq += 1;
            let (seq, overruns) = (self.heartbeat_seq, self.stats.overruns);
            self.stats.published += 1;
            let _ = self.ports.health.publish_with(|h| {
                h.seq = seq;
                h.stamp_ns = ns(now);
                h.set_role(ProcessRole::Executive);
                h.pid = std::process::id();
                h.overruns = overruns;
            });
        }
    }

    fn arm_cycle(&mut self, now: Duration) {
        match self.arm.update(now) {
            Ok(snapshot) => {
                self.arm_snapshot = snapshot;
                if snapshot.protective_stop || snapshot.emergency_stop {
                    self.abort(AbortReason::ArmStopped, now);
                }
            }
            Err(ArmFault::LinkLost) => self.abort(AbortReason::ArmLinkLost, now),
            Err(ArmFault::ProtectiveStop | ArmFault::EmergencyStop) => {
                self.abort(AbortReason::ArmStopped, now)
            }
            Err(_) => {}
        }
        if let (Some(Phase::Unloading), Some(seq)) = (&self.phase, &mut self.unload) {
            if matches!(self.state, MissionState::Running) {
                let progress = seq.poll(&mut self.arm, &self.tray, now);
                match progress {
                    UnloadProgress::Busy(_) => {}
                    UnloadProgress::Placed => self.unload_done(now, None),
                    UnloadProgress::Failed(f) => self.unload_done(now, Some(f)),
                }
            }
        }
        self.arm_seq += 1;
        let (seq, s) = (self.arm_seq, self.arm_snapshot);
        self.stats.published += 1;
        let _ = self.ports.arm_state.publish_with(|m| {
            m.seq = seq;
            m.stamp_ns = ns(now);
            m.joints_rad = s.q_rad;
            m.joint_speeds_radps = s.qd_radps;
            m.flange_pose = s.flange_pose;
            m.robot_mode = s.robot_mode;
            m.program_running = u8::from(s.program_running);
            m.connected = 1;
            m.set_safety(if s.emergency_stop {
                ArmSafety::EmergencyStop
            } else if s.protective_stop {
                ArmSafety::ProtectiveStop
            } else {
                ArmSafety::Normal
            });
        });
    }

    fn base_cycle(&mut self, now: Duration) {
        // Localisation: odometry, then fixes.
        let odo = *self.base.odometry();
        self.localiser
            .on_odometry(PlanarPose::new(odo.x_m, odo.y_m, odo.yaw_rad));
        while let Ok(Some(fix)) = self.ports.poses.try_recv() {
            let Ok(pose) = fix.pose() else { continue };
            let pose = PlanarPose::new(pose[0], pose[1], pose[2]);
            let outcome = match fix.kind() {
                Ok(PoseFixKind::Global) => self.localiser.on_global_fix(pose, fix.stamp_ns),
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
                    );
                }
            }
        }
        // Peers.
        while let Ok(Some(hb)) = self.ports.peers.try_recv() {
            if hb.role() == Ok(ProcessRole::Planner) {
                self.planner_seen = Some(now);
            }
        }
        if let Some(seen) = self.planner_seen {
            if now.saturating_sub(seen) > self.config.planner_timeout
                && matches!(self.state, MissionState::Starting | MissionState::Running)
            {
                self.event(
                    EventKind::PeerLost,
                    now,
                    format_args!("planner heartbeats missing for {:?}", now - seen),
                );
                self.abort(AbortReason::PlannerLost, now);
            }
        }
        // Plans.
        while let Ok(Some(plan)) = self.ports.plans.try_recv() {
            if plan.answers_request == self.request_id && self.request_id != 0 {
                self.take_plan(&plan, now);
            }
        }

        self.velocity = Twist::ZERO;
        match self.state {
            MissionState::Starting => {
                if !self.mode_requested {
                    self.mode_requested = true;
                    self.base.request_mode(BaseMode::Tractor, now);
                    // The one explicit re-arm of the RMP driver: at mission start. After a lost
                    // link, a base fault or an overspeed the driver disarms itself and the
                    // mission aborts; nothing here re-arms it again.
                    self.base.rearm();
                }
                if self.base.is_driving() && self.localiser.is_initialised() {
                    self.state = MissionState::Running;
                    self.request_plan(ReplanReason::MissionStart, now, None);
                }
            }
            MissionState::Running => self.mission_step(now),
            MissionState::Finished | MissionState::Aborted(_) => {}
        }
        if self.jump_hold_until.is_some_and(|until| now < until) {
            self.velocity = Twist::ZERO;
        } else {
            self.jump_hold_until = None;
        }
        if matches!(self.state, MissionState::Running)
            && self.velocity != Twist::ZERO
            && self.localiser.is_stale(ns(now))
        {
            // No fixes: do not drive on odometry alone.
            self.velocity = Twist::ZERO;
            if !self.stale_reported {
                self.stale_reported = true;
                self.event(
                    EventKind::StaleInput,
                    now,
                    format_args!("no localisation fix: holding"),
                );
            }
        } else if !self.localiser.is_stale(ns(now)) {
            self.stale_reported = false;
        }
        // A request nobody answered (the planner joined late): ask again.
        if let Some(sent) = self.request_sent {
            if now.saturating_sub(sent) > self.config.plan_request_retry {
                self.request_sent = Some(now);
                self.last_request.stamp_ns = ns(now);
                self.stats.published += 1;
                let _ = self.ports.requests.publish(&self.last_request);
            }
        }

        self.base.set_velocity(self.velocity, now);
        let tick = self.base.tick(now);
        match &tick {
            // Unreadable feedback disarms the driver like silence does: no mission goes on
            // with a base that only ever gets zero.
            Err(BaseError::Silent { .. } | BaseError::FeedbackUnreadable { .. }) => {
                self.abort(AbortReason::BaseLinkLost, now)
            }
            Err(BaseError::Faulted { .. } | BaseError::Overspeed { .. }) => {
                self.abort(AbortReason::BaseFault, now)
            }
            Err(BaseError::SecondCommander { .. }) => self.abort(AbortReason::SecondCommander, now),
            _ => {}
        }
        let odo = *self.base.odometry();
        let est = self.localiser.estimate();
        let status = *self.base.status();
        let commanded = tick.as_ref().map(|t| t.commanded).unwrap_or(Twist::ZERO);
        let watchdog = tick.as_ref().map(|t| t.input_stale).unwrap_or(true);
        let link_up = !matches!(tick, Err(BaseError::Silent { .. }));
        self.base_seq += 1;
        let seq = self.base_seq;
        self.stats.published += 1;
        let _ = self.ports.base_state.publish_with(|m| {
            m.seq = seq;
            m.stamp_ns = ns(now);
            m.x_m = est.x_m;
            m.y_m = est.y_m;
            m.yaw_rad = est.yaw_rad;
            m.speed_mps = odo.speed_mps;
            m.yaw_rate_radps = odo.yaw_rate_radps;
            m.commanded_speed_mps = f64::from(commanded.speed_mps);
            m.commanded_yaw_rate_radps = f64::from(commanded.yaw_rate_radps);
            m.set_mode(match status.state {
                Some(OperationalState::Tractor) => IpcBaseMode::Tractor,
                Some(OperationalState::Standby) => IpcBaseMode::Standby,
                Some(OperationalState::DisablePower) => IpcBaseMode::Disabled,
                Some(_) => IpcBaseMode::DecelToZero,
                None => IpcBaseMode::Unknown,
            });
            m.fault_bits = status.faults.words()[0];
            m.link_up = u8::from(link_up);
            m.watchdog_stopped = u8::from(watchdog);
        });
    }

    fn take_plan(&mut self, plan: &TaskPlanMsg, now: Duration) {
        let Ok(steps) = plan.steps() else {
            self.event(
                EventKind::StaleInput,
                now,
                format_args!("plan {} rejected: malformed", plan.plan_id),
            );
            return;
        };
        if let Err(why) = self.check_tray(steps) {
            self.event(
                EventKind::StaleInput,
                now,
                format_args!("plan {} rejected: {why}", plan.plan_id),
            );
            return;
        }
        self.stats.plans += 1;
        self.steps.clear();
        self.steps.extend_from_slice(steps);
        self.plan_id = plan.plan_id;
        self.step_index = 0;
        self.phase = None;
        self.request_sent = None;
        self.event(
            EventKind::PlanStarted,
            now,
            // Not the wall-clock decision time: events are behaviour, and the same mission
            // must log the same events (the time is in the plan and the log's /timing/).
            format_args!(
                "plan {}: {} steps, U={:.1} F={:.2} C={:.1}s",
                plan.plan_id,
                steps.len(),
                plan.utility,
                plan.feasibility,
                plan.cost_s
            ),
        );
    }

    /// Whether the plan's loads fit the tray: from what is on board now, every load step adds
    /// its objects not yet on board, every unload frees its object; never more than the usable
    /// slots at once.
    fn check_tray(&self, steps: &[TaskStep]) -> Result<(), String> {
        let slots = self.slots.len().min(self.tray.pick.len());
        let mut on_board = self
            .slots
            .iter()
            .flatten()
            .fold(0u64, |m, &o| m | (1u64 << o.min(63)));
        for (i, step) in steps.iter().enumerate() {
            match step.kind() {
                Ok(TaskStepKind::Load) => {
                    on_board |= step.load_mask;
                    let count = on_board.count_ones() as usize;
                    if count > slots {
                        return Err(format!(
                            "step {i} loads {count} objects onto a tray of {slots} slots"
                        ));
                    }
                }
                Ok(TaskStepKind::Unload) => {
                    if let Ok(o) = step.object() {
                        on_board &= !(1u64 << o);
                    }
                }
                _ => {}
            }
        }
        Ok(())
    }

    fn request_plan(&mut self, reason: ReplanReason, now: Duration, failed: Option<&TaskStep>) {
        self.request_id += 1;
        let est = self.localiser.estimate();
        let mut on_board = 0u64;
        for object in self.slots.iter().flatten() {
            on_board |= 1u64 << (*object).min(63);
        }
        let mut req = zero_request();
        req.request_id = self.request_id;
        req.stamp_ns = ns(now);
        req.set_reason(reason);
        req.remaining_mask = self.remaining;
        req.on_board_mask = on_board;
        req.pose = [est.x_m, est.y_m, est.yaw_rad];
        if let Some(step) = failed {
            req.failed_object = step.object_index;
            req.failed_side = step.side;
            req.failed_goal_m = [step.x_m, step.y_m];
        }
        self.last_request = req;
        self.request_sent = Some(now);
        self.steps.clear();
        self.phase = None;
        self.stats.published += 1;
        let _ = self.ports.requests.publish(&req);
        let id = self.request_id;
        self.event(
            EventKind::ReplanRequested,
            now,
            format_args!("request {id} ({reason:?})"),
        );
    }

    fn current_step(&self) -> Option<TaskStep> {
        self.steps.get(self.step_index).copied()
    }

    fn next_step(&mut self, now: Duration) {
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
            );
        }
    }

    fn mission_step(&mut self, now: Duration) {
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
                );
            }
            return;
        };
        let kind = step.kind();
        let pose = self.localiser.estimate();
        let phase = self.phase.take();
        if !self.arm_parked && phase.is_none() {
            self.phase = Some(Phase::ParkingArm {
                started: false,
                since: now,
            });
            return;
        }
        self.phase = match (kind, phase) {
            (Ok(_), Some(Phase::ParkingArm { started, since })) => {
                let carry = self.tray.carry;
                let result = if started {
                    self.arm.poll(now)
                } else {
                    self.arm
                        .start_move_joints(&carry, now)
                        .map(|()| unload::SkillStatus::Running)
                };
                match result {
                    Ok(unload::SkillStatus::Done { .. }) => {
                        self.arm_parked = true;
                        None
                    }
                    Ok(unload::SkillStatus::Running)
                        if now.saturating_sub(since) < Duration::from_secs(20) =>
                    {
                        Some(Phase::ParkingArm {
                            started: true,
                            since,
                        })
                    }
                    Ok(unload::SkillStatus::Running) | Err(_) => {
                        self.abort(AbortReason::ArmStopped, now);
                        None
                    }
                }
            }
            // Every step is "be at (x, y, yaw)" first; a load or unload step whose location the
            // preceding navigation reached skips straight to its work.
            (Ok(TaskStepKind::Navigate), None) => Some(self.start_leg(&step, pose, now)),
            (Ok(TaskStepKind::Load), None) => Some(Phase::Loading {
                until: now + self.config.load_wait,
            }),
            (Ok(TaskStepKind::Unload), None) => Some(Phase::AwaitTableFix { since: now }),
            (Ok(_), Some(Phase::PathRequested { id, since })) => match self.worker.try_answer() {
                Some(Answer::Path(answer_id, Ok(points))) if answer_id == id => {
                    match self.follower.set_path(&points) {
                        Ok(()) => Some(Phase::Following {
                            deadline: self.leg_deadline(&step, pose, now),
                        }),
                        Err(_) => self.leg_failed(&step, now, "path refused by the follower"),
                    }
                }
                Some(Answer::Path(answer_id, Err(e))) if answer_id == id => {
                    let why = match e {
                        PathFailure::NoRoute => "no route on the map",
                        PathFailure::WorkerGone => "planning worker gone",
                    };
                    self.leg_failed(&step, now, why)
                }
                _ if now.saturating_sub(since) > Duration::from_secs(5) => {
                    self.leg_failed(&step, now, "no path within 5 s")
                }
                _ => Some(Phase::PathRequested { id, since }),
            },
            (
                Ok(_),
                Some(Phase::Reversing {
                    start,
                    distance_m,
                    deadline,
                }),
            ) => {
                if pose.distance_m(&start) >= distance_m {
                    Some(self.request_path(&step, pose, now))
                } else if now > deadline {
                    // Blocked behind: plan from here.
                    Some(self.request_path(&step, pose, now))
                } else {
                    self.velocity = Twist::new(-REVERSE_SPEED_MPS, 0.0);
                    Some(Phase::Reversing {
                        start,
                        distance_m,
                        deadline,
                    })
                }
            }
            (Ok(_), Some(Phase::Following { deadline })) => {
                let p = Pose2 {
                    x_m: pose.x_m as f32,
                    y_m: pose.y_m as f32,
                    yaw_rad: pose.yaw_rad as f32,
                };
                if now > deadline {
                    self.leg_failed(&step, now, "leg took too long (blocked?)")
                } else {
                    match self.follower.step(&p) {
                        FollowStep::Drive(t) => {
                            self.velocity = t;
                            Some(Phase::Following { deadline })
                        }
                        FollowStep::Arrived | FollowStep::NoPath => {
                            Some(Phase::Aligning { deadline })
                        }
                    }
                }
            }
            (Ok(_), Some(Phase::Aligning { deadline })) => {
                let err = wrap(step.yaw_rad - pose.yaw_rad);
                if err.abs() <= self.config.yaw_tolerance_rad {
                    Some(Phase::Settling {
                        until: now + self.config.settle,
                    })
                } else if now > deadline {
                    self.leg_failed(&step, now, "could not turn to the goal heading")
                } else {
                    let max_w = self.config.robot.yaw_rate_radps;
                    let w = (self.config.align_gain * err).clamp(-max_w, max_w);
                    // A floor so the last degrees do not take forever against the limiter.
                    let w = if w.abs() < 0.05 {
                        0.05_f64.copysign(err)
                    } else {
                        w
                    };
                    self.velocity = Twist::new(0.0, w as f32);
                    Some(Phase::Aligning { deadline })
                }
            }
            (Ok(_), Some(Phase::Settling { until })) => {
                if now >= until && self.dock.is_some() {
                    // At the pre-goal, facing the table: drive straight in to the goal.
                    let goal = self
                        .dock
                        .take()
                        .unwrap_or([step.x_m, step.y_m, step.yaw_rad]);
                    let points = [
                        [pose.x_m as f32, pose.y_m as f32],
                        [goal[0] as f32, goal[1] as f32],
                    ];
                    match self.follower.set_path(&points) {
                        Ok(()) => Some(Phase::Following {
                            deadline: self.leg_deadline(&step, pose, now),
                        }),
                        Err(_) => self.leg_failed(&step, now, "docking path refused"),
                    }
                } else if now >= until {
                    self.failed_legs = 0;
                    let err = pose.distance_m(&PlanarPose::new(step.x_m, step.y_m, 0.0));
                    self.event(
                        EventKind::GoalReached,
                        now,
                        format_args!(
                            "at ({:.3}, {:.3}) believed, {:.3} m from goal",
                            pose.x_m, pose.y_m, err
                        ),
                    );
                    self.next_step(now);
                    None
                } else {
                    Some(Phase::Settling { until })
                }
            }
            (Ok(_), Some(Phase::Loading { until })) => {
                if now >= until {
                    let mut slot = 0;
                    for object in 0..64u32 {
                        if step.load_mask & (1u64 << object) != 0 {
                            while slot < self.slots.len() && self.slots[slot].is_some() {
                                slot += 1;
                            }
                            if slot < self.slots.len().min(self.tray.pick.len()) {
                                self.slots[slot] = Some(object);
                            }
                        }
                    }
                    self.event(
                        EventKind::Loaded,
                        now,
                        format_args!("objects {:#x} on the tray", step.load_mask),
                    );
                    self.next_step(now);
                    None
                } else {
                    Some(Phase::Loading { until })
                }
            }
            (Ok(_), Some(Phase::AwaitTableFix { since })) => {
                if let Some(fix) = self.localiser.table_pose(ns(since)) {
                    self.start_unload(&step, fix, now)
                } else if now.saturating_sub(since) > self.config.table_fix_wait {
                    // No table fix: fall back to the global estimate (less precise).
                    self.start_unload(&step, pose, now)
                } else {
                    Some(Phase::AwaitTableFix { since })
                }
            }
            (Ok(_), Some(Phase::PlanningArm { id, since, slot })) => match self.worker.try_answer()
            {
                Some(Answer::Unload(answer_id, planned)) if answer_id == id => match planned {
                    Ok(plan) => {
                        self.unload = Some(UnloadSequence::new(slot, plan));
                        Some(Phase::Unloading)
                    }
                    Err(f) => {
                        self.finish_failed_unload(&step, now, f);
                        None
                    }
                },
                _ if now.saturating_sub(since) > Duration::from_secs(10) => {
                    self.finish_failed_unload(&step, now, UnloadFailure::NoArmPath);
                    None
                }
                _ => Some(Phase::PlanningArm { id, since, slot }),
            },
            (Ok(_), Some(Phase::Unloading)) => Some(Phase::Unloading), // the arm cycle drives it
            (Err(_), _) => {
                let index = self.step_index;
                self.event(
                    EventKind::StaleInput,
                    now,
                    format_args!("step {index} has no known kind: skipped"),
                );
                self.next_step(now);
                None
            }
        };
    }

    /// Starts a leg: back out from the table first if the robot stands at it, then ask for the
    /// path (to a pre-goal in front of a table goal, see [`Self::request_path`]).
    fn start_leg(&mut self, step: &TaskStep, pose: PlanarPose, now: Duration) -> Phase {
        if std::mem::take(&mut self.at_table) {
            // Straight back, away from the table, as far as the map allows (up to the docking
            // distance): turning in place next to the table would sweep the footprint into it.
            let (s, c) = pose.yaw_rad.sin_cos();
            let distance_m = DOCKING_DISTANCES_M
                .iter()
                .copied()
                .find(|d| self.grid.is_free((pose.x_m - c * d, pose.y_m - s * d)))
                .unwrap_or(0.0);
            if distance_m > 0.0 {
                return Phase::Reversing {
                    start: pose,
                    distance_m,
                    deadline: now
                        + Duration::from_secs_f64(3.0 * distance_m / REVERSE_SPEED_MPS as f64),
                };
            }
        }
        self.request_path(step, pose, now)
    }

    /// Asks the worker for the leg's path. A goal followed by an unload is docked: the path
    /// ends at a pre-goal straight behind the goal (facing the table), where the base turns,
    /// then drives straight in, so it never turns next to the table or between chairs.
    fn request_path(&mut self, step: &TaskStep, pose: PlanarPose, now: Duration) -> Phase {
        let id = self.next_path_id;
        self.next_path_id += 1;
        let mut to = (step.x_m, step.y_m);
        self.dock = None;
        let unload_next = self
            .steps
            .get(self.step_index + 1)
            .is_some_and(|n| n.kind() == Ok(TaskStepKind::Unload));
        if unload_next {
            let (s, c) = step.yaw_rad.sin_cos();
            let straight_free = |d: f64| {
                (0..=((d / 0.05).ceil() as usize)).all(|k| {
                    let t = (k as f64 * 0.05).min(d);
                    self.grid.is_free((step.x_m - c * t, step.y_m - s * t))
                })
            };
            if let Some(d) = DOCKING_DISTANCES_M
                .iter()
                .copied()
                .find(|d| straight_free(*d))
            {
                to = (step.x_m - c * d, step.y_m - s * d);
                self.dock = Some([step.x_m, step.y_m, step.yaw_rad]);
            }
        }
        let job = Job::Path {
            id,
            from: (pose.x_m, pose.y_m),
            to,
        };
        match self.worker.submit(job) {
            Ok(true) => Phase::PathRequested { id, since: now },
            // Queue full (cannot happen with one job at a time): try again next period.
            Ok(false) | Err(_) => Phase::PathRequested { id: 0, since: now },
        }
    }

    fn leg_deadline(&self, step: &TaskStep, pose: PlanarPose, now: Duration) -> Duration {
        let planned = step.travel_cost_s.max(
            pose.distance_m(&PlanarPose::new(step.x_m, step.y_m, 0.0))
                / self.config.robot.speed_mps.max(0.05),
        );
        now + Duration::from_secs_f64(planned * self.config.leg_time_factor) + self.config.leg_slack
    }

    fn leg_failed(&mut self, step: &TaskStep, now: Duration, why: &str) -> Option<Phase> {
        self.event(
            EventKind::LegFinished,
            now,
            format_args!("leg to ({:.2}, {:.2}) failed: {why}", step.x_m, step.y_m),
        );
        self.failed_legs += 1;
        if self.failed_legs > MAX_FAILED_LEGS {
            // The base cannot get anywhere from here: stop rather than ask forever.
            self.event(
                EventKind::MissionAborted,
                now,
                format_args!("{MAX_FAILED_LEGS} legs in a row failed: the base is stuck"),
            );
            self.state = MissionState::Aborted(AbortReason::Stuck);
            self.velocity = Twist::ZERO;
            return None;
        }
        // The unload that needed this leg cannot happen from here: let the planner decide.
        if let Some(next) = self.steps.get(self.step_index + 1).copied() {
            if next.kind() == Ok(TaskStepKind::Unload) {
                self.stats.unloads_failed += 1;
                self.request_plan(ReplanReason::LegFailed, now, Some(&next));
                return None;
            }
        }
        self.request_plan(ReplanReason::LegFailed, now, None);
        None
    }

    /// Hands the unload's arm planning (IK at the measured pose, RRT-Connect transits) to the
    /// worker.
    fn start_unload(&mut self, step: &TaskStep, at: PlanarPose, now: Duration) -> Option<Phase> {
        let object = step.object_index;
        let Some(slot) = self.slots.iter().position(|s| *s == Some(object)) else {
            self.finish_failed_unload(step, now, UnloadFailure::NothingInSlot);
            return None;
        };
        let id = self.next_path_id;
        self.next_path_id += 1;
        let job = Job::Unload {
            id,
            base: BasePose {
                x_m: at.x_m,
                y_m: at.y_m,
                yaw_rad: at.yaw_rad,
            },
            target: step.target_m,
            from_slot: self.tray.pick_above[slot.min(self.tray.pick_above.len() - 1)],
            carry: self.tray.carry,
            seed: self.plan_id ^ (u64::from(object) << 32) ^ id,
        };
        match self.worker.submit(job) {
            Ok(true) => Some(Phase::PlanningArm {
                id,
                since: now,
                slot,
            }),
            _ => {
                self.finish_failed_unload(step, now, UnloadFailure::NoArmPath);
                None
            }
        }
    }

    fn unload_done(&mut self, now: Duration, failure: Option<UnloadFailure>) {
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
                );
                self.next_step(now);
            }
            Some(UnloadFailure::Arm(fault)) => {
                let reason = match fault {
                    ArmFault::LinkLost => AbortReason::ArmLinkLost,
                    ArmFault::ProtectiveStop | ArmFault::EmergencyStop => AbortReason::ArmStopped,
                    ArmFault::SkillFailed | ArmFault::GripperFault => {
                        self.finish_failed_unload(&step, now, UnloadFailure::Arm(fault));
                        return;
                    }
                };
                self.abort(reason, now);
            }
            Some(f) => self.finish_failed_unload(&step, now, f),
        }
    }

    fn finish_failed_unload(&mut self, step: &TaskStep, now: Duration, failure: UnloadFailure) {
        self.stats.unloads_failed += 1;
        self.at_table = true;
        self.event(
            EventKind::UnloadFailed,
            now,
            format_args!("object {}: {failure:?}", step.object_index),
        );
        self.request_plan(ReplanReason::UnloadFailed, now, Some(step));
    }

    fn abort(&mut self, reason: AbortReason, now: Duration) {
        self.velocity = Twist::ZERO;
        self.base.set_velocity(Twist::ZERO, now);
        if !self.arm_stopped_sent {
            self.arm_stopped_sent = true;
            self.arm.stop(now);
        }
        if matches!(self.state, MissionState::Aborted(_)) {
            return;
        }
        self.state = MissionState::Aborted(reason);
        self.phase = None;
        self.request_sent = None;
        let kind = match reason {
            AbortReason::BaseLinkLost | AbortReason::ArmLinkLost => EventKind::LinkLost,
            AbortReason::BaseFault | AbortReason::SecondCommander => EventKind::BaseFault,
            AbortReason::ArmStopped => EventKind::ArmStopped,
            AbortReason::PlannerLost => EventKind::PeerLost,
            AbortReason::ClockLost | AbortReason::Shutdown | AbortReason::Stuck => {
                EventKind::MissionAborted
            }
        };
        if kind != EventKind::MissionAborted {
            self.event(
                kind,
                now,
                format_args!("{reason:?}: base to zero, arm stopped"),
            );
        }
        self.event(
            EventKind::MissionAborted,
            now,
            format_args!("{reason:?}; restart the executive to re-arm"),
        );
    }

    fn event(&mut self, kind: EventKind, now: Duration, args: std::fmt::Arguments<'_>) {
        self.event_seq += 1;
        let detail = text(args);
        log::info!("event {kind:?} step {}: {detail}", self.step_index);
        let mut msg = EventMsg::new(kind, ns(now), &detail).with_source(ProcessRole::Executive);
        msg.seq = self.event_seq;
        msg.plan_id = self.plan_id;
        msg.step_index = self.step_index as u32;
        self.stats.published += 1;
        let _ = self.ports.events.publish(&msg);
    }
}

/// Legs that may fail in a row before the mission is given up.
const MAX_FAILED_LEGS: u32 = 3;

/// Backing-out speed from the table, m/s.
const REVERSE_SPEED_MPS: f32 = 0.15;

/// Docking / back-out distances tried, longest first, m.
const DOCKING_DISTANCES_M: [f64; 3] = [0.45, 0.3, 0.15];

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
        reserved: 0,
        failed_goal_m: [0.0; 2],
    }
}
