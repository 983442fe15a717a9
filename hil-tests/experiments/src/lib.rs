//! The paper's experiments (section V): GROP and the four baselines plan 3-object table-setting
//! tasks in the 30 evaluation scenes, and each plan is executed in the trial simulator with
//! navigation noise. Measures per-object and all-three success, execution time, difficulty thirds
//! by ground-truth servable area, and the robot-speed sweep of Table I.
//!
//! ```no_run
//! use experiments::{EvalConfig, Workload, ground_truth, evaluate_heatmaps, run, Summary};
//! let cfg = EvalConfig::default();
//! let workload = Workload::build(&cfg);
//! // Ground truth (for difficulty), cached on disk because it is the slow part.
//! let truth = ground_truth(&cfg, &workload, Some(std::path::Path::new("target/gt.json")))?;
//! // Psi for the planners: here the simulator oracle (an independent estimate).
//! let mut oracle = psi_eval::heuristics::OracleEvaluator::new(5, 99);
//! let psi = evaluate_heatmaps(&workload, &mut oracle)?;
//! let records = run(&cfg, &workload, &psi, &truth)?;
//! let summary = Summary::from_records(&cfg, &records);
//! println!("{}", summary.markdown(&cfg));
//! # Ok::<(), experiments::EvalError>(())
//! ```
//!
//! Execution protocol (paper and authors' code): drive to the station and load everything, then
//! for each unloading step drive (A* path at the robot's speed) to the commanded goal, where the
//! base ends at goal + N(0, sigma^2 I); the object is placed iff the realised base is collision-free
//! and the arm can place it. A navigation that finds no path or ends in collision fails and counts
//! [`EvalConfig::failed_nav_time_s`] (60 s). No replanning after a failure, except GROP+'s
//! retries ([`planner::grop_plus::retry_goal`]): each retry is one more attempt of the trial
//! simulator ([`trial_sim::retry`]), with the same noise model and its own travel and unloading
//! time.

pub mod full_setting;
pub mod plot;

use std::path::{Path, PathBuf};

use planner::costs::GridTravelTime;
use planner::feasibility::{FeasibilityError, FeasibilityEvaluator, FeasibilityQuery};
use planner::grop_plus::retry_goal;
use planner::methods::{
    MethodKind, PlanError, PlannedTask, Planner, PlannerConfig, TaskMotionPlanner,
};
use planner::problem::{CANDIDATE_CELLS, TaskProblem, candidate_cells};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use trial_sim::retry::{Attempt, AttemptCosts, unload_with_retries};
pub use trial_sim::shard::Shard;
use trial_sim::{TrialResult, TrialSimulator, ground_truth_heatmap};
use world::generate::{evaluation_suite, mix_seed};
use world::nav::OccupancyGrid;
use world::view::{CELL_SIZE_M, render_crop};
use world::{Heatmap, RobotConfig, Scene, Side};

/// Everything that defines an evaluation run. `Default` is the paper's setup.
#[derive(Debug, Clone)]
pub struct EvalConfig {
    /// Seed of scenes, goal draws, tie-breaks and navigation noise.
    pub seed: u64,
    /// Scenes per chair count (paper: 10).
    pub scenes_per_chair_count: usize,
    /// Chair counts (paper: 15, 20, 25).
    pub chair_counts: Vec<usize>,
    /// Tasks per scene (paper: 14, i.e. 420 tasks).
    pub tasks_per_scene: usize,
    /// Objects per task (paper: 3).
    pub objects_per_task: usize,
    /// Methods of the main comparison (Fig. 5).
    pub methods: Vec<MethodKind>,
    /// Speed of the main comparison (m/s).
    pub main_speed_mps: f64,
    /// Speeds of the sweep (Table I: 0.2, 0.4, 0.8 m/s); empty for none.
    pub sweep_speeds_mps: Vec<f64>,
    /// Methods of the sweep (Table I: GROP, PETLON, DVH).
    pub sweep_methods: Vec<MethodKind>,
    /// Planner settings (R, aggregation, goal draws, baseline goal variant); the speed is set per run.
    pub planner: PlannerConfig,
    /// Time to load one object at the station (s).
    pub load_time_s: f64,
    /// Time of one unloading attempt (s).
    pub unload_time_s: f64,
    /// Time charged for a navigation that finds no path or ends in collision (s).
    pub failed_nav_time_s: f64,
    /// Trials per cell of the ground-truth heatmaps that define difficulty.
    pub gt_trials_per_cell: u16,
    /// The robot (speed is overridden per run).
    pub robot: RobotConfig,
}

impl Default for EvalConfig {
    fn default() -> Self {
        let robot = RobotConfig::default();
        Self {
            seed: 2022,
            scenes_per_chair_count: 10,
            chair_counts: vec![15, 20, 25],
            tasks_per_scene: 14,
            objects_per_task: 3,
            methods: MethodKind::ALL.to_vec(),
            main_speed_mps: 0.4,
            sweep_speeds_mps: vec![0.2, 0.4, 0.8],
            sweep_methods: vec![
                MethodKind::GropPlus,
                MethodKind::Grop,
                MethodKind::Petlon,
                MethodKind::Dvh,
            ],
            planner: PlannerConfig::for_robot(&robot),
            // 3 x 3 s + 3 x 5 s = 24 s of manipulation per task: what Table I's times imply
            // (t = D / v + M at the three speeds gives M ~ 24 s for GROP).
            load_time_s: 3.0,
            unload_time_s: 5.0,
            failed_nav_time_s: 60.0,
            gt_trials_per_cell: 5,
            robot,
        }
    }
}

impl EvalConfig {
    /// Checks the values a user can set.
    pub fn check(&self) -> Result<(), EvalError> {
        let bad = |s: &str| Err(EvalError::Config(s.to_string()));
        if self.chair_counts.is_empty()
            || self.scenes_per_chair_count == 0
            || self.tasks_per_scene == 0
        {
            return bad("need at least one chair count, scene and task");
        }
        if self.objects_per_task == 0 || self.objects_per_task > planner::task::MAX_OBJECTS {
            return bad("objects per task must be in 1..=12");
        }
        let speeds =
            std::iter::once(self.main_speed_mps).chain(self.sweep_speeds_mps.iter().copied());
        for s in speeds {
            if !(s.is_finite() && s > 0.0) {
                return bad("speeds must be finite and > 0");
            }
        }
        if self.methods.is_empty() {
            return bad("no methods to evaluate");
        }
        if self.gt_trials_per_cell == 0 {
            return bad("ground truth needs at least one trial per cell");
        }
        Ok(())
    }

    /// The (speed, method) pairs to run: every method at the main speed, the sweep methods at the
    /// other sweep speeds.
    pub fn runs(&self) -> Vec<(f64, MethodKind)> {
        let mut runs: Vec<(f64, MethodKind)> = self
            .methods
            .iter()
            .map(|&m| (self.main_speed_mps, m))
            .collect();
        for &s in &self.sweep_speeds_mps {
            for &m in &self.sweep_methods {
                if !runs.iter().any(|&(rs, rm)| rs == s && rm == m) {
                    runs.push((s, m));
                }
            }
        }
        runs
    }
}

/// Why an evaluation failed.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum EvalError {
    /// A configuration value is out of range.
    #[error("evaluation configuration: {0}")]
    Config(String),
    /// A planner failed on a task.
    #[error("{method} on task {task}: {source}")]
    Plan {
        /// The method.
        method: &'static str,
        /// Task id.
        task: usize,
        /// The planner's error.
        source: PlanError,
    },
    /// The feasibility evaluator failed.
    #[error("feasibility evaluation: {0}")]
    Feasibility(#[from] FeasibilityError),
    /// A file could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The operating system's error.
        source: std::io::Error,
    },
    /// A shard's records file cannot be read back.
    #[error("eval records {path}: {reason}")]
    Records {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        reason: String,
    },
    /// The ground-truth cache file is not what this version writes.
    #[error("ground-truth cache {path}: {reason}")]
    Cache {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        reason: String,
    },
    /// Drawing the figure failed.
    #[error("plot {path}: {reason}")]
    Plot {
        /// The file.
        path: PathBuf,
        /// The backend's error.
        reason: String,
    },
}

/// One evaluation task: 3 targets in one scene.
#[derive(Debug, Clone)]
pub struct EvalTask {
    /// Task id (0..420).
    pub id: usize,
    /// Index of the scene.
    pub scene: usize,
    /// Chairs in the scene.
    pub n_chairs: usize,
    /// Indices of the targets in the scene's target list.
    pub target_ids: Vec<usize>,
}

/// The scenes, their occupancy grids and the tasks.
pub struct Workload {
    /// The evaluation scenes.
    pub scenes: Vec<Scene>,
    /// One grid per scene.
    pub grids: Vec<OccupancyGrid>,
    /// All tasks, scene by scene.
    pub tasks: Vec<EvalTask>,
}

impl Workload {
    /// The paper's scenes (10 x 15, 20, 25 chairs) with `tasks_per_scene * objects_per_task`
    /// targets each; task k of a scene uses targets `k*3 .. k*3+3`.
    pub fn build(cfg: &EvalConfig) -> Self {
        let n_targets = cfg.tasks_per_scene * cfg.objects_per_task;
        let mut scenes: Vec<Scene> =
            if cfg.chair_counts == [15, 20, 25] && cfg.scenes_per_chair_count == 10 {
                evaluation_suite(cfg.seed, n_targets)
            } else {
                cfg.chair_counts
                    .iter()
                    .flat_map(|&c| {
                        (0..cfg.scenes_per_chair_count as u64).map(move |i| {
                            world::generate::evaluation_scene(
                                mix_seed(cfg.seed, c as u64, i),
                                c,
                                n_targets,
                            )
                        })
                    })
                    .collect()
            };
        scenes
            .iter_mut()
            .for_each(|s| s.targets.truncate(n_targets));
        let grids = scenes
            .par_iter()
            .map(|s| OccupancyGrid::from_scene(s, &cfg.robot))
            .collect();
        let mut tasks = Vec::new();
        for (si, scene) in scenes.iter().enumerate() {
            for k in 0..cfg.tasks_per_scene {
                tasks.push(EvalTask {
                    id: tasks.len(),
                    scene: si,
                    n_chairs: scene.chairs.len(),
                    target_ids: (k * cfg.objects_per_task..(k + 1) * cfg.objects_per_task)
                        .collect(),
                });
            }
        }
        Self {
            scenes,
            grids,
            tasks,
        }
    }

    /// The (x, y, z) of a task's targets.
    pub fn targets(&self, task: &EvalTask) -> Vec<[f64; 3]> {
        task.target_ids
            .iter()
            .map(|&t| self.scenes[task.scene].targets[t].as_array())
            .collect()
    }
}

/// Heatmaps for every (scene, target, side): `maps[scene][target][0 near, 1 far]`.
#[derive(Debug, Clone)]
pub struct HeatmapSet {
    /// The heatmaps.
    pub maps: Vec<Vec<[Heatmap; 2]>>,
}

impl HeatmapSet {
    /// The 2n heatmaps of a task in location order.
    pub fn for_task(&self, task: &EvalTask) -> Vec<Heatmap> {
        task.target_ids
            .iter()
            .flat_map(|&t| self.maps[task.scene][t].iter().cloned())
            .collect()
    }
}

fn side_index(side: Side) -> usize {
    usize::from(side == Side::Far)
}

#[derive(Serialize, Deserialize)]
struct GtCache {
    fingerprint: String,
    /// Per (scene, target, side) in order: the 192 candidate-cell values.
    values: Vec<Vec<f32>>,
}

/// Simulated ground truth for every (scene, target, side) over the candidate area
/// (`gt_trials_per_cell` trials per cell, seeded), computed in parallel and cached in `cache`
/// (recomputed when the file was made with other settings).
pub fn ground_truth(
    cfg: &EvalConfig,
    workload: &Workload,
    cache: Option<&Path>,
) -> Result<HeatmapSet, EvalError> {
    let robot_json = serde_json::to_string(&cfg.robot).unwrap_or_default();
    let names: Vec<String> = workload
        .scenes
        .iter()
        .map(|s| format!("{}:{}", s.name, s.targets.len()))
        .collect();
    let fingerprint = format!(
        "v1 seed={} trials={} robot={robot_json} scenes={}",
        cfg.seed,
        cfg.gt_trials_per_cell,
        names.join(",")
    );
    let jobs: Vec<(usize, usize, Side)> = workload
        .scenes
        .iter()
        .enumerate()
        .flat_map(|(s, scene)| {
            (0..scene.targets.len()).flat_map(move |t| Side::BOTH.map(|side| (s, t, side)))
        })
        .collect();
    if let Some(path) = cache.filter(|p| p.exists()) {
        let text = std::fs::read_to_string(path).map_err(|source| EvalError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        match serde_json::from_str::<GtCache>(&text) {
            Ok(c) if c.fingerprint == fingerprint && c.values.len() == jobs.len() => {
                if c.values.iter().any(|v| v.len() != CANDIDATE_CELLS) {
                    return Err(EvalError::Cache {
                        path: path.to_path_buf(),
                        reason: format!("every entry must hold {CANDIDATE_CELLS} values"),
                    });
                }
                log::info!("ground truth from cache {}", path.display());
                return Ok(assemble(
                    workload,
                    &jobs,
                    c.values.iter().map(|v| candidate_heatmap(v)).collect(),
                ));
            }
            Ok(_) => log::info!(
                "ground-truth cache {} was made with other settings; recomputing",
                path.display()
            ),
            Err(e) => log::warn!(
                "ground-truth cache {} unreadable ({e}); recomputing",
                path.display()
            ),
        }
    }
    log::info!(
        "simulating ground truth: {} heatmaps x {} cells x {} trials",
        jobs.len(),
        CANDIDATE_CELLS,
        cfg.gt_trials_per_cell
    );
    let maps: Vec<Heatmap> = jobs
        .par_iter()
        .map(|&(s, t, side)| {
            let scene = &workload.scenes[s];
            let seed = mix_seed(
                cfg.seed ^ 0x6774,
                (s * 1000 + t) as u64,
                side_index(side) as u64,
            );
            ground_truth_heatmap(
                scene,
                &cfg.robot,
                scene.targets[t].as_array(),
                side,
                cfg.gt_trials_per_cell,
                seed,
            )
        })
        .collect();
    if let Some(path) = cache {
        let values = maps
            .iter()
            .map(|h| candidate_cells().map(|(r, c)| h.get(r, c)).collect())
            .collect();
        let text = serde_json::to_string(&GtCache {
            fingerprint,
            values,
        })
        .map_err(|e| EvalError::Cache {
            path: path.to_path_buf(),
            reason: e.to_string(),
        })?;
        if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir).map_err(|source| EvalError::Io {
                path: dir.to_path_buf(),
                source,
            })?;
        }
        std::fs::write(path, text).map_err(|source| EvalError::Io {
            path: path.to_path_buf(),
            source,
        })?;
    }
    Ok(assemble(workload, &jobs, maps))
}

fn candidate_heatmap(values: &[f32]) -> Heatmap {
    let mut h = Heatmap::zeros();
    for ((r, c), &v) in candidate_cells().zip(values) {
        h.set(r, c, v);
    }
    h
}

fn assemble(workload: &Workload, jobs: &[(usize, usize, Side)], maps: Vec<Heatmap>) -> HeatmapSet {
    let mut out: Vec<Vec<[Heatmap; 2]>> = workload
        .scenes
        .iter()
        .map(|s| vec![[Heatmap::zeros(), Heatmap::zeros()]; s.targets.len()])
        .collect();
    for (&(s, t, side), h) in jobs.iter().zip(maps) {
        out[s][t][side_index(side)] = h;
    }
    HeatmapSet { maps: out }
}

/// `Psi` for every (scene, target, side) from a feasibility evaluator, in batches of 6 crops.
pub fn evaluate_heatmaps(
    workload: &Workload,
    evaluator: &mut dyn FeasibilityEvaluator,
) -> Result<HeatmapSet, EvalError> {
    let robot = RobotConfig::default();
    let mut maps = Vec::with_capacity(workload.scenes.len());
    for scene in &workload.scenes {
        let mut per_scene = Vec::with_capacity(scene.targets.len());
        for chunk in scene.targets.chunks(3) {
            let crops: Vec<[u8; 2048]> = chunk
                .iter()
                .flat_map(|t| Side::BOTH.map(|side| render_crop(scene, t.x_m, side)))
                .collect();
            let queries: Vec<FeasibilityQuery<'_>> = crops
                .iter()
                .enumerate()
                .map(|(i, crop)| FeasibilityQuery {
                    scene,
                    robot: &robot,
                    target: chunk[i / 2].as_array(),
                    side: Side::BOTH[i % 2],
                    crop,
                })
                .collect();
            let mut out = vec![Heatmap::zeros(); queries.len()];
            evaluator.evaluate(&queries, &mut out)?;
            for pair in out.chunks(2) {
                per_scene.push([pair[0].clone(), pair[1].clone()]);
            }
        }
        maps.push(per_scene);
    }
    Ok(HeatmapSet { maps })
}

/// Difficulty third of a task.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize)]
pub enum Difficulty {
    /// Largest servable areas.
    Easy,
    /// Middle third.
    Normal,
    /// Smallest servable areas.
    Hard,
}

impl Difficulty {
    /// Easy, Normal, Hard.
    pub const ALL: [Difficulty; 3] = [Difficulty::Easy, Difficulty::Normal, Difficulty::Hard];
    /// Lower-case name.
    pub fn name(self) -> &'static str {
        match self {
            Difficulty::Easy => "easy",
            Difficulty::Normal => "normal",
            Difficulty::Hard => "hard",
        }
    }
}

/// Servable area of a task (m^2): the expected area from which its targets can be served, i.e.
/// the ground-truth success fraction summed over both sides' candidate cells, times the cell area.
pub fn servable_area_m2(truth: &HeatmapSet, task: &EvalTask) -> f64 {
    let cell_area = CELL_SIZE_M * CELL_SIZE_M;
    truth
        .for_task(task)
        .iter()
        .map(|h| {
            candidate_cells()
                .map(|(r, c)| h.get(r, c) as f64)
                .sum::<f64>()
                * cell_area
        })
        .sum()
}

/// The paper's grouping: sort tasks by servable area and split them in thirds (smallest area =
/// hard). Returns one difficulty per task id. Ties keep task order.
pub fn difficulty_groups(areas: &[f64]) -> Vec<Difficulty> {
    let mut order: Vec<usize> = (0..areas.len()).collect();
    order.sort_by(|&a, &b| areas[a].total_cmp(&areas[b]).then(a.cmp(&b)));
    let mut out = vec![Difficulty::Normal; areas.len()];
    let n = areas.len();
    for (rank, &i) in order.iter().enumerate() {
        out[i] = if rank * 3 < n {
            Difficulty::Hard
        } else if rank * 3 < 2 * n {
            Difficulty::Normal
        } else {
            Difficulty::Easy
        };
    }
    out
}

/// How one unloading step went.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum StepOutcome {
    /// Placed.
    Placed,
    /// The navigation planner found no path to the goal.
    NoPath,
    /// The realised base pose collides.
    BaseCollision,
    /// The arm could not place the object from the realised pose.
    ArmFailure,
}

/// The execution of one plan in the simulator.
#[derive(Debug, Clone, PartialEq)]
pub struct Execution {
    /// One outcome per unloading step, in plan order: (object, outcome of each attempt; more
    /// than one only when GROP+ retried).
    pub steps: Vec<(usize, Vec<StepOutcome>)>,
    /// Retries made (GROP+).
    pub retries: usize,
    /// Objects placed.
    pub placed: usize,
    /// Total time: navigation + manipulation + failure charges (s).
    pub time_s: f64,
    /// Distance driven (m).
    pub distance_m: f64,
}

/// Executes a planned task: noisy navigation to each commanded goal, then the placing check of the
/// trial simulator. `rng` draws the navigation noise. With `retry` (GROP+'s planner settings), a
/// failed unload is retried where [`planner::grop_plus::retry_goal`] says, at most
/// `retry.plus.max_retries` times per object.
#[allow(clippy::too_many_arguments)]
pub fn execute(
    cfg: &EvalConfig,
    scene: &Scene,
    robot: &RobotConfig,
    grid: &OccupancyGrid,
    problem: &TaskProblem,
    planned: &PlannedTask,
    retry: Option<&PlannerConfig>,
    rng: &mut ChaCha8Rng,
) -> Execution {
    let speed = robot.speed_mps;
    let mut time_s = 0.0;
    let mut distance_m = 0.0;
    let mut steps = Vec::with_capacity(planned.plan.unloads.len());
    let mut at = problem.start_xy;
    match grid.plan(at, problem.station_xy) {
        Some(p) => {
            time_s += p.travel_time_s(speed);
            distance_m += p.length_m;
            at = problem.station_xy;
        }
        None => {
            // Cannot reach the station: nothing is loaded, nothing placed.
            time_s += cfg.failed_nav_time_s;
            for u in &planned.plan.unloads {
                steps.push((u.object, vec![StepOutcome::NoPath]));
            }
            return Execution {
                steps,
                retries: 0,
                placed: 0,
                time_s,
                distance_m,
            };
        }
    }
    time_s += cfg.load_time_s * planned.plan.load_order.len() as f64;
    let mut sim = TrialSimulator::new(scene, robot);
    let costs = AttemptCosts {
        speed_mps: speed,
        unload_time_s: cfg.unload_time_s,
        failed_nav_time_s: cfg.failed_nav_time_s,
    };
    let max_retries = retry.map_or(0, |c| c.plus.max_retries);
    let mut travel = GridTravelTime::new(grid, speed);
    let mut placed = 0;
    let mut retries = 0;
    for u in &planned.plan.unloads {
        let goal = planned.goal_of(u);
        let target = problem.location(u.object, u.side).target;
        let log = unload_with_retries(
            &mut sim,
            target,
            (u.side, goal.xy),
            at,
            &costs,
            max_retries,
            |from, to| grid.plan(from, to).map(|p| p.length_m),
            |attempts, at_xy| {
                let config = retry?;
                let tried: Vec<(f64, f64)> = attempts.iter().map(|a| a.commanded_xy).collect();
                retry_goal(
                    config,
                    problem,
                    u.object,
                    &tried,
                    at_xy,
                    attempts.len() - 1,
                    &mut travel,
                )
                .map(|g| (problem.locations[g.location].side, g.xy))
            },
            rng,
        );
        time_s += log.time_s;
        distance_m += log.distance_m;
        at = log.end_xy;
        retries += log.attempts.len() - 1;
        if log.placed {
            placed += 1;
        }
        steps.push((
            u.object,
            log.attempts.iter().map(step_outcome).collect::<Vec<_>>(),
        ));
    }
    Execution {
        steps,
        retries,
        placed,
        time_s,
        distance_m,
    }
}

fn step_outcome(attempt: &Attempt) -> StepOutcome {
    match attempt.outcome.map(|o| o.result) {
        None => StepOutcome::NoPath,
        Some(TrialResult::Success) => StepOutcome::Placed,
        Some(TrialResult::BaseCollision) => StepOutcome::BaseCollision,
        Some(_) => StepOutcome::ArmFailure,
    }
}

/// One (task, speed, method) result: a CSV row.
#[derive(Debug, Clone, Serialize)]
pub struct TaskRecord {
    /// Task id.
    pub task: usize,
    /// Scene index.
    pub scene: usize,
    /// Chairs in the scene.
    pub n_chairs: usize,
    /// Robot speed (m/s).
    pub speed_mps: f64,
    /// Method name.
    pub method: &'static str,
    /// Difficulty third.
    pub difficulty: Difficulty,
    /// Ground-truth servable area (m^2).
    pub servable_area_m2: f64,
    /// Objects in the task.
    pub objects: usize,
    /// Objects placed.
    pub placed: usize,
    /// Execution time (s).
    pub time_s: f64,
    /// Distance driven (m).
    pub distance_m: f64,
    /// The plan's F(p) from Psi (closed form).
    pub predicted_f: f64,
    /// The plan's C(p) from the navigation planner (s).
    pub predicted_cost_s: f64,
    /// Navigation motion-planner calls to decide.
    pub motion_planner_calls: usize,
    /// Retries after failed unloads (GROP+).
    pub retries: usize,
    /// Step outcomes, `object:outcome` joined by `|`; a retried step lists its attempts'
    /// outcomes joined by `>`.
    pub steps: String,
}

/// Plans and executes every task with every (speed, method) of [`EvalConfig::runs`], in parallel
/// over tasks. `psi` feeds the planners; `truth` only defines difficulty.
pub fn run(
    cfg: &EvalConfig,
    workload: &Workload,
    psi: &HeatmapSet,
    truth: &HeatmapSet,
) -> Result<Vec<TaskRecord>, EvalError> {
    run_shard(cfg, workload, psi, truth, Shard::WHOLE)
}

/// [`run`] for one shard: the tasks at positions `k mod N == I` of the task list (task ids are
/// positions). Difficulty groups are still those of the whole suite (`truth` covers every task),
/// so each record equals the whole run's record of its task.
pub fn run_shard(
    cfg: &EvalConfig,
    workload: &Workload,
    psi: &HeatmapSet,
    truth: &HeatmapSet,
    shard: Shard,
) -> Result<Vec<TaskRecord>, EvalError> {
    cfg.check()?;
    let areas: Vec<f64> = workload
        .tasks
        .iter()
        .map(|t| servable_area_m2(truth, t))
        .collect();
    let groups = difficulty_groups(&areas);
    let runs = cfg.runs();
    let per_task: Result<Vec<Vec<TaskRecord>>, EvalError> = workload
        .tasks
        .par_iter()
        .filter(|task| shard.contains(task.id))
        .map(|task| {
            let scene = &workload.scenes[task.scene];
            let grid = &workload.grids[task.scene];
            let targets = workload.targets(task);
            let problem =
                TaskProblem::from_heatmaps(scene, &cfg.robot, &targets, &psi.for_task(task));
            let mut out = Vec::with_capacity(runs.len());
            for &(speed, method) in &runs {
                let robot = RobotConfig {
                    speed_mps: speed,
                    ..cfg.robot.clone()
                };
                let pcfg = PlannerConfig {
                    speed_mps: speed,
                    ..cfg.planner
                };
                let mut travel = GridTravelTime::new(grid, speed);
                // Same seeds for every method: baselines draw the same uniform goals and every
                // method meets the same noise stream (paired comparison).
                let plan_seed = mix_seed(cfg.seed, task.id as u64, 0x706c);
                let planned = Planner::new(method, pcfg)
                    .plan(&problem, &mut travel, plan_seed)
                    .map_err(|source| EvalError::Plan {
                        method: method.name(),
                        task: task.id,
                        source,
                    })?;
                let mut rng = ChaCha8Rng::seed_from_u64(mix_seed(cfg.seed, task.id as u64, 0x6578));
                let retry = (method == MethodKind::GropPlus).then_some(&pcfg);
                let exec = execute(
                    cfg, scene, &robot, grid, &problem, &planned, retry, &mut rng,
                );
                out.push(TaskRecord {
                    task: task.id,
                    scene: task.scene,
                    n_chairs: task.n_chairs,
                    speed_mps: speed,
                    method: method.name(),
                    difficulty: groups[task.id],
                    servable_area_m2: areas[task.id],
                    objects: targets.len(),
                    placed: exec.placed,
                    time_s: exec.time_s,
                    distance_m: exec.distance_m,
                    predicted_f: planned.feasibility,
                    predicted_cost_s: planned.cost_s,
                    motion_planner_calls: planned.motion_planner_calls,
                    retries: exec.retries,
                    steps: exec
                        .steps
                        .iter()
                        .map(|(o, attempts)| {
                            let names: Vec<String> = attempts
                                .iter()
                                .map(|s| {
                                    serde_json::to_string(s)
                                        .unwrap_or_default()
                                        .trim_matches('"')
                                        .to_string()
                                })
                                .collect();
                            format!("{o}:{}", names.join(">"))
                        })
                        .collect::<Vec<_>>()
                        .join("|"),
                });
            }
            Ok(out)
        })
        .collect();
    Ok(per_task?.into_iter().flatten().collect())
}

/// Writes the records as CSV.
pub fn write_csv(path: &Path, records: &[TaskRecord]) -> Result<(), EvalError> {
    use std::fmt::Write;
    let mut s = String::from(
        "task,scene,n_chairs,speed_mps,method,difficulty,servable_area_m2,objects,placed,time_s,distance_m,predicted_f,predicted_cost_s,motion_planner_calls,retries,steps\n",
    );
    for r in records {
        let _ = writeln!(
            s,
            "{},{},{},{},{},{},{:.4},{},{},{:.2},{:.2},{:.4},{:.2},{},{},{}",
            r.task,
            r.scene,
            r.n_chairs,
            r.speed_mps,
            r.method,
            r.difficulty.name(),
            r.servable_area_m2,
            r.objects,
            r.placed,
            r.time_s,
            r.distance_m,
            r.predicted_f,
            r.predicted_cost_s,
            r.motion_planner_calls,
            r.retries,
            r.steps
        );
    }
    write_file(path, &s)
}

/// Header of [`write_records_exact`]'s files.
const EXACT_HEADER: &str = "grop-eval-records-1\ttask\tscene\tn_chairs\tspeed_mps\tmethod\tdifficulty\tservable_area_m2\tobjects\tplaced\ttime_s\tdistance_m\tpredicted_f\tpredicted_cost_s\tmotion_planner_calls\tretries\tsteps";

/// Writes records exactly (a shard's results): tab-separated, every number in Rust's shortest
/// round-trip form, so [`read_records_exact`] gives back the very same values.
pub fn write_records_exact(path: &Path, records: &[TaskRecord]) -> Result<(), EvalError> {
    use std::fmt::Write;
    let mut s = String::from(EXACT_HEADER);
    s.push('\n');
    for r in records {
        let _ = writeln!(
            s,
            "\t{}\t{}\t{}\t{:?}\t{}\t{}\t{:?}\t{}\t{}\t{:?}\t{:?}\t{:?}\t{:?}\t{}\t{}\t{}",
            r.task,
            r.scene,
            r.n_chairs,
            r.speed_mps,
            r.method,
            r.difficulty.name(),
            r.servable_area_m2,
            r.objects,
            r.placed,
            r.time_s,
            r.distance_m,
            r.predicted_f,
            r.predicted_cost_s,
            r.motion_planner_calls,
            r.retries,
            r.steps
        );
    }
    write_file(path, &s)
}

/// Reads what [`write_records_exact`] wrote.
pub fn read_records_exact(path: &Path) -> Result<Vec<TaskRecord>, EvalError> {
    let text = std::fs::read_to_string(path).map_err(|source| EvalError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let bad = |line: usize, reason: String| EvalError::Records {
        path: path.to_path_buf(),
        reason: format!("line {line}: {reason}"),
    };
    let mut lines = text.lines();
    if lines.next() != Some(EXACT_HEADER) {
        return Err(bad(1, "not a grop eval records file (header)".into()));
    }
    let mut out = Vec::new();
    for (i, line) in lines.enumerate() {
        let n = i + 2;
        let f: Vec<&str> = line.split('\t').collect();
        if f.len() != 17 || !f[0].is_empty() {
            return Err(bad(n, format!("{} fields, expected 17", f.len())));
        }
        fn num<T: std::str::FromStr>(s: &str, what: &str) -> Result<T, String> {
            s.parse()
                .map_err(|_| format!("{what} {s:?} is not a number"))
        }
        let rec = (|| -> Result<TaskRecord, String> {
            let method = MethodKind::parse(f[5])
                .ok_or_else(|| format!("unknown method {:?}", f[5]))?
                .name();
            let difficulty = Difficulty::ALL
                .into_iter()
                .find(|d| d.name() == f[6])
                .ok_or_else(|| format!("unknown difficulty {:?}", f[6]))?;
            Ok(TaskRecord {
                task: num(f[1], "task")?,
                scene: num(f[2], "scene")?,
                n_chairs: num(f[3], "n_chairs")?,
                speed_mps: num(f[4], "speed_mps")?,
                method,
                difficulty,
                servable_area_m2: num(f[7], "servable_area_m2")?,
                objects: num(f[8], "objects")?,
                placed: num(f[9], "placed")?,
                time_s: num(f[10], "time_s")?,
                distance_m: num(f[11], "distance_m")?,
                predicted_f: num(f[12], "predicted_f")?,
                predicted_cost_s: num(f[13], "predicted_cost_s")?,
                motion_planner_calls: num(f[14], "motion_planner_calls")?,
                retries: num(f[15], "retries")?,
                steps: f[16].to_owned(),
            })
        })()
        .map_err(|e| bad(n, e))?;
        out.push(rec);
    }
    Ok(out)
}

/// Writes a text file, creating its folder.
pub fn write_file(path: &Path, text: &str) -> Result<(), EvalError> {
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(|source| EvalError::Io {
            path: dir.to_path_buf(),
            source,
        })?;
    }
    std::fs::write(path, text).map_err(|source| EvalError::Io {
        path: path.to_path_buf(),
        source,
    })
}

/// Aggregate of a set of records.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Stats {
    /// Tasks.
    pub tasks: usize,
    /// Fraction of objects placed (the paper's task completion rate).
    pub completion: f64,
    /// Fraction of tasks with every object placed.
    pub all_placed: f64,
    /// Mean execution time (s).
    pub mean_time_s: f64,
    /// Standard deviation of execution time over tasks (s).
    pub std_time_s: f64,
    /// Mean motion-planner calls to decide.
    pub mean_calls: f64,
}

impl Stats {
    /// Aggregates records.
    pub fn of<'a>(records: impl IntoIterator<Item = &'a TaskRecord>) -> Stats {
        let rs: Vec<&TaskRecord> = records.into_iter().collect();
        if rs.is_empty() {
            return Stats::default();
        }
        let n = rs.len() as f64;
        let objects: usize = rs.iter().map(|r| r.objects).sum();
        let placed: usize = rs.iter().map(|r| r.placed).sum();
        let mean_time_s = rs.iter().map(|r| r.time_s).sum::<f64>() / n;
        let var = rs
            .iter()
            .map(|r| (r.time_s - mean_time_s).powi(2))
            .sum::<f64>()
            / n;
        Stats {
            tasks: rs.len(),
            completion: placed as f64 / objects.max(1) as f64,
            all_placed: rs.iter().filter(|r| r.placed == r.objects).count() as f64 / n,
            mean_time_s,
            std_time_s: var.sqrt(),
            mean_calls: rs
                .iter()
                .map(|r| r.motion_planner_calls as f64)
                .sum::<f64>()
                / n,
        }
    }
}

/// The tables of an evaluation.
#[derive(Debug, Clone)]
pub struct Summary {
    /// (method, difficulty or None for all) -> stats at the main speed.
    pub main: Vec<(MethodKind, Option<Difficulty>, Stats)>,
    /// (speed, method) -> stats over all tasks.
    pub sweep: Vec<(f64, MethodKind, Stats)>,
    /// Fig. 5 points: (method, difficulty, mean time of 10 tasks, completion of those 10).
    pub points: Vec<(MethodKind, Difficulty, f64, f64)>,
    /// GROP minus each other method at the main speed, paired over the same tasks:
    /// (method, difficulty or None for all, difference).
    pub paired: Vec<(MethodKind, Option<Difficulty>, PairedDiff)>,
    /// GROP+ minus GROP at the main speed, paired over the same tasks (when both ran):
    /// (difficulty or None for all, difference).
    pub plus: Vec<(Option<Difficulty>, PlusDiff)>,
}

/// GROP+ minus GROP on the same tasks: completion, all placed, time.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct PlusDiff {
    /// Per-task fraction placed.
    pub completion: PairedDiff,
    /// Per task 1 if every object was placed, else 0.
    pub all_placed: PairedDiff,
    /// Task time (s).
    pub time_s: PairedDiff,
}

impl PlusDiff {
    /// `a - b` over the tasks both ran.
    pub fn of(a: &[&TaskRecord], b: &[&TaskRecord]) -> PlusDiff {
        PlusDiff {
            completion: PairedDiff::of(a, b),
            all_placed: PairedDiff::of_metric(a, b, |r| f64::from(u8::from(r.placed == r.objects))),
            time_s: PairedDiff::of_metric(a, b, |r| r.time_s),
        }
    }
}

/// Mean difference of per-task completion between two methods on the same tasks, with its
/// standard error (the spread of the per-task differences over the square root of their count).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct PairedDiff {
    /// Tasks paired.
    pub tasks: usize,
    /// Mean of (placed / objects) of the first method minus the second's.
    pub mean: f64,
    /// Standard error of that mean.
    pub std_error: f64,
}

impl PairedDiff {
    /// The paired difference `a - b` of per-task completion over the tasks both ran.
    pub fn of(a: &[&TaskRecord], b: &[&TaskRecord]) -> PairedDiff {
        Self::of_metric(a, b, |r| r.placed as f64 / r.objects.max(1) as f64)
    }

    /// The paired difference `a - b` of a per-task measure over the tasks both ran.
    pub fn of_metric(
        a: &[&TaskRecord],
        b: &[&TaskRecord],
        rate: impl Fn(&TaskRecord) -> f64,
    ) -> PairedDiff {
        let by_task: std::collections::HashMap<usize, f64> =
            b.iter().map(|r| (r.task, rate(r))).collect();
        let d: Vec<f64> = a
            .iter()
            .filter_map(|r| by_task.get(&r.task).map(|rb| rate(r) - rb))
            .collect();
        if d.len() < 2 {
            return PairedDiff {
                tasks: d.len(),
                mean: d.first().copied().unwrap_or(0.0),
                std_error: f64::NAN,
            };
        }
        let n = d.len() as f64;
        let mean = d.iter().sum::<f64>() / n;
        let var = d.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0);
        PairedDiff {
            tasks: d.len(),
            mean,
            std_error: (var / n).sqrt(),
        }
    }
}

impl Summary {
    /// Aggregates records.
    pub fn from_records(cfg: &EvalConfig, records: &[TaskRecord]) -> Summary {
        let at = |speed: f64, m: MethodKind| {
            records
                .iter()
                .filter(move |r| r.speed_mps == speed && r.method == m.name())
        };
        let mut main = Vec::new();
        let mut points = Vec::new();
        for &m in &cfg.methods {
            main.push((m, None, Stats::of(at(cfg.main_speed_mps, m))));
            for d in Difficulty::ALL {
                let rs: Vec<&TaskRecord> = at(cfg.main_speed_mps, m)
                    .filter(|r| r.difficulty == d)
                    .collect();
                main.push((m, Some(d), Stats::of(rs.iter().copied())));
                // Each Fig. 5 point is the average of 10 tasks (task id order).
                for chunk in rs.chunks(10) {
                    let s = Stats::of(chunk.iter().copied());
                    points.push((m, d, s.mean_time_s, s.completion));
                }
            }
        }
        let mut paired = Vec::new();
        let grop: Vec<&TaskRecord> = at(cfg.main_speed_mps, MethodKind::Grop).collect();
        let grop_plus: Vec<&TaskRecord> = at(cfg.main_speed_mps, MethodKind::GropPlus).collect();
        let mut plus = Vec::new();
        if !grop.is_empty() && !grop_plus.is_empty() {
            plus.push((None, PlusDiff::of(&grop_plus, &grop)));
            for d in Difficulty::ALL {
                let a: Vec<&TaskRecord> = grop_plus
                    .iter()
                    .copied()
                    .filter(|r| r.difficulty == d)
                    .collect();
                let b: Vec<&TaskRecord> =
                    grop.iter().copied().filter(|r| r.difficulty == d).collect();
                plus.push((Some(d), PlusDiff::of(&a, &b)));
            }
        }
        if !grop.is_empty() {
            for &m in cfg
                .methods
                .iter()
                .filter(|&&m| m != MethodKind::Grop && m != MethodKind::GropPlus)
            {
                let other: Vec<&TaskRecord> = at(cfg.main_speed_mps, m).collect();
                paired.push((m, None, PairedDiff::of(&grop, &other)));
                for d in Difficulty::ALL {
                    let g: Vec<&TaskRecord> =
                        grop.iter().copied().filter(|r| r.difficulty == d).collect();
                    let o: Vec<&TaskRecord> = other
                        .iter()
                        .copied()
                        .filter(|r| r.difficulty == d)
                        .collect();
                    paired.push((m, Some(d), PairedDiff::of(&g, &o)));
                }
            }
        }
        let mut sweep = Vec::new();
        for &s in &cfg.sweep_speeds_mps {
            for &m in &cfg.sweep_methods {
                sweep.push((s, m, Stats::of(at(s, m))));
            }
        }
        Summary {
            main,
            sweep,
            points,
            paired,
            plus,
        }
    }

    /// Stats of a method and group at the main speed.
    pub fn get(&self, m: MethodKind, d: Option<Difficulty>) -> Option<Stats> {
        self.main
            .iter()
            .find(|(mm, dd, _)| *mm == m && *dd == d)
            .map(|x| x.2)
    }

    /// GROP minus `m`, paired over tasks, in group `d` (None: all tasks).
    pub fn paired_get(&self, m: MethodKind, d: Option<Difficulty>) -> Option<PairedDiff> {
        self.paired
            .iter()
            .find(|(mm, dd, _)| *mm == m && *dd == d)
            .map(|x| x.2)
    }

    /// GROP+ minus GROP, paired over tasks, in group `d` (None: all tasks).
    pub fn plus_get(&self, d: Option<Difficulty>) -> Option<PlusDiff> {
        self.plus.iter().find(|(dd, _)| *dd == d).map(|x| x.1)
    }

    /// Stats of the sweep.
    pub fn sweep_get(&self, speed: f64, m: MethodKind) -> Option<Stats> {
        self.sweep
            .iter()
            .find(|(s, mm, _)| *s == speed && *mm == m)
            .map(|x| x.2)
    }

    /// The issue's expectations, each with whether the measurement supports it.
    pub fn checks(&self, cfg: &EvalConfig) -> Vec<(String, bool)> {
        let mut out = Vec::new();
        let g = MethodKind::Grop;
        for d in Difficulty::ALL {
            if let Some(gs) = self.get(g, Some(d)) {
                let best_other = cfg
                    .methods
                    .iter()
                    .filter(|&&m| m != g && m != MethodKind::GropPlus)
                    .filter_map(|&m| self.get(m, Some(d)).map(|s| (m, s.completion)))
                    .max_by(|a, b| a.1.total_cmp(&b.1));
                if let Some((m, c)) = best_other {
                    let diff = self.paired_get(m, Some(d)).unwrap_or_default();
                    out.push((
                        format!(
                            "{}: GROP has the highest completion ({:.3} vs best other {} {:.3}; \
                             paired difference {:+.3} ± {:.3} standard error)",
                            d.name(),
                            gs.completion,
                            m.name(),
                            c,
                            diff.mean,
                            diff.std_error
                        ),
                        gs.completion > c,
                    ));
                }
            }
        }
        if let (Some(gs), Some(ps)) = (self.get(g, None), self.get(MethodKind::Petlon, None)) {
            out.push((
                format!(
                    "GROP's time within 10% of PETLON's ({:.1} s vs {:.1} s)",
                    gs.mean_time_s, ps.mean_time_s
                ),
                gs.mean_time_s <= 1.1 * ps.mean_time_s,
            ));
        }
        if let (Some(gs), Some(ds)) = (self.get(g, None), self.get(MethodKind::Dvh, None)) {
            out.push((
                format!(
                    "GROP's time below DVH's ({:.1} s vs {:.1} s)",
                    gs.mean_time_s, ds.mean_time_s
                ),
                gs.mean_time_s < ds.mean_time_s,
            ));
        }
        let mut speeds = cfg.sweep_speeds_mps.clone();
        speeds.sort_by(f64::total_cmp);
        let comps: Vec<f64> = speeds
            .iter()
            .filter_map(|&s| self.sweep_get(s, g).map(|x| x.completion))
            .collect();
        if comps.len() >= 2 {
            let rising = comps.windows(2).all(|w| w[1] >= w[0]);
            let txt: Vec<String> = comps.iter().map(|c| format!("{c:.3}")).collect();
            out.push((
                format!("GROP's completion rises with speed ({})", txt.join(" -> ")),
                rising,
            ));
        }
        // Issue 13: GROP+ on the hard third.
        let hard = Some(Difficulty::Hard);
        if let (Some(p), Some(gs), Some(d)) = (
            self.get(MethodKind::GropPlus, hard),
            self.get(g, hard),
            self.plus_get(hard),
        ) {
            out.push((
                format!(
                    "hard: GROP+ places at least 0.90 of the objects ({:.3}; GROP {:.3}; paired {:+.3} ± {:.3})",
                    p.completion, gs.completion, d.completion.mean, d.completion.std_error
                ),
                p.completion >= 0.90,
            ));
            out.push((
                format!(
                    "hard: GROP+ places all three in at least 0.75 of the tasks ({:.3}; GROP {:.3}; paired {:+.3} ± {:.3})",
                    p.all_placed, gs.all_placed, d.all_placed.mean, d.all_placed.std_error
                ),
                p.all_placed >= 0.75,
            ));
            out.push((
                format!(
                    "hard: GROP+'s mean task time no higher than GROP's ({:.1} s vs {:.1} s; paired {:+.1} ± {:.1} s)",
                    p.mean_time_s, gs.mean_time_s, d.time_s.mean, d.time_s.std_error
                ),
                p.mean_time_s <= gs.mean_time_s,
            ));
        }
        out
    }

    /// Markdown tables: main comparison by difficulty, speed sweep (Table I), checks.
    #[allow(
        clippy::too_many_lines,
        reason = "the report's sections in the order they are printed"
    )]
    pub fn markdown(&self, cfg: &EvalConfig) -> String {
        use std::fmt::Write;
        let mut s = String::new();
        let _ = writeln!(
            s,
            "Main comparison at {} m/s: completion (objects placed) / all three placed / mean time (s) ± std\n",
            cfg.main_speed_mps
        );
        let _ = writeln!(
            s,
            "| method | easy | normal | hard | all | decide: nav-planner calls |"
        );
        let _ = writeln!(s, "|---|---|---|---|---|---|");
        for &m in &cfg.methods {
            let cell = |d| {
                self.get(m, d)
                    .map(|x| {
                        format!(
                            "{:.3} / {:.3} / {:.1} ± {:.1}",
                            x.completion, x.all_placed, x.mean_time_s, x.std_time_s
                        )
                    })
                    .unwrap_or_default()
            };
            let calls = self.get(m, None).map(|x| x.mean_calls).unwrap_or(0.0);
            let _ = writeln!(
                s,
                "| {} | {} | {} | {} | {} | {:.1} |",
                m.name(),
                cell(Some(Difficulty::Easy)),
                cell(Some(Difficulty::Normal)),
                cell(Some(Difficulty::Hard)),
                cell(None),
                calls
            );
        }
        if !self.paired.is_empty() {
            let _ = writeln!(
                s,
                "\nGROP minus each method, completion paired over the same tasks: mean difference ± standard error\n"
            );
            let _ = writeln!(s, "| method | easy | normal | hard | all |");
            let _ = writeln!(s, "|---|---|---|---|---|");
            for &m in cfg
                .methods
                .iter()
                .filter(|&&m| m != MethodKind::Grop && m != MethodKind::GropPlus)
            {
                let cell = |d| {
                    self.paired_get(m, d)
                        .map(|x| format!("{:+.3} ± {:.3}", x.mean, x.std_error))
                        .unwrap_or_default()
                };
                let _ = writeln!(
                    s,
                    "| {} | {} | {} | {} | {} |",
                    m.name(),
                    cell(Some(Difficulty::Easy)),
                    cell(Some(Difficulty::Normal)),
                    cell(Some(Difficulty::Hard)),
                    cell(None)
                );
            }
        }
        if !self.plus.is_empty() {
            let p = cfg.planner.plus;
            let _ = writeln!(
                s,
                "\nGROP+ (retries {}, goal draws {}, goal margin {} m, R follows speed {}) minus GROP, paired over the same tasks: completion / all placed / time (s), mean difference ± standard error\n",
                p.max_retries,
                p.goal_draws.map_or_else(
                    || format!("GROP's ({})", cfg.planner.goal_draws),
                    |n| n.to_string()
                ),
                p.goal_margin_m,
                if p.r_follows_speed { "on" } else { "off" }
            );
            let _ = writeln!(s, "| group | completion | all placed | time (s) |");
            let _ = writeln!(s, "|---|---|---|---|");
            for d in [
                Some(Difficulty::Easy),
                Some(Difficulty::Normal),
                Some(Difficulty::Hard),
                None,
            ] {
                if let Some(x) = self.plus_get(d) {
                    let _ = writeln!(
                        s,
                        "| {} | {:+.3} ± {:.3} | {:+.3} ± {:.3} | {:+.1} ± {:.1} |",
                        d.map_or("all", Difficulty::name),
                        x.completion.mean,
                        x.completion.std_error,
                        x.all_placed.mean,
                        x.all_placed.std_error,
                        x.time_s.mean,
                        x.time_s.std_error
                    );
                }
            }
        }
        if !self.sweep.is_empty() {
            let _ = writeln!(
                s,
                "\nSpeed sweep (Table I), all tasks: completion / mean time (s)\n"
            );
            let _ = write!(s, "| speed |");
            for m in &cfg.sweep_methods {
                let _ = write!(s, " {} |", m.name());
            }
            let _ = write!(s, "\n|---|");
            for _ in &cfg.sweep_methods {
                let _ = write!(s, "---|");
            }
            let _ = writeln!(s);
            for &sp in &cfg.sweep_speeds_mps {
                let _ = write!(s, "| {sp} m/s |");
                for &m in &cfg.sweep_methods {
                    let cell = self
                        .sweep_get(sp, m)
                        .map(|x| format!("{:.3} / {:.1}", x.completion, x.mean_time_s));
                    let _ = write!(s, " {} |", cell.unwrap_or_default());
                }
                let _ = writeln!(s);
            }
        }
        let _ = writeln!(s, "\nThe issue's expectations, as measured:\n");
        for (text, ok) in self.checks(cfg) {
            let _ = writeln!(
                s,
                "- {} {}",
                if ok { "holds:" } else { "DOES NOT hold:" },
                text
            );
        }
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn thirds_by_area() {
        let areas = [5.0, 1.0, 3.0, 2.0, 6.0, 4.0];
        let g = difficulty_groups(&areas);
        assert_eq!(g[1], Difficulty::Hard);
        assert_eq!(g[3], Difficulty::Hard);
        assert_eq!(g[2], Difficulty::Normal);
        assert_eq!(g[5], Difficulty::Normal);
        assert_eq!(g[0], Difficulty::Easy);
        assert_eq!(g[4], Difficulty::Easy);
    }

    #[test]
    fn stats_aggregate() {
        let r = |placed, time_s| TaskRecord {
            task: 0,
            scene: 0,
            n_chairs: 15,
            speed_mps: 0.4,
            method: "GROP",
            difficulty: Difficulty::Easy,
            servable_area_m2: 1.0,
            objects: 3,
            placed,
            time_s,
            distance_m: 0.0,
            predicted_f: 0.0,
            predicted_cost_s: 0.0,
            motion_planner_calls: 19,
            retries: 0,
            steps: String::new(),
        };
        let s = Stats::of(&[r(3, 10.0), r(0, 30.0)]);
        assert_eq!(s.tasks, 2);
        assert_eq!(s.completion, 0.5);
        assert_eq!(s.all_placed, 0.5);
        assert_eq!(s.mean_time_s, 20.0);
        assert_eq!(s.std_time_s, 10.0);
        assert_eq!(Stats::of(&[]), Stats::default());
    }

    #[test]
    fn paired_difference_matches_tasks() {
        let r = |task, method, placed| TaskRecord {
            task,
            scene: 0,
            n_chairs: 15,
            speed_mps: 0.4,
            method,
            difficulty: Difficulty::Easy,
            servable_area_m2: 1.0,
            objects: 3,
            placed,
            time_s: 1.0,
            distance_m: 0.0,
            predicted_f: 0.0,
            predicted_cost_s: 0.0,
            motion_planner_calls: 0,
            retries: 0,
            steps: String::new(),
        };
        let a = [
            r(0, "GROP", 3),
            r(1, "GROP", 2),
            r(2, "GROP", 3),
            r(7, "GROP", 0),
        ];
        // Listed in another order; task 7 has no partner and is left out.
        let b = [r(2, "DVH", 0), r(0, "DVH", 3), r(1, "DVH", 2)];
        let d = PairedDiff::of(&a.iter().collect::<Vec<_>>(), &b.iter().collect::<Vec<_>>());
        assert_eq!(d.tasks, 3);
        // Differences 0, 0, 1: mean 1/3, sample sd sqrt(1/3), se sqrt(1/9).
        assert!((d.mean - 1.0 / 3.0).abs() < 1e-12);
        assert!((d.std_error - (1.0f64 / 9.0).sqrt()).abs() < 1e-12);
        assert!(PairedDiff::of(&[], &[]).std_error.is_nan());
    }

    #[test]
    fn runs_cover_main_and_sweep_once() {
        let cfg = EvalConfig::default();
        let runs = cfg.runs();
        // Six methods at 0.4 m/s; GROP+, GROP, PETLON and DVH also at 0.2 and 0.8 m/s.
        assert_eq!(runs.len(), 6 + 2 * 4);
        assert!(runs.contains(&(0.2, MethodKind::Dvh)));
        assert!(runs.contains(&(0.8, MethodKind::GropPlus)));
        assert!(!runs.contains(&(0.2, MethodKind::Satisficing)));
    }

    #[test]
    fn bad_config_is_reported() {
        let cfg = EvalConfig {
            main_speed_mps: 0.0,
            ..EvalConfig::default()
        };
        assert!(matches!(cfg.check(), Err(EvalError::Config(_))));
        let cfg = EvalConfig {
            methods: vec![],
            ..EvalConfig::default()
        };
        assert!(matches!(cfg.check(), Err(EvalError::Config(_))));
    }
}
