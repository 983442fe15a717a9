//! `grop merge`: the shard folders of a campaign (`--shard I/N` runs of `grop eval`, `grop hil`,
//! `grop soak` or `grop datagen`) into what one unsharded run writes (docs/campaigns.md).
//!
//! The set is checked first ([`trial_sim::shard::check_set`]): every shard `0..N` once, all of
//! one campaign (job, seed, version, commit, configuration); otherwise it is refused, naming the
//! folder. The result is written into a temporary folder beside `--out` and renamed into place
//! at the end; `--out` must not exist yet (or be empty), so nothing is ever overwritten.

use std::path::PathBuf;

use trial_sim::shard::{check_set, expand_folders};

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
