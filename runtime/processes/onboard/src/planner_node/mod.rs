//! The perception and planning node (`grop-planner`): camera frame -> Psi's views cut by the
//! frame's metric header -> Psi -> GROP (or a baseline) -> `plan/task` and `heatmaps`.
//!
//! It is a separate process so that a slow plan never delays the executive's control loops. Its
//! loop is `loop { now = clock.now(); poll everything non-blocking; clock.sleep_until(next) }`
//! with a 10 ms period on the runtime clock ([`grop_clock::Clock`]), so in HIL it runs in
//! lock-step with the simulated world (a long plan simply holds the simulated clock still).
//!
//! Per cycle ([`PlannerNode::step`]):
//! * keeps the newest `camera/frame` (a borrowed shared-memory sample, no copy);
//! * answers the newest `plan/request` once a frame is there (older unanswered requests are
//!   superseded): for every (object, side) it cuts the 64 x 32 view out of the frame
//!   (`world::camera::cut_view`; a view that reaches past the frame's edge with
//!   `cut_view_past_frame`: wall where it lies outside the room, *unknown* where it lies inside
//!   the room, and unknown is no goal: those heatmap cells are zeroed; an object whose views keep
//!   no goal is not planned, reported as `NotPlanned` on `events`, and the rest is), runs Psi on all of them in one batch (`h = Psi(IM)`, eq. 2),
//!   builds the task problem (obstacle-free cells from the map, navigation costs `C` from the
//!   occupancy grid built once at start), lets the selected method choose the plan
//!   (GROP: argmax of `U = R F - C`, eq. 1, with `F` per location in closed form, eq. 4) and
//!   publishes it as a `TaskPlanMsg` (Navigate to the station + Load, then Navigate + Unload per
//!   object) with the `HeatmapsMsg` it came from;
//! * publishes a `HeartbeatMsg` (role Planner) every 100 ms of clock time.
//!
//! Whole table settings: when a request has more objects than the tray holds (the robot file's
//! `carry_capacity`) or than the single-trip planner takes (12), the node plans trips
//! ([`MultiTripPlanner`]) and publishes them in one plan: per trip a navigation to the station,
//! one Load step with the trip's objects, then Navigate + Unload per object. Objects already on
//! board are delivered first (single-trip planner, no station visit), then the trips. Otherwise
//! it plans one trip exactly as before. Remainders after a failed unload keep the trips.
//!
//! What a request plans:
//! * `MissionStart`: the objects of `remaining_mask` (all of the map's targets when 0) from the
//!   request's pose (the planner's start is the pose, not the map's `robot_start`); the seed is
//!   the deployment's, so the plan equals `Planner::plan` on `TaskProblem::from_world` for the
//!   same scene up to the differences between cut and rendered crops.
//! * `UnloadFailed` (and `LegFailed` naming the unload it was for) with [`RetryPolicy::None`]
//!   (the paper: no retry): the remainder of the current
//!   plan without the failed object, in the same order with the same goals; objects already on
//!   board need no station visit. No new frame or Psi run. (Without a current plan, e.g. after a
//!   restart, it plans the remaining objects minus the failed one as below.)
//! * `UnloadFailed` with [`RetryPolicy::GropPlus`]: GROP+'s retry
//!   ([`planner::grop_plus::retry_goal`], the policy `grop eval` measures) on the problem of the
//!   current plan: a navigation to the best untried cell of either side of the failed object and
//!   an unload there, then the remainder of the current plan. No new frame or Psi run. When the
//!   policy gives the object up (its retries spent, or no cell worth the drive), the answer is the
//!   `None` answer.
//! * `UnloadFailed` with [`RetryPolicy::Replan`], and `SceneChanged` / `LegFailed` with either
//!   policy: a new plan over `remaining_mask` from the request's pose with the newest frame. The
//!   planner's domain always loads at the station first; when every remaining object is already on
//!   board the station is moved onto the pose, which makes that leg free, so the choice is exactly
//!   the optimum without a station visit, and no station steps are emitted. The planner cannot
//!   exclude the goal that just failed: the replan draws its goals with a seed mixed with the
//!   request id, so Smp draws anew rather than repeating the failed draw.

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use grop_clock::Clock;
use grop_ipc::{
    CameraFrameMsg, EventKind, EventMsg, HeartbeatMsg, HeatmapsMsg, IpcNode, MAX_HEATMAPS,
    MAX_TASK_STEPS, MessageError, NodeError, PortError, ProcessRole, PublishError, ReceiveError,
    Received, ReplanReason, ReplanRequestMsg, TableSide, TaskPlanMsg, TaskStep, TaskStepKind,
    TopicPublisher, TopicSubscriber,
};
use planner::costs::{GridTravelTime, TravelTime};
use planner::feasibility::{FcnEvaluator, FeasibilityError, FeasibilityEvaluator};
use planner::grop_plus::retry_goal;
use planner::methods::{PlanError, PlannedTask, Planner, PlannerConfig, TaskMotionPlanner};
use planner::problem::{MAX_PROBLEM_OBJECTS, TaskProblem, evaluate_crops, side_of_location};
use planner::task::{MAX_OBJECTS, location_index};
use planner::trip_methods::{MultiTripError, MultiTripPlanner};
use world::camera::{CameraError, check_view, cut_view_past_frame, cut_views};
use world::nav::OccupancyGrid;
use world::view::CROP_CELLS;
use world::{Heatmap, RobotConfig, Scene, Side};

use crate::deployment::{Deployment, PlannerSettings, RetryPolicy};
use grop_clock::duration_ns;

mod io;
mod multi_trip;
mod remainder;
mod single_trip;

/// Rank of the planner among the participants of a simulated clock.
pub const PLANNER_CLOCK_RANK: u32 = 10;
/// Period of the node's loop.
pub const CYCLE: Duration = Duration::from_millis(10);
/// Period of the heartbeat.
pub const HEARTBEAT_PERIOD: Duration = Duration::from_millis(100);

/// Why the node could not start or run.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum PlannerNodeError {
    /// The map/task scene file.
    #[error("map file {path}")]
    Map {
        /// The file.
        path: std::path::PathBuf,
        /// Why.
        source: world::SceneError,
    },
    /// The robot file.
    #[error("robot file")]
    Robot(#[from] world::RobotError),
    /// The model file.
    #[error("model {path}")]
    Model {
        /// The file.
        path: std::path::PathBuf,
        /// Why.
        source: fcn_infer::ModelLoadError,
    },
    /// The map's targets do not fit the planner.
    #[error("the map has {0} targets; the planner node plans 1..={MAX_PROBLEM_OBJECTS}")]
    TargetCount(usize),
    /// The robot file's `carry_capacity` is not a tray the planner can plan for.
    #[error("robot file: carry_capacity = {0} is not a tray the planner can plan for")]
    CarryCapacity(u32),
    /// The iceoryx2 node.
    #[error(transparent)]
    Node(#[from] NodeError),
    /// A publisher or subscriber.
    #[error(transparent)]
    Port(#[from] PortError),
    /// Receiving.
    #[error(transparent)]
    Receive(#[from] ReceiveError),
}

/// Why one request could not be answered (logged; the node goes on).
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum RequestError {
    /// The request or the frame does not decode.
    #[error("message: {0}")]
    Message(#[from] MessageError),
    /// A view could not be cut from the frame.
    #[error("cutting the {side} view of object {object}: {error}")]
    Cut {
        /// Object index in the map.
        object: usize,
        /// Side.
        side: Side,
        /// Why.
        error: CameraError,
    },
    /// Psi failed.
    #[error("Psi: {0}")]
    Feasibility(#[from] FeasibilityError),
    /// The planner failed.
    #[error("planner: {0}")]
    Plan(#[from] PlanError),
    /// The multi-trip planner failed.
    #[error("multi-trip planner: {0}")]
    Trips(#[from] MultiTripError),
    /// The tray is full of objects the plan does not unload, and some must be loaded.
    #[error(
        "{kept} objects given up stay on the tray of {capacity} (carry_capacity): no room to load"
    )]
    TrayFull {
        /// Objects on board that the plan does not unload.
        kept: usize,
        /// The tray.
        capacity: usize,
    },
    /// More objects than the planner takes.
    #[error("{0} objects to plan; at most {MAX_PROBLEM_OBJECTS}")]
    TooManyObjects(usize),
    /// The plan's tray does not add up from the tray the request describes.
    #[error("the tray: {0}")]
    Tray(#[from] crate::tray_plan::TrayPlanError),
    /// The plan or heatmaps do not fit their message.
    #[error("publishing: {0}")]
    Publish(#[from] PublishError),
}

/// What a cycle did with a request.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Answer {
    /// The request answered.
    pub request_id: u64,
    /// The plan published.
    pub plan_id: u64,
    /// Steps of the plan.
    pub step_count: usize,
    /// Whether it was planned anew (Psi + planner) or is the remainder of the current plan.
    pub replanned: bool,
}

/// The oldest camera frame the node plans from (three frame periods of the overhead camera).
pub const MAX_FRAME_AGE: Duration = Duration::from_secs(3);

/// A camera frame stamped later than the node's clock by more than this is refused (the
/// stamps are taken on the same monotonic clock; a future stamp would keep a frozen frame
/// fresh for ever, as the saturating age read it as 0 s old).
pub const MAX_FRAME_LEAD: Duration = Duration::from_millis(100);

/// The node: its ports, the static knowledge (map, robot, occupancy grid), Psi and the planner.
pub struct PlannerNode {
    frames: TopicSubscriber<CameraFrameMsg>,
    requests: TopicSubscriber<ReplanRequestMsg>,
    plans: TopicPublisher<TaskPlanMsg>,
    heatmaps: TopicPublisher<HeatmapsMsg>,
    health: TopicPublisher<HeartbeatMsg>,
    /// What the node cannot plan (`NotPlanned`), with the reason.
    events: TopicPublisher<EventMsg>,
    newest_frame: Option<Received<CameraFrameMsg>>,
    /// When the newest frame was taken (its age counts from here too, whatever its stamp).
    newest_frame_taken: Duration,
    /// Frames refused for a stamp in the future.
    frames_refused: u64,
    /// The frame id last reported too old to plan from.
    stale_frame_warned: Option<u64>,
    pending: Option<ReplanRequestMsg>,
    scene: Scene,
    robot: RobotConfig,
    grid: OccupancyGrid,
    /// Where the base docks, from how far, and how far it backs out (written into every plan).
    docking: crate::docking::Docking,
    psi: Box<dyn FeasibilityEvaluator>,
    planner: Planner,
    /// Objects per trip (the robot file's `carry_capacity`).
    capacity: usize,
    retry: RetryPolicy,
    seed: u64,
    /// Steps of the plan published last (to cut the remainder from).
    current: Option<CurrentPlan>,
    /// The problem of the last plan made with Psi (for GROP+'s retries) and its objects.
    last_problem: Option<(Vec<usize>, TaskProblem)>,
    /// Per object: the goals tried since the mission started (GROP+'s retries).
    tried: Vec<Vec<(f64, f64)>>,
    plan_counter: u64,
    heartbeat_seq: u64,
    next_heartbeat: Option<Duration>,
    overruns: u64,
    failures: u64,
    last_error: Option<String>,
    crops: Vec<[u8; CROP_CELLS]>,
    heat_buffers: Vec<Heatmap>,
    // Last: the ports above must be dropped before their node.
    _ipc: IpcNode,
}

struct CurrentPlan {
    source_frame_id: u64,
    steps: Vec<TaskStep>,
}

impl PlannerNode {
    /// Starts the node a deployment describes: loads the map, the robot and the model, builds the
    /// occupancy grid, opens the ports in the deployment's namespace.
    pub fn from_deployment(deployment: &Deployment) -> Result<Self, PlannerNodeError> {
        let scene = deployment
            .load_scene()
            .map_err(|source| PlannerNodeError::Map {
                path: deployment.map.clone(),
                source,
            })?;
        let robot = deployment.load_robot()?;
        let psi =
            FcnEvaluator::load(&deployment.model).map_err(|source| PlannerNodeError::Model {
                path: deployment.model.clone(),
                source,
            })?;
        Self::new(
            &deployment.namespace,
            scene,
            robot,
            Box::new(psi),
            deployment.planner,
            deployment.seed,
        )
    }

    /// A node on `namespace` with the given map, robot, Psi and planner settings.
    pub fn new(
        namespace: &str,
        scene: Scene,
        robot: RobotConfig,
        psi: Box<dyn FeasibilityEvaluator>,
        settings: PlannerSettings,
        seed: u64,
    ) -> Result<Self, PlannerNodeError> {
        let n = scene.targets.len();
        if n == 0 || n > MAX_PROBLEM_OBJECTS {
            return Err(PlannerNodeError::TargetCount(n));
        }
        if robot.carry_capacity == 0 || robot.carry_capacity > world::robot::MAX_CARRY_CAPACITY {
            return Err(PlannerNodeError::CarryCapacity(robot.carry_capacity));
        }
        let mut grid = OccupancyGrid::from_scene(&scene, &robot);
        // Once per map, so that no decision checks lines of sight from its goals, start or
        // station to every corner, nor connects the station (the same paths; tens of ms).
        let started = std::time::Instant::now();
        let sight = planner::costs::prepare_grid_for_decisions(&mut grid, &scene);
        log::info!(
            "navigation map: {} corners; sight of {} cells precomputed in {:.0} ms ({} KiB)",
            grid.corner_count(),
            sight.cells,
            started.elapsed().as_secs_f64() * 1e3,
            sight.bytes / 1024
        );
        let config = PlannerConfig {
            free_goals_only: !settings.paper_smp,
            ..PlannerConfig::for_robot(&robot)
        };
        let ipc = IpcNode::new(namespace, "grop-planner")?;
        let node = Self {
            frames: ipc.subscriber()?,
            requests: ipc.subscriber()?,
            plans: ipc.publisher()?,
            heatmaps: ipc.publisher()?,
            health: ipc.publisher()?,
            events: ipc.publisher()?,
            newest_frame: None,
            newest_frame_taken: Duration::ZERO,
            frames_refused: 0,
            pending: None,
            planner: Planner::new(settings.method, config),
            capacity: robot.carry_capacity as usize,
            retry: settings.retry,
            seed,
            docking: crate::docking::Docking::new(scene.clone(), &robot),
            scene,
            robot,
            grid,
            psi,
            current: None,
            last_problem: None,
            tried: vec![Vec::new(); n],
            plan_counter: 0,
            heartbeat_seq: 0,
            next_heartbeat: None,
            overruns: 0,
            failures: 0,
            last_error: None,
            stale_frame_warned: None,
            crops: vec![[0; CROP_CELLS]; 2 * n],
            heat_buffers: vec![Heatmap::zeros(); 2 * n],
            _ipc: ipc,
        };
        log::info!(
            "planner node on `{namespace}`: {} with {} targets, a tray of {}, retry {:?}, seed {seed}",
            node.planner.kind.name(),
            n,
            node.capacity,
            node.retry
        );
        Ok(node)
    }

    /// The map and task.
    pub fn scene(&self) -> &Scene {
        &self.scene
    }

    /// The planner's settings (GROP+'s retry levers among them).
    pub fn planner_config(&self) -> PlannerConfig {
        self.planner.config
    }

    /// The task problem of the last plan made with Psi and the scene's object index of each of
    /// its objects (what GROP+'s retries are chosen on).
    pub fn last_problem(&self) -> Option<(&[usize], &TaskProblem)> {
        self.last_problem.as_ref().map(|(o, p)| (o.as_slice(), p))
    }

    /// Loop overruns counted so far.
    pub fn overruns(&self) -> u64 {
        self.overruns
    }

    /// Camera frames refused so far for a stamp in the future ([`MAX_FRAME_LEAD`]).
    pub fn frames_refused(&self) -> u64 {
        self.frames_refused
    }

    /// Requests that could not be answered so far, and the last reason.
    pub fn failures(&self) -> (u64, Option<&str>) {
        (self.failures, self.last_error.as_deref())
    }
}

fn table_side(side: Side) -> TableSide {
    match side {
        Side::Near => TableSide::Near,
        Side::Far => TableSide::Far,
    }
}
