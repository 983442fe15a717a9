//! `grop datagen`: the feasibility dataset (paper section III-B). With no arguments it writes
//! the paper's 96,000-trial dataset (10 environments x 10 targets x 5 trials x 24 x 8 cells)
//! into `out/dataset`. Format: docs/dataset.md.
//!
//! The dataset is written into a temporary folder beside the destination and renamed into place
//! at the end ([`staging`]), so a run that fails or is killed midway leaves the previous dataset
//! whole.

use std::path::PathBuf;

use anyhow::Context;
use serde::{Deserialize, Serialize};
use trial_sim::datagen::{DatagenConfig, SideSelection, generate};
use trial_sim::shard::{Shard, ShardDir, ShardManifest};

/// Arguments of `grop datagen`.
#[derive(clap::Args, Debug, Serialize, Deserialize)]
pub struct Args {
    /// Output folder, replaced as a whole when the run completes (it must be a dataset folder,
    /// with a dataset.json, or empty, or not exist yet). With `--shard`: the campaign folder
    /// that gets the shard's folder `shard-III-of-NNN`.
    #[arg(long, default_value = "out/dataset")]
    #[serde(default)]
    pub out: PathBuf,
    /// Run only shard I of N (0-based): array row k when k mod N == I. Writes the shard's tasks
    /// exactly (`tasks.bin`) and its manifest into `<out>/shard-III-of-NNN`; `grop merge` makes
    /// the dataset folder one run writes (docs/campaigns.md).
    #[arg(long, value_name = "I/N")]
    #[serde(default)]
    pub shard: Option<Shard>,
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
    /// Robot file (TOML/JSON); default: the built-in robot (runtime/libraries/world/data/robot.toml).
    #[arg(long)]
    pub robot: Option<PathBuf>,
    /// Skip trials.csv (one row per trial).
    #[arg(long)]
    pub no_trials_csv: bool,
    /// Worker threads (default: all cores).
    #[arg(long)]
    #[serde(default)]
    pub threads: Option<usize>,
}

/// `--sides` values.
#[derive(clap::ValueEnum, Clone, Copy, Debug, Serialize, Deserialize)]
pub enum SidesArg {
    /// Near side only.
    Near,
    /// Near and far side.
    Both,
}

/// The run's configuration, files going to `out_dir`.
fn config(args: &Args, robot: world::RobotConfig, out_dir: PathBuf) -> DatagenConfig {
    DatagenConfig {
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
        out_dir,
        write_trials_csv: !args.no_trials_csv,
    }
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let robot = match &args.robot {
        Some(path) => world::RobotConfig::load(path)?,
        None => world::RobotConfig::default(),
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
    if let Some(shard) = args.shard {
        return run_shard(&args, robot, shard, &bar, started);
    }
    let staged = staging::StagedDir::prepare(&args.out)?;
    let cfg = config(&args, robot, staged.path().to_path_buf());
    let summary = generate(&cfg, &bar)
        .with_context(|| format!("generating the dataset into {}", staged.path().display()))?;
    staged.commit()?;
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

/// A shard's tasks' data, exactly (see [`trial_sim::datagen::write_shard_tasks`]).
const SHARD_TASKS: &str = trial_sim::datagen::SHARD_TASKS_FILE;

fn run_shard(
    args: &Args,
    robot: world::RobotConfig,
    shard: Shard,
    bar: &indicatif::ProgressBar,
    started: std::time::Instant,
) -> anyhow::Result<()> {
    let dir = ShardDir::create(&args.out, shard)
        .with_context(|| format!("creating the shard folder in {}", args.out.display()))?;
    let cfg = config(args, robot, dir.path().to_path_buf());
    let data = trial_sim::datagen::simulate_shard(&cfg, shard, bar, cfg.write_trials_csv)?;
    trial_sim::datagen::write_shard_tasks(&data, &dir.path().join(SHARD_TASKS))?;
    let total = cfg.tasks().1.len();
    let manifest = crate::shards::manifest(
        "datagen",
        shard,
        args.seed,
        shard_config(args, &cfg.robot)?,
        total,
        started,
    );
    let dest = dir.commit(&manifest).context("writing the shard folder")?;
    println!(
        "shard {shard}: {} of {total} tasks, {} trials -> {} in {:.1} s",
        data.tasks.len(),
        data.summary.trials,
        dest.display(),
        started.elapsed().as_secs_f64()
    );
    Ok(())
}

/// The configuration a shard records: the options without the output folder, the shard and
/// the thread count, and the robot as TOML.
fn shard_config(args: &Args, robot: &world::RobotConfig) -> anyhow::Result<serde_json::Value> {
    let mut opts = serde_json::to_value(args).context("recording the options")?;
    if let Some(o) = opts.as_object_mut() {
        for k in ["out", "shard", "threads"] {
            o.remove(k);
        }
    }
    Ok(serde_json::json!({
        "options": opts,
        "robot_toml": toml::to_string(robot).context("recording the robot")?,
    }))
}

/// `grop merge` of datagen shards: the dataset folder one run writes (all files byte for byte,
/// except the wall-clock fields `simulate_s` and `trials_per_s` of `dataset.json`, which differ
/// between any two runs; here they are the shards' simulation seconds summed).
pub fn merge(set: &[(PathBuf, ShardManifest)], out: &std::path::Path) -> anyhow::Result<()> {
    let first = &set[0].1;
    let args: Args = serde_json::from_value(first.config["options"].clone())
        .context("the shards' recorded options")?;
    let robot: world::RobotConfig = toml::from_str(
        first.config["robot_toml"]
            .as_str()
            .context("the shards' manifest has no robot_toml")?,
    )
    .context("the shards' recorded robot")?;
    let staged = trial_sim::shard::MergeDir::create(out)?;
    let cfg = config(&args, robot, staged.path().to_path_buf());
    let mut tasks = Vec::new();
    let mut simulate_s = 0.0;
    for (dir, m) in set {
        let (s, part) = trial_sim::datagen::read_shard_tasks(&cfg, &dir.join(SHARD_TASKS))?;
        let ids: Vec<usize> = part.iter().map(|t| t.task.index).collect();
        anyhow::ensure!(
            ids == m.task_ids,
            "shard folder {}: its tasks file does not hold its {} tasks",
            dir.display(),
            m.task_ids.len()
        );
        simulate_s += s;
        tasks.extend(part);
    }
    let dataset = trial_sim::datagen::merge_shards(&cfg, tasks, simulate_s)?;
    trial_sim::datagen::write_dataset(&dataset, &cfg)?;
    let dest = staged.commit()?;
    println!(
        "merged {} datagen shards ({} tasks, {} trials, success rate {:.3}) into {}",
        set.len(),
        dataset.summary.tasks,
        dataset.summary.trials,
        dataset.summary.success_rate,
        dest.display()
    );
    Ok(())
}

fn rayon_pool(threads: usize) -> Result<(), String> {
    trial_sim::datagen::set_worker_threads(threads)
}

/// Replacing a dataset folder without ever leaving a half-written one.
///
/// Files go into `.<name>.partial-<pid>` beside the destination `<name>` (same parent, so the
/// same file system and a rename). At the end the old folder is renamed to `.<name>.old-<pid>`,
/// the new one to `<name>`, and the old one removed. A failed run removes its partial folder;
/// a killed one leaves it, and the next run removes it once its process is gone (`/proc/<pid>`).
/// Killed between the two renames (microseconds), the previous dataset sits whole in
/// `.<name>.old-<pid>`, and the next run moves it back before it starts.
pub(crate) mod staging {
    use std::path::{Path, PathBuf};

    use anyhow::Context;

    /// The manifest every dataset folder holds: what makes a folder safe to replace.
    const MANIFEST: &str = "dataset.json";

    /// A temporary folder that becomes `dest` on [`StagedDir::commit`].
    #[derive(Debug)]
    pub(crate) struct StagedDir {
        dest: PathBuf,
        temp: PathBuf,
        old: PathBuf,
        committed: bool,
    }

    impl StagedDir {
        /// Checks that `dest` may be replaced, clears what killed runs left beside it and
        /// creates the temporary folder.
        pub(crate) fn prepare(dest: &Path) -> anyhow::Result<Self> {
            let name = dest
                .file_name()
                .with_context(|| format!("--out {} names no folder", dest.display()))?
                .to_string_lossy()
                .into_owned();
            let parent = dest
                .parent()
                .filter(|p| !p.as_os_str().is_empty())
                .unwrap_or(Path::new("."));
            std::fs::create_dir_all(parent)
                .with_context(|| format!("creating {}", parent.display()))?;
            recover(parent, &name, dest)?;
            check_replaceable(dest)?;
            let pid = std::process::id();
            let temp = parent.join(format!(".{name}.partial-{pid}"));
            let old = parent.join(format!(".{name}.old-{pid}"));
            if temp.exists() {
                std::fs::remove_dir_all(&temp)
                    .with_context(|| format!("removing {}", temp.display()))?;
            }
            std::fs::create_dir(&temp).with_context(|| format!("creating {}", temp.display()))?;
            Ok(Self {
                dest: dest.to_path_buf(),
                temp,
                old,
                committed: false,
            })
        }

        /// Where the files go until the commit.
        pub(crate) fn path(&self) -> &Path {
            &self.temp
        }

        /// Puts the finished folder in place of `dest` and removes the previous one.
        pub(crate) fn commit(mut self) -> anyhow::Result<()> {
            let had_old = self.dest.exists();
            if had_old {
                check_replaceable(&self.dest)?;
                std::fs::rename(&self.dest, &self.old).with_context(|| {
                    format!("moving {} to {}", self.dest.display(), self.old.display())
                })?;
            }
            if let Err(e) = std::fs::rename(&self.temp, &self.dest) {
                if had_old {
                    // Put the previous dataset back.
                    let _ = std::fs::rename(&self.old, &self.dest);
                }
                return Err(e).with_context(|| {
                    format!("moving {} to {}", self.temp.display(), self.dest.display())
                });
            }
            self.committed = true;
            if had_old && let Err(e) = std::fs::remove_dir_all(&self.old) {
                log::warn!(
                    "could not remove the previous dataset {}: {e}",
                    self.old.display()
                );
            }
            Ok(())
        }
    }

    impl Drop for StagedDir {
        /// A run that ends without a commit (an error) removes its partial folder.
        fn drop(&mut self) {
            if !self.committed {
                let _ = std::fs::remove_dir_all(&self.temp);
            }
        }
    }

    /// `dest` may be replaced when it does not exist, is an empty folder or holds a dataset.
    fn check_replaceable(dest: &Path) -> anyhow::Result<()> {
        if !dest.exists() {
            return Ok(());
        }
        anyhow::ensure!(
            dest.is_dir(),
            "--out {} exists and is not a folder; refusing to replace it",
            dest.display()
        );
        let empty = std::fs::read_dir(dest)
            .with_context(|| format!("reading {}", dest.display()))?
            .next()
            .is_none();
        anyhow::ensure!(
            empty || dest.join(MANIFEST).is_file(),
            "--out {} exists and is not a dataset folder (no {MANIFEST}); refusing to replace it: \
             choose another folder or remove it",
            dest.display()
        );
        Ok(())
    }

    /// Clears what runs killed earlier left beside `dest` (their processes are gone): partial
    /// folders are removed; a previous dataset moved aside is put back if `dest` is missing.
    fn recover(parent: &Path, name: &str, dest: &Path) -> anyhow::Result<()> {
        let Ok(entries) = std::fs::read_dir(parent) else {
            return Ok(());
        };
        let (partial, old) = (format!(".{name}.partial-"), format!(".{name}.old-"));
        for entry in entries.flatten() {
            let file_name = entry.file_name().to_string_lossy().into_owned();
            let (is_old, pid) = if let Some(pid) = file_name.strip_prefix(&old) {
                (true, pid)
            } else if let Some(pid) = file_name.strip_prefix(&partial) {
                (false, pid)
            } else {
                continue;
            };
            let Ok(pid) = pid.parse::<u32>() else {
                continue;
            };
            // Only where a live process can be told from a dead one.
            let procfs = Path::new("/proc/self").exists();
            if !procfs || Path::new("/proc").join(pid.to_string()).exists() {
                continue;
            }
            let path = entry.path();
            if is_old && !dest.exists() {
                log::warn!(
                    "{} is missing and an interrupted run left the previous dataset in {}: moving it back",
                    dest.display(),
                    path.display()
                );
                std::fs::rename(&path, dest)
                    .with_context(|| format!("moving {} to {}", path.display(), dest.display()))?;
            } else {
                std::fs::remove_dir_all(&path)
                    .with_context(|| format!("removing {}", path.display()))?;
            }
        }
        Ok(())
    }
}
