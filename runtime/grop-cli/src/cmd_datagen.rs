//! `grop datagen`.

/// Arguments of `grop datagen`.
#[derive(clap::Args, Debug)]
pub struct Args {}

pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("`grop datagen` is not built yet")
}
