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
use serde::{Deserialize, Serialize};
use trial_sim::shard::{Shard, ShardManifest};
use world::generate::mix_seed;

/// Arguments of `grop hil`.
#[derive(clap::Args, Debug, Serialize, Deserialize)]
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
    #[serde(default)]
    pub jobs: usize,
    /// Folder for per-task results (tasks.csv, summary.md, each mission's files). With
    /// `--shard`: the campaign folder that gets the shard's folder `shard-III-of-NNN`.
    #[arg(long, default_value = "out/hil")]
    #[serde(default)]
    pub out_dir: PathBuf,
    /// Also write the summary to docs/hil.md (regenerates the committed doc).
    #[arg(long)]
    #[serde(default)]
    pub write_docs: bool,
    /// Do not run `cargo build` for the world and the onboard binaries first (they must stand
    /// beside this program, as after `cargo build --release -p grop-cli -p hil-world -p
    /// grop-onboard`; what array jobs do, docs/campaigns.md).
    #[arg(long)]
    #[serde(default)]
    pub no_build: bool,
    /// Run only shard I of N (0-based) of the chosen tasks: the k-th chosen task when
    /// k mod N == I. Writes the shard's exact rows, its missions' files and its manifest into
    /// `<out-dir>/shard-III-of-NNN`; `grop merge` makes what one run writes (docs/campaigns.md).
    #[arg(long, value_name = "I/N")]
    #[serde(default)]
    pub shard: Option<Shard>,
    /// Do not simulate the range sensor: the executive drives without its collision monitor
    /// (the behaviour before the lidar, for paired comparisons).
    #[arg(long)]
    #[serde(default)]
    pub no_lidar: bool,
    /// Run a named scene suite instead of the task suite: `handmade` (the hand-made layouts in
    /// `hil-tests/layouts/`, docs/hil.md). One mission per scene, one row per scene.
    #[arg(long, value_name = "NAME", conflicts_with = "scenes")]
    #[serde(default)]
    pub suite: Option<String>,
    /// Run every scene file (.toml, .json) of this folder as one mission each (as `--suite`).
    #[arg(long, value_name = "DIR")]
    #[serde(default)]
    pub scenes: Option<PathBuf>,
    /// Draw each mission as `mission.png` in its folder (routes, standing spots with their F,
    /// outcomes, scale and legend, as `grop demo` draws out/demo.png).
    #[arg(long)]
    #[serde(default)]
    pub pictures: bool,
}

/// `mission.png` in the mission's folder, when `--pictures` asks for it.
pub(crate) fn save_picture(
    args: &Args,
    spec: &MissionSpec,
    report: &WorldReport,
) -> anyhow::Result<()> {
    if !args.pictures {
        return Ok(());
    }
    let title = crate::picture::mission_title(
        "hil",
        &spec.scene.name,
        &spec.method.to_string(),
        spec.seed,
        report,
    );
    let path = spec.dir.join("mission.png");
    crate::picture::mission(&spec.scene, &spec.robot, report, 48.0, title)
        .save(&path)
        .with_context(|| format!("writing {}", path.display()))
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

pub(crate) fn model_path(p: &std::path::Path) -> anyhow::Result<PathBuf> {
    crate::common::committed_file_abs(p, "the feasibility network")
}

/// Runs the comparison.
#[allow(
    clippy::too_many_lines,
    reason = "a command's steps in order: arguments, the suite, the missions, the report"
)]
pub fn run(args: Args) -> anyhow::Result<()> {
    let run_started = Instant::now();
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
    let all_chosen: Vec<usize> = (0..n).map(|k| k * n_all / n).collect();
    let shard = args.shard.unwrap_or(Shard::WHOLE);
    let chosen: Vec<usize> = shard
        .positions(n)
        .into_iter()
        .map(|k| all_chosen[k])
        .collect();
    let total = n;
    let n = chosen.len();
    let bins = crate::common::mission_binaries(!args.no_build)?;
    let (shard_dir, out_dir) = crate::common::output_folder(&args.out_dir, args.shard)?;

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
                    robot: cfg.robot.clone(),
                    method: args.method.clone(),
                    paper_smp: args.paper_smp,
                    lidar: !args.no_lidar,
                    ..MissionSpec::new(
                        out_dir.join(format!("task-{:03}", task.id)),
                        scene,
                        model.clone(),
                        mix_seed(cfg.seed, task.id as u64, 0x706c),
                    )
                };
                let t0 = Instant::now();
                let result = mission::start(&spec, &bins)
                    .and_then(|m| m.finish(Duration::from_secs(600), &mut |_| {}))
                    .map_err(anyhow::Error::from)
                    .and_then(|report| save_picture(&args, &spec, &report).map(|()| report));
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
    if let (Some(dir), Some(shard)) = (shard_dir, args.shard) {
        write_rows_exact(&dir.path().join(ROWS_FILE), &rows)?;
        let failed: String = failures.iter().map(|f| format!("{f}\n")).collect();
        std::fs::write(dir.path().join(FAILURES_FILE), failed).context("writing failures")?;
        let manifest = crate::shards::manifest(
            "hil",
            shard,
            args.seed,
            shard_config(&args),
            total,
            run_started,
        );
        let dest = dir.commit(&manifest).context("writing the shard folder")?;
        println!(
            "shard {shard}: {} of {total} tasks ({} missions failed to run) -> {} in {:.1} s",
            rows.len(),
            failures.len(),
            dest.display(),
            wall.as_secs_f64()
        );
        return Ok(());
    }
    anyhow::ensure!(!rows.is_empty(), "no mission finished");
    let wall_line = format!(
        "Wall time: {:.1} s in all, {:.1} s per mission with {} side by side ({:.0}x faster than real time per mission).",
        wall.as_secs_f64(),
        mean_wall(&rows),
        args.jobs,
        mean_sim(&rows) / mean_wall(&rows).max(1e-9),
    );
    let summary = summarize(&args, &rows, failures.len(), &wall_line);
    println!("{summary}");
    write_csv(&args.out_dir.join("tasks.csv"), &rows)?;
    std::fs::write(args.out_dir.join("summary.md"), &summary)
        .with_context(|| format!("writing {}", args.out_dir.join("summary.md").display()))?;
    if args.write_docs {
        let doc = PathBuf::from("docs/hil.md");
        // The hand-made suite's section (written by hand from `--suite handmade` runs) stays.
        let kept = std::fs::read_to_string(&doc)
            .ok()
            .and_then(|old| old.find(SUITE_SECTION).map(|at| old[at..].to_owned()))
            .unwrap_or_default();
        let sep = if kept.is_empty() { "" } else { "\n" };
        std::fs::write(&doc, format!("{}\n{summary}{sep}{kept}", DOC_HEAD))
            .with_context(|| format!("writing {}", doc.display()))?;
        println!("wrote {}", doc.display());
    }
    Ok(())
}

fn mean_wall(rows: &[Row]) -> f64 {
    rows.iter().map(|r| r.wall_s).sum::<f64>() / rows.len().max(1) as f64
}

fn mean_sim(rows: &[Row]) -> f64 {
    rows.iter().map(|r| r.loop_time_s).sum::<f64>() / rows.len().max(1) as f64
}

/// A shard's rows (exact numbers) and the missions that failed to run, inside its folder.
const ROWS_FILE: &str = "rows.tsv";
const FAILURES_FILE: &str = "failures.txt";
const ROWS_HEADER: &str = "grop-hil-rows-1\ttask\tscene\tchairs\tcalc_placed\tcalc_time_s\tcalc_steps\tloop_steps\tloop_placed\tloop_placed_strict\tloop_time_s\tloop_end\tloop_contacts\twall_s\tlegs";

/// The configuration a shard records: the options that change results, and the model's digest.
fn shard_config(args: &Args) -> serde_json::Value {
    serde_json::json!({
        "tasks": args.tasks,
        "seed": args.seed,
        "method": args.method,
        "paper_smp": args.paper_smp,
        "model": args.model,
        "model_sha256": trial_sim::shard::file_sha256(&args.model),
    })
}

fn write_rows_exact(path: &std::path::Path, rows: &[Row]) -> anyhow::Result<()> {
    use std::fmt::Write as _;
    let mut s = format!("{ROWS_HEADER}\n");
    for r in rows {
        let legs: Vec<String> = r
            .legs
            .iter()
            .map(|l| format!("{:?},{:?}", l[0], l[1]))
            .collect();
        let _ = writeln!(
            s,
            "\t{}\t{}\t{}\t{}\t{:?}\t{}\t{}\t{}\t{}\t{:?}\t{}\t{}\t{:?}\t{}",
            r.task,
            r.scene,
            r.chairs,
            r.calc_placed,
            r.calc_time_s,
            r.calc_steps,
            r.loop_steps,
            r.loop_placed,
            r.loop_placed_strict,
            r.loop_time_s,
            serde_json::to_string(&r.loop_end)?.trim_matches('"'),
            r.loop_collisions,
            r.wall_s,
            legs.join(";")
        );
    }
    std::fs::write(path, s).with_context(|| format!("writing {}", path.display()))
}

fn read_rows_exact(path: &std::path::Path) -> anyhow::Result<Vec<Row>> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
    let mut lines = text.lines();
    anyhow::ensure!(
        lines.next() == Some(ROWS_HEADER),
        "{}: not a grop hil rows file (header)",
        path.display()
    );
    fn num<T: std::str::FromStr>(s: &str, what: &str) -> anyhow::Result<T> {
        s.parse()
            .map_err(|_| anyhow::anyhow!("{what} {s:?} is not a number"))
    }
    lines
        .enumerate()
        .map(|(i, line)| {
            let f: Vec<&str> = line.split('\t').collect();
            (|| -> anyhow::Result<Row> {
                anyhow::ensure!(f.len() == 15, "{} fields, expected 15", f.len());
                let legs = f[14]
                    .split(';')
                    .filter(|l| !l.is_empty())
                    .map(|l| {
                        let (a, b) = l.split_once(',').context("a leg is not x,y")?;
                        Ok([num(a, "leg")?, num(b, "leg")?])
                    })
                    .collect::<anyhow::Result<Vec<[f64; 2]>>>()?;
                Ok(Row {
                    task: num(f[1], "task")?,
                    scene: num(f[2], "scene")?,
                    chairs: num(f[3], "chairs")?,
                    calc_placed: num(f[4], "calc_placed")?,
                    calc_time_s: num(f[5], "calc_time_s")?,
                    calc_steps: f[6].to_owned(),
                    loop_steps: f[7].to_owned(),
                    loop_placed: num(f[8], "loop_placed")?,
                    loop_placed_strict: num(f[9], "loop_placed_strict")?,
                    loop_time_s: num(f[10], "loop_time_s")?,
                    loop_end: serde_json::from_str(&format!("\"{}\"", f[11]))
                        .with_context(|| format!("mission end {:?}", f[11]))?,
                    loop_collisions: num(f[12], "loop_contacts")?,
                    wall_s: num(f[13], "wall_s")?,
                    legs,
                })
            })()
            .with_context(|| format!("{} line {}", path.display(), i + 2))
        })
        .collect()
}

/// `grop merge` of hil shards: per-task rows in task order (tasks.csv as one run writes it,
/// wall-time column aside), the paired statistics over all tasks (summary.md), and every
/// mission's files.
pub fn merge(set: &[(PathBuf, ShardManifest)], out: &std::path::Path) -> anyhow::Result<()> {
    let first = &set[0].1;
    let c = &first.config;
    let args = Args {
        tasks: c["tasks"].as_u64().context("manifest: tasks")? as usize,
        seed: first.seed,
        method: c["method"].as_str().context("manifest: method")?.to_owned(),
        paper_smp: c["paper_smp"].as_bool().context("manifest: paper_smp")?,
        model: serde_json::from_value(c["model"].clone()).context("manifest: model")?,
        jobs: 0,
        out_dir: out.to_path_buf(),
        write_docs: false,
        no_build: true,
        shard: None,
        no_lidar: c["no_lidar"].as_bool().unwrap_or(false),
        suite: None,
        scenes: None,
        pictures: false,
    };
    let staged = trial_sim::shard::MergeDir::create(out)?;
    let mut rows = Vec::new();
    let mut failures = 0;
    let mut shard_walls = Vec::new();
    for (dir, m) in set {
        let part = read_rows_exact(&dir.join(ROWS_FILE))?;
        let failed = std::fs::read_to_string(dir.join(FAILURES_FILE))
            .with_context(|| format!("reading {}", dir.join(FAILURES_FILE).display()))?;
        failures += failed.lines().filter(|l| !l.is_empty()).count();
        for r in &part {
            let task_dir = format!("task-{:03}", r.task);
            crate::shards::copy_tree(&dir.join(&task_dir), &staged.path().join(&task_dir))?;
        }
        shard_walls.push(m.wall_s);
        rows.extend(part);
    }
    rows.sort_by_key(|r| r.task);
    anyhow::ensure!(!rows.is_empty(), "no mission finished in any shard");
    let longest = shard_walls.iter().copied().fold(0.0, f64::max);
    let wall_line = format!(
        "Wall time: {} shards, the longest {:.1} s, all together {:.1} s; {:.1} s per mission ({:.0}x faster than real time per mission).",
        set.len(),
        longest,
        shard_walls.iter().sum::<f64>(),
        mean_wall(&rows),
        mean_sim(&rows) / mean_wall(&rows).max(1e-9),
    );
    let summary = summarize(&args, &rows, failures, &wall_line);
    write_csv(&staged.path().join("tasks.csv"), &rows)?;
    std::fs::write(staged.path().join("summary.md"), &summary).context("writing summary.md")?;
    let dest = staged.commit()?;
    println!("{summary}");
    println!(
        "merged {} hil shards ({} tasks) into {}",
        set.len(),
        rows.len(),
        dest.display()
    );
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

/// Where docs/hil.md's hand-made suite section starts (kept by `--write-docs`).
const SUITE_SECTION: &str = "## The hand-made layout suite";

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

fn summarize(args: &Args, rows: &[Row], failed: usize, wall_line: &str) -> String {
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
- {wall_line}\n",
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
