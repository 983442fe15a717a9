//! `grop eval`: the paper's experiments. GROP and the baselines plan every evaluation task, each
//! plan is executed in the trial simulator with navigation noise, and the results go to a CSV, a
//! markdown summary and a Fig. 5-like SVG in `out/experiments` (see docs/experiments.md); the
//! committed copies under docs/experiments are regenerated only with `--write-docs`.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::Context;
use experiments::{EvalConfig, HeatmapSet, Summary, TaskRecord, Workload};
use planner::feasibility::FcnEvaluator;
use planner::grop_plus::GropPlusConfig;
use planner::methods::{BaselineGoals, MethodKind};
use psi_eval::heuristics::{BinaryAnnulusEvaluator, BlurredAnnulusEvaluator, OracleEvaluator};
use serde::{Deserialize, Serialize};
use trial_sim::shard::{Shard, ShardDir, ShardManifest};

/// Which feasibility evaluator `Psi` feeds the planners.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum Evaluator {
    /// The trained FCN (`--model`).
    Fcn,
    /// The simulator as an oracle: an independent Monte-Carlo estimate of the ground truth.
    Oracle,
    /// The very ground truth that defines difficulty (an optimistic upper bound).
    GroundTruth,
    /// Geometric heuristic: 1 on obstacle-free cells within the arm's reach annulus, else 0.
    Binary,
    /// The binary heuristic blurred by the navigation noise.
    Blurred,
}

/// How the plan's feasibility combines its pairs'.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum Aggregation {
    /// Sum (the paper).
    Sum,
    /// Product.
    Product,
}

/// Baselines' navigation goals.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum Goals {
    /// Uniform among obstacle-free candidate cells (the paper).
    Paper,
    /// The authors' code: FCN-nonzero cells; Satisficing in a fixed region.
    Authors,
}

/// Which experiment `grop eval` runs.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum Suite {
    /// The paper's: 3-object tasks in the 30 evaluation scenes, Fig. 5 and Table I.
    Paper,
    /// Whole table settings (8 and 12 place settings), several trips with the robot's tray
    /// (`crate::cmd_eval_settings`).
    FullSetting,
}

/// Arguments of `grop eval`.
#[derive(clap::Args, Debug, Serialize, Deserialize)]
pub struct Args {
    /// Folder for eval_tasks.csv, summary.md and fig5.svg (with `--shard`: the campaign folder
    /// that gets the shard's folder `shard-III-of-NNN`).
    #[arg(long, default_value = "out/experiments")]
    #[serde(default)]
    pub out_dir: PathBuf,
    /// Also copy the three files into docs/experiments, or into the folder given
    /// (`--write-docs docs/experiments/oracle`): regenerates the committed results.
    #[arg(long, num_args = 0..=1, default_missing_value = "docs/experiments", value_name = "DIR")]
    #[serde(default)]
    pub write_docs: Option<PathBuf>,
    /// Ground-truth cache file (simulated once, reused while the settings match).
    #[arg(long, default_value = "target/grop-eval/ground-truth.json")]
    #[serde(default)]
    pub cache: PathBuf,
    /// Run only shard I of N (0-based) of the tasks: task k when k mod N == I. Writes the
    /// shard's exact records and its manifest into `<out-dir>/shard-III-of-NNN`; `grop merge`
    /// turns the N folders into what one run writes (docs/campaigns.md). Paper suite only.
    #[arg(long, value_name = "I/N")]
    #[serde(default)]
    pub shard: Option<Shard>,
    /// Feasibility evaluator for the planners.
    #[arg(long, value_enum, default_value_t = Evaluator::Fcn)]
    pub evaluator: Evaluator,
    /// FCN model file (with `--evaluator fcn`).
    #[arg(long, default_value = "models/psi-fcn.onnx")]
    pub model: PathBuf,
    /// Robot file (TOML); the paper's robot when absent.
    #[arg(long)]
    pub robot: Option<PathBuf>,
    /// Seed of scenes, goal draws, tie-breaks and noise.
    #[arg(long, default_value_t = 2022)]
    pub seed: u64,
    /// Scenes per chair count (15, 20, 25 chairs).
    #[arg(long, default_value_t = 10)]
    pub scenes_per_chair_count: usize,
    /// Tasks (of 3 objects) per scene.
    #[arg(long, default_value_t = 14)]
    pub tasks_per_scene: usize,
    /// Robot speed of the main comparison (m/s).
    #[arg(long, default_value_t = 0.4)]
    pub speed: f64,
    /// Speeds of the Table I sweep (m/s), comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "0.2,0.4,0.8")]
    pub sweep_speeds: Vec<f64>,
    /// Skip the speed sweep (main comparison only).
    #[arg(long)]
    pub no_sweep: bool,
    /// Methods of the main comparison, comma-separated (`grop+` is GROP with the levers below).
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "grop+,grop,satisficing,petlon,dvh,fcn-planning"
    )]
    pub methods: Vec<String>,
    /// Methods of the speed sweep, comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "grop+,grop,petlon,dvh")]
    pub sweep_methods: Vec<String>,
    /// GROP+ lever: retries after a failed unload (0: off). Default: GROP+'s (1).
    #[arg(long)]
    pub plus_retries: Option<usize>,
    /// GROP+ lever: Smp draws per (target, side), keeping the best (0: off, GROP's
    /// `--goal-draws`). Default: GROP+'s.
    #[arg(long)]
    pub plus_goal_draws: Option<usize>,
    /// GROP+ lever: goals at least this far (m) from a candidate cell where the base collides
    /// (0: off). Default: GROP+'s.
    #[arg(long)]
    pub plus_goal_margin: Option<f64>,
    /// GROP+ lever: R scaled by 0.4 m/s / speed (true) or fixed (false). Default: GROP+'s.
    #[arg(long)]
    pub plus_r_follows_speed: Option<bool>,
    /// Start from every GROP+ lever off (GROP+ then plans and executes exactly as GROP) instead
    /// of GROP+'s defaults; the `--plus-*` flags given switch single levers back on.
    #[arg(long)]
    pub plus_off: bool,
    /// F(p) = sum (paper) or product of the pairs' feasibilities.
    #[arg(long, value_enum, default_value_t = Aggregation::Sum)]
    pub aggregation: Aggregation,
    /// GROP's Smp draws per (target, side), keeping the best (paper: 1).
    #[arg(long, default_value_t = 1)]
    pub goal_draws: usize,
    /// GROP draws its Smp goal from the whole heatmap, as the paper does, instead of from the
    /// obstacle-free cells only (the default: no goal the base would collide at; Fea^t over the
    /// same cells).
    #[arg(long)]
    pub paper_smp: bool,
    /// Success bonus R of U = R F - C (GROP and FCN-Planning); the robot file's (40) when absent.
    #[arg(long)]
    pub success_bonus: Option<f64>,
    /// Baselines' goal choice.
    #[arg(long, value_enum, default_value_t = Goals::Paper)]
    pub baseline_goals: Goals,
    /// Trials per cell of the ground truth and the oracle.
    #[arg(long, default_value_t = 5)]
    pub trials_per_cell: u16,
    /// The experiment: the paper's, or whole table settings (results in
    /// `<out-dir>/full-setting`, `--write-docs` to docs/experiments/full-setting).
    #[arg(long, value_enum, default_value_t = Suite::Paper)]
    pub suite: Suite,
    /// Full-setting suite: tables per size.
    #[arg(long, default_value_t = 10)]
    pub tables_per_size: usize,
    /// Full-setting suite: table sizes in place settings, comma-separated (1..=12).
    #[arg(long, value_delimiter = ',', default_value = "8,12")]
    pub place_settings: Vec<usize>,
}

/// The experiment's configuration from the options and the robot.
pub(crate) fn config(args: &Args, robot: &world::RobotConfig) -> anyhow::Result<EvalConfig> {
    let methods = args
        .methods
        .iter()
        .map(|m| MethodKind::parse(m).with_context(|| format!("unknown method {m:?}")))
        .collect::<anyhow::Result<Vec<_>>>()?;
    let sweep_methods = args
        .sweep_methods
        .iter()
        .map(|m| MethodKind::parse(m).with_context(|| format!("unknown sweep method {m:?}")))
        .collect::<anyhow::Result<Vec<_>>>()?;
    let mut cfg = EvalConfig {
        sweep_methods,
        seed: args.seed,
        scenes_per_chair_count: args.scenes_per_chair_count,
        tasks_per_scene: args.tasks_per_scene,
        methods,
        main_speed_mps: args.speed,
        sweep_speeds_mps: if args.no_sweep {
            Vec::new()
        } else {
            args.sweep_speeds.clone()
        },
        gt_trials_per_cell: args.trials_per_cell,
        robot: robot.clone(),
        ..EvalConfig::default()
    };
    cfg.planner = planner::methods::PlannerConfig {
        success_bonus_r: args.success_bonus.unwrap_or(robot.success_bonus_r),
        aggregation: match args.aggregation {
            Aggregation::Sum => grop_select_aggregation(false),
            Aggregation::Product => grop_select_aggregation(true),
        },
        goal_draws: args.goal_draws,
        free_goals_only: !args.paper_smp,
        baseline_goals: match args.baseline_goals {
            Goals::Paper => BaselineGoals::Paper,
            Goals::Authors => BaselineGoals::AuthorsCode,
        },
        plus: plus_config(args),
        ..cfg.planner
    };
    cfg.planner
        .plus
        .check()
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    Ok(cfg)
}

pub(crate) fn load_robot(args: &Args) -> anyhow::Result<world::RobotConfig> {
    Ok(match &args.robot {
        Some(p) => world::RobotConfig::load(p)
            .with_context(|| format!("loading robot file {}", p.display()))?,
        None => world::RobotConfig::default(),
    })
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let started = Instant::now();
    let robot = load_robot(&args)?;
    let cfg = config(&args, &robot)?;
    cfg.check()?;

    let workload = Workload::build(&cfg);
    log::info!(
        "{} scenes, {} tasks; {} (speed, method) runs",
        workload.scenes.len(),
        workload.tasks.len(),
        cfg.runs().len()
    );
    let truth =
        experiments::ground_truth(&cfg, &workload, Some(&args.cache)).context("ground truth")?;
    log::info!(
        "ground truth ready after {:.1} s",
        started.elapsed().as_secs_f64()
    );
    let psi: HeatmapSet = match args.evaluator {
        Evaluator::GroundTruth => truth.clone(),
        Evaluator::Oracle => {
            let mut oracle = OracleEvaluator::new(args.trials_per_cell, args.seed ^ 0x6f72_6163);
            experiments::evaluate_heatmaps(&workload, &mut oracle)?
        }
        Evaluator::Binary => {
            experiments::evaluate_heatmaps(&workload, &mut BinaryAnnulusEvaluator::new())?
        }
        Evaluator::Blurred => {
            experiments::evaluate_heatmaps(&workload, &mut BlurredAnnulusEvaluator::new())?
        }
        Evaluator::Fcn => {
            let mut fcn = FcnEvaluator::load(&crate::common::committed_file(&args.model))
                .with_context(|| format!("loading FCN model {}", args.model.display()))?;
            experiments::evaluate_heatmaps(&workload, &mut fcn)?
        }
    };
    log::info!(
        "Psi ({:?}) ready after {:.1} s",
        args.evaluator,
        started.elapsed().as_secs_f64()
    );
    if let Some(shard) = args.shard {
        let records = experiments::run_shard(&cfg, &workload, &psi, &truth, shard)?;
        let dir = ShardDir::create(&args.out_dir, shard)
            .with_context(|| format!("creating the shard folder in {}", args.out_dir.display()))?;
        experiments::write_records_exact(&dir.path().join(RECORDS_FILE), &records)?;
        let manifest = crate::shards::manifest(
            "eval",
            shard,
            args.seed,
            shard_config(&args, &robot)?,
            workload.tasks.len(),
            started,
        );
        let dest = dir
            .commit(&manifest)
            .with_context(|| format!("writing the shard folder {}", dir_name(&args, shard)))?;
        println!(
            "shard {shard}: {} of {} tasks, {} records -> {} in {:.1} s",
            manifest.task_ids.len(),
            workload.tasks.len(),
            records.len(),
            dest.display(),
            started.elapsed().as_secs_f64()
        );
        return Ok(());
    }
    let records = experiments::run(&cfg, &workload, &psi, &truth)?;
    let (csv, md_path, svg) =
        write_results(&args, &cfg, workload.tasks.len(), &records, &args.out_dir)?;
    println!(
        "wrote {}, {}, {} in {:.1} s",
        csv.display(),
        md_path.display(),
        svg.display(),
        started.elapsed().as_secs_f64()
    );
    if let Some(docs) = &args.write_docs {
        std::fs::create_dir_all(docs).with_context(|| format!("creating {}", docs.display()))?;
        // Copying a file onto itself would empty it.
        let same = |a: &std::path::Path, b: &std::path::Path| matches!((a.canonicalize(), b.canonicalize()), (Ok(a), Ok(b)) if a == b);
        for file in [&csv, &md_path, &svg]
            .into_iter()
            .filter(|_| !same(docs, &args.out_dir))
        {
            let to = docs.join(file.file_name().unwrap_or_default());
            std::fs::copy(file, &to)
                .with_context(|| format!("copying {} to {}", file.display(), to.display()))?;
        }
        println!("wrote the results into {}", docs.display());
    }
    Ok(())
}

/// A shard's records (exact numbers) inside its folder.
const RECORDS_FILE: &str = "records.tsv";

fn dir_name(args: &Args, shard: Shard) -> String {
    args.out_dir.join(shard.folder_name()).display().to_string()
}

/// The configuration a shard records: the options without those that only say where files go
/// or how fast, the robot as TOML and a digest of the model file.
fn shard_config(args: &Args, robot: &world::RobotConfig) -> anyhow::Result<serde_json::Value> {
    let mut opts = serde_json::to_value(args).context("recording the options")?;
    if let Some(o) = opts.as_object_mut() {
        for k in ["out_dir", "write_docs", "cache", "shard"] {
            o.remove(k);
        }
    }
    Ok(serde_json::json!({
        "options": opts,
        "robot_toml": toml::to_string(robot).context("recording the robot")?,
        "model_sha256": if args.evaluator == Evaluator::Fcn {
            trial_sim::shard::file_sha256(&crate::common::committed_file(&args.model))
        } else {
            String::new()
        },
    }))
}

/// The results files of a run (`eval_tasks.csv`, `summary.md`, `fig5.svg`) into `dir`; the
/// summary also on stdout.
fn write_results(
    args: &Args,
    cfg: &EvalConfig,
    n_tasks: usize,
    records: &[TaskRecord],
    dir: &std::path::Path,
) -> anyhow::Result<(PathBuf, PathBuf, PathBuf)> {
    let summary = Summary::from_records(cfg, records);
    let csv = dir.join("eval_tasks.csv");
    experiments::write_csv(&csv, records)?;
    let mut md = format!(
        "<!-- written by `grop eval` ({} tasks, evaluator {:?}, seed {}, R {}, aggregation {:?}, goal draws {}{}, baseline goals {:?}) -->\n\n",
        n_tasks,
        args.evaluator,
        args.seed,
        cfg.planner.success_bonus_r,
        args.aggregation,
        args.goal_draws,
        if args.paper_smp {
            ", paper Smp (whole heatmap)"
        } else {
            ""
        },
        args.baseline_goals
    );
    md.push_str(&summary.markdown(cfg));
    let md_path = dir.join("summary.md");
    experiments::write_file(&md_path, &md)?;
    let svg = dir.join("fig5.svg");
    experiments::plot::fig5_svg(&summary, &cfg.methods, &svg)?;
    println!("{}", summary.markdown(cfg));
    Ok((csv, md_path, svg))
}

/// `grop merge` of eval shards: the records of all shards in task order, then the very files
/// one run writes.
pub fn merge(set: &[(PathBuf, ShardManifest)], out: &std::path::Path) -> anyhow::Result<()> {
    let first = &set[0].1;
    let mut opts = first.config["options"].clone();
    if let Some(o) = opts.as_object_mut() {
        o.insert("out_dir".into(), serde_json::json!(out));
    }
    let args: Args = serde_json::from_value(opts).context("the shards' recorded options")?;
    let robot: world::RobotConfig = toml::from_str(
        first.config["robot_toml"]
            .as_str()
            .context("the shards' manifest has no robot_toml")?,
    )
    .context("the shards' recorded robot")?;
    let cfg = config(&args, &robot)?;
    let runs = cfg.runs().len();
    let mut records: Vec<TaskRecord> = Vec::new();
    for (dir, m) in set {
        let part = experiments::read_records_exact(&dir.join(RECORDS_FILE))?;
        let mut per_task = std::collections::BTreeMap::<usize, usize>::new();
        for r in &part {
            *per_task.entry(r.task).or_default() += 1;
        }
        let ids: Vec<usize> = per_task.keys().copied().collect();
        anyhow::ensure!(
            ids == m.task_ids && per_task.values().all(|&c| c == runs),
            "shard folder {}: its records do not cover its {} tasks with {runs} runs each",
            dir.display(),
            m.task_ids.len()
        );
        records.extend(part);
    }
    // Stable: within a task the runs keep the order they were run in.
    records.sort_by_key(|r| r.task);
    let staged = trial_sim::shard::MergeDir::create(out)?;
    write_results(&args, &cfg, first.total_tasks, &records, staged.path())?;
    let dest = staged.commit()?;
    println!(
        "merged {} eval shards ({} tasks) into {}",
        set.len(),
        first.total_tasks,
        dest.display()
    );
    Ok(())
}

/// GROP+'s levers from the flags: GROP+'s defaults (or every lever off with `--plus-off`), with
/// the `--plus-*` flags given on top.
fn plus_config(args: &Args) -> GropPlusConfig {
    let base = if args.plus_off {
        GropPlusConfig::OFF
    } else {
        GropPlusConfig::DEFAULT
    };
    GropPlusConfig {
        max_retries: args.plus_retries.unwrap_or(base.max_retries),
        goal_draws: match args.plus_goal_draws {
            Some(0) => None,
            Some(n) => Some(n),
            None => base.goal_draws,
        },
        goal_margin_m: args.plus_goal_margin.unwrap_or(base.goal_margin_m),
        r_follows_speed: args.plus_r_follows_speed.unwrap_or(base.r_follows_speed),
    }
}

fn grop_select_aggregation(product: bool) -> planner::methods::Aggregation {
    if product {
        planner::methods::Aggregation::Product
    } else {
        planner::methods::Aggregation::Sum
    }
}
