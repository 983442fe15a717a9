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
use planner::feasibility::{
    FcnEvaluator, FeasibilityError, FeasibilityEvaluator, FeasibilityQuery,
};
use planner::grop_plus::retry_goal;
use planner::methods::{PlanError, PlannedTask, Planner, PlannerConfig, TaskMotionPlanner};
use planner::problem::{MAX_PROBLEM_OBJECTS, TaskProblem, side_of_location};
use planner::task::{MAX_OBJECTS, location_index};
use planner::trip_methods::{MultiTripError, MultiTripPlanner};
use world::camera::{
    CameraError, FrameLayout, OverheadCamera, PixelFormat, check_view, cut_view_past_frame,
    cut_views,
};
use world::nav::OccupancyGrid;
use world::view::CROP_CELLS;
use world::{Heatmap, RobotConfig, Scene, Side};

use crate::deployment::{Deployment, PlannerSettings, RetryPolicy};

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

    /// A frame to plan from: there is one, and it is no older than [`MAX_FRAME_AGE`] (a frozen
    /// camera keeps delivering its last picture; the world may have changed since). Reports a
    /// too-old frame once.
    fn fresh_frame(&mut self, now: Duration) -> bool {
        let Some(frame) = self.newest_frame.as_ref() else {
            return false;
        };
        // From its stamp and from when it was taken: a frame that stops coming goes stale
        // whatever its stamp says.
        let age = now
            .saturating_sub(Duration::from_nanos(frame.header.stamp_ns))
            .max(now.saturating_sub(self.newest_frame_taken));
        if age <= MAX_FRAME_AGE {
            return true;
        }
        if self.pending.is_some() && self.stale_frame_warned != Some(frame.header.frame_id) {
            self.stale_frame_warned = Some(frame.header.frame_id);
            self.failures += 1;
            let text = format!(
                "camera frame {} is {:.1} s old (at most {:.1} s): not planning from it; waiting for a fresh one",
                frame.header.frame_id,
                age.as_secs_f64(),
                MAX_FRAME_AGE.as_secs_f64()
            );
            log::warn!("{text}");
            self.last_error = Some(text);
        }
        false
    }

    /// Runs the loop until `stop` is set or the clock is lost: every [`CYCLE`] of clock time one
    /// [`step`](Self::step), absolute deadlines (a late cycle does not shift the later ones;
    /// missed cycles are skipped and counted as overruns).
    pub fn run(&mut self, clock: &dyn Clock, stop: &AtomicBool) -> Result<(), PlannerNodeError> {
        clock.wait_turn();
        // On the wall clock the node also wakes the moment a frame or a request arrives (the
        // frame-to-plan latency is then the decision, not the loop's phase); on a simulated
        // clock it runs on its ticks only, which is what makes a mission repeatable.
        let event_driven = !clock.is_simulated();
        let mut next = clock.now();
        while !stop.load(Ordering::Relaxed) {
            if clock.is_lost() {
                log::warn!("the clock is lost; the planner node stops");
                break;
            }
            if event_driven {
                self.frames.clear_wakeups()?;
                self.requests.clear_wakeups()?;
            }
            let now = clock.now();
            self.step(now)?;
            let after = clock.now();
            if after >= next {
                next += CYCLE;
                while next <= after {
                    next += CYCLE;
                    self.overruns += 1;
                }
            }
            if event_driven {
                let fds = [self.frames.wake_fd(), self.requests.wake_fd()];
                if let Err(e) = grop_ipc::wait_any(&fds, next.saturating_sub(clock.now())) {
                    log::warn!("waiting for frames and requests: {e}; sleeping instead");
                    clock.sleep_until(next);
                }
            } else {
                clock.sleep_until(next);
            }
        }
        Ok(())
    }

    /// One cycle at clock time `now`: take the newest frame and request, answer the request if a
    /// frame is there, send the heartbeat when due. Returns the answer if one was published.
    /// Failures to answer are logged and counted, not returned (the node keeps serving).
    pub fn step(&mut self, now: Duration) -> Result<Option<Answer>, PlannerNodeError> {
        while let Some(frame) = self.frames.try_recv()? {
            let stamp = Duration::from_nanos(frame.header.stamp_ns);
            if stamp > now.saturating_add(MAX_FRAME_LEAD) {
                self.frames_refused += 1;
                self.failures += 1;
                let text = format!(
                    "camera frame {} stamped {:.3} s, {:.3} s after now: refused (a stamp in the future)",
                    frame.header.frame_id,
                    stamp.as_secs_f64(),
                    (stamp - now).as_secs_f64()
                );
                log::warn!("{text}");
                self.last_error = Some(text);
                continue;
            }
            self.newest_frame = Some(frame);
            self.newest_frame_taken = now;
        }
        while let Some(request) = self.requests.try_recv()? {
            if let Some(old) = self.pending.replace(*request) {
                log::warn!(
                    "request {} superseded by {} before it was answered",
                    old.request_id,
                    request.request_id
                );
            }
        }
        let mut answer = None;
        let fresh = self.fresh_frame(now);
        let can_answer = self.pending.is_some_and(|r| {
            fresh
                || (r.reason() == Ok(ReplanReason::UnloadFailed)
                    && matches!(self.retry, RetryPolicy::None | RetryPolicy::GropPlus)
                    && self.current.is_some())
        });
        if can_answer {
            if let Some(request) = self.pending.take() {
                match self.answer(&request, now) {
                    Ok(a) => {
                        log::info!(
                            "answered request {} with plan {} ({} steps, {})",
                            a.request_id,
                            a.plan_id,
                            a.step_count,
                            if a.replanned { "planned" } else { "remainder" }
                        );
                        answer = Some(a);
                    }
                    Err(error) => {
                        self.failures += 1;
                        log::error!("request {}: {error}", request.request_id);
                        self.last_error = Some(error.to_string());
                    }
                }
            }
        }
        if self.next_heartbeat.is_none_or(|due| now >= due) {
            self.send_heartbeat(now);
            let due = self.next_heartbeat.unwrap_or(now) + HEARTBEAT_PERIOD;
            self.next_heartbeat = Some(if due <= now {
                now + HEARTBEAT_PERIOD
            } else {
                due
            });
        }
        for result in [
            self.plans.serve_late_subscribers(),
            self.heatmaps.serve_late_subscribers(),
        ] {
            if let Err(error) = result {
                log::warn!("{error}");
            }
        }
        Ok(answer)
    }

    fn send_heartbeat(&mut self, now: Duration) {
        self.heartbeat_seq += 1;
        let (seq, overruns) = (self.heartbeat_seq, self.overruns);
        let sent = self.health.publish_with(|beat| {
            beat.seq = seq;
            beat.stamp_ns = duration_ns(now);
            beat.set_role(ProcessRole::Planner);
            beat.pid = std::process::id();
            beat.overruns = overruns;
        });
        if let Err(error) = sent {
            log::warn!("heartbeat: {error}");
        }
    }

    fn answer(
        &mut self,
        request: &ReplanRequestMsg,
        now: Duration,
    ) -> Result<Answer, RequestError> {
        let reason = request.reason()?;
        let n = self.scene.targets.len();
        let all = if n >= 64 { u64::MAX } else { (1u64 << n) - 1 };
        let mut remaining = request.remaining_mask & all;
        if remaining == 0 && reason == ReplanReason::MissionStart {
            remaining = all;
        }
        let on_board = request.on_board_mask & remaining;
        let pose = request.pose;
        if !pose.iter().all(|v| v.is_finite()) {
            return Err(MessageError::NotFinite {
                message: "ReplanRequestMsg",
                field: "pose",
                index: 0,
            }
            .into());
        }
        let failed_bit = if (request.failed_object as usize) < n {
            1u64 << request.failed_object
        } else {
            0
        };
        if reason == ReplanReason::MissionStart {
            self.tried.iter_mut().for_each(Vec::clear);
        }
        // GROP+ retries an unload elsewhere when it failed at the table, and when the leg to its
        // standing spot failed (no way in, blocked, stalled): the spot is tried either way.
        if matches!(reason, ReplanReason::UnloadFailed | ReplanReason::LegFailed)
            && self.retry == RetryPolicy::GropPlus
            && failed_bit != 0
            && self.current.is_some()
        {
            let object = request.failed_object as usize;
            self.tried[object].push((request.failed_goal_m[0], request.failed_goal_m[1]));
            if let Some(retry) = self.retry_pair(object, (pose[0], pose[1])) {
                return self.publish_remainder(request, Some(retry), remaining, on_board, now);
            }
        }
        match (reason, self.retry) {
            // A leg that could not be driven to an unload's goal failed that unload (the
            // paper's no-retry: go on with the rest; GROP+ once no other spot is left).
            (
                ReplanReason::UnloadFailed | ReplanReason::LegFailed,
                RetryPolicy::None | RetryPolicy::GropPlus,
            ) if failed_bit != 0 || reason == ReplanReason::UnloadFailed => {
                let left = remaining & !failed_bit;
                if self.current.is_some() {
                    self.publish_remainder(request, None, left, on_board & left, now)
                } else {
                    self.plan_and_publish(request, left, on_board & left, now)
                }
            }
            _ => self.plan_and_publish(request, remaining, on_board, now),
        }
    }

    /// Cut + Psi + planner over the objects of `objects_mask` from the request's pose.
    #[allow(
        clippy::too_many_lines,
        reason = "one request planned in order: frame, problem, method, checks, message"
    )]
    fn plan_and_publish(
        &mut self,
        request: &ReplanRequestMsg,
        objects_mask: u64,
        on_board: u64,
        now: Duration,
    ) -> Result<Answer, RequestError> {
        let started = Instant::now();
        let mut objects_mask = objects_mask;
        let mut objects: Vec<usize> = (0..self.scene.targets.len())
            .filter(|i| objects_mask & (1 << i) != 0)
            .collect();
        if objects.len() > MAX_PROBLEM_OBJECTS {
            return Err(RequestError::TooManyObjects(objects.len()));
        }
        // Objects on the tray that this plan does not unload (given up after a failed unload)
        // keep their slots.
        let free = self.tray_free(request, objects_mask)?;
        // One trip when the tray takes everything (the single-trip planner, exactly as before);
        // otherwise trips, the objects already on board first (delivered before the next
        // station visit).
        let mut single_trip = objects.len() <= free.min(MAX_OBJECTS);
        if !single_trip {
            objects.sort_by_key(|&o| on_board & (1 << o) == 0);
        }
        if objects.is_empty() {
            let frame_id = self.newest_frame.as_ref().map_or(0, |f| f.header.frame_id);
            return self.publish_plan(request, frame_id, &[], (0.0, 0.0, 0.0), started, now);
        }
        let Some(frame) = self.newest_frame.as_ref() else {
            // `step` answers only with a frame; keep the invariant visible.
            return Err(MessageError::NotFinite {
                message: "CameraFrameMsg",
                field: "none received",
                index: 0,
            }
            .into());
        };
        let header = frame.header;
        let pixels = frame.image()?;
        let layout = FrameLayout {
            camera: OverheadCamera {
                width_px: header.width_px,
                height_px: header.height_px,
                metres_per_px: header.metres_per_px,
                left_x_m: header.left_x_m,
                top_y_m: header.top_y_m,
            },
            format: match header.pixel_format()? {
                grop_ipc::PixelFormat::Rgb8 => PixelFormat::Rgb8,
                grop_ipc::PixelFormat::Mono8 => PixelFormat::Mono8,
            },
            row_stride_bytes: header.row_stride_bytes as usize,
        };
        let mut targets: Vec<[f64; 3]> = objects
            .iter()
            .map(|&i| self.scene.targets[i].as_array())
            .collect();
        let mut m = 2 * objects.len();
        let views: Vec<(f64, Side)> = (0..m)
            .map(|i| (targets[i / 2][0], side_of_location(i)))
            .collect();
        // Views inside the frame are cut together; a view that reaches past the frame's edge
        // is cut alone: wall where it lies outside the room, unknown (read as wall, and no
        // goal) where it lies inside the room but outside the frame.
        let mut inside: Vec<usize> = Vec::with_capacity(m);
        let mut unknown: Vec<(usize, Box<[bool; CROP_CELLS]>, usize)> = Vec::new();
        for (i, &(x, side)) in views.iter().enumerate() {
            let cut_error = |error| RequestError::Cut {
                object: objects[i / 2],
                side,
                error,
            };
            match check_view(&layout, x, side) {
                Ok(()) => inside.push(i),
                Err(CameraError::ViewOutsideFrame { .. }) => {
                    let mut cells = Box::new([false; CROP_CELLS]);
                    let n = cut_view_past_frame(
                        pixels,
                        &layout,
                        &self.scene.room,
                        x,
                        side,
                        &mut self.crops[i],
                        &mut cells,
                    )
                    .map_err(cut_error)?;
                    if n > 0 {
                        unknown.push((i, cells, n));
                    }
                }
                Err(error) => return Err(cut_error(error)),
            }
        }
        if !inside.is_empty() {
            let inside_views: Vec<(f64, Side)> = inside.iter().map(|&i| views[i]).collect();
            let mut crops = vec![[0u8; CROP_CELLS]; inside.len()];
            cut_views(pixels, &layout, &inside_views, &mut crops).map_err(|error| {
                RequestError::Cut {
                    object: objects[inside[0] / 2],
                    side: inside_views[0].1,
                    error,
                }
            })?;
            for (&i, crop) in inside.iter().zip(&crops) {
                self.crops[i] = *crop;
            }
        }
        let queries: Vec<FeasibilityQuery<'_>> = self.crops[..m]
            .iter()
            .enumerate()
            .map(|(i, crop)| FeasibilityQuery {
                scene: &self.scene,
                robot: &self.robot,
                target: targets[i / 2],
                side: side_of_location(i),
                crop,
            })
            .collect();
        self.psi.evaluate(&queries, &mut self.heat_buffers[..m])?;
        // Unknown is not free: no goal on a cell the camera did not see. An object whose views
        // keep no cell with a chance is not planned; the node says so on `events` and plans the
        // rest.
        for (i, cells, _) in &unknown {
            for (v, u) in self.heat_buffers[*i]
                .values_mut()
                .iter_mut()
                .zip(cells.iter())
            {
                if *u {
                    *v = 0.0;
                }
            }
        }
        let unknown_of = |i: usize| unknown.iter().find(|(k, _, _)| *k == i).map_or(0, |u| u.2);
        let not_planned: Vec<usize> = (0..objects.len())
            .filter(|&k| {
                let blind = unknown_of(2 * k) + unknown_of(2 * k + 1) > 0;
                let hopeless = (2 * k..2 * k + 2)
                    .all(|i| self.heat_buffers[i].values().iter().all(|&v| v <= 0.0));
                blind && hopeless
            })
            .collect();
        for &k in not_planned.iter().rev() {
            let object = objects[k];
            let detail = format!(
                "object {object} not planned: view cells unknown past the camera frame (near {}, far {}), no goal left",
                unknown_of(2 * k),
                unknown_of(2 * k + 1)
            );
            log::warn!("request {}: {detail}", request.request_id);
            let mut event = EventMsg::new(EventKind::NotPlanned, duration_ns(now), &detail)
                .with_source(ProcessRole::Planner);
            event.step_index = object as u32;
            if let Err(error) = self.events.publish(&event) {
                log::warn!("event: {error}");
            }
            objects.remove(k);
            targets.remove(k);
            self.crops.copy_within(2 * k + 2..m, 2 * k);
            self.heat_buffers[2 * k..m].rotate_left(2);
            m -= 2;
            objects_mask &= !(1u64 << object);
        }
        if objects.is_empty() {
            return self.publish_plan(request, header.frame_id, &[], (0.0, 0.0, 0.0), started, now);
        }
        single_trip = single_trip || objects.len() <= free.min(MAX_OBJECTS);
        let heatmaps = &mut self.heat_buffers[..m];
        let mut problem = TaskProblem::from_heatmaps(&self.scene, &self.robot, &targets, heatmaps);
        let pose_xy = (request.pose[0], request.pose[1]);
        problem.start_xy = pose_xy;
        let seed = match request.reason()? {
            ReplanReason::MissionStart => self.seed,
            _ => world::generate::mix_seed(self.seed, 0x7265_706c, request.request_id),
        };
        let (steps, totals, feasibility_of) = if single_trip {
            let all_on_board = objects.iter().all(|&o| on_board & (1 << o) != 0);
            if all_on_board {
                problem.station_xy = pose_xy;
            }
            let mut travel = GridTravelTime::new(&self.grid, self.robot.speed_mps);
            let decision = self.planner.plan(&problem, &mut travel, seed)?;
            self.last_problem = Some((objects.clone(), problem));
            let load_mask = if all_on_board {
                0
            } else {
                objects_mask & !on_board
            };
            let steps = self.steps_of(
                &decision,
                &objects,
                &targets,
                load_mask,
                pose_xy,
                &mut travel,
            );
            log::debug!("{}", decision.explain(3));
            let feasibility_of: Vec<f64> =
                decision.locations.iter().map(|l| l.feasibility).collect();
            (
                steps,
                (decision.feasibility, decision.cost_s, decision.utility),
                feasibility_of,
            )
        } else {
            let planned = self.plan_trips(&objects, &targets, on_board, pose_xy, seed, free)?;
            self.last_problem = Some((objects.clone(), problem));
            planned
        };
        let frame_id = header.frame_id;
        // Heatmaps first: a reader of the plan finds the heatmaps it came from. More than 12
        // objects take several messages of MAX_HEATMAPS locations, same source frame.
        for first in (0..m).step_by(MAX_HEATMAPS) {
            let chunk = &self.heat_buffers[first..m.min(first + MAX_HEATMAPS)];
            self.heatmaps.publish_with(|msg| {
                msg.stamp_ns = duration_ns(now);
                msg.source_frame_id = frame_id;
                msg.count = chunk.len() as u32;
                for (k, (slot, h)) in msg.locations.iter_mut().zip(chunk).enumerate() {
                    let i = first + k;
                    slot.object_index = objects[i / 2] as u32;
                    slot.side = i32::from(side_of_location(i).sign());
                    slot.target_m = targets[i / 2];
                    slot.feasibility = feasibility_of[i];
                    slot.values.copy_from_slice(h.values());
                }
            })?;
        }
        self.publish_plan(request, frame_id, &steps, totals, started, now)
            .map(|a| Answer {
                replanned: true,
                ..a
            })
    }

    /// Several trips over `objects` (those on board first, then those at the station, as
    /// `plan_and_publish` orders them; `targets` and the heatmap buffers in the same order): the
    /// objects on board are delivered first with the single-trip planner (station on the pose,
    /// no station visit), then the multi-trip planner ([`MultiTripPlanner`], a tray of
    /// `carry_capacity`) plans the objects at the station from where that leaves the robot.
    /// Per trip: navigate to the station, one load step with the trip's objects, navigate +
    /// unload per object. Returns the steps, (F, C, U) of the steps (C = the sum of their legs,
    /// U = R F - C) and `Fea^t` per location in `objects` order.
    #[allow(clippy::type_complexity)]
    #[allow(
        clippy::too_many_lines,
        reason = "one multi-trip request planned in order: frame, problem, trips, checks, message"
    )]
    fn plan_trips(
        &mut self,
        objects: &[usize],
        targets: &[[f64; 3]],
        on_board: u64,
        pose_xy: (f64, f64),
        seed: u64,
        capacity: usize,
    ) -> Result<(Vec<TaskStep>, (f64, f64, f64), Vec<f64>), RequestError> {
        let n_board = objects
            .iter()
            .take_while(|&&o| on_board & (1 << o) != 0)
            .count();
        let mut travel = GridTravelTime::new(&self.grid, self.robot.speed_mps);
        let no_path_s = self.planner.config.no_path_cost_s;
        let mut steps = Vec::new();
        let mut feasibility_of = Vec::with_capacity(2 * objects.len());
        let mut at = pose_xy;
        let mut capacity = capacity;
        if n_board > 0 {
            let mut problem = TaskProblem::from_heatmaps(
                &self.scene,
                &self.robot,
                &targets[..n_board],
                &self.heat_buffers[..2 * n_board],
            );
            problem.start_xy = pose_xy;
            problem.station_xy = pose_xy;
            let decision = self.planner.plan(&problem, &mut travel, seed)?;
            steps = self.steps_of(
                &decision,
                &objects[..n_board],
                &targets[..n_board],
                0,
                pose_xy,
                &mut travel,
            );
            feasibility_of.extend(decision.locations.iter().map(|l| l.feasibility));
            if let Some(last) = decision.plan.unloads.last() {
                at = decision.goal_of(last).xy;
            }
            // An object on board that the decision leaves out (not worth its cost) keeps its
            // slot for the trips after.
            let kept = n_board.saturating_sub(decision.plan.unloads.len());
            capacity = capacity.saturating_sub(kept);
        }
        let rest = if capacity == 0 {
            log::warn!(
                "the tray stays full of objects the plan does not unload: {} objects at the \
                 station are not planned",
                objects.len() - n_board
            );
            &objects[..0]
        } else {
            &objects[n_board..]
        };
        if !rest.is_empty() {
            let mut problem = TaskProblem::from_heatmaps(
                &self.scene,
                &self.robot,
                &targets[n_board..],
                &self.heat_buffers[2 * n_board..2 * objects.len()],
            );
            problem.start_xy = at;
            let trips = MultiTripPlanner::new(self.planner.kind, self.planner.config, capacity)
                .plan(&problem, &mut travel, seed)?;
            log::debug!(
                "{} trips over {} objects: U {:.2}, F {:.3}, C {:.1} s, bound {:?}",
                trips.plan.trips.len(),
                rest.len(),
                trips.utility,
                trips.feasibility,
                trips.cost_s,
                trips.search.map(|r| r.upper_bound)
            );
            feasibility_of.extend(trips.locations.iter().map(|l| l.feasibility));
            let station = (
                self.scene.loading_station.x_m,
                self.scene.loading_station.y_m,
            );
            let mut leg = |from: (f64, f64), to: (f64, f64)| {
                travel.travel_time_s(from, to).unwrap_or(no_path_s)
            };
            for trip in &trips.plan.trips {
                let mask = trip
                    .load_order
                    .iter()
                    .fold(0u64, |m, &o| m | (1u64 << rest[o]));
                steps.push(TaskStep::navigate(
                    station.0,
                    station.1,
                    self.station_yaw_rad(),
                    leg(at, station),
                ));
                steps.push(TaskStep::load(mask, station.0, station.1));
                at = station;
                for u in &trip.unloads {
                    let goal = trips.goal_of(u);
                    let mut nav =
                        TaskStep::navigate(goal.xy.0, goal.xy.1, goal.yaw_rad, leg(at, goal.xy));
                    nav.side = i32::from(u.side.sign());
                    steps.push(nav);
                    steps.push(TaskStep::unload(
                        rest[u.object] as u32,
                        table_side(u.side),
                        targets[n_board + u.object],
                        [goal.xy.0, goal.xy.1, goal.yaw_rad],
                        trips.locations[location_index(u.object, u.side)].feasibility,
                    ));
                    at = goal.xy;
                }
            }
        }
        let feasibility: f64 = steps
            .iter()
            .filter(|s| s.kind() == Ok(TaskStepKind::Unload))
            .map(|s| s.feasibility)
            .sum();
        let cost_s: f64 = steps.iter().map(|s| s.travel_cost_s).sum();
        let utility = self.planner.config.success_bonus_r * feasibility - cost_s;
        Ok((steps, (feasibility, cost_s, utility), feasibility_of))
    }

    /// The plan's steps: station visit and load (if anything must be loaded), then per unload
    /// the navigation to its goal (leg cost from the grid) and the unload.
    fn steps_of(
        &self,
        decision: &PlannedTask,
        objects: &[usize],
        targets: &[[f64; 3]],
        load_mask: u64,
        start_xy: (f64, f64),
        travel: &mut dyn TravelTime,
    ) -> Vec<TaskStep> {
        let no_path_s = self.planner.config.no_path_cost_s;
        let mut leg =
            |from: (f64, f64), to: (f64, f64)| travel.travel_time_s(from, to).unwrap_or(no_path_s);
        let mut steps = Vec::with_capacity(2 + 2 * objects.len());
        let mut at = start_xy;
        if load_mask != 0 {
            let station = (
                self.scene.loading_station.x_m,
                self.scene.loading_station.y_m,
            );
            steps.push(TaskStep::navigate(
                station.0,
                station.1,
                self.station_yaw_rad(),
                leg(at, station),
            ));
            steps.push(TaskStep::load(load_mask, station.0, station.1));
            at = station;
        }
        for u in &decision.plan.unloads {
            let goal = decision.goal_of(u);
            let side = table_side(u.side);
            let mut nav = TaskStep::navigate(goal.xy.0, goal.xy.1, goal.yaw_rad, leg(at, goal.xy));
            nav.side = i32::from(u.side.sign());
            steps.push(nav);
            steps.push(TaskStep::unload(
                objects[u.object] as u32,
                side,
                targets[u.object],
                [goal.xy.0, goal.xy.1, goal.yaw_rad],
                decision.locations[location_index(u.object, u.side)].feasibility,
            ));
            at = goal.xy;
        }
        steps
    }

    /// Heading at the station: facing the loading table.
    fn station_yaw_rad(&self) -> f64 {
        let (s, t) = (&self.scene.loading_station, &self.scene.loading_table);
        (t.center_y_m - s.y_m).atan2(t.center_x_m - s.x_m)
    }

    /// GROP+'s retry of `object` from `at_xy` (navigate + unload steps), if the policy retries:
    /// [`planner::grop_plus::retry_goal`] on the last plan's problem, the goals tried for the
    /// object so far excluded.
    fn retry_pair(&mut self, object: usize, at_xy: (f64, f64)) -> Option<(TaskStep, TaskStep)> {
        let (objects, problem) = self.last_problem.as_ref()?;
        let local = objects.iter().position(|&o| o == object)?;
        let tried = &self.tried[object];
        let mut travel = GridTravelTime::new(&self.grid, self.robot.speed_mps);
        let goal = retry_goal(
            &self.planner.config,
            problem,
            local,
            tried,
            at_xy,
            tried.len().saturating_sub(1),
            &mut travel,
        )?;
        let loc = &problem.locations[goal.location];
        let mut nav = TaskStep::navigate(goal.xy.0, goal.xy.1, goal.yaw_rad, 0.0);
        nav.side = i32::from(loc.side.sign());
        let unload = TaskStep::unload(
            object as u32,
            table_side(loc.side),
            loc.target,
            [goal.xy.0, goal.xy.1, goal.yaw_rad],
            // The retry's predicted success: the heatmap value of its cell.
            f64::from(goal.heat_value),
        );
        Some((nav, unload))
    }

    /// The no-retry answer (the paper's): the current plan's unloads of the objects in `left`, in
    /// order, from the request's pose; a station visit only for objects not on board. With
    /// `first` (GROP+'s retry of the failed object) that unload comes first and the failed object
    /// is not repeated from the current plan.
    fn publish_remainder(
        &mut self,
        request: &ReplanRequestMsg,
        first: Option<(TaskStep, TaskStep)>,
        left: u64,
        on_board: u64,
        now: Duration,
    ) -> Result<Answer, RequestError> {
        let started = Instant::now();
        let Some(current) = self.current.as_ref() else {
            return self.plan_and_publish(request, left, on_board, now);
        };
        let frame_id = current.source_frame_id;
        // Groups of (navigate, unload): first the objects on board (the retry first), then, per
        // trip of the current plan, its objects still at the station (one station visit each).
        let mut groups: Vec<Vec<(TaskStep, TaskStep)>> = vec![first.into_iter().collect()];
        let retried = first.map_or(0, |(_, u)| 1u64 << u.object_index);
        for w in current.steps.windows(2) {
            if w[1].kind() == Ok(TaskStepKind::Load) {
                groups.push(Vec::new());
            }
            if w[1].kind() == Ok(TaskStepKind::Unload)
                && let Ok(o) = w[1].object()
                && left & !retried & (1 << o) != 0
            {
                let group = if on_board & (1 << o) != 0 {
                    0
                } else {
                    groups.len() - 1
                };
                groups[group].push((w[0], w[1]));
            }
        }
        let mut travel = GridTravelTime::new(&self.grid, self.robot.speed_mps);
        let no_path_s = self.planner.config.no_path_cost_s;
        let mut at = (request.pose[0], request.pose[1]);
        let mut steps = Vec::with_capacity(current.steps.len() + 2);
        let station = (
            self.scene.loading_station.x_m,
            self.scene.loading_station.y_m,
        );
        // The tray's free slots for the trips: what is on board less what the first group
        // unloads (an object given up, or one the current plan does not unload, stays on the
        // tray). None free: the objects still at the station cannot be fetched.
        let unloaded_first = groups[0]
            .iter()
            .filter_map(|(_, u)| u.object().ok())
            .fold(0u64, |m, o| m | (1u64 << o));
        let kept = (request.on_board_mask & !unloaded_first).count_ones() as usize;
        let free = self.capacity.saturating_sub(kept);
        if free == 0 && groups.len() > 1 {
            log::warn!(
                "request {}: the tray stays full ({kept} objects kept on it); the objects at \
                 the station are not planned",
                request.request_id
            );
            groups.truncate(1);
        }
        // A trip of the current plan larger than the tray's free slots becomes several station
        // visits, in the same order.
        let groups: Vec<Vec<(TaskStep, TaskStep)>> = groups
            .into_iter()
            .enumerate()
            .flat_map(|(g, pairs)| {
                if g == 0 || pairs.len() <= free {
                    vec![pairs]
                } else {
                    pairs.chunks(free).map(<[_]>::to_vec).collect()
                }
            })
            .collect();
        let (mut feasibility, mut cost_s) = (0.0, 0.0);
        for (g, pairs) in groups.into_iter().enumerate() {
            let to_load = pairs
                .iter()
                .filter_map(|(_, u)| u.object().ok())
                .fold(0u64, |m, o| m | (1u64 << o))
                & !on_board;
            if g > 0 && to_load == 0 {
                continue;
            }
            if to_load != 0 {
                let cost = travel.travel_time_s(at, station).unwrap_or(no_path_s);
                steps.push(TaskStep::navigate(
                    station.0,
                    station.1,
                    self.station_yaw_rad(),
                    cost,
                ));
                steps.push(TaskStep::load(to_load, station.0, station.1));
                at = station;
            }
            for (mut nav, unload) in pairs {
                nav.travel_cost_s = travel
                    .travel_time_s(at, (nav.x_m, nav.y_m))
                    .unwrap_or(no_path_s);
                at = (nav.x_m, nav.y_m);
                feasibility += unload.feasibility;
                steps.push(nav);
                steps.push(unload);
            }
        }
        for s in &steps {
            cost_s += s.travel_cost_s;
        }
        let utility = self.planner.config.success_bonus_r * feasibility - cost_s;
        self.publish_plan(
            request,
            frame_id,
            &steps,
            (feasibility, cost_s, utility),
            started,
            now,
        )
    }

    /// Free tray slots for a plan over `objects_mask`: the tray (`carry_capacity`) less the
    /// objects on board (`request.on_board_mask`) that the plan does not unload. None free while
    /// something must be loaded is an error.
    fn tray_free(
        &self,
        request: &ReplanRequestMsg,
        objects_mask: u64,
    ) -> Result<usize, RequestError> {
        let kept = (request.on_board_mask & !objects_mask).count_ones() as usize;
        let free = self.capacity.saturating_sub(kept);
        if free == 0 && objects_mask & !request.on_board_mask != 0 {
            return Err(RequestError::TrayFull {
                kept,
                capacity: self.capacity,
            });
        }
        Ok(free.max(1))
    }

    fn publish_plan(
        &mut self,
        request: &ReplanRequestMsg,
        frame_id: u64,
        steps: &[TaskStep],
        (feasibility, cost_s, utility): (f64, f64, f64),
        started: Instant,
        now: Duration,
    ) -> Result<Answer, RequestError> {
        if steps.len() > MAX_TASK_STEPS {
            return Err(MessageError::CountTooLarge {
                message: "TaskPlanMsg",
                field: "steps",
                count: steps.len() as u64,
                capacity: MAX_TASK_STEPS as u64,
            }
            .into());
        }
        self.plan_counter += 1;
        let plan_id = self.plan_counter;
        let reward = self.planner.config.success_bonus_r;
        let object_count = self.scene.targets.len() as u32;
        let decision_us = started.elapsed().as_micros().min(u128::from(u64::MAX)) as u64;
        self.plans.publish_with(|msg| {
            msg.plan_id = plan_id;
            msg.stamp_ns = duration_ns(now);
            msg.source_frame_id = frame_id;
            msg.answers_request = request.request_id;
            msg.utility = utility;
            msg.feasibility = feasibility;
            msg.cost_s = cost_s;
            msg.reward = reward;
            msg.object_count = object_count;
            msg.decision_us = decision_us;
            // Cannot fail: checked above.
            let _ = msg.set_steps(steps);
        })?;
        self.current = Some(CurrentPlan {
            source_frame_id: frame_id,
            steps: steps.to_vec(),
        });
        Ok(Answer {
            request_id: request.request_id,
            plan_id,
            step_count: steps.len(),
            replanned: false,
        })
    }
}

fn table_side(side: Side) -> TableSide {
    match side {
        Side::Near => TableSide::Near,
        Side::Far => TableSide::Far,
    }
}

fn duration_ns(t: Duration) -> u64 {
    t.as_nanos().min(u128::from(u64::MAX)) as u64
}
