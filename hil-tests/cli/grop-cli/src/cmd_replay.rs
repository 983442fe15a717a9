//! `grop replay LOG`: re-runs the planning node and the executive against a mission log's
//! recorded inputs in simulated time and reports the first message where their outputs differ
//! from the log (none for an unchanged build). Exit status 0 when they agree, 1 when not.

use std::path::PathBuf;

use anyhow::Context;
use grop_onboard::mission_log::replay::{ReplayOptions, replay};

/// Options of `grop replay`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The mission log (MCAP) written by `grop demo` or `grop-recorder`.
    #[arg(value_name = "LOG", default_value = "out/demo.mcap")]
    pub path: PathBuf,
    /// Run with this model instead of the one the log names (the log's SHA-256 is then not
    /// checked; expect differences from the first plan on).
    #[arg(long)]
    pub model: Option<PathBuf>,
    /// Where to write the replay's own log (default: LOG with `.replay.mcap`).
    #[arg(long)]
    pub out: Option<PathBuf>,
}

/// Runs the replay and prints what it found.
pub fn run(args: Args) -> anyhow::Result<()> {
    let started = std::time::Instant::now();
    let report = replay(
        &args.path,
        &ReplayOptions {
            // A committed model named relative to the checkout works from any folder.
            model: args.model.as_deref().map(crate::common::committed_file),
            out: args.out.clone(),
        },
    )
    .with_context(|| format!("replaying {}", args.path.display()))?;
    println!(
        "replayed {:.1} s of simulated time in {:.1} s: {} messages recorded, {} replayed (wall-clock /timing/ channels not compared); the replay's log is {}",
        report.sim_s,
        started.elapsed().as_secs_f64(),
        report.recorded,
        report.replayed,
        report.replay_log.display()
    );
    if report.arm_mismatches > 0 {
        println!(
            "the executive called the arm differently {} times (the log answered what it could)",
            report.arm_mismatches
        );
    }
    match &report.first_difference {
        None => {
            println!("no difference: the planner and the executive did exactly what the log says");
            Ok(())
        }
        Some(d) => {
            println!("first difference at {d}");
            std::process::exit(1);
        }
    }
}
