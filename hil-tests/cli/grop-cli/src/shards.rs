//! What a sharded subcommand (`grop eval`, `grop hil`, `grop soak`, `grop datagen` with
//! `--shard I/N`) writes beside its results and how `grop merge` puts shards together: the
//! shard's manifest and the copy of its per-task files (docs/campaigns.md). The commands and
//! `cmd_merge` use it; it uses none of them.

use std::time::Instant;

use anyhow::Context;
use trial_sim::shard::{MANIFEST_FORMAT, Shard, ShardManifest};

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
