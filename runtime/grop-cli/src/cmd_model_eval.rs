//! `grop model-eval`.

/// Arguments of `grop model-eval`.
#[derive(clap::Args, Debug)]
pub struct Args {}

pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("`grop model-eval` is not built yet")
}
