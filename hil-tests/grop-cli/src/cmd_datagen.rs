//! `grop datagen`: the feasibility dataset (paper section III-B). With no arguments it writes
//! the paper's 96,000-trial dataset (10 environments x 10 targets x 5 trials x 24 x 8 cells)
//! into `out/dataset`. Format: docs/dataset.md.

use std::path::PathBuf;

use anyhow::Context;
use trial_sim::datagen::{DatagenConfig, SideSelection, generate};

/// Arguments of `grop datagen`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Output folder (created; files in it are replaced).
    #[arg(long, default_value = "out/dataset")]
    pub out: PathBuf,
    /// Seed of scenes and trials (same seed, same dataset, on any thread count).
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Training environments (10 near-side chairs each).
    #[arg(long, default_value_t = 10)]
    pub envs: usize,
    /// Unloading targets per environment.
    #[arg(long, default_value_t = 10)]
    pub targets_per_env: usize,
    /// Trials per candidate cell (the label's denominator).
    #[arg(long, default_value_t = 5)]
    pub trials_per_cell: u16,
    /// Sides of the table that get tasks: near (the paper) or both.
    #[arg(long, value_enum, default_value_t = SidesArg::Near)]
    pub sides: SidesArg,
    /// Robot file (TOML/JSON); default: the built-in robot (runtime/world/data/robot.toml).
    #[arg(long)]
    pub robot: Option<PathBuf>,
    /// Skip trials.csv (one row per trial).
    #[arg(long)]
    pub no_trials_csv: bool,
    /// Worker threads (default: all cores).
    #[arg(long)]
    pub threads: Option<usize>,
}

/// `--sides` values.
#[derive(clap::ValueEnum, Clone, Copy, Debug)]
pub enum SidesArg {
    /// Near side only.
    Near,
    /// Near and far side.
    Both,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let robot = match &args.robot {
        Some(path) => world::RobotConfig::load(path)?,
        None => world::RobotConfig::default(),
    };
    let cfg = DatagenConfig {
        seed: args.seed,
        n_envs: args.envs,
        targets_per_env: args.targets_per_env,
        trials_per_cell: args.trials_per_cell,
        sides: match args.sides {
            SidesArg::Near => SideSelection::Near,
            SidesArg::Both => SideSelection::Both,
        },
        robot,
        robot_file: args.robot.clone(),
        out_dir: args.out.clone(),
        write_trials_csv: !args.no_trials_csv,
    };
    if let Some(threads) = args.threads {
        // Only fails when a pool exists already; then that pool serves.
        if let Err(e) = rayon_pool(threads) {
            log::warn!("--threads {threads} ignored: {e}");
        }
    }
    let bar = indicatif::ProgressBar::new(0);
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "{spinner} tasks {pos}/{len} [{bar:40}] {elapsed_precise} eta {eta}",
        )
        .context("progress bar template")?,
    );
    let started = std::time::Instant::now();
    let summary = generate(&cfg, &bar)
        .with_context(|| format!("generating the dataset into {}", args.out.display()))?;
    let total_s = started.elapsed().as_secs_f64();
    println!(
        "{} tasks, {} trials: success rate {:.3} (authors: ~0.31), mean best cell {:.3}, {} tasks without a feasible cell",
        summary.tasks,
        summary.trials,
        summary.success_rate,
        summary.mean_best_cell,
        summary.tasks_without_feasible_cell
    );
    let results: Vec<String> = summary
        .results
        .iter()
        .map(|(k, v)| format!("{k} {v}"))
        .collect();
    if !results.is_empty() {
        println!("results: {}", results.join(", "));
    }
    println!(
        "successes per cell (0..={}): {:?}",
        cfg.trials_per_cell, summary.successes_per_cell_histogram
    );
    let rows: Vec<String> = summary
        .success_rate_by_row
        .iter()
        .map(|r| format!("{:.2} m: {:.2}", r.distance_m, r.success_rate))
        .collect();
    println!(
        "success by distance from the table's centre line: {}",
        rows.join(", ")
    );
    println!(
        "simulated in {:.2} s ({:.0} trials/s), {:.2} s with files; wrote {}",
        summary.simulate_s,
        summary.trials_per_s,
        total_s,
        args.out.display()
    );
    Ok(())
}

fn rayon_pool(threads: usize) -> Result<(), String> {
    trial_sim::datagen::set_worker_threads(threads)
}
