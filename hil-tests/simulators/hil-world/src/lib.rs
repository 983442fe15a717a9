//! The closed-loop HIL world: one process owns the truth and the clock.
//!
//! It creates the simulated clock ([`grop_clock::SimClockHost`]) and steps, every 2 ms of
//! simulated time: the simulated Segway RMP on the iceoryx2 virtual CAN bus (it answers the
//! executive's commands and moves as a unicycle), the simulated UR5e controller on loopback TCP
//! (externally stepped, mounted on the moving base), the objects (tray, gripper, release and
//! judgement, [`objects`]), continuous collision checks of the base footprint and the arm links
//! against the furniture, an overhead camera publishing real-size RGB frames on
//! `camera/frame`, and localisation fixes on `base/pose` whose per-leg error makes the
//! realised stop follow the robot file's navigation noise ([`fixes`]). Between steps it lets
//! the onboard processes (planner, executive) run in lock-step. It listens to `events`,
//! `plan/task` and `load/request` (the station loads what the executive asks), notices dead processes through the clock, and writes a [`report`].
//!
//! The onboard binaries run against it unchanged: they see a CAN bus, a UR5e, iceoryx2 topics
//! and a clock.

pub mod faults;
pub mod fixes;
pub mod harness_error;
mod injector;
pub mod lidar;
pub mod mission;
pub mod moves;
pub mod objects;
pub mod report;
pub mod suite;

use std::time::{Duration, Instant};

use can_bus::VirtualCanBus;
use grop_clock::{HostConfig, SimClockHost};
use grop_ipc::{
    BasePoseMsg, CameraFrameMsg, EventMsg, HeartbeatMsg, IpcNode, LoadRequestMsg, PoseFixKind,
    ProcessRole, TaskPlanMsg, TaskStepKind, TopicPublisher, TopicSubscriber,
};
use nalgebra::Point3;
use planar::Pose2;
use sim_rmp::{SimRmp, SimRmpNode};
use sim_ur5e::Ur5eSim;
use ur5e_kin::ObstacleBox;
use world::{RobotConfig, Scene};

use faults::{CanFault, FaultKind, FaultRecord, FaultSpec, FaultyBus, Trigger};
use fixes::{FixModel, FixSimulator};
use grop_clock::duration_ns as ns;
use injector::Injector;
use objects::{JudgeConfig, ObjectEvent, ObjectTracker, Verdict};
use report::{
    CollisionRecord, DeathRecord, EventRecord, LegRecord, LoopTiming, MissionEnd, Part, PlanRecord,
    WorldReport,
};

/// The world's settings.
#[derive(Debug, Clone)]
pub struct WorldConfig {
    /// iceoryx2 namespace of the run.
    pub namespace: String,
    /// Name of the simulated clock (`sim:<name>` for the onboard processes).
    pub clock_name: String,
    /// Virtual CAN bus name.
    pub bus_name: String,
    /// The scene (truth).
    pub scene: Scene,
    /// The robot file.
    pub robot: RobotConfig,
    /// Seed of the world's noise (localisation).
    pub seed: u64,
    /// Step of the world (the UR5e's RTDE period). 2 ms.
    pub step: Duration,
    /// Camera frame size, px (width, height).
    pub camera_px: (u32, u32),
    /// Camera frame period (simulated).
    pub camera_period: Duration,
    /// Localisation fix period.
    pub fix_period: Duration,
    /// Localisation error model.
    pub fixes: FixModel,
    /// Judging.
    pub judge: JudgeConfig,
    /// Tray slots, base frame (the executive's, so loading matches).
    pub tray_slots: Vec<[f64; 3]>,
    /// `None`: lock-step as fast as possible; `Some(r)`: r simulated seconds per wall second.
    pub pace: Option<f64>,
    /// Participants that must join before the mission clock runs (names).
    pub expect: Vec<String>,
    /// How long (wall) to wait for them.
    pub join_timeout: Duration,
    /// Simulated time limit of the mission.
    pub max_sim_time: Duration,
    /// After the mission ends, keep stepping this long (so stops can be observed).
    pub linger: Duration,
    /// Print a progress line every this much simulated time (`None`: quiet).
    pub progress_every: Option<Duration>,
    /// The fault to inject (docs/reliability.md).
    pub fault: Option<FaultSpec>,
    /// Simulate the robot file's range sensor (the executive's collision monitor needs it).
    pub lidar: bool,
    /// The world plays the deployment's operator: when the executive asks for the enable (at
    /// start, and after a latched safety stop whose cause cleared) it gives it this much later
    /// on `operator/enable`. `None`: it never does (the executive then never arms).
    pub operator_delay: Option<Duration>,
    /// When the executive asks again after a latched stop cleared (a safeguard stop), the
    /// operator looks before enabling: this long.
    pub operator_resume_delay: Duration,
    /// Chairs the world moves during the mission ([`moves`]).
    pub chair_moves: Vec<moves::ChairMove>,
}

impl WorldConfig {
    /// Defaults for a scene and robot; names derived from `run`.
    pub fn new(run: &str, scene: Scene, robot: RobotConfig, seed: u64) -> Self {
        let sigma = robot.nav_noise_sigma_m;
        Self {
            namespace: format!("hil-{run}"),
            clock_name: format!("hil-{run}"),
            bus_name: format!("hil-{run}"),
            scene,
            robot,
            seed,
            step: Duration::from_millis(2),
            camera_px: (640, 480),
            camera_period: Duration::from_secs(1),
            fix_period: Duration::from_millis(100),
            fixes: FixModel::for_sigma(sigma),
            judge: JudgeConfig::default(),
            tray_slots: vec![
                [-0.20, -0.18, 1.10],
                [-0.20, 0.0, 1.10],
                [-0.20, 0.18, 1.10],
            ],
            pace: None,
            expect: vec!["grop-planner".into(), "grop-executive".into()],
            join_timeout: Duration::from_secs(60),
            max_sim_time: Duration::from_secs(900),
            linger: Duration::from_secs(2),
            progress_every: None,
            fault: None,
            lidar: true,
            operator_delay: Some(Duration::from_millis(100)),
            operator_resume_delay: Duration::from_secs(1),
            chair_moves: Vec::new(),
        }
    }
}

/// Why the world could not start.
#[derive(Debug, thiserror::Error)]
pub enum WorldError {
    /// The clock.
    #[error("simulated clock: {0}")]
    Clock(#[from] grop_clock::ClockError),
    /// The range sensor.
    #[error("simulated lidar: {0}")]
    Lidar(String),
    /// The CAN bus.
    #[error("virtual CAN bus: {0}")]
    Bus(String),
    /// The UR5e simulator.
    #[error("simulated UR5e: {0}")]
    Arm(std::io::Error),
    /// iceoryx2.
    #[error("IPC: {0}")]
    Ipc(String),
    /// A chair move that does not fit the scene.
    #[error("{0}")]
    ChairMove(#[from] moves::ChairMoveError),
    /// The robot file's `carry_capacity` exceeds the tray's slots (the plans would load objects
    /// the tray cannot hold).
    #[error(
        "robot file: carry_capacity = {carry_capacity} exceeds the world's {tray_slots} tray slots"
    )]
    CarryCapacity {
        /// The robot file's `carry_capacity`.
        carry_capacity: u32,
        /// `WorldConfig::tray_slots`.
        tray_slots: usize,
    },
}

/// The ports the simulated UR5e listens on (for the executive's deployment).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ArmPorts {
    /// RTDE.
    pub rtde: u16,
    /// Dashboard.
    pub dashboard: u16,
    /// Secondary (URScript).
    pub secondary: u16,
    /// Gripper.
    pub gripper: u16,
}

struct Ports {
    frames: TopicPublisher<CameraFrameMsg>,
    poses: TopicPublisher<BasePoseMsg>,
    world_events: TopicPublisher<EventMsg>,
    health: TopicPublisher<HeartbeatMsg>,
    enable: TopicPublisher<grop_ipc::OperatorEnableMsg>,
    truth: TopicPublisher<grop_ipc::TruthMsg>,
    events: TopicSubscriber<EventMsg>,
    plans: TopicSubscriber<TaskPlanMsg>,
    loads: TopicSubscriber<LoadRequestMsg>,
}

/// The world, built and listening; [`World::run`] runs the mission.
pub struct World {
    config: WorldConfig,
    host: SimClockHost,
    base: SimRmpNode<FaultyBus<VirtualCanBus>>,
    arm: Ur5eSim,
    ports: Ports,
    objects: ObjectTracker,
    fixes: FixSimulator,
    start: Pose2,
    lidar: Option<lidar::SimLidar>,
    _node: IpcNode,
}

fn ipc(e: impl std::fmt::Display) -> WorldError {
    WorldError::Ipc(e.to_string())
}

fn secs(d: Duration) -> f64 {
    d.as_secs_f64()
}

impl World {
    /// Creates the clock, joins the bus, starts the simulated UR5e (externally stepped, on
    /// ephemeral loopback ports) and opens the topics.
    pub fn new(config: WorldConfig) -> Result<Self, WorldError> {
        for m in &config.chair_moves {
            m.check(&config.scene)?;
        }
        if config.robot.carry_capacity as usize > config.tray_slots.len() {
            return Err(WorldError::CarryCapacity {
                carry_capacity: config.robot.carry_capacity,
                tray_slots: config.tray_slots.len(),
            });
        }
        let host = SimClockHost::create(
            &config.clock_name,
            HostConfig {
                // Until everyone joined, run at wall-clock pace so connections can be made.
                pace: Some(1.0),
                ..HostConfig::default()
            },
        )?;
        let bus = VirtualCanBus::join(&config.bus_name, "sim-rmp")
            .map_err(|e| WorldError::Bus(e.to_string()))?;
        let mut sim = SimRmp::new(sim_rmp::SimConfig::default());
        // The base as an earlier start of this robot's executive left it: its F-RAM holds the
        // robot's limits, which the driver reads back and does not write again. (The first
        // start on a factory base, which writes them, is tested in rmp-base and sim-rmp.)
        let driver = grop_onboard::executive::rmp_config_for(&config.robot, BASE_PERIOD);
        for (setting, value) in driver.base_settings() {
            if !sim.set_nvm(setting, value) {
                log::warn!("world: the simulated base refused {setting:?} = {value}");
            }
        }
        let limits = base_limits(&sim);
        let base = SimRmpNode::new(FaultyBus::new(bus, config.seed, limits), sim);
        let arm = Ur5eSim::start(sim_ur5e::SimConfig {
            stepping: sim_ur5e::Stepping::External,
            rate_hz: 1.0 / config.step.as_secs_f64(),
            ..sim_ur5e::SimConfig::ephemeral()
        })
        .map_err(WorldError::Arm)?;
        if config
            .fault
            .is_some_and(|f| f.kind == FaultKind::DashboardLate)
        {
            // From the start: the executive talks to the dashboard while it starts up.
            arm.link_faults()
                .dashboard_delay_ms
                .store(3000, std::sync::atomic::Ordering::Relaxed);
        }
        let node = IpcNode::new(&config.namespace, "world").map_err(ipc)?;
        let ports = Ports {
            frames: node.publisher().map_err(ipc)?,
            poses: node.publisher().map_err(ipc)?,
            world_events: node.publisher().map_err(ipc)?,
            health: node.publisher().map_err(ipc)?,
            enable: node.publisher().map_err(ipc)?,
            truth: node.publisher().map_err(ipc)?,
            events: node.subscriber().map_err(ipc)?,
            plans: node.subscriber().map_err(ipc)?,
            loads: node.subscriber().map_err(ipc)?,
        };
        let targets: Vec<[f64; 3]> = config.scene.targets.iter().map(|t| t.as_array()).collect();
        let objects = ObjectTracker::new(&targets, &config.tray_slots, config.judge);
        let fixes = FixSimulator::new(config.fixes, config.seed);
        let lidar = if config.lidar {
            Some(
                lidar::SimLidar::new(&config.scene, config.robot.lidar, config.seed)
                    .map_err(|e| WorldError::Lidar(e.to_string()))?,
            )
        } else {
            None
        };
        let start = config.scene.robot_start;
        Ok(Self {
            config,
            host,
            base,
            arm,
            ports,
            objects,
            fixes,
            start,
            lidar,
            _node: node,
        })
    }

    /// The loopback UDP port the simulated VLP-16 sends to (`None`: no sensor simulated).
    pub fn lidar_port(&self) -> Option<u16> {
        self.lidar.as_ref().map(lidar::SimLidar::port)
    }

    /// Where the simulated UR5e listens.
    pub fn arm_ports(&self) -> ArmPorts {
        let p = self.arm.ports();
        ArmPorts {
            rtde: p.rtde.port(),
            dashboard: p.dashboard.port(),
            secondary: p.secondary.port(),
            gripper: p.gripper.port(),
        }
    }

    /// The settings.
    pub fn config(&self) -> &WorldConfig {
        &self.config
    }

    /// The true base pose in the world.
    fn base_pose(&self) -> Pose2 {
        self.start.compose(&self.base.sim().pose())
    }

    /// Runs the mission to its end and returns the report. `stop` is polled every step (a
    /// signal handler's flag).
    #[allow(
        clippy::too_many_lines,
        reason = "the world's step loop; splitting it into an ordered list of systems is #23 item 5, still open"
    )]
    pub fn run(&mut self, stop: &dyn Fn() -> bool) -> WorldReport {
        let wall_start = Instant::now();
        // The truth may change during the run (chairs moved); the configuration keeps the start.
        let mut cfg = self.config.clone();
        let mut mover = moves::Mover::new(&cfg.chair_moves);
        let mut report = WorldReport {
            scene: cfg.scene.name.clone(),
            seed: cfg.seed,
            end: MissionEnd::NeverStarted,
            placed: 0,
            placed_end_state: 0,
            objects: Vec::new(),
            collisions: Vec::new(),
            legs: Vec::new(),
            trajectory: Vec::new(),
            events: Vec::new(),
            plans: Vec::new(),
            deaths: Vec::new(),
            timing: LoopTiming::default(),
            fault: cfg.fault.map(|f| FaultRecord {
                spec: f.to_string(),
                ..FaultRecord::default()
            }),
            commands: faults::CommandMonitor::default(),
            max_base_speed: (0.0, 0.0),
            min_base_clearance: None,
            base_blocks: 0,
            not_attempted: Vec::new(),
        };
        let mut injector = Injector::default();
        let mut frame_id = 0u64;
        let mut fix_seq = 0u64;
        let mut hb_seq = 0u64;
        let mut next_frame = Duration::ZERO;
        let mut next_fix = Duration::ZERO;
        let mut next_truth = Duration::ZERO;
        let mut truth_seq = 0u64;
        let mut next_traj = Duration::ZERO;
        let mut next_progress = Duration::ZERO;
        let mut next_collision_check = Duration::ZERO;
        let mut joined = false;
        let mut mission_start: Option<Duration> = None;
        let mut ended_at: Option<Duration> = None;
        let mut latest_plan: Vec<grop_ipc::TaskStep> = Vec::new();
        // The load request the station has not served yet (the newest; one load per request).
        let mut pending_load: Option<LoadRequestMsg> = None;
        let mut still_s = 0.0_f64;
        let mut was_moving = false;
        let mut leg_recorded = true;
        let mut goal_reached_pending = false;
        // The operator's enable, asked for and due then.
        let mut enable_due: Option<Duration> = None;
        let mut enable_seq = 0u64;
        let mut collided_this_leg = false;
        let mut in_collision = [false; 2];
        let mut blocked_since_check = false;
        let mut first_request: Option<f64> = None;
        let mut first_plan: Option<f64> = None;
        let mut first_motion: Option<f64> = None;
        let mut step_wall = Duration::ZERO;
        let mut obstacles: Vec<ObstacleBox> = Vec::with_capacity(64);
        let mut frame_buf = vec![0u8; (cfg.camera_px.0 * cfg.camera_px.1 * 3) as usize];
        let camera = world::camera::OverheadCamera::fitting_room_with(
            &cfg.scene,
            cfg.camera_px.0,
            cfg.camera_px.1,
        );
        let mut rendered_once = false;
        let dt = cfg.step;

        loop {
            let now = self.host.now();
            let work_started = Instant::now();
            if stop() {
                break;
            }
            // Everyone there? Then the mission clock runs at its own pace.
            if !joined {
                let names: Vec<String> =
                    self.host.participants().into_iter().map(|p| p.0).collect();
                if cfg.expect.iter().all(|e| names.iter().any(|n| n == e)) {
                    // Their subscriptions exist once they wait for their first turn: only then
                    // does the world publish its first frame and fix.
                    self.host.settle();
                    joined = true;
                    mission_start = Some(now);
                    self.host.set_pace(cfg.pace);
                    log::info!(
                        "world: {names:?} joined at {:.3} s; mission starts",
                        secs(now)
                    );
                } else if wall_start.elapsed() > cfg.join_timeout {
                    log::error!("world: onboard processes never joined ({names:?})");
                    report.end = MissionEnd::NeverStarted;
                    break;
                } else {
                    // Simulated time stays at zero (nothing is stepped) until everyone is
                    // there: how long the processes take to start never shows in the mission,
                    // so the same mission twice is the same, message for message. Connecting
                    // needs no step (request/reply, and the controller sends a state package
                    // as soon as RTDE streaming starts).
                    std::thread::sleep(Duration::from_millis(2));
                    continue;
                }
            }

            // Faults: strike when the trigger comes, then keep up what lasts.
            if let (Some(spec), Some(start)) = (cfg.fault, mission_start) {
                self.inject(spec, &mut injector, now, start, &mut report);
            }
            // The operator enables once a released fault is clear (a restart is not asked
            // for: the test checks that nothing moves all the same).
            if injector.enable_at.is_some_and(|t| now >= t) {
                injector.enable_at = None;
                enable_due = Some(now);
                if let Some(rec) = report.fault.as_mut() {
                    rec.enabled_after_release_at_s = Some(secs(now));
                }
            }
            // Things move: the sensor, the contact check and the camera see the new truth.
            if mover.apply_due(now, &mut cfg.scene)
                && let Some(lidar) = self.lidar.as_mut()
            {
                lidar.set_scene(&cfg.scene);
            }
            // Devices.
            let limits = base_limits(self.base.sim());
            let bus = self.base.bus_mut();
            bus.set_limits(limits);
            if let Err(e) = bus.set_now(now) {
                log::warn!("world: CAN injector: {e}");
            }
            let before = self.base.sim().kinematics();
            let pose_before = self.base_pose();
            if let Err(e) = self.base.poll(now) {
                log::warn!("world: sim-rmp: {e}");
            }
            // Contact is not free: a base that would move into furniture stays where it was,
            // its drives stalled (one already touching, e.g. from its start or a chair pushed
            // against it, may move, so that it can get away).
            if world::base_collides(&cfg.scene, &cfg.robot, self.base_pose())
                && !world::base_collides(&cfg.scene, &cfg.robot, pose_before)
            {
                self.base.sim_mut().block(before);
                blocked_since_check = true;
            }
            if let Err(e) = self.arm.step() {
                log::warn!("world: sim-ur5e step: {e}");
            }
            let pose = self.base_pose();
            if let Some(lidar) = self.lidar.as_mut() {
                // Every packet fired by now, from where the base is (a revolution's packets
                // spread over its 100 ms: the scan is skewed by the base's motion, as the real
                // one is).
                lidar.step(u64::try_from(now.as_micros()).unwrap_or(u64::MAX), pose);
            }
            let (v, w) = self.base.sim().velocity();
            let speed = f64::from(v).abs() + 0.3 * f64::from(w).abs();
            self.fixes.observe_motion(speed, secs(dt));
            let world_from_base = ur5e_kin::world_from_base(&pose);
            let snap = self.arm.snapshot();
            report.max_base_speed.0 = report.max_base_speed.0.max(f64::from(v).abs());
            report.max_base_speed.1 = report.max_base_speed.1.max(f64::from(w).abs());
            if let (Some(rec), Some(at)) = (report.fault.as_mut(), injector.at) {
                if now >= at {
                    if rec.base_stopped_at_s.is_none()
                        && f64::from(v).abs() < 0.01
                        && f64::from(w).abs() < 0.01
                    {
                        rec.base_stopped_at_s = Some(secs(now));
                    }
                    if rec.arm_stopped_at_s.is_none() && max_abs(&snap.qd) < 0.01 {
                        rec.arm_stopped_at_s = Some(secs(now));
                    }
                    let stops = self.arm.with_robot(|r| r.stops_asked());
                    let before = injector.stops_at_fault;
                    if rec.arm_stop_asked_at_s.is_none()
                        && stops.stop_programs > before.stop_programs
                    {
                        rec.arm_stop_asked_at_s = Some(secs(now));
                    }
                    rec.dashboard_stops = stops.dashboard.saturating_sub(before.dashboard);
                    if let Some((xy, q)) = injector.release_pose {
                        let moved = (pose.x_m - xy[0]).hypot(pose.y_m - xy[1]);
                        rec.base_moved_after_release_m = rec.base_moved_after_release_m.max(moved);
                        let turned = snap
                            .q
                            .iter()
                            .zip(q)
                            .fold(0.0_f64, |m, (a, b)| m.max((a - b).abs()));
                        rec.arm_moved_after_release_rad =
                            rec.arm_moved_after_release_rad.max(turned);
                    }
                }
            }
            injector.base_speed = f64::from(v).abs();
            injector.arm_speed = max_abs(&snap.qd);
            injector.gripper_active = self.arm.with_robot(|r| r.gripper.is_active());
            let place = &cfg.robot.place;
            let flange = world_from_base * place.mount.base_from_arm() * place.arm.forward(&snap.q);
            let tcp = flange * Point3::new(0.0, 0.0, place.tcp_offset_m);

            // Leg bookkeeping: a start after standing still begins a new leg.
            if speed > 0.01 {
                if !was_moving && still_s >= cfg.fixes.still_before_leg_s {
                    collided_this_leg = false;
                    leg_recorded = false;
                }
                if first_motion.is_none() && first_plan.is_some() {
                    first_motion = Some(secs(now));
                }
                still_s = 0.0;
                was_moving = true;
            } else {
                still_s += secs(dt);
                was_moving = false;
            }
            // The executive reached a goal: realised vs commanded.
            if !leg_recorded && goal_reached_pending {
                goal_reached_pending = false;
                leg_recorded = true;
                let goal = latest_plan
                    .iter()
                    .filter(|s| s.kind() == Ok(TaskStepKind::Navigate))
                    .map(|s| [s.x_m, s.y_m, s.yaw_rad])
                    .min_by(|a, b| {
                        let da = (a[0] - pose.x_m).hypot(a[1] - pose.y_m);
                        let db = (b[0] - pose.x_m).hypot(b[1] - pose.y_m);
                        da.total_cmp(&db)
                    });
                if let Some(goal) = goal {
                    if (goal[0] - pose.x_m).hypot(goal[1] - pose.y_m) < 0.6 {
                        let b = self.fixes.bias();
                        report.legs.push(LegRecord {
                            t_s: secs(now),
                            commanded: goal,
                            realised: [pose.x_m, pose.y_m, pose.yaw_rad],
                            fix_bias: [b[0], b[1]],
                        });
                    }
                }
            }

            // Collisions, every 10 ms.
            if now >= next_collision_check {
                next_collision_check = now + Duration::from_millis(10);
                let blocked = std::mem::take(&mut blocked_since_check);
                let base_hit = world::base_collides(&cfg.scene, &cfg.robot, pose) || blocked;
                if mission_start.is_some() {
                    let gap = if blocked {
                        0.0
                    } else {
                        world::base_clearance(&cfg.scene, &cfg.robot, pose)
                    };
                    if report.min_base_clearance.is_none_or(|(g, _)| gap < g) {
                        report.min_base_clearance = Some((gap, [pose.x_m, pose.y_m, pose.yaw_rad]));
                    }
                }
                cfg.scene
                    .obstacle_boxes_into(&cfg.robot, pose, &mut obstacles);
                // The robot's own body (first box) is not furniture.
                let furniture = obstacles.get(1..).unwrap_or(&[]);
                let arm_hit =
                    ur5e_kin::place::arm_touches_obstacles(place, pose, &snap.q, furniture);
                for (k, (hit, part)) in [(base_hit, Part::Base), (arm_hit, Part::Arm)]
                    .into_iter()
                    .enumerate()
                {
                    if hit && !in_collision[k] {
                        collided_this_leg = true;
                        let obstacle = match part {
                            Part::Arm => furniture
                                .iter()
                                .find(|b| {
                                    ur5e_kin::place::arm_collides(
                                        place,
                                        pose,
                                        &snap.q,
                                        std::slice::from_ref(*b),
                                    )
                                })
                                .map(|b| [b.center.x, b.center.y, b.center.z]),
                            Part::Base => None,
                        };
                        report.collisions.push(CollisionRecord {
                            t_s: secs(now),
                            part,
                            base: [pose.x_m, pose.y_m, pose.yaw_rad],
                            q: snap.q,
                            obstacle,
                        });
                        self.world_event(
                            grop_ipc::EventKind::Collision,
                            now,
                            &format!(
                                "{part:?} touched furniture at ({:.2}, {:.2})",
                                pose.x_m, pose.y_m
                            ),
                        );
                    }
                    in_collision[k] = hit;
                }
            }

            // Objects: loading at the station (exactly what the executive asks for, once per
            // request, once the base stands there), gripper, release.
            while let Ok(Some(req)) = self.ports.loads.try_recv() {
                if let Some(old) = pending_load.replace(*req) {
                    self.world_event(
                        grop_ipc::EventKind::Loaded,
                        now,
                        &format!(
                            "load request {} superseded by {} before the base stood at the station: nothing loaded for it",
                            old.request_id, req.request_id
                        ),
                    );
                }
            }
            let station = cfg.scene.loading_station;
            if still_s >= 1.0 && (pose.x_m - station.x_m).hypot(pose.y_m - station.y_m) < 0.5 {
                if let Some(req) = pending_load.take() {
                    let detail = match self.objects.load(req.object_mask, &req.slots) {
                        Some(ObjectEvent::Loaded { mask }) if mask == req.object_mask => format!(
                            "load request {}: objects {mask:#x} put on the tray",
                            req.request_id
                        ),
                        Some(ObjectEvent::Loaded { mask }) => format!(
                            "load request {}: objects {mask:#x} put on the tray of {:#x} asked for (the rest is not at the station or the tray is full)",
                            req.request_id, req.object_mask
                        ),
                        _ => format!(
                            "load request {}: nothing of {:#x} at the station or room on the tray",
                            req.request_id, req.object_mask
                        ),
                    };
                    self.world_event(grop_ipc::EventKind::Loaded, now, &detail);
                }
            }
            let table = &cfg.scene.banquet_table;
            let (width, event) = self.objects.step_gripper(
                &world_from_base,
                tcp,
                snap.gripper_opening_m,
                collided_this_leg,
                in_collision[0] || in_collision[1],
                |x, y| table.top_contains(x, y),
            );
            self.arm.set_gripper_object(width);
            if let Some(ObjectEvent::Judged {
                index,
                verdict,
                error_m,
            }) = event
            {
                self.world_event(
                    grop_ipc::EventKind::ObjectJudged,
                    now,
                    &format!(
                        "object {index}: {verdict:?}, {:.3} m from its target",
                        error_m
                    ),
                );
            }

            // The truth, for the log (never read onboard).
            if now >= next_truth {
                next_truth = now + TRUTH_PERIOD;
                truth_seq += 1;
                let _ = self.ports.truth.publish(&grop_ipc::TruthMsg {
                    seq: truth_seq,
                    stamp_ns: ns(now),
                    x_m: pose.x_m,
                    y_m: pose.y_m,
                    yaw_rad: pose.yaw_rad,
                    speed_mps: f64::from(v),
                    yaw_rate_radps: f64::from(w),
                });
            }

            // Localisation fixes.
            if now >= next_fix {
                next_fix = now + cfg.fix_period;
                let truth = [pose.x_m, pose.y_m, pose.yaw_rad];
                let mut g = self.fixes.global_fix(truth);
                if injector.take_fix_jump() {
                    // 1.5 m to the side of the heading: a plausible, wrong fix.
                    g[0] -= 1.5 * truth[2].sin();
                    g[1] += 1.5 * truth[2].cos();
                }
                fix_seq += 1;
                let m = &cfg.fixes;
                let _ = self.ports.poses.publish(&BasePoseMsg::fix(
                    fix_seq,
                    ns(now),
                    PoseFixKind::Global,
                    g,
                    m.leg_bias_sigma_m,
                    m.leg_yaw_sigma_rad,
                ));
                let to_table = (pose.y_m - table_edge_y(&cfg.scene, pose.y_m)).abs();
                if let Some(t) = self.fixes.table_fix(truth, to_table) {
                    fix_seq += 1;
                    let _ = self.ports.poses.publish(&BasePoseMsg::fix(
                        fix_seq,
                        ns(now),
                        PoseFixKind::TableRelative,
                        t,
                        m.table_sigma_m,
                        m.table_yaw_sigma_rad,
                    ));
                }
                hb_seq += 1;
                let hb = hb_seq;
                let _ = self.ports.health.publish_with(|h| {
                    h.seq = hb;
                    h.stamp_ns = ns(now);
                    h.set_role(ProcessRole::World);
                    h.pid = std::process::id();
                });
            }

            // The operator.
            if enable_due.is_some_and(|due| now >= due) {
                enable_due = None;
                enable_seq += 1;
                let _ = self.ports.enable.publish(&grop_ipc::OperatorEnableMsg {
                    seq: enable_seq,
                    stamp_ns: ns(now),
                    pid: std::process::id(),
                    reserved: 0,
                });
                self.world_event(grop_ipc::EventKind::Enable, now, "operator: enable given");
            }

            // Camera.
            if now >= next_frame {
                next_frame = now + cfg.camera_period;
                frame_id += 1;
                let mut header = grop_ipc::CameraFrameHeader::for_layout(
                    frame_id,
                    ns(now),
                    &world::camera::FrameLayout::rgb8(camera),
                );
                let corrupt = injector
                    .camera_corrupt_until
                    .is_some_and(|until| now < until);
                if corrupt {
                    // A row stride shorter than a row: no consumer may read pixels from it.
                    header.row_stride_bytes = camera.width_px;
                }
                if injector.camera_narrow {
                    // The same rows, fewer columns: the frame's west quarter only.
                    header.width_px = (camera.width_px / 4).max(1);
                }
                // The furniture does not move: render once, publish the same picture.
                if !rendered_once {
                    rendered_once = true;
                    if let Err(e) = world::camera::render_frame(&cfg.scene, &camera, &mut frame_buf)
                    {
                        log::error!("world: camera: {e}");
                    }
                }
                let published = if corrupt {
                    self.ports
                        .frames
                        .publish_with(|f| f.header = header)
                        .is_ok()
                } else {
                    // Only the image's bytes are written (not the whole 3.5 MiB buffer).
                    self.ports
                        .frames
                        .publish_frame(header, |dst| {
                            if dst.len() == frame_buf.len() {
                                dst.copy_from_slice(&frame_buf);
                            }
                        })
                        .is_ok()
                };
                if published {
                    report.timing.frames += 1;
                }
            }

            // What the onboard processes say.
            while let Ok(Some(plan)) = self.ports.plans.try_recv() {
                if let Ok(steps) = plan.steps() {
                    latest_plan.clear();
                    latest_plan.extend_from_slice(steps);
                    if first_plan.is_none() {
                        first_plan = Some(secs(now));
                    }
                    report.plans.push(PlanRecord {
                        t_s: secs(now),
                        plan_id: plan.plan_id,
                        answers_request: plan.answers_request,
                        decision_us: plan.decision_us,
                        utility: plan.utility,
                        feasibility: plan.feasibility,
                        cost_s: plan.cost_s,
                        unloads: steps
                            .iter()
                            .filter(|s| s.kind() == Ok(TaskStepKind::Unload))
                            .map(|s| (s.object_index, s.side, s.x_m, s.y_m, s.feasibility))
                            .collect(),
                    });
                }
            }
            while let Ok(Some(ev)) = self.ports.events.try_recv() {
                let kind = ev.kind();
                let detail = ev.detail().unwrap_or("<not UTF-8>").to_owned();
                let kind_name = match kind {
                    Ok(k) => format!("{k:?}"),
                    Err(_) => format!("unknown({})", ev.kind),
                };
                if kind == Ok(grop_ipc::EventKind::GoalReached) {
                    goal_reached_pending = true;
                }
                // The executive asks for the operator's enable: the operator gives it.
                if kind == Ok(grop_ipc::EventKind::Enable)
                    && detail.contains("waiting for the operator's enable")
                {
                    let resume = detail.contains("normal again");
                    enable_due = cfg
                        .operator_delay
                        .map(|d| now + if resume { cfg.operator_resume_delay } else { d });
                }
                if kind == Ok(grop_ipc::EventKind::ReplanRequested) && first_request.is_none() {
                    first_request = Some(ns_to_s(ev.stamp_ns));
                }
                let is_end = matches!(
                    kind,
                    Ok(grop_ipc::EventKind::PlanFinished | grop_ipc::EventKind::MissionAborted)
                );
                if cfg.progress_every.is_some() {
                    println!("[{:7.2} s] {kind_name}: {detail}", ns_to_s(ev.stamp_ns));
                }
                report.events.push(EventRecord {
                    t_s: ns_to_s(ev.stamp_ns),
                    kind: kind_name,
                    plan_id: ev.plan_id,
                    step: ev.step_index,
                    detail,
                });
                if is_end && ended_at.is_none() {
                    ended_at = Some(now);
                    report.end = if kind == Ok(grop_ipc::EventKind::PlanFinished) {
                        MissionEnd::Finished
                    } else {
                        MissionEnd::Aborted
                    };
                }
            }

            // Deaths (the clock noticed), and what the base and arm did afterwards.
            for gone in self.host.take_departures() {
                println!(
                    "[{:7.2} s] world: participant {:?} (pid {}) died",
                    secs(gone.at),
                    gone.name,
                    gone.pid
                );
                report.deaths.push(DeathRecord {
                    name: gone.name.clone(),
                    pid: gone.pid,
                    t_s: secs(gone.at),
                    base_speed_then_mps: f64::from(v).abs(),
                    base_stopped_at_s: None,
                    arm_speed_then_radps: max_abs(&snap.qd),
                    arm_stopped_at_s: None,
                });
                if gone.name == "grop-executive" && ended_at.is_none() {
                    ended_at = Some(now);
                    report.end = MissionEnd::ExecutiveDied;
                }
            }
            for d in report.deaths.iter_mut() {
                if d.base_stopped_at_s.is_none()
                    && f64::from(v).abs() < 0.01
                    && f64::from(w).abs() < 0.01
                {
                    d.base_stopped_at_s = Some(secs(now));
                }
                if d.arm_stopped_at_s.is_none() && max_abs(&snap.qd) < 0.01 {
                    d.arm_stopped_at_s = Some(secs(now));
                }
            }

            if now >= next_traj {
                next_traj = now + Duration::from_millis(200);
                report
                    .trajectory
                    .push([secs(now), pose.x_m, pose.y_m, pose.yaw_rad]);
            }
            if let Some(every) = cfg.progress_every {
                if now >= next_progress {
                    next_progress = now + every;
                    let placed = self
                        .objects
                        .objects()
                        .iter()
                        .filter(|o| {
                            matches!(
                                o.state,
                                objects::ObjectState::Released {
                                    verdict: Verdict::Placed,
                                    ..
                                }
                            )
                        })
                        .count();
                    println!(
                        "progress t={:.1} x={:.2} y={:.2} v={:.2} arm={:.2} placed={placed}/{}",
                        secs(now),
                        pose.x_m,
                        pose.y_m,
                        v,
                        max_abs(&snap.qd),
                        self.objects.objects().len()
                    );
                }
            }

            step_wall += work_started.elapsed();
            report.timing.steps += 1;
            if let Some(end) = ended_at {
                // A fault a person releases: watched until 3 s after its release too.
                let watched = injector.release_at.is_none()
                    && injector.watch_until.is_none_or(|until| now >= until);
                if now >= end + cfg.linger && watched {
                    break;
                }
            }
            if let Some(start) = mission_start {
                if now.saturating_sub(start) > cfg.max_sim_time {
                    report.end = MissionEnd::TimedOut;
                    break;
                }
            }
            if injector.jump.take().is_some() {
                self.host.jump_to(now + Duration::from_secs(1));
            } else {
                self.host.advance_to(now + dt);
            }
        }
        report.commands = self.base.bus_mut().monitor();
        report.base_blocks = self.base.sim().stats().blocks;
        if let (Some(rec), Some(at)) = (report.fault.as_mut(), injector.at) {
            rec.can = self.base.bus_mut().counts();
            rec.can.intruder = injector.intruder_frames;
            let at_s = secs(at);
            rec.commanded_zero_at_s = report.commands.zero_since_s.map(|z| z.max(at_s));
            rec.first_zero_command_at_s = report.commands.first_zero_after_mark_s;
        }

        report.objects = self.objects.objects().to_vec();
        report.not_attempted = report
            .objects
            .iter()
            .filter(|o| o.state == objects::ObjectState::AtStation)
            .map(|o| o.index)
            .collect();
        let verdicts: Vec<Verdict> = report
            .objects
            .iter()
            .filter_map(|o| match o.state {
                objects::ObjectState::Released { verdict, .. } => Some(verdict),
                _ => None,
            })
            .collect();
        report.placed = verdicts.iter().filter(|v| v.placed_strictly()).count();
        report.placed_end_state = verdicts.iter().filter(|v| v.placed_end_state()).count();
        report.timing.sim_time_s = secs(self.host.now());
        report.timing.wall_time_s = wall_start.elapsed().as_secs_f64();
        report.timing.world_step_us =
            step_wall.as_secs_f64() * 1e6 / report.timing.steps.max(1) as f64;
        report.timing.request_to_plan_s = match (first_request, first_plan) {
            (Some(r), Some(p)) => Some((p - r).max(0.0)),
            _ => None,
        };
        report.timing.plan_to_motion_s = match (first_plan, first_motion) {
            (Some(p), Some(m)) => Some(m - p),
            _ => None,
        };
        report
    }

    fn world_event(&mut self, kind: grop_ipc::EventKind, now: Duration, detail: &str) {
        log::info!("world: {detail}");
        let msg = EventMsg::new(kind, ns(now), detail).with_source(grop_ipc::ProcessRole::World);
        let _ = self.ports.world_events.publish(&msg);
    }
}

/// The executive's base command period (the stored limits do not depend on it).
const BASE_PERIOD: Duration = Duration::from_millis(20);
/// Time between two messages of the truth (`world/truth`, 20 Hz).
const TRUTH_PERIOD: Duration = Duration::from_millis(50);

/// The simulated base's velocity and yaw-rate limits (what a normalised command is scaled by).
fn base_limits(sim: &SimRmp) -> (f64, f64) {
    (
        f64::from(sim.nvm(rmp_codec::v3::NvmFloat::MaxVelocityMps)),
        f64::from(sim.nvm(rmp_codec::v3::NvmFloat::MaxTurnRateRadps)),
    )
}

fn ns_to_s(ns: u64) -> f64 {
    ns as f64 * 1e-9
}

fn max_abs(v: &[f64; 6]) -> f64 {
    v.iter().fold(0.0, |m, x| m.max(x.abs()))
}

/// The banquet table's long edge on the side of `y`.
fn table_edge_y(scene: &Scene, y: f64) -> f64 {
    let t = &scene.banquet_table;
    if y < world::scene::TABLE_CENTER_Y_M {
        world::scene::TABLE_CENTER_Y_M - 0.5 * t.depth_m
    } else {
        world::scene::TABLE_CENTER_Y_M + 0.5 * t.depth_m
    }
}

/// The deployment file the onboard processes of a HIL mission read (the format of
/// `grop_onboard::deployment`): the scene as the map, the run's clock, bus and namespace, and
/// the simulated UR5e's ports from the world's ready line.
pub(crate) fn deployment_for(
    spec: &mission::MissionSpec,
    scene: &std::path::Path,
    robot: &std::path::Path,
    namespace: &str,
    clock: &str,
    bus: &str,
    field: &dyn Fn(&str) -> Result<String, harness_error::HarnessError>,
) -> Result<String, harness_error::HarnessError> {
    let quote = |p: &std::path::Path| format!("{:?}", p.display().to_string());
    Ok(format!(
        "# Written by the HIL mission runner for one closed-loop run.\n\
         namespace = {namespace:?}\n\
         map = {}\n\
         robot = {}\n\
         model = {}\n\
         can = \"vcan:{bus}\"\n\
         clock = {clock:?}\n\
         seed = {}\n\
         lidar = {:?}\n\
         {}\n\
         [inputs]\n\
         fixes = \"world\"\n\
         operator = \"world\"\n\n\
         [arm]\n\
         host = \"127.0.0.1\"\n\
         rtde_port = {}\n\
         dashboard_port = {}\n\
         script_port = {}\n\
         gripper_port = {}\n\n\
         [planner]\n\
         method = {:?}\n\
         paper_smp = {}\n\
         retry = {:?}\n",
        quote(scene),
        quote(robot),
        quote(&spec.model),
        spec.seed,
        match field("lidar")?.as_str() {
            "none" => "none".to_owned(),
            port => format!("udp:127.0.0.1:{port}"),
        },
        // The simulated sensor sends from loopback.
        match field("lidar")?.as_str() {
            "none" => "",
            _ => "lidar_sensor = \"127.0.0.1\"\n",
        },
        field("rtde")?,
        field("dashboard")?,
        field("secondary")?,
        field("gripper")?,
        spec.method,
        spec.paper_smp,
        spec.retry,
    ))
}
