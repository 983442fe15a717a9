//! The executive's I/O shell: each cycle it reads the devices and the topics into
//! [`CycleInputs`], calls [`MissionCore::update`] once, and writes [`CycleOutputs`] to the
//! base, the arm, the planning worker and the topics (read / update / write, as ros2_control's
//! controller manager runs its hardware interfaces and controllers).
//!
//! Everything the shell keeps between cycles is allocated before the first one: the plan and
//! fix buffers, the outputs, the worker's channels.

use std::sync::Arc;
use std::time::Duration;

use can_bus::CanBus;
use grop_clock::Clock;
use grop_ipc::{
    ArmSafety, ArmStateMsg, BaseMode as IpcBaseMode, BasePoseMsg, BaseStateMsg, EventMsg,
    HeartbeatMsg, IpcNode, ProcessRole, ReplanRequestMsg, TaskPlanMsg, TopicPublisher,
};
use planar::Pose2;
use rmp_base::{BaseError, CanLink, RmpBase, Tick};
use rmp_codec::v3::OperationalState;
use world::Scene;
use world::nav::OccupancyGrid;

use motion_control::Twist;
use motion_control::collision::{CollisionMonitor, MonitorConfig, Obstacles, Verdict};

use super::base::BaseDevice;
use super::cycle::{ArmCommand, BaseReading, CycleInputs, CycleOutputs};
use super::inputs::{ExecutiveInputs, InputSources};
use super::mission::{MissionCore, ns};
use super::range::{MapOverhangs, RangeSensor};
use super::unload::{self, ArmFault, SkillStatus, UnloadFailure};
use super::worker::{ALIGN_POINTS, Answer, Job, PathFailure, Worker};
use super::{
    AbortReason, ArmDevice, ArmSnapshot, ExecutiveConfig, ExecutiveError, ExecutiveStats,
    MAX_TRAY_SLOTS, MissionState,
};

/// Most pose fixes one base cycle takes in (the world sends one or two per cycle); the rest
/// wait in the subscriber's queue for the next cycle.
pub const MAX_FIXES_PER_CYCLE: usize = 16;

/// Most plans one base cycle takes in.
pub const MAX_PLANS_PER_CYCLE: usize = 4;

/// The topics of the executive.
pub struct ExecutivePorts {
    base_state: TopicPublisher<BaseStateMsg>,
    arm_state: TopicPublisher<ArmStateMsg>,
    events: TopicPublisher<EventMsg>,
    requests: TopicPublisher<ReplanRequestMsg>,
    loads: TopicPublisher<grop_ipc::LoadRequestMsg>,
    health: TopicPublisher<HeartbeatMsg>,
    /// Each revolution of the range sensor, for the mission log (nothing onboard reads it).
    scan: TopicPublisher<grop_ipc::ScanMsg>,
    /// Plans, fixes and the planner's heartbeats, from the deployment's publishers only.
    inputs: ExecutiveInputs,
}

impl ExecutivePorts {
    /// Opens the executive's topics in `node`; its command inputs are accepted from the nodes
    /// `sources` names.
    pub fn open(node: &IpcNode, sources: &InputSources) -> Result<Self, ExecutiveError> {
        let e = |e: grop_ipc::PortError| ExecutiveError::Ipc(e.to_string());
        Ok(Self {
            base_state: node.publisher().map_err(e)?,
            arm_state: node.publisher().map_err(e)?,
            events: node.publisher().map_err(e)?,
            requests: node.publisher().map_err(e)?,
            loads: node.publisher().map_err(e)?,
            health: node.publisher().map_err(e)?,
            scan: node.publisher().map_err(e)?,
            inputs: ExecutiveInputs::open(node, sources).map_err(e)?,
        })
    }
}

/// The executive process's state: the core, the devices, the ports, the worker.
pub struct Executive<D: BaseDevice, A: ArmDevice> {
    core: MissionCore,
    cycle_period: Duration,
    base_every: u32,
    heartbeat_period: Duration,
    clock: Arc<dyn Clock>,
    base: D,
    arm: A,
    ports: ExecutivePorts,
    worker: Worker,
    outputs: CycleOutputs,
    fixes: Vec<BasePoseMsg>,
    plans: Vec<TaskPlanMsg>,
    /// An answer of the worker, or one the shell made for a job it could not hand over.
    answer: Option<Answer>,
    /// The base driver's last tick, for the next update.
    pending_tick: Option<Result<Tick, BaseError>>,
    arm_snapshot: ArmSnapshot,
    /// The arm's state read this cycle.
    arm_reading: Result<ArmSnapshot, ArmFault>,
    /// The skill in flight's result read this cycle.
    skill_reading: Option<Result<SkillStatus, ArmFault>>,
    /// Planner heartbeats read this base cycle.
    planner_heartbeats: u32,
    /// A skill was started and has not reported done or failed.
    skill_in_flight: bool,
    /// The arm refused the start of the skill in flight.
    start_refused: Option<ArmFault>,
    base_seq: u64,
    arm_seq: u64,
    heartbeat_seq: u64,
    next_heartbeat: Duration,
    stats: ExecutiveStats,
    /// Wake-up lateness of the minor cycle (allocation-free histogram).
    loop_stats: grop_clock::rt::LoopStats,
    /// The range sensor and the collision monitor between the core and the base driver
    /// (`None`: no sensor configured, the monitor is off).
    guard: Option<Guard>,
    /// What the monitor did on the last base cycle, and the velocity sent.
    last_verdict: Verdict,
    /// A scan alignment is with the worker.
    align_in_flight: bool,
    /// An accepted alignment for the next update (pose, odometry then).
    aligned: Option<(Pose2, Pose2)>,
    /// Alignments the worker made and the shell refused (too few pairs, residual too large).
    alignments_refused: u64,
    /// The first cycle's time: an enable given before it is not for this executive.
    started_at: Option<Duration>,
    /// An operator's enable given after the start came in this base cycle.
    operator_enable: bool,
    /// Enables refused (given before this executive started, or stamped in the future).
    enables_refused: u64,
}

/// The range sensor, the collision monitor and its buffers.
struct Guard {
    sensor: Box<dyn RangeSensor>,
    monitor: CollisionMonitor,
    scan: Obstacles,
    overhangs: MapOverhangs,
    /// Odometry at the last base cycle (to move the obstacles with the base).
    last_odometry: Option<rmp_base::Odometry>,
    /// Scans taken in.
    scans: u64,
}

/// The executive on the Segway RMP over a CAN bus `B`, as the robot runs it.
pub type RmpExecutive<B, A> = Executive<RmpBase<CanLink<B>>, A>;

/// The RMP driver's configuration for the robot file's limits (the follower plans within them;
/// the driver's limiter enforces them).
fn rmp_config(config: &ExecutiveConfig) -> rmp_base::RmpBaseConfig {
    rmp_base::RmpBaseConfig {
        adopt_stored_limits: config.adopt_base_limits,
        ..rmp_config_for(&config.robot, config.cycle * config.base_every)
    }
}

/// The RMP driver's configuration for `robot`'s limits at `command_period`: what the executive
/// runs the driver with (its [`rmp_base::RmpBaseConfig::base_settings`] are the limits it keeps
/// in the base's stored settings).
pub fn rmp_config_for(
    robot: &world::RobotConfig,
    command_period: std::time::Duration,
) -> rmp_base::RmpBaseConfig {
    let mut base_config = rmp_base::RmpBaseConfig {
        command_period,
        ..rmp_base::RmpBaseConfig::default()
    };
    base_config.limits.max_forward_mps = robot.speed_mps as f32;
    base_config.limits.max_reverse_mps = (0.5 * robot.speed_mps) as f32;
    base_config.limits.max_yaw_rate_radps = robot.yaw_rate_radps as f32;
    base_config.limits.max_accel_mps2 = robot.accel_mps2 as f32;
    base_config.limits.max_decel_mps2 = robot.accel_mps2 as f32;
    base_config.limits.max_yaw_accel_radps2 = robot.yaw_accel_radps2 as f32;
    base_config.emergency_decel_mps2 = robot.emergency_decel_mps2 as f32;
    base_config
}

impl<B: CanBus, A: ArmDevice> Executive<RmpBase<CanLink<B>>, A> {
    /// Builds the executive on the RMP base over `bus`: configures the driver from the robot
    /// file, opens its topics in `node`, then as [`Executive::with_devices`].
    pub fn new(
        config: ExecutiveConfig,
        clock: Arc<dyn Clock>,
        bus: B,
        arm: A,
        node: &IpcNode,
        scene: Scene,
        objects: usize,
    ) -> Result<Self, ExecutiveError> {
        check_capacity(&config)?;
        let base = RmpBase::new(CanLink::new(bus), rmp_config(&config))
            .map_err(|e| ExecutiveError::BaseConfig(e.to_string()))?;
        let ports = ExecutivePorts::open(node, &config.inputs)?;
        Executive::with_devices(config, clock, base, arm, ports, scene, objects)
    }
}

fn check_capacity(config: &ExecutiveConfig) -> Result<(), ExecutiveError> {
    let tray_slots = config.tray_slots.len().min(MAX_TRAY_SLOTS);
    if config.robot.carry_capacity as usize > tray_slots {
        return Err(ExecutiveError::CarryCapacity {
            carry_capacity: config.robot.carry_capacity,
            tray_slots,
        });
    }
    Ok(())
}

impl<D: BaseDevice, A: ArmDevice> Executive<D, A> {
    /// Builds the executive on devices and ports opened by the caller: solves the tray, builds
    /// the map, starts the path worker. `objects` is the number of objects of the task.
    pub fn with_devices(
        config: ExecutiveConfig,
        clock: Arc<dyn Clock>,
        base: D,
        arm: A,
        ports: ExecutivePorts,
        scene: Scene,
        objects: usize,
    ) -> Result<Self, ExecutiveError> {
        check_capacity(&config)?;
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
        let (cycle_period, base_every, heartbeat_period) =
            (config.cycle, config.base_every, config.heartbeat_period);
        Ok(Self {
            core: MissionCore::new(config, grid, Arc::new(scene), tray, objects),
            cycle_period,
            base_every,
            heartbeat_period,
            clock,
            base,
            arm,
            ports,
            worker,
            outputs: CycleOutputs::default(),
            fixes: Vec::with_capacity(MAX_FIXES_PER_CYCLE),
            plans: Vec::with_capacity(MAX_PLANS_PER_CYCLE),
            answer: None,
            pending_tick: None,
            arm_snapshot: ArmSnapshot::default(),
            arm_reading: Ok(ArmSnapshot::default()),
            skill_reading: None,
            planner_heartbeats: 0,
            skill_in_flight: false,
            start_refused: None,
            base_seq: 0,
            arm_seq: 0,
            heartbeat_seq: 0,
            next_heartbeat: Duration::ZERO,
            stats: ExecutiveStats::default(),
            loop_stats: grop_clock::rt::LoopStats::new(cycle_period),
            guard: None,
            align_in_flight: false,
            aligned: None,
            alignments_refused: 0,
            started_at: None,
            operator_enable: false,
            enables_refused: 0,
            last_verdict: Verdict {
                twist: Twist::ZERO,
                action: super::MonitorAction::Stale,
                clearance_m: f32::NEG_INFINITY,
                points: 0,
            },
        })
    }

    /// Puts the collision monitor, fed by `sensor`, between the core and the base driver, with
    /// the prior map's overhangs of `scene` (table tops the sensor's rings pass under). From
    /// then on a silent or out-of-spec sensor stops the base.
    pub fn set_range_sensor(&mut self, sensor: Box<dyn RangeSensor>, scene: &Scene) {
        let fp = self.core_config_footprint();
        self.guard = Some(Guard {
            sensor,
            monitor: CollisionMonitor::new(MonitorConfig::for_footprint(fp.0, fp.1)),
            scan: Obstacles::new(),
            overhangs: MapOverhangs::of_scene(scene),
            last_odometry: None,
            scans: 0,
        });
    }

    fn core_config_footprint(&self) -> (f32, f32) {
        let fp = self.core.footprint();
        (fp.length_m as f32, fp.width_m as f32)
    }

    /// What the collision monitor did on the last base cycle.
    pub fn monitor_verdict(&self) -> Verdict {
        self.last_verdict
    }

    /// The range sensor's health, or `None` without one.
    pub fn range_status(&self, now: Duration) -> Option<String> {
        self.guard.as_ref().map(|g| {
            format!(
                "{} ({} scans taken, {} alignments taken, {} refused)",
                g.sensor.status(now),
                g.scans,
                self.core.stats().alignments,
                self.alignments_refused
            )
        })
    }

    /// The mission state.
    pub fn state(&self) -> MissionState {
        self.core.state()
    }

    /// Operator enables refused: given before this executive started, or stamped in the
    /// future.
    pub fn enables_refused(&self) -> u64 {
        self.enables_refused
    }

    /// Counters.
    pub fn stats(&self) -> ExecutiveStats {
        let core = self.core.stats();
        ExecutiveStats {
            unloads_ok: core.unloads_ok,
            unloads_failed: core.unloads_failed,
            plans: core.plans,
            inputs_refused: self.ports.inputs.refused(),
            ..self.stats
        }
    }

    /// How late the minor cycle woke (p50 / p99 / max) and its overruns.
    pub fn loop_summary(&self) -> grop_clock::rt::LoopSummary {
        self.loop_stats.summary()
    }

    /// The base device (tests inspect it).
    pub fn base(&self) -> &D {
        &self.base
    }

    /// The mission core (tests inspect it).
    pub fn core(&self) -> &MissionCore {
        &self.core
    }

    /// Runs cycles until `keep_going` says stop, the mission ends and `exit_when_done` is set,
    /// or the clock is lost. Returns the final state.
    pub fn run(&mut self, keep_going: &dyn Fn() -> bool, exit_when_done: bool) -> MissionState {
        self.clock.wait_turn();
        let mut deadline = self.clock.now();
        loop {
            if !keep_going() {
                self.abort_now(AbortReason::Shutdown, deadline);
                // A few more base periods so the zero command reaches the base.
                for _ in 0..5 * self.base_every {
                    deadline += self.cycle_period;
                    self.clock.sleep_until(deadline);
                    self.cycle(deadline);
                }
                return self.state();
            }
            if self.clock.is_lost() {
                self.abort_now(AbortReason::ClockLost, deadline);
                return self.state();
            }
            self.cycle(deadline);
            if exit_when_done
                && matches!(
                    self.state(),
                    MissionState::Finished | MissionState::Aborted(_)
                )
            {
                return self.state();
            }
            deadline += self.cycle_period;
            if self.clock.now() > deadline {
                self.stats.overruns += 1;
                // Far behind: skip ahead rather than burst.
                let now = self.clock.now();
                if now > deadline + 5 * self.cycle_period {
                    deadline = now;
                }
            }
            self.clock.sleep_until(deadline);
            self.loop_stats.record(deadline, self.clock.now());
        }
    }

    /// Aborts at once, outside a cycle: zero velocity target, the arm stopped, the events out.
    fn abort_now(&mut self, reason: AbortReason, now: Duration) {
        self.outputs.clear();
        self.core.abort(reason, now, &mut self.outputs);
        if self.outputs.safety_stop {
            self.base.safety_stop();
        }
        self.base.set_velocity(self.outputs.velocity, now);
        self.write_arm(now);
        self.write_messages();
    }

    /// One minor cycle at `now`: read, update, write (public so tests can step it).
    pub fn cycle(&mut self, now: Duration) {
        self.stats.cycles += 1;
        self.started_at.get_or_insert(now);
        let base_cycle =
            self.base_every <= 1 || self.stats.cycles % u64::from(self.base_every.max(1)) == 1;
        self.read(now, base_cycle);
        let tick = self.pending_tick.take();
        let inputs = CycleInputs {
            now,
            base_cycle,
            base: BaseReading {
                odometry: self.base.odometry(),
                driving: self.base.is_driving(),
            },
            base_tick: tick.as_ref(),
            arm: self.arm_reading,
            skill: self.skill_reading,
            fixes: &self.fixes,
            plans: &self.plans,
            planner_heartbeats: self.planner_heartbeats,
            answer: self.answer.as_ref(),
            shutdown: false,
            clock_lost: false,
            monitor: self.last_verdict.action,
            sent: self.last_verdict.twist,
            aligned: self.aligned.take(),
            operator_enable: self.operator_enable,
            scan: self.guard.as_ref().and_then(|g| g.monitor.obstacles()),
        };
        self.outputs.clear();
        self.core.update(&inputs, &mut self.outputs);
        if base_cycle {
            // The core reads answers on base cycles only.
            self.answer = None;
        }
        self.write(now, base_cycle);
    }
}

impl<D: BaseDevice, A: ArmDevice> Executive<D, A> {
    /// Read: the arm every cycle (its state, then the skill in flight) and the plans; on base
    /// cycles the fixes, heartbeats and the worker's answer too.
    fn read(&mut self, now: Duration, base_cycle: bool) {
        self.arm_reading = self.arm.update(now);
        if let Ok(s) = self.arm_reading {
            self.arm_snapshot = s;
        }
        self.skill_reading = None;
        if self.skill_in_flight {
            let result = match self.start_refused.take() {
                Some(fault) => Err(fault),
                None => self.arm.poll(now),
            };
            if !matches!(result, Ok(SkillStatus::Running)) {
                self.skill_in_flight = false;
            }
            self.skill_reading = Some(result);
        }
        // Only the deployment's publishers, in sequence (inputs.rs); refusals are reported.
        let inputs = &mut self.ports.inputs;
        if !base_cycle {
            // Plans every cycle: the core asks for the path as soon as one is in (docs/latency.md).
            inputs.read_plans(now, &mut self.plans, MAX_PLANS_PER_CYCLE);
            return;
        }
        inputs.read_fixes(now, &mut self.fixes, MAX_FIXES_PER_CYCLE);
        self.planner_heartbeats = inputs.read_planner_heartbeats(now);
        inputs.read_plans(now, &mut self.plans, MAX_PLANS_PER_CYCLE);
        // The operator's enable, from the deployment's operator; taken only if given after
        // this executive started (a restart is not an enable) and not in the future.
        self.operator_enable = false;
        let since = ns(self.started_at.unwrap_or(now));
        let latest = ns(now.saturating_add(Duration::from_millis(100)));
        while let Some(enable) = inputs.read_enable(now) {
            if (since..=latest).contains(&enable.stamp_ns) {
                self.operator_enable = true;
            } else {
                // The newest enable (kept for late joiners) was given to the executive before
                // this one, or the stamp lies.
                self.enables_refused += 1;
                log::warn!(
                    "operator enable #{} from pid {} stamped {:.3} s refused: not given after this executive started at {:.3} s (or in the future)",
                    enable.seq,
                    enable.pid,
                    enable.stamp_ns as f64 * 1e-9,
                    since as f64 * 1e-9
                );
            }
        }
        inputs.report_pending(now);
        if self.answer.is_none() {
            self.answer = match self.worker.try_answer() {
                Some(Answer::Align(_, alignment, odom)) => {
                    self.align_in_flight = false;
                    if alignment.accepted() {
                        self.aligned = Some((alignment.pose, odom));
                    } else {
                        self.alignments_refused += 1;
                    }
                    None
                }
                other => other,
            };
        }
    }

    /// The collision monitor's pass over the core's velocity (base cycles): a new revolution
    /// replaces the obstacles (with the map's overhangs at the estimate), otherwise they move
    /// with the odometry; then the check. Without a sensor the velocity passes unchanged.
    fn guarded(&mut self, velocity: Twist, now: Duration) -> Twist {
        let Some(g) = self.guard.as_mut() else {
            self.last_verdict = Verdict {
                twist: velocity,
                action: super::MonitorAction::Clear,
                clearance_m: f32::INFINITY,
                points: 0,
            };
            return velocity;
        };
        let odometry = self.base.odometry();
        let own = g.monitor.config().own_body();
        if g.sensor.poll(
            now,
            odometry.speed_mps as f32,
            odometry.yaw_rate_radps as f32,
            &mut g.scan,
        ) {
            g.scans += 1;
            let (seq, stamp_ns) = (g.scans, u64::try_from(now.as_nanos()).unwrap_or(u64::MAX));
            let _ = self.ports.scan.publish_with(|m| {
                m.seq = seq;
                m.stamp_ns = stamp_ns;
                m.set_points(g.scan.iter());
            });
            // The scan as the sensor saw it, to the worker for the alignment to the map.
            if !self.align_in_flight {
                let mut points = [[0.0f32; 2]; ALIGN_POINTS];
                let mut count = 0usize;
                for (slot, p) in points.iter_mut().zip(g.scan.iter()) {
                    *slot = p;
                    count += 1;
                }
                let e = self.core.estimate();
                let job = Job::Align {
                    id: 0,
                    prior: e,
                    odom: odometry.pose(),
                    count: count as u16,
                    points,
                };
                self.align_in_flight = matches!(self.worker.submit(job), Ok(true));
            }
            g.overhangs.add_to(self.core.estimate(), own, &mut g.scan);
            g.monitor.set_scan(&g.scan);
        } else if let (Some(before), Some(obstacles)) = (g.last_odometry, g.monitor.obstacles_mut())
        {
            // The base moved since the last cycle: the new base pose in the old base frame.
            let (x_m, y_m) = before
                .pose()
                .inverse_transform_point(odometry.x_m, odometry.y_m);
            let yaw_rad = planar::wrap_angle(odometry.yaw_rad - before.yaw_rad);
            obstacles.move_base(Pose2::new(x_m, y_m, yaw_rad).to_f32());
        }
        g.last_odometry = Some(odometry);
        let now_us = u64::try_from(now.as_micros()).unwrap_or(u64::MAX);
        let verdict = g.monitor.check(velocity, self.outputs.monitor_mode, now_us);
        if verdict.action != self.last_verdict.action && log::log_enabled!(log::Level::Debug) {
            let fp = g.monitor.config();
            let nearest = g.monitor.obstacles().and_then(|o| {
                o.iter().min_by(|a, b| {
                    let d = |p: &[f32; 2]| {
                        motion_control::collision::signed_distance(
                            p[0],
                            p[1],
                            fp.half_length_m,
                            fp.half_width_m,
                        )
                    };
                    d(a).total_cmp(&d(b))
                })
            });
            log::debug!(
                "monitor at {:.3} s: {:?} -> {:?} ({:?} mode), command {:?} -> {:?}, clearance {:.3} m, {} points, nearest {:?} (base frame), estimate {:?}",
                now.as_secs_f64(),
                self.last_verdict.action,
                verdict.action,
                self.outputs.monitor_mode,
                velocity,
                verdict.twist,
                verdict.clearance_m,
                verdict.points,
                nearest,
                self.core.estimate()
            );
        }
        self.last_verdict = verdict;
        verdict.twist
    }

    /// Write: the arm command, the worker job, the base's mode, velocity and tick (base cycles),
    /// then the messages.
    fn write(&mut self, now: Duration, base_cycle: bool) {
        self.write_arm(now);
        if let Some(job) = self.outputs.job.take() {
            self.submit(job);
        }
        if let Some(mode) = self.outputs.base_mode {
            self.base.request_mode(mode, now);
        }
        if self.outputs.rearm_base {
            self.base.rearm();
        }
        if self.outputs.safety_stop {
            self.base.safety_stop();
        }
        self.write_messages();
        self.publish_arm_state(now);
        if base_cycle {
            let velocity = self.guarded(self.outputs.velocity, now);
            self.base.set_velocity(velocity, now);
            let tick = self.base.tick(now);
            self.publish_base_state(now, &tick);
            self.pending_tick = Some(tick);
        }
        if now >= self.next_heartbeat {
            self.next_heartbeat = now + self.heartbeat_period;
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

    fn write_arm(&mut self, now: Duration) {
        let started = match self.outputs.arm {
            ArmCommand::None => return,
            ArmCommand::Stop => {
                self.arm.stop(now);
                self.skill_in_flight = false;
                self.start_refused = None;
                return;
            }
            ArmCommand::MoveJoints(q) => self.arm.start_move_joints(&q, now),
            ArmCommand::Gripper(close) => self.arm.start_gripper(close, now),
        };
        self.skill_in_flight = true;
        self.start_refused = started.err();
    }

    /// Hands a job to the worker; one it cannot take is answered as failed for the next update.
    /// A path job gets what the range sensor sees now, in the world frame at the estimate.
    fn submit(&mut self, mut job: Job) {
        if let Job::Path { seen, .. } = &mut job
            && let Some(obstacles) = self.guard.as_ref().and_then(|g| g.monitor.obstacles())
        {
            let e = self.core.estimate();
            let (s, c) = e.yaw_rad.sin_cos();
            for [px, py] in obstacles.iter() {
                let (bx, by) = (f64::from(px), f64::from(py));
                let _ = seen.push(
                    (e.x_m + c * bx - s * by) as f32,
                    (e.y_m + s * bx + c * by) as f32,
                );
            }
        }
        match self.worker.submit(job) {
            Ok(true) => {}
            refused => {
                let gone = matches!(refused, Err(PathFailure::WorkerGone));
                self.answer = Some(match job {
                    Job::Path { id, .. } => Answer::Path(
                        id,
                        Err(if gone {
                            PathFailure::WorkerGone
                        } else {
                            PathFailure::NoRoute
                        }),
                    ),
                    Job::Unload { id, .. } => Answer::Unload(id, Err(UnloadFailure::NoArmPath)),
                    // Not taken: the next scan tries again.
                    Job::Align { .. } => return,
                });
            }
        }
    }

    fn write_messages(&mut self) {
        if let Some(req) = self.outputs.request.take() {
            self.stats.published += 1;
            let _ = self.ports.requests.publish(&req);
        }
        if let Some(load) = self.outputs.load_request.take() {
            self.stats.published += 1;
            let _ = self.ports.loads.publish(&load);
        }
        for event in &self.outputs.events {
            self.stats.published += 1;
            let _ = self.ports.events.publish(event);
        }
        self.outputs.events.clear();
        if self.outputs.events_dropped > 0 {
            log::warn!(
                "{} events of one cycle did not fit the outputs",
                self.outputs.events_dropped
            );
        }
    }

    fn publish_arm_state(&mut self, now: Duration) {
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

    fn publish_base_state(&mut self, now: Duration, tick: &Result<Tick, BaseError>) {
        let odo = self.base.odometry();
        let est = self.core.estimate();
        let status = self.base.status();
        let commanded = tick
            .as_ref()
            .map(|t| t.commanded)
            .unwrap_or(motion_control::Twist::ZERO);
        let watchdog = tick.as_ref().map(|t| t.input_stale).unwrap_or(true);
        let link_up = !matches!(tick, Err(BaseError::Silent { .. }));
        let (monitor, clearance_cm) = self.monitor_wire();
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
            m.set_monitor(monitor);
            m.monitor_clearance_cm = clearance_cm;
        });
    }

    /// The collision monitor's last verdict as `base/state` carries it: its state, and the
    /// clearance in whole centimetres (saturated; none seen, or no sensor: `NO_CLEARANCE_CM`).
    fn monitor_wire(&self) -> (grop_ipc::MonitorState, u16) {
        use grop_ipc::{MonitorState, NO_CLEARANCE_CM};
        use motion_control::collision::Action;
        if self.guard.is_none() {
            return (MonitorState::Off, NO_CLEARANCE_CM);
        }
        let v = &self.last_verdict;
        let state = match v.action {
            Action::Clear => MonitorState::Clear,
            Action::Crawl => MonitorState::Crawl,
            Action::Slowdown => MonitorState::Slowdown,
            Action::Approach => MonitorState::Approach,
            Action::Stop => MonitorState::Stop,
            Action::Stale => MonitorState::Stale,
        };
        let cm = if v.clearance_m.is_finite() {
            // In range: 0 ..= 65,534 cm after the clamp.
            (v.clearance_m.max(0.0) * 100.0)
                .round()
                .min(f32::from(NO_CLEARANCE_CM - 1)) as u16
        } else {
            NO_CLEARANCE_CM
        };
        (state, cm)
    }
}
