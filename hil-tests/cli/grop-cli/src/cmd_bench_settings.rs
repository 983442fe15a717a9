//! `grop bench-settings`: multi-trip GROP decision latency for whole table settings (issue 13),
//! p50 and p99 on one core, with the optimiser's gap to the optimum; written to
//! `out/settings-bench.md`, and to the committed `docs/settings-bench.md` with `--write-docs`.
//!
//! Its own command and file because `grop bench --write-docs` rewrites docs/planner-bench.md
//! whole. Cases, per table of 8 and 12 place settings (24 and 36 objects, tray of the robot
//! file's capacity, 3 by default):
//! - `settings-N`: one full decision: 2N crops rendered and run through the FCN, free cells, every
//!   navigation leg (`1 + 2N + 2N(2N - 2)`), the multi-trip optimiser at its default node limit;
//! - `settings-N/psi`, `/nav`, `/optimiser`: its parts;
//! - `settings-N/optimiser@L`: the optimiser alone at larger node limits `L`, to show what closing
//!   the gap costs.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::Context;
use planner::costs::{GridTravelTime, LegCache};
use planner::feasibility::{FcnEvaluator, FeasibilityEvaluator};
use planner::methods::{MethodKind, PlannerConfig};
use planner::multi_trip::{DEFAULT_NODE_LIMIT, TripSearchLimits, optimise_trips};
use planner::problem::TaskProblem;
use planner::task::PlanningTable;
use planner::trip_methods::MultiTripPlanner;
use world::nav::OccupancyGrid;

/// Arguments of `grop bench-settings`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// FCN model file.
    #[arg(long, default_value = "models/psi-fcn.onnx")]
    pub model: PathBuf,
    /// Robot file (its `carry_capacity` is the tray); default: the paper's robot, a tray of 3.
    #[arg(long)]
    pub robot: Option<PathBuf>,
    /// Measured decisions per table size (after warm-up).
    #[arg(long, default_value_t = 100)]
    pub iterations: usize,
    /// Table-setting scenes the decisions cycle through.
    #[arg(long, default_value_t = 10)]
    pub scenes: usize,
    /// Markdown file for the results.
    #[arg(long, default_value = "out/settings-bench.md")]
    pub out: PathBuf,
    /// Also write the results to docs/settings-bench.md.
    #[arg(long)]
    pub write_docs: bool,
    /// Seed of the scenes.
    #[arg(long, default_value_t = 7)]
    pub seed: u64,
}

struct Samples {
    name: String,
    what: String,
    ms: Vec<f64>,
}

impl Samples {
    fn new(name: String, what: impl Into<String>) -> Self {
        Self {
            name,
            what: what.into(),
            ms: Vec::new(),
        }
    }
}

fn pct(values: &[f64], p: f64) -> f64 {
    let mut v = values.to_vec();
    v.sort_by(f64::total_cmp);
    if v.is_empty() {
        return f64::NAN;
    }
    v[(((v.len() - 1) as f64) * p).round() as usize]
}

/// Gap statistics of a set of decisions.
#[derive(Default)]
struct Gaps {
    gaps: Vec<f64>,
    relative: Vec<f64>,
    proven: usize,
}

impl Gaps {
    fn push(&mut self, gap: f64, utility: f64, proven: bool) {
        self.gaps.push(gap);
        self.relative.push(gap / utility.abs().max(1e-9));
        self.proven += usize::from(proven);
    }

    fn row(&self, case: &str) -> String {
        format!(
            "| {case} | {} | {}/{} | {:.2} | {:.2} | {:.2} | {:.2}% | {:.2}% |\n",
            self.gaps.len(),
            self.proven,
            self.gaps.len(),
            pct(&self.gaps, 0.5),
            pct(&self.gaps, 0.99),
            self.gaps.iter().cloned().fold(0.0, f64::max),
            100.0 * pct(&self.relative, 0.5),
            100.0 * self.relative.iter().cloned().fold(0.0, f64::max),
        )
    }
}

const LIMITS: [u64; 2] = [200_000, 2_000_000];

#[allow(
    clippy::too_many_lines,
    reason = "a command's steps in order: arguments, setup, the measurements, the report"
)]
pub fn run(args: Args) -> anyhow::Result<()> {
    anyhow::ensure!(args.iterations >= 10, "--iterations must be at least 10");
    anyhow::ensure!(args.scenes >= 1, "--scenes must be at least 1");
    let robot = match &args.robot {
        Some(p) => world::RobotConfig::load(p)?,
        None => world::RobotConfig::default(),
    };
    let capacity = robot.carry_capacity as usize;
    let mut fcn = FcnEvaluator::load(&crate::common::committed_file(&args.model))
        .with_context(|| format!("loading {}", args.model.display()))?;
    let cfg = PlannerConfig::for_robot(&robot);
    let warmup = 3;
    let mut cases: Vec<Samples> = Vec::new();
    let mut gap_rows = String::new();
    for settings in [8usize, 12] {
        let n = 3 * settings;
        let scenes = world::table_settings::table_settings_suite(args.seed, settings, args.scenes)?;
        let grids: Vec<OccupancyGrid> = scenes
            .iter()
            .map(|s| OccupancyGrid::from_scene(s, &robot))
            .collect();
        let legs = 1 + 2 * n + 2 * n * (2 * n - 2);
        let mut full = Samples::new(
            format!("settings-{n}"),
            format!(
                "full GROP decision, {settings} place settings = {n} objects, tray {capacity} ({} crops FCN + {legs} navigation legs + optimiser, {DEFAULT_NODE_LIMIT} nodes)",
                2 * n
            ),
        );
        let mut psi = Samples::new(
            format!("settings-{n}/psi"),
            format!("  of which: render {} crops + FCN + free cells", 2 * n),
        );
        let mut nav = Samples::new(
            format!("settings-{n}/nav"),
            format!("  of which: {legs} navigation legs"),
        );
        let mut opt = Samples::new(
            format!("settings-{n}/optimiser"),
            format!("  of which: multi-trip optimiser ({DEFAULT_NODE_LIMIT} nodes), table given"),
        );
        let mut more: Vec<Samples> = LIMITS
            .iter()
            .map(|l| {
                Samples::new(
                    format!("settings-{n}/optimiser@{l}"),
                    format!("optimiser alone, node limit {l}"),
                )
            })
            .collect();
        let mut gaps = Gaps::default();
        let mut more_gaps: Vec<Gaps> = LIMITS.iter().map(|_| Gaps::default()).collect();
        for k in 0..warmup + args.iterations {
            let s = k % scenes.len();
            let scene = &scenes[s];
            let targets: Vec<[f64; 3]> = scene.targets.iter().map(|t| t.as_array()).collect();
            let t0 = Instant::now();
            let problem = TaskProblem::from_world(
                scene,
                &robot,
                &targets,
                &mut fcn as &mut dyn FeasibilityEvaluator,
            )?;
            let t1 = Instant::now();
            let mut travel = GridTravelTime::new(&grids[s], robot.speed_mps);
            let planned = MultiTripPlanner::new(MethodKind::Grop, cfg, capacity).plan(
                &problem,
                &mut travel,
                k as u64,
            )?;
            let t2 = Instant::now();
            // The parts, again on the same goals: legs, then the optimiser on the filled table.
            let goals_xy: Vec<(f64, f64)> = planned.goals.iter().map(|g| g.xy).collect();
            let mut cache = LegCache::new(&problem, &goals_xy, cfg.no_path_cost_s);
            let mut table = PlanningTable::zeros(n);
            let mut fresh = GridTravelTime::new(&grids[s], robot.speed_mps);
            let t3 = Instant::now();
            cache.fill_table(&mut table, &mut fresh);
            let t4 = Instant::now();
            for (i, row) in planned.locations.iter().enumerate() {
                table.feasibility[i] = row.feasibility;
            }
            let t5 = Instant::now();
            let best = optimise_trips(
                &table,
                cfg.success_bonus_r,
                capacity,
                TripSearchLimits::default(),
            )?;
            let t6 = Instant::now();
            anyhow::ensure!(
                (best.utility - planned.utility).abs() < 1e-6,
                "optimiser alone disagrees with the planner"
            );
            if k < warmup {
                continue;
            }
            full.ms.push((t2 - t0).as_secs_f64() * 1e3);
            psi.ms.push((t1 - t0).as_secs_f64() * 1e3);
            nav.ms.push((t4 - t3).as_secs_f64() * 1e3);
            opt.ms.push((t6 - t5).as_secs_f64() * 1e3);
            gaps.push(best.gap(), best.utility, best.proven_optimal);
            // Larger node limits on a tenth of the decisions (they take longer).
            if k % 10 == 0 {
                for ((limit, samples), g) in LIMITS.iter().zip(&mut more).zip(&mut more_gaps) {
                    let t = Instant::now();
                    let b = optimise_trips(
                        &table,
                        cfg.success_bonus_r,
                        capacity,
                        TripSearchLimits { max_nodes: *limit },
                    )?;
                    samples.ms.push(t.elapsed().as_secs_f64() * 1e3);
                    anyhow::ensure!(b.utility >= best.utility - 1e-9, "more nodes, worse plan");
                    g.push(b.gap(), b.utility, b.proven_optimal);
                }
            }
        }
        gap_rows.push_str(&gaps.row(&format!("settings-{n} ({DEFAULT_NODE_LIMIT} nodes)")));
        for (limit, g) in LIMITS.iter().zip(&more_gaps) {
            gap_rows.push_str(&g.row(&format!("settings-{n} ({limit} nodes)")));
        }
        cases.extend([full, psi, nav, opt]);
        cases.extend(more);
    }

    let mut md = format!(
        "# Whole table settings: decision latency and gap\n\n<!-- written by `grop bench-settings` -->\n\n\
         One core, release build, table-setting scenes (`world::table_settings`, {} per size, a chair \
         at every seat), the committed FCN, the world's navigation planner, tray of {capacity}. \
         Reproduce: `cargo run --release -p grop-cli -- bench-settings --write-docs`.\n\n\
         | case | what | n | p50 (ms) | p99 (ms) |\n|---|---|---|---|---|\n",
        args.scenes
    );
    for c in &cases {
        md.push_str(&format!(
            "| {} | {} | {} | {:.3} | {:.3} |\n",
            c.name,
            c.what,
            c.ms.len(),
            pct(&c.ms, 0.5),
            pct(&c.ms, 0.99)
        ));
        println!(
            "{:<36} p50 {:9.3} ms  p99 {:9.3} ms  (n = {})",
            c.name,
            pct(&c.ms, 0.5),
            pct(&c.ms, 0.99),
            c.ms.len()
        );
    }
    md.push_str(
        "\nGap to the optimum: the optimiser's proven upper bound on the optimal `U` minus the \
         chosen plan's `U` (utility units, i.e. seconds; `R` = 40 per expected object placed), \
         0 when the search finished (proven optimal). Relative: gap / |U|.\n\n\
         | case | decisions | proven optimal | gap p50 | gap p99 | gap max | relative p50 | relative max |\n\
         |---|---|---|---|---|---|---|---|\n",
    );
    md.push_str(&gap_rows);
    print!("{gap_rows}");
    md.push_str(&format!(
        "\nMachine: {} logical CPUs available; the planner runs on one thread.\n",
        std::thread::available_parallelism()
            .map(|n| n.get())
            .unwrap_or(1)
    ));
    write_markdown(&args.out, &md)?;
    if args.write_docs {
        write_markdown(std::path::Path::new("docs/settings-bench.md"), &md)?;
    }
    Ok(())
}

fn write_markdown(path: &std::path::Path, md: &str) -> anyhow::Result<()> {
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    std::fs::write(path, md).with_context(|| format!("writing {}", path.display()))?;
    println!("wrote {}", path.display());
    Ok(())
}
