//! `grop merge`: the shard folders of a campaign (`--shard I/N` runs of `grop eval`, `grop hil`,
//! `grop soak` or `grop datagen`) into what one unsharded run writes (docs/campaigns.md).
//!
//! The set is checked first ([`trial_sim::shard::check_set`]): every shard `0..N` once, all of
//! one campaign (job, seed, version, commit, configuration); otherwise it is refused, naming the
//! folder. The result is written into a temporary folder beside `--out` and renamed into place
//! at the end; `--out` must not exist yet (or be empty), so nothing is ever overwritten.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::Context;
use trial_sim::shard::{MANIFEST_FORMAT, Shard, ShardManifest, check_set, expand_folders};

/// Arguments of `grop merge`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Folder for the merged results; must not exist yet (or be empty).
    #[arg(long)]
    pub out: PathBuf,
    /// Shard folders (`shard-III-of-NNN`, holding `shard.json`), or folders holding them.
    #[arg(required = true, value_name = "SHARD_DIR")]
    pub shards: Vec<PathBuf>,
}

/// Runs `grop merge`.
pub fn run(args: Args) -> anyhow::Result<()> {
    let folders = expand_folders(&args.shards)?;
    let set = check_set(&folders)?;
    let first = &set[0].1;
    log::info!(
        "{} shards of a `grop {}` campaign, seed {}, commit {}",
        set.len(),
        first.job,
        first.seed,
        first.commit
    );
    match first.job.as_str() {
        "eval" => crate::cmd_eval::merge(&set, &args.out),
        "hil" => crate::cmd_hil::merge(&set, &args.out),
        "soak" => crate::cmd_soak::merge(&set, &args.out),
        "datagen" => crate::cmd_datagen::merge(&set, &args.out),
        other => anyhow::bail!("shard folder {}: unknown job {other:?}", set[0].0.display()),
    }
}

/// The manifest of a shard that started at `started`: the program's version and commit (of
/// the checkout it was built from), the configuration and its share of `total_tasks`.
pub fn manifest(
    job: &str,
    shard: Shard,
    seed: u64,
    config: serde_json::Value,
    total_tasks: usize,
    started: Instant,
) -> ShardManifest {
    let exe = std::env::current_exe().ok();
    ShardManifest {
        format: MANIFEST_FORMAT.into(),
        job: job.into(),
        shard,
        seed,
        version: env!("CARGO_PKG_VERSION").into(),
        // The checkout the program was built from.
        commit: trial_sim::shard::source_commit(&crate::common::checkout()),
        binary_sha256: exe
            .as_deref()
            .map(trial_sim::shard::file_sha256)
            .unwrap_or_default(),
        config,
        total_tasks,
        task_ids: shard.positions(total_tasks),
        wall_s: started.elapsed().as_secs_f64(),
    }
}

/// Copies a folder tree (a shard's per-task files into the merged folder).
pub fn copy_tree(from: &std::path::Path, to: &std::path::Path) -> anyhow::Result<()> {
    std::fs::create_dir_all(to).with_context(|| format!("creating {}", to.display()))?;
    for entry in std::fs::read_dir(from).with_context(|| format!("reading {}", from.display()))? {
        let entry = entry.with_context(|| format!("reading {}", from.display()))?;
        let (src, dst) = (entry.path(), to.join(entry.file_name()));
        if entry.file_type()?.is_dir() {
            copy_tree(&src, &dst)?;
        } else {
            std::fs::copy(&src, &dst)
                .with_context(|| format!("copying {} to {}", src.display(), dst.display()))?;
        }
    }
    Ok(())
}
