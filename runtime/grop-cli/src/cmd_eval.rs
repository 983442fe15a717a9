//! `grop eval`.

/// Arguments of `grop eval`.
#[derive(clap::Args, Debug)]
pub struct Args {}

pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("`grop eval` is not built yet")
}
