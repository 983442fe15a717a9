//! Running the plans in the trial simulator: one task's execution, the records, shards.

use super::*;

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
