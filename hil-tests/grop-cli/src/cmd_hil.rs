//! `grop hil`: tasks of the evaluation suite in closed loop (world + onboard processes, as
//! `grop demo` runs one) next to `grop eval`'s in-process calculation of the same tasks (the
//! trial simulator's noise model), paired per task. The two must agree statistically: the mean
//! paired difference of completion within two standard errors (docs/hil.md).

use std::path::PathBuf;
use std::sync::Mutex;
use std::time::{Duration, Instant};

use anyhow::Context;
use experiments::{EvalConfig, Workload, execute};
use hil_world::mission::{self, MissionSpec};
use hil_world::report::{MissionEnd, WorldReport};
use planner::costs::GridTravelTime;
use planner::feasibility::FcnEvaluator;
use planner::methods::{MethodKind, Planner, PlannerConfig, TaskMotionPlanner};
use planner::problem::TaskProblem;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use world::generate::mix_seed;

/// Arguments of `grop hil`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Tasks of the 420-task evaluation suite, spread evenly over its scenes.
    #[arg(long, default_value_t = 100)]
    pub tasks: usize,
    /// Seed of the suite (`grop eval`'s).
    #[arg(long, default_value_t = 2022)]
    pub seed: u64,
    /// Planning method.
    #[arg(long, default_value = "grop")]
    pub method: String,
    /// The paper's Smp (whole heatmap).
    #[arg(long)]
    pub paper_smp: bool,
    /// The feasibility network Psi (ONNX).
    #[arg(long, default_value = "models/psi-fcn.onnx")]
    pub model: PathBuf,
    /// Missions run side by side.
    #[arg(long, default_value_t = 2)]
    pub jobs: usize,
    /// Folder for per-task results (tasks.csv, summary.md, each mission's files).
    #[arg(long, default_value = "out/hil")]
    pub out_dir: PathBuf,
    /// Also write the summary to docs/hil.md (regenerates the committed doc).
    #[arg(long)]
    pub write_docs: bool,
    /// Do not run `cargo build` for the world and the onboard binaries first.
    #[arg(long)]
    pub no_build: bool,
}

/// One task's results.
#[derive(Debug, Clone)]
struct Row {
    task: usize,
    scene: usize,
    chairs: usize,
    calc_placed: usize,
    calc_time_s: f64,
    calc_steps: String,
    loop_steps: String,
    loop_placed: usize,
    loop_placed_strict: usize,
    loop_time_s: f64,
    loop_end: MissionEnd,
    loop_collisions: usize,
    wall_s: f64,
    legs: Vec<[f64; 2]>,
}

fn model_path(p: &std::path::Path) -> anyhow::Result<PathBuf> {
    std::fs::canonicalize(p)
        .or_else(|_| {
            std::fs::canonicalize(
                std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
                    .join("../..")
                    .join(p),
            )
        })
        .with_context(|| format!("the feasibility network {}", p.display()))
}

/// Runs the comparison.
pub fn run(args: Args) -> anyhow::Result<()> {
    let method = MethodKind::parse(&args.method)
        .with_context(|| format!("unknown --method {:?}", args.method))?;
    anyhow::ensure!(
        args.tasks > 0 && args.jobs > 0,
        "--tasks and --jobs must be positive"
    );
    let model = model_path(&args.model)?;
    let cfg = EvalConfig {
        seed: args.seed,
        ..EvalConfig::default()
    };
    let workload = Workload::build(&cfg);
    let n_all = workload.tasks.len();
    let n = args.tasks.min(n_all);
    let chosen: Vec<usize> = (0..n).map(|k| k * n_all / n).collect();
    let bins = mission::binaries(!args.no_build)?;
    std::fs::create_dir_all(&args.out_dir)
        .with_context(|| format!("creating {}", args.out_dir.display()))?;

    // The calculation (what `grop eval` does for one method), task by task.
    let mut psi = FcnEvaluator::load(&model).context("loading Psi")?;
    let pcfg = PlannerConfig {
        free_goals_only: !args.paper_smp,
        ..cfg.planner
    };
    let mut calc = Vec::with_capacity(n);
    for &t in &chosen {
        let task = &workload.tasks[t];
        let scene = &workload.scenes[task.scene];
        let targets = workload.targets(task);
        let problem = TaskProblem::from_world(scene, &cfg.robot, &targets, &mut psi)?;
        let grid = &workload.grids[task.scene];
        let mut travel = GridTravelTime::new(grid, cfg.robot.speed_mps);
        let plan_seed = mix_seed(cfg.seed, task.id as u64, 0x706c);
        let planned = Planner::new(method, pcfg).plan(&problem, &mut travel, plan_seed)?;
        let mut rng = ChaCha8Rng::seed_from_u64(mix_seed(cfg.seed, task.id as u64, 0x6578));
        // The missions run with `retry = "none"`, so the calculation does not retry either.
        let exec = execute(
            &cfg, scene, &cfg.robot, grid, &problem, &planned, None, &mut rng,
        );
        let goals: Vec<String> = planned
            .plan
            .unloads
            .iter()
            .zip(&exec.steps)
            .map(|(u, (_, outcome))| {
                let g = planned.goal_of(u).xy;
                format!("{}@({:.2};{:.2}):{:?}", u.object, g.0, g.1, outcome)
            })
            .collect();
        calc.push((exec.placed, exec.time_s, goals.join(" ")));
    }

    // The closed loop, `jobs` missions at a time.
    let started = Instant::now();
    let rows: Mutex<Vec<Row>> = Mutex::new(Vec::with_capacity(n));
    let next = Mutex::new(0usize);
    let failures: Mutex<Vec<String>> = Mutex::new(Vec::new());
    std::thread::scope(|scope| {
        for _ in 0..args.jobs.min(n) {
            scope.spawn(|| loop {
                let k = {
                    let mut g = next.lock().unwrap_or_else(|e| e.into_inner());
                    let k = *g;
                    *g += 1;
                    k
                };
                if k >= n {
                    return;
                }
                let task = &workload.tasks[chosen[k]];
                let mut scene = workload.scenes[task.scene].clone();
                scene.targets = task
                    .target_ids
                    .iter()
                    .map(|&i| workload.scenes[task.scene].targets[i])
                    .collect();
                scene.name = format!("task-{}", task.id);
                let spec = MissionSpec {
                    dir: args.out_dir.join(format!("task-{:03}", task.id)),
                    scene,
                    robot: cfg.robot.clone(),
                    model: model.clone(),
                    method: args.method.clone(),
                    paper_smp: args.paper_smp,
                    retry: "none".into(),
                    seed: mix_seed(cfg.seed, task.id as u64, 0x706c),
                    pace: None,
                    camera_px: (640, 480),
                    max_sim_s: 600.0,
                    progress_s: 0.0,
                    log: None,
                    fault: None,
                };
                let t0 = Instant::now();
                let result = mission::start(&spec, &bins)
                    .and_then(|m| m.finish(Duration::from_secs(600), &mut |_| {}));
                match result {
                    Ok(report) => {
                        let row = row_of(task.id, task.scene, task.n_chairs, &calc[k], &report, t0);
                        eprintln!(
                            "task {:3}: calc {} / loop {} placed ({} strictly; {:?}, {:.1} s sim, {:.1} s wall)",
                            row.task, row.calc_placed, row.loop_placed, row.loop_placed_strict, row.loop_end, row.loop_time_s, row.wall_s
                        );
                        rows.lock().unwrap_or_else(|e| e.into_inner()).push(row);
                    }
                    Err(e) => failures
                        .lock()
                        .unwrap_or_else(|e| e.into_inner())
                        .push(format!("task {}: {e:#}", task.id)),
                }
            });
        }
    });
    let wall = started.elapsed();
    let failures = failures.into_inner().unwrap_or_else(|e| e.into_inner());
    for f in &failures {
        eprintln!("{f}");
    }
    let mut rows = rows.into_inner().unwrap_or_else(|e| e.into_inner());
    rows.sort_by_key(|r| r.task);
    anyhow::ensure!(!rows.is_empty(), "no mission finished");
    let summary = summarize(&args, &rows, failures.len(), wall);
    println!("{summary}");
    write_csv(&args.out_dir.join("tasks.csv"), &rows)?;
    std::fs::write(args.out_dir.join("summary.md"), &summary)
        .with_context(|| format!("writing {}", args.out_dir.join("summary.md").display()))?;
    if args.write_docs {
        let doc = PathBuf::from("docs/hil.md");
        std::fs::write(&doc, format!("{}\n{summary}", DOC_HEAD))
            .with_context(|| format!("writing {}", doc.display()))?;
        println!("wrote {}", doc.display());
    }
    Ok(())
}

fn row_of(
    task: usize,
    scene: usize,
    chairs: usize,
    calc: &(usize, f64, String),
    r: &WorldReport,
    t0: Instant,
) -> Row {
    use hil_world::objects::ObjectState;
    let goals: Vec<String> = r
        .plans
        .first()
        .map(|p| {
            p.unloads
                .iter()
                .map(|(object, _side, x, y, _f)| {
                    let what = match r.objects.get(*object as usize).map(|o| o.state) {
                        Some(ObjectState::Released { verdict, .. }) => format!("{verdict:?}"),
                        Some(ObjectState::OnTray { .. }) => "NotUnloaded".to_owned(),
                        Some(other) => format!("{other:?}"),
                        None => String::new(),
                    };
                    format!("{object}@({x:.2};{y:.2}):{what}")
                })
                .collect()
        })
        .unwrap_or_default();
    Row {
        task,
        scene,
        chairs,
        calc_placed: calc.0,
        calc_time_s: calc.1,
        calc_steps: calc.2.clone(),
        loop_steps: goals.join(" "),
        loop_placed: r.placed_end_state,
        loop_placed_strict: r.placed,
        loop_time_s: r.timing.sim_time_s,
        loop_end: r.end,
        loop_collisions: r.collisions.len(),
        wall_s: t0.elapsed().as_secs_f64(),
        legs: r
            .legs
            .iter()
            .map(|l| {
                [
                    l.realised[0] - l.commanded[0],
                    l.realised[1] - l.commanded[1],
                ]
            })
            .collect(),
    }
}

fn mean_se(v: &[f64]) -> (f64, f64) {
    let n = v.len() as f64;
    let m = v.iter().sum::<f64>() / n;
    let var = if v.len() > 1 {
        v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (n - 1.0)
    } else {
        0.0
    };
    (m, (var / n).sqrt())
}

const DOC_HEAD: &str = "# Closed loop against the calculation (`grop hil`)\n\n\
Tasks of the 420-task evaluation suite run twice: in closed loop (the world process with the \
simulated RMP, UR5e, camera and localisation; the unchanged `grop-planner` and `grop-executive`; \
lock-step simulated time) and in `grop eval`'s in-process calculation (commanded goal + \
N(0, sigma^2 I), the trial simulator's placing check). Both without retries. Regenerate with \
`cargo run --release -p grop-cli -- hil --write-docs` (add `--tasks N`); per-task results, \
with each object's goal and outcome on both sides, go to `out/hil/tasks.csv`.\n\n\
The two sides plan the same goals (same seeds, views cut from the camera frame instead of \
rendered: F differs by about 0.001), so the pairing is tight; each side draws its own noise. \
What it took to agree, found by replaying the closed loop's realised stops through the trial \
simulator's check: the arm's approach above the target must not need more reach than the \
placing pose (it is lowered at the edge of the workspace); the final heading is aligned to \
0.008 rad (at 0.02 rad the footprint's corners touched chairs more often than the exact \
heading of the calculation); paths keep a clearance from the furniture; the base docks \
straight in and backs straight out. The strict row counts a contact of the base or the arm \
with furniture anywhere on the way to a goal as a failure: the calculation does not model \
the way there, the closed loop does, and a base that drives its estimate (off by the leg's \
localisation bias) between chairs touches them often.\n";

fn summarize(args: &Args, rows: &[Row], failed: usize, wall: Duration) -> String {
    let objects = 3.0;
    let calc: Vec<f64> = rows
        .iter()
        .map(|r| r.calc_placed as f64 / objects)
        .collect();
    let looped: Vec<f64> = rows
        .iter()
        .map(|r| r.loop_placed as f64 / objects)
        .collect();
    let strict: Vec<f64> = rows
        .iter()
        .map(|r| r.loop_placed_strict as f64 / objects)
        .collect();
    let diff: Vec<f64> = looped.iter().zip(&calc).map(|(a, b)| a - b).collect();
    let (ms, ss) = mean_se(&strict);
    let (mc, sc) = mean_se(&calc);
    let (ml, sl) = mean_se(&looped);
    let (md, sd) = mean_se(&diff);
    let agree = md.abs() <= 2.0 * sd;
    let legs: Vec<f64> = rows
        .iter()
        .flat_map(|r| r.legs.iter().flat_map(|l| [l[0], l[1]]))
        .collect();
    let (ml_err, _) = mean_se(&legs);
    let leg_sd = (legs.iter().map(|x| (x - ml_err).powi(2)).sum::<f64>()
        / (legs.len().max(2) - 1) as f64)
        .sqrt();
    let ends = |e: MissionEnd| rows.iter().filter(|r| r.loop_end == e).count();
    let mean = |f: &dyn Fn(&Row) -> f64| rows.iter().map(f).sum::<f64>() / rows.len() as f64;
    let wall_per = mean(&|r| r.wall_s);
    format!(
        "\n## {} tasks, method {}{} ({} missions failed to run)\n\n\
| | completion (placed / 3) | mean task time |\n|---|---|---|\n\
| calculation (`grop eval`) | {mc:.3} +- {sc:.3} | {:.1} s |\n\
| closed loop, end-state criterion (the paper's, as the calculation) | {ml:.3} +- {sl:.3} | {:.1} s simulated |\n\
| closed loop, strict (no contact with furniture on the way either) | {ms:.3} +- {ss:.3} | |\n\n\
Paired difference, closed loop minus calculation: **{md:+.3} +- {sd:.3}** (standard error): \
{}.\n\n\
- Missions: {} finished, {} aborted, {} timed out; {} contacts with furniture in all.\n\
- Realised minus commanded stop over {} legs: mean {ml_err:+.3} m, sd {leg_sd:.3} m per axis \
(the robot file's sigma: 0.1 m).\n\
- Wall time: {:.1} s in all, {:.1} s per mission with {} side by side ({:.0}x faster than real time per mission).\n",
        rows.len(),
        args.method,
        if args.paper_smp { " (paper Smp)" } else { "" },
        failed,
        mean(&|r| r.calc_time_s),
        mean(&|r| r.loop_time_s),
        if agree {
            "within two standard errors"
        } else {
            "NOT within two standard errors"
        },
        ends(MissionEnd::Finished),
        ends(MissionEnd::Aborted),
        ends(MissionEnd::TimedOut),
        rows.iter().map(|r| r.loop_collisions).sum::<usize>(),
        legs.len() / 2,
        wall.as_secs_f64(),
        wall_per,
        args.jobs,
        mean(&|r| r.loop_time_s) / wall_per.max(1e-9),
    )
}

fn write_csv(path: &std::path::Path, rows: &[Row]) -> anyhow::Result<()> {
    let mut s = String::from(
        "task,scene,chairs,calc_placed,calc_time_s,loop_placed,loop_placed_strict,loop_time_s,loop_end,loop_contacts,wall_s,calc_steps,loop_steps\n",
    );
    for r in rows {
        s.push_str(&format!(
            "{},{},{},{},{:.2},{},{},{:.2},{:?},{},{:.2},{},{}\n",
            r.task,
            r.scene,
            r.chairs,
            r.calc_placed,
            r.calc_time_s,
            r.loop_placed,
            r.loop_placed_strict,
            r.loop_time_s,
            r.loop_end,
            r.loop_collisions,
            r.wall_s,
            r.calc_steps,
            r.loop_steps
        ));
    }
    std::fs::write(path, s).with_context(|| format!("writing {}", path.display()))
}
