//! `grop bench`: GROP decision latency on one core, p50 and p99, written to
//! `out/planner-bench.md`, and to the committed `docs/planner-bench.md` with `--write-docs`.
//!
//! Cases (evaluation scenes, the real world rendering, FCN and navigation planner):
//! - `grop-3`: one full GROP decision for 3 objects on the onboard perception path: 6 views cut
//!   from an overhead camera frame and run through the FCN in one batch, free cells marked, every
//!   navigation cost (19 navigation legs), all 288 plans scored, argmax; with the split into cut,
//!   Psi, free cells, planning (navigation costs and selection); `grop+-3` the same with GROP+;
//!   `grop-3-rendered` / `grop-3-lazy` with crops rendered from the scene;
//! - `exact-10`: 10 objects with the exact optimiser: the optimiser alone on the cost table, and
//!   the full decision (20 crops, 381 navigation legs, optimiser);
//! - `map`: per map, outside every decision: the occupancy grid and its corner visibility graph.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::Context;
use planner::costs::{GridTravelTime, LegCache, MemoTravel};
use planner::feasibility::{FcnEvaluator, FeasibilityEvaluator};
use planner::methods::{
    MethodKind, PlannedTask, Planner, PlannerConfig, SearchMode, TaskMotionPlanner,
};
use planner::problem::{TaskProblem, evaluate_crops, side_of_location};
use planner::task::{PlanningTable, optimise};
use world::camera::{FrameLayout, OverheadCamera, cut_views, render_frame};
use world::nav::OccupancyGrid;

/// Arguments of `grop bench`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// FCN model file.
    #[arg(long, default_value = "models/psi-fcn.onnx")]
    pub model: PathBuf,
    /// Measured iterations per case (after warm-up).
    #[arg(long, default_value_t = 200)]
    pub iterations: usize,
    /// Markdown file for the results.
    #[arg(long, default_value = "out/planner-bench.md")]
    pub out: PathBuf,
    /// Also write the results to docs/planner-bench.md (regenerates the committed doc).
    #[arg(long)]
    pub write_docs: bool,
    /// Seed of the scenes.
    #[arg(long, default_value_t = 7)]
    pub seed: u64,
    /// Run only the `grop-3` decision (camera frame, GROP) this many times and print its p50 and
    /// p99, writing nothing: a loop to put under a profiler (`perf record`).
    #[arg(long, value_name = "N")]
    pub decision_only: Option<usize>,
}

/// Latency samples of one case.
struct Samples {
    name: &'static str,
    what: &'static str,
    ms: Vec<f64>,
}

impl Samples {
    fn new(name: &'static str, what: &'static str) -> Self {
        Self {
            name,
            what,
            ms: Vec::new(),
        }
    }

    fn pct(&self, p: f64) -> f64 {
        let mut v = self.ms.clone();
        v.sort_by(f64::total_cmp);
        if v.is_empty() {
            return f64::NAN;
        }
        let i = ((v.len() as f64 - 1.0) * p).round() as usize;
        v[i.min(v.len() - 1)]
    }
}

/// Goals of the `count` scene targets starting at `first`: one task of the case.
fn task_targets(scene: &world::Scene, first: usize, count: usize) -> Vec<[f64; 3]> {
    scene.targets[first..first + count]
        .iter()
        .map(|t| t.as_array())
        .collect()
}

/// One full GROP decision with lazy costs: a fresh problem (crops rendered, FCN run) and the
/// planner asking the navigation grid only for the legs it needs. The timed body of the
/// `*-lazy` cases.
fn lazy_decision(
    scene: &world::Scene,
    robot: &world::RobotConfig,
    targets: &[[f64; 3]],
    fcn: &mut dyn FeasibilityEvaluator,
    grid: &OccupancyGrid,
    cfg: PlannerConfig,
    seed: u64,
) -> anyhow::Result<PlannedTask> {
    let problem = TaskProblem::from_world(scene, robot, targets, fcn)?;
    let mut grid_travel = GridTravelTime::new(grid, robot.speed_mps);
    let lazy = Planner::new(
        MethodKind::Grop,
        PlannerConfig {
            lazy_costs: true,
            ..cfg
        },
    )
    .plan(&problem, &mut grid_travel, seed)?;
    Ok(lazy)
}

/// The onboard perception path of one decision (as `grop-planner` runs it): cut the views of
/// every (target, side) from the camera frame, run Psi on all of them in one batch, build the
/// problem (candidate cells and free-cell marking). With `record`, the three stages' times go to
/// `stages` (cut, Psi, free cells), when three are given.
#[allow(clippy::too_many_arguments)]
fn camera_problem(
    scene: &world::Scene,
    robot: &world::RobotConfig,
    targets: &[[f64; 3]],
    (layout, pixels): (&FrameLayout, &[u8]),
    fcn: &mut FcnEvaluator,
    crops: &mut [[u8; 2048]],
    heatmaps: &mut [world::Heatmap],
    stages: &mut [&mut Samples],
    record: bool,
) -> anyhow::Result<TaskProblem> {
    let m = 2 * targets.len();
    anyhow::ensure!(crops.len() >= m && heatmaps.len() >= m, "buffers too small");
    let t0 = Instant::now();
    let mut views = [(0.0, world::Side::Near); 2 * planner::task::MAX_OBJECTS];
    for (i, view) in views[..m].iter_mut().enumerate() {
        *view = (targets[i / 2][0], side_of_location(i));
    }
    cut_views(pixels, layout, &views[..m], &mut crops[..m])?;
    let t1 = Instant::now();
    evaluate_crops(scene, robot, targets, &crops[..m], fcn, &mut heatmaps[..m])?;
    let t2 = Instant::now();
    let problem = TaskProblem::from_heatmaps(scene, robot, targets, &heatmaps[..m]);
    let t3 = Instant::now();
    if record && stages.len() == 3 {
        for (samples, (a, b)) in stages.iter_mut().zip([(t0, t1), (t1, t2), (t2, t3)]) {
            samples.ms.push((b - a).as_secs_f64() * 1e3);
        }
    }
    Ok(problem)
}

/// The scenes, the robot, each scene's camera frame and its prepared grid.
type BenchInputs<'a> = (
    &'a [world::Scene],
    &'a world::RobotConfig,
    &'a [(FrameLayout, Vec<u8>)],
    &'a [OccupancyGrid],
);

/// The `grop-3` decisions `ks` (camera frame, GROP, 3 objects; decision `k` takes scene
/// `k % 3` and its target triples in turn) one after the other; the times of those from
/// `warmup` on go to `samples`.
fn decisions_back_to_back(
    (scenes, robot, frames, grids): BenchInputs<'_>,
    cfg: PlannerConfig,
    (fcn, crops, heatmaps): (&mut FcnEvaluator, &mut [[u8; 2048]], &mut [world::Heatmap]),
    ks: std::ops::Range<usize>,
    warmup: usize,
    samples: &mut Samples,
) -> anyhow::Result<()> {
    for k in ks {
        let s = k % scenes.len();
        let targets = task_targets(&scenes[s], (k / scenes.len() * 3) % 27, 3);
        let t0 = Instant::now();
        let problem = camera_problem(
            &scenes[s],
            robot,
            &targets,
            (&frames[s].0, &frames[s].1),
            fcn,
            crops,
            heatmaps,
            &mut [],
            false,
        )?;
        let mut travel = GridTravelTime::new(&grids[s], robot.speed_mps);
        Planner::new(MethodKind::Grop, cfg).plan(&problem, &mut travel, k as u64)?;
        if k >= warmup {
            samples.ms.push(t0.elapsed().as_secs_f64() * 1e3);
        }
    }
    Ok(())
}

#[allow(
    clippy::too_many_lines,
    reason = "a command's steps in order: arguments, setup, the measurements, the report"
)]
pub fn run(args: Args) -> anyhow::Result<()> {
    anyhow::ensure!(args.iterations >= 10, "--iterations must be at least 10");
    let robot = world::RobotConfig::default();
    // Every decision below reads only the candidate cells of Psi's heatmaps, so Psi computes
    // only those (`candidate_cells_only`); `grop-3/whole-heatmaps` runs the same decision with
    // whole heatmaps, as `grop-planner` computes them to publish them.
    let mut fcn = FcnEvaluator::load(&crate::common::committed_file(&args.model))
        .with_context(|| format!("loading {}", args.model.display()))?
        .candidate_cells_only();
    let mut fcn_whole = FcnEvaluator::load(&crate::common::committed_file(&args.model))
        .with_context(|| format!("loading {}", args.model.display()))?;
    let scenes: Vec<world::Scene> = [15usize, 20, 25]
        .iter()
        .map(|&c| world::generate::evaluation_scene(args.seed, c, 30))
        .collect();
    // Per map, outside the decision: the occupancy grid and its corner graph.
    let mut map = Samples::new(
        "map",
        "per map, not per decision: occupancy grid + corner visibility graph (all-pairs)",
    );
    let mut sight = Samples::new(
        "map/sight",
        "per map, not per decision: which corners each cell of the goal bands, the start and the station sees; the station connected",
    );
    let mut grids: Vec<OccupancyGrid> = Vec::new();
    let (mut sight_cells, mut sight_bytes) = (0, 0);
    for k in 0..3 * 10 {
        let t = Instant::now();
        let mut grid = OccupancyGrid::from_scene(&scenes[k % scenes.len()], &robot);
        let t1 = Instant::now();
        let stats =
            planner::costs::prepare_grid_for_decisions(&mut grid, &scenes[k % scenes.len()]);
        sight_cells = sight_cells.max(stats.cells);
        sight_bytes = sight_bytes.max(stats.bytes);
        map.ms.push((t1 - t).as_secs_f64() * 1e3);
        sight.ms.push(t1.elapsed().as_secs_f64() * 1e3);
        if k < scenes.len() {
            grids.push(grid);
        }
    }
    let cfg = PlannerConfig::for_robot(&robot);
    let warmup = 5;
    let total = warmup + args.iterations;

    // The onboard perception path (`grop-planner`): one overhead camera frame per scene, rendered
    // once (the camera's work, not the decision's), and Psi's views cut from it per decision.
    let frames: Vec<(FrameLayout, Vec<u8>)> = scenes
        .iter()
        .map(|scene| {
            let camera = OverheadCamera::fitting_room(scene);
            let mut pixels = vec![0u8; camera.rgb8_len()];
            render_frame(scene, &camera, &mut pixels)?;
            Ok((FrameLayout::rgb8(camera), pixels))
        })
        .collect::<anyhow::Result<_>>()?;

    let mut crops = vec![[0u8; 2048]; 6];
    let mut heatmaps = vec![world::Heatmap::zeros(); 6];
    // The same decisions back to back with nothing between them: the caches keep the model,
    // its buffers and the frame's rows, as on a core given to the planner. The `grop-3` row
    // below runs each decision between the other cases, so its caches are cold: the two side
    // by side show what that costs. `--decision-only` runs this loop alone (for a profiler).
    let mut warm3 = Samples::new(
        "grop-3/back-to-back",
        "the `grop-3` decision timed back to back in blocks of 25, no other case between decisions (warm caches)",
    );
    let mut whole3 = Samples::new(
        "grop-3/whole-heatmaps",
        "the `grop-3/back-to-back` decisions with Psi writing whole heatmaps (as `grop-planner` does, to publish them), in blocks alternating with them",
    );
    let inputs = (
        scenes.as_slice(),
        &robot,
        frames.as_slice(),
        grids.as_slice(),
    );
    if let Some(n) = args.decision_only {
        decisions_back_to_back(
            inputs,
            cfg,
            (&mut fcn, &mut crops, &mut heatmaps),
            0..n,
            0,
            &mut warm3,
        )?;
        println!(
            "grop-3 decision: p50 {:.3} ms, p99 {:.3} ms (n = {n})",
            warm3.pct(0.5),
            warm3.pct(0.99)
        );
        return Ok(());
    }
    // Blocks of the same decisions, with candidate cells and with whole heatmaps in turn, so
    // that the host's noise falls on both alike.
    for start in (0..total).step_by(BLOCK) {
        let ks = start..(start + BLOCK).min(total);
        decisions_back_to_back(
            inputs,
            cfg,
            (&mut fcn, &mut crops, &mut heatmaps),
            ks.clone(),
            warmup,
            &mut warm3,
        )?;
        decisions_back_to_back(
            inputs,
            cfg,
            (&mut fcn_whole, &mut crops, &mut heatmaps),
            ks,
            warmup,
            &mut whole3,
        )?;
    }

    let mut full3 = Samples::new(
        "grop-3",
        "full GROP decision, 3 objects, camera frame: 6 views cut + FCN + free cells + 19 navigation legs + 288 plans",
    );
    let mut cut3 = Samples::new(
        "grop-3/cut",
        "  of which: cut 6 views from the camera frame",
    );
    let mut psi3 = Samples::new(
        "grop-3/psi",
        "  of which: Psi, one FCN batch of 6 views (their candidate cells)",
    );
    let mut free3 = Samples::new(
        "grop-3/free",
        "  of which: candidate cells + free-cell marking (6 x 192 base footprints)",
    );
    let mut plan3 = Samples::new(
        "grop-3/plan",
        "  of which: GROP itself (Smp + 19 navigation legs + 288 plans + argmax)",
    );
    let mut nav3 = Samples::new(
        "grop-3/nav",
        "  of which: 19 navigation costs (endpoints connected to the corner graph, legs)",
    );
    let mut sel3 = Samples::new(
        "grop-3/select",
        "  of which: Smp goals + 288 plans scored + argmax (costs cached)",
    );
    let mut plus3 = Samples::new(
        "grop+-3",
        "full GROP+ decision (the default method), 3 objects, camera frame, same stages",
    );
    let mut plus3_plan = Samples::new(
        "grop+-3/plan",
        "  of which: GROP+ itself (20 Smp draws per location, 0.2 m margin, legs, plans)",
    );
    let mut rendered3 = Samples::new(
        "grop-3-rendered",
        "full GROP decision, 3 objects, crops rendered from the scene instead of cut",
    );
    let mut lazy3 = Samples::new(
        "grop-3-lazy",
        "full GROP decision, 3 objects, rendered crops, lazy costs (same argmax, fewer legs)",
    );
    let mut lazy3_calls = 0usize;
    for k in 0..total {
        let s = k % scenes.len();
        let scene = &scenes[s];
        let (layout, pixels) = &frames[s];
        let targets = task_targets(scene, (k / scenes.len() * 3) % 27, 3);
        let t0 = Instant::now();
        let problem = camera_problem(
            scene,
            &robot,
            &targets,
            (layout, pixels),
            &mut fcn,
            &mut crops,
            &mut heatmaps,
            &mut [&mut cut3, &mut psi3, &mut free3],
            k >= warmup,
        )?;
        let t1 = Instant::now();
        let mut travel = MemoTravel::new(GridTravelTime::new(&grids[s], robot.speed_mps));
        let planned = Planner::new(MethodKind::Grop, cfg).plan(&problem, &mut travel, k as u64)?;
        let t2 = Instant::now();
        // The same decision again with every leg already known: selection alone.
        let goals_xy: Vec<(f64, f64)> = planned.goals.iter().map(|g| g.xy).collect();
        let mut cache = LegCache::new(&problem, &goals_xy, cfg.no_path_cost_s);
        let mut table = PlanningTable::zeros(3);
        let mut grid_only = GridTravelTime::new(&grids[s], robot.speed_mps);
        let t3 = Instant::now();
        cache.fill_table(&mut table, &mut grid_only);
        let t4 = Instant::now();
        // Every leg is now in the memo: this decision is Smp + 288 plans + argmax alone.
        let t5 = Instant::now();
        let again = Planner::new(MethodKind::Grop, cfg).plan(&problem, &mut travel, k as u64)?;
        let t6 = Instant::now();
        anyhow::ensure!(
            again.plan == planned.plan,
            "cached decision differs from the full one"
        );
        // GROP+ on the same frame, from scratch.
        let t7 = Instant::now();
        let plus_problem = camera_problem(
            scene,
            &robot,
            &targets,
            (layout, pixels),
            &mut fcn,
            &mut crops,
            &mut heatmaps,
            &mut [],
            false,
        )?;
        let t8 = Instant::now();
        let mut plus_travel = GridTravelTime::new(&grids[s], robot.speed_mps);
        Planner::new(MethodKind::GropPlus, cfg).plan(&plus_problem, &mut plus_travel, k as u64)?;
        let t9 = Instant::now();
        // The same decision with whole heatmaps (timed in `grop-3/whole-heatmaps`): the same
        // candidate cells, bit for bit, so the same plan.
        let whole_problem = camera_problem(
            scene,
            &robot,
            &targets,
            (layout, pixels),
            &mut fcn_whole,
            &mut crops,
            &mut heatmaps,
            &mut [],
            false,
        )?;
        let mut whole_travel = GridTravelTime::new(&grids[s], robot.speed_mps);
        let whole = Planner::new(MethodKind::Grop, cfg).plan(
            &whole_problem,
            &mut whole_travel,
            k as u64,
        )?;
        anyhow::ensure!(
            whole.plan == planned.plan && whole.utility == planned.utility,
            "the decision on whole heatmaps differs from the one on candidate cells"
        );
        // The rendered-crop path (simulation, experiments).
        let t10 = Instant::now();
        let rendered = TaskProblem::from_world(
            scene,
            &robot,
            &targets,
            &mut fcn as &mut dyn FeasibilityEvaluator,
        )?;
        let mut r_travel = GridTravelTime::new(&grids[s], robot.speed_mps);
        let r_planned =
            Planner::new(MethodKind::Grop, cfg).plan(&rendered, &mut r_travel, k as u64)?;
        let t11 = Instant::now();
        let lazy = lazy_decision(scene, &robot, &targets, &mut fcn, &grids[s], cfg, k as u64)?;
        let t12 = Instant::now();
        anyhow::ensure!(
            (lazy.utility - r_planned.utility).abs() < 1e-6,
            "lazy decision differs from the full one:\n{}\n{}",
            r_planned.explain(3),
            lazy.explain(3)
        );
        if k >= warmup {
            full3.ms.push((t2 - t0).as_secs_f64() * 1e3);
            plan3.ms.push((t2 - t1).as_secs_f64() * 1e3);
            nav3.ms.push((t4 - t3).as_secs_f64() * 1e3);
            sel3.ms.push((t6 - t5).as_secs_f64() * 1e3);
            plus3.ms.push((t9 - t7).as_secs_f64() * 1e3);
            plus3_plan.ms.push((t9 - t8).as_secs_f64() * 1e3);
            rendered3.ms.push((t11 - t10).as_secs_f64() * 1e3);
            lazy3.ms.push((t12 - t11).as_secs_f64() * 1e3);
            lazy3_calls += lazy.motion_planner_calls;
        }
    }

    let mut opt10 = Samples::new(
        "exact-10/optimiser",
        "exact optimiser alone, 10 objects (sum), table given",
    );
    let mut opt10p = Samples::new(
        "exact-10/optimiser-product",
        "exact optimiser alone, 10 objects (product), table given",
    );
    let mut full10 = Samples::new(
        "exact-10",
        "full decision, 10 objects (20 crops FCN + 381 navigation legs + optimiser)",
    );
    let mut lazy10 = Samples::new(
        "exact-10-lazy",
        "full decision, 10 objects, exact optimiser with lazy costs",
    );
    let mut lazy10_calls = 0usize;
    let full10_iters = (args.iterations / 10).max(10);
    for k in 0..warmup + full10_iters {
        let s = k % scenes.len();
        let scene = &scenes[s];
        let targets = task_targets(scene, (k * 10) % 20, 10);
        let t0 = Instant::now();
        let problem = TaskProblem::from_world(
            scene,
            &robot,
            &targets,
            &mut fcn as &mut dyn FeasibilityEvaluator,
        )?;
        let mut travel = GridTravelTime::new(&grids[s], robot.speed_mps);
        let exact = PlannerConfig {
            search: SearchMode::Exact,
            ..cfg
        };
        let planned =
            Planner::new(MethodKind::Grop, exact).plan(&problem, &mut travel, k as u64)?;
        let t1 = Instant::now();
        let t2 = Instant::now();
        let lazy = lazy_decision(
            scene, &robot, &targets, &mut fcn, &grids[s], exact, k as u64,
        )?;
        let t3 = Instant::now();
        anyhow::ensure!(
            (lazy.utility - planned.utility).abs() < 1e-6,
            "lazy 10-object decision differs"
        );
        if k >= warmup {
            full10.ms.push((t1 - t0).as_secs_f64() * 1e3);
            lazy10.ms.push((t3 - t2).as_secs_f64() * 1e3);
            lazy10_calls += lazy.motion_planner_calls;
        }
        // Optimiser alone on this task's real table, repeated.
        let goals_xy: Vec<(f64, f64)> = planned.goals.iter().map(|g| g.xy).collect();
        let mut cache = LegCache::new(&problem, &goals_xy, cfg.no_path_cost_s);
        let mut table = PlanningTable::zeros(10);
        cache.fill_table(&mut table, &mut travel);
        for (i, r) in planned.locations.iter().enumerate() {
            table.feasibility[i] = r.feasibility;
        }
        if k >= warmup {
            for _ in 0..10 {
                let t = Instant::now();
                let best = optimise(
                    &table,
                    cfg.success_bonus_r,
                    planner::methods::Aggregation::Sum,
                )?;
                opt10.ms.push(t.elapsed().as_secs_f64() * 1e3);
                anyhow::ensure!(
                    best.plan == planned.plan,
                    "optimiser disagrees with the planner"
                );
                let t = Instant::now();
                optimise(
                    &table,
                    cfg.success_bonus_r,
                    planner::methods::Aggregation::Product,
                )?;
                opt10p.ms.push(t.elapsed().as_secs_f64() * 1e3);
            }
        }
    }

    let lazy3_mean_calls = lazy3_calls as f64 / lazy3.ms.len().max(1) as f64;
    let lazy10_mean_calls = lazy10_calls as f64 / lazy10.ms.len().max(1) as f64;
    // The verdict's figures, by name (the rows move into `cases` below).
    let (p50, p99) = (full3.pct(0.5), full3.pct(0.99));
    let (warm50, warm99) = (warm3.pct(0.5), warm3.pct(0.99));
    let plus50 = plus3.pct(0.5);
    let whole50 = whole3.pct(0.5);
    let cases = [
        full3, cut3, psi3, free3, plan3, nav3, sel3, warm3, whole3, plus3, plus3_plan, rendered3,
        lazy3, opt10, opt10p, full10, lazy10, map, sight,
    ];
    let mut md = String::from(
        "# GROP decision latency\n\n<!-- written by `grop bench` -->\n\nOne core, release build, evaluation scenes \
         (15/20/25 chairs), the committed FCN `models/psi-fcn.onnx`; the `grop-3` and `grop+-3` decisions take Psi's views \
         cut from a 640 x 480 overhead camera frame (`world::camera::cut_view`, the onboard `grop-planner` path; the frame is \
         rendered once per scene, outside the decision), `grop-3-rendered` renders the crops from the scene instead; shortest any-angle paths on the world's 0.1 m grid (corner visibility graph, built once per map: the `map` row; which corners the cells where decisions put endpoints see, and the station's connection, also once per map: the `map/sight` row, `planner::costs::prepare_grid_for_decisions`). \
         Reproduce: `cargo run --release -p grop-cli -- bench --write-docs`.\n\n| case | what | n | p50 (ms) | p99 (ms) |\n|---|---|---|---|---|\n",
    );
    for c in &cases {
        md.push_str(&format!(
            "| {} | {} | {} | {:.3} | {:.3} |\n",
            c.name,
            c.what,
            c.ms.len(),
            c.pct(0.5),
            c.pct(0.99)
        ));
        println!(
            "{:<28} p50 {:8.3} ms  p99 {:8.3} ms  (n = {})",
            c.name,
            c.pct(0.5),
            c.pct(0.99),
            c.ms.len()
        );
    }
    md.push_str(&format!(
        "\nLazy costing asked the navigation planner {lazy3_mean_calls:.1} times per 3-object decision (full: 19) and \
         {lazy10_mean_calls:.1} times per 10-object decision (full: 381). \
         With legs this cheap, lazy costing saves nothing here (each leg it skips costs ~1 us, its repeated \
         re-optimisation more); it pays off with a costly motion planner and is what PETLON's call count measures.\n"
    ));
    let verdict = |v: f64, limit: f64| if v < limit { "met" } else { "not met" };
    md.push_str(&format!(
        "\nIssue 12 targets for the 3-object GROP decision from a camera frame on one core: p50 under 0.5 ms, \
         p99 under 1 ms. Between the other cases (`grop-3`, cold caches): p50 {p50:.3} ms ({}), p99 {p99:.3} ms ({}). \
         Back to back (`grop-3/back-to-back`, warm caches): p50 {warm50:.3} ms ({}), p99 {warm99:.3} ms ({}); \
         the cold caches cost {:.3} ms at the median. Psi computes only the candidate cells the decisions read; \
         with whole heatmaps (`grop-3/whole-heatmaps`, as `grop-planner` publishes them; back to back, in blocks \
         alternating with `grop-3/back-to-back`) the decision takes {whole50:.3} ms p50, {:.3} ms more. GROP+ costs {:.3} ms p50 more than GROP \
         (its 20 goal draws per location and the margin).\n",
        verdict(p50, 0.5),
        verdict(p99, 1.0),
        verdict(warm50, 0.5),
        verdict(warm99, 1.0),
        p50 - warm50,
        whole50 - warm50,
        plus50 - p50,
    ));
    md.push_str(&format!(
        "\nPer-map sight table: at most {sight_cells} cells, {} KiB.\n",
        sight_bytes / 1024
    ));
    println!(
        "lazy calls: 3 objects {lazy3_mean_calls:.1} (of 19), 10 objects {lazy10_mean_calls:.1} (of 381)"
    );
    let load = std::fs::read_to_string("/proc/loadavg")
        .ok()
        .and_then(|l| l.split_whitespace().next().map(str::to_owned))
        .unwrap_or_else(|| "unknown".into());
    md.push_str(&format!(
        "\nMachine: {} logical CPUs available, 1-minute load average {load} at the end of the run \
         (shared machine: p99 reflects other processes); the planner itself runs on one thread.\n",
        std::thread::available_parallelism()
            .map(|n| n.get())
            .unwrap_or(1)
    ));
    write_markdown(&args.out, &md)?;
    if args.write_docs {
        write_markdown(std::path::Path::new(DOC), &md)?;
    }
    Ok(())
}

/// Decisions per block of `grop-3/back-to-back`, alternating with `grop-3/whole-heatmaps`.
const BLOCK: usize = 25;

/// The committed results, regenerated only with `--write-docs`.
const DOC: &str = "docs/planner-bench.md";

fn write_markdown(path: &std::path::Path, md: &str) -> anyhow::Result<()> {
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    std::fs::write(path, md).with_context(|| format!("writing {}", path.display()))?;
    println!("wrote {}", path.display());
    Ok(())
}
