//! `grop render`.

/// Arguments of `grop render`.
#[derive(clap::Args, Debug)]
pub struct Args {}

pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("`grop render` is not built yet")
}
