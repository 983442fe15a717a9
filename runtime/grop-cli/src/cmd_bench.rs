//! `grop bench`.

/// Arguments of `grop bench`.
#[derive(clap::Args, Debug)]
pub struct Args {}

pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("`grop bench` is not built yet")
}
