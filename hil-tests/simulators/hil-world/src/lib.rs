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
//!
//! [`World::run`]'s step is an ordered list of systems (the private `systems` module, as
//! copper-rs's task list): join, fault injector, chair moves, base and CAN, arm, lidar,
//! readings, fault watch, legs, contacts, loads, tray, truth, fixes, heartbeat, operator,
//! camera, plans, events, deaths, trajectory, progress, end, clock advance; each a struct with
//! a `step(&mut self, ctx)`, run in that fixed order every step and sharing one context. The
//! order is behaviour: every publish and every random draw happens in it, and the logs of two
//! runs are compared byte for byte.

mod binaries;
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
mod systems;

use std::time::Duration;

use can_bus::VirtualCanBus;
use grop_clock::{HostConfig, SimClockHost};
use grop_ipc::{
    BasePoseMsg, CameraFrameMsg, EventMsg, HeartbeatMsg, IpcNode, LoadRequestMsg, TaskPlanMsg,
    TopicPublisher, TopicSubscriber,
};
use planar::Pose2;
use sim_rmp::{SimRmp, SimRmpNode};
use sim_ur5e::Ur5eSim;
use world::{RobotConfig, Scene};

use faults::{FaultKind, FaultSpec, FaultyBus};
use fixes::{FixModel, FixSimulator};
use grop_clock::duration_ns as ns;
use objects::{JudgeConfig, ObjectTracker};

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

pub(crate) fn secs(d: Duration) -> f64 {
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
    pub(crate) fn base_pose(&self) -> Pose2 {
        self.start.compose(&self.base.sim().pose())
    }

    /// Publishes a world event (and logs it).
    pub(crate) fn world_event(&mut self, kind: grop_ipc::EventKind, now: Duration, detail: &str) {
        log::info!("world: {detail}");
        let msg = EventMsg::new(kind, ns(now), detail).with_source(grop_ipc::ProcessRole::World);
        let _ = self.ports.world_events.publish(&msg);
    }
}

/// The executive's base command period (the stored limits do not depend on it).
const BASE_PERIOD: Duration = Duration::from_millis(20);
/// Time between two messages of the truth (`world/truth`, 20 Hz).
pub(crate) const TRUTH_PERIOD: Duration = Duration::from_millis(50);

/// The simulated base's velocity and yaw-rate limits (what a normalised command is scaled by).
pub(crate) fn base_limits(sim: &SimRmp) -> (f64, f64) {
    (
        f64::from(sim.nvm(rmp_codec::v3::NvmFloat::MaxVelocityMps)),
        f64::from(sim.nvm(rmp_codec::v3::NvmFloat::MaxTurnRateRadps)),
    )
}

pub(crate) fn ns_to_s(ns: u64) -> f64 {
    ns as f64 * 1e-9
}

pub(crate) fn max_abs(v: &[f64; 6]) -> f64 {
    v.iter().fold(0.0, |m, x| m.max(x.abs()))
}

/// The banquet table's long edge on the side of `y`.
pub(crate) fn table_edge_y(scene: &Scene, y: f64) -> f64 {
    let t = &scene.banquet_table;
    if y < world::scene::TABLE_CENTER_Y_M {
        world::scene::TABLE_CENTER_Y_M - 0.5 * t.depth_m
    } else {
        world::scene::TABLE_CENTER_Y_M + 0.5 * t.depth_m
    }
}
