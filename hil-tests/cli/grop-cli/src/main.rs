//! `grop`: the command-line entry point of the GROP dinner-table controller.
//!
//! Every job is a subcommand in its own module (`cmd_*.rs`), each with `--help` and defaults:
//! `grop demo`, `grop datagen`, `grop render`, `grop model-eval`, `grop eval` (`--suite
//! full-setting` for whole table settings), `grop bench`, `grop bench-settings`, `grop hil`,
//! `grop soak`, `grop merge` (shards of a campaign, docs/campaigns.md).

use clap::{Parser, Subcommand};

mod cmd_bench;
mod cmd_bench_settings;
mod cmd_datagen;
mod cmd_demo;
mod cmd_demo_closed_loop;
mod cmd_enable;
mod cmd_eval;
mod cmd_eval_settings;
mod cmd_hil;
mod cmd_hil_suite;
mod cmd_latency;
mod cmd_layout_picture;
mod cmd_merge;
mod cmd_model_eval;
mod cmd_render;
mod cmd_replay;
mod cmd_soak;
mod common;
mod mission_end;
mod picture;
mod shards;

/// GROP: visually grounded task-and-motion planning for a mobile manipulator setting dinner tables.
#[derive(Parser, Debug)]
#[command(name = "grop", version, about, long_about = None)]
struct Cli {
    /// Log level filter (error, warn, info, debug, trace); RUST_LOG overrides it.
    #[arg(long, global = true, default_value = "info")]
    log: String,
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// The whole pipeline once on the simulated robot: perceive, plan with GROP, explain, execute.
    Demo(cmd_demo::Args),
    /// Generate the feasibility dataset: trials at every candidate cell of every task.
    Datagen(cmd_datagen::Args),
    /// Render a scene (generated or from a file) with its heatmaps overlaid, as a PNG.
    Render(cmd_render::Args),
    /// Measure a feasibility evaluator (FCN, heuristics) against simulated ground truth.
    ModelEval(cmd_model_eval::Args),
    /// Run the paper's experiments: GROP and the baselines executed in the simulator.
    Eval(cmd_eval::Args),
    /// Benchmarks: writes medians and p99 to docs/.
    Bench(cmd_bench::Args),
    /// Whole table settings (24 and 36 objects, several trips): decision latency and the gap to
    /// the optimum; writes out/settings-bench.md (docs/settings-bench.md with --write-docs).
    BenchSettings(cmd_bench_settings::Args),
    /// Evaluation tasks in closed loop (world + onboard processes) next to `grop eval`'s
    /// calculation of the same tasks, paired.
    Hil(cmd_hil::Args),
    /// Re-run the planner and the executive against a mission log's recorded inputs and report
    /// the first message where they now differ.
    Replay(cmd_replay::Args),
    /// Draw what the committed Foxglove layout (docs/foxglove-layout.json) shows of a mission
    /// log, panel by panel, into a PNG (no Foxglove app needed).
    LayoutPicture(cmd_layout_picture::Args),
    /// Latency suite: camera frames across processes, loop jitter, CAN round trip,
    /// allocations; writes out/latency.md (docs/latency.md with --write-docs).
    Latency(cmd_latency::Args),
    /// Soak: many closed-loop missions back to back; memory must stay flat and no shared
    /// memory, socket or file descriptor may be left behind -> out/soak.md (`--write-docs`:
    /// docs/soak.md).
    Soak(cmd_soak::Args),
    /// Merge the shard folders of a campaign (`--shard I/N` runs of eval, hil, soak or datagen)
    /// into what one unsharded run writes (docs/campaigns.md).
    Merge(cmd_merge::Args),
    /// The operator's enable: arms a (re)started executive, lets a mission paused by a
    /// safeguard stop go on once the stop has cleared (docs/runtime.md).
    Enable(cmd_enable::Args),
}

fn main() -> std::process::ExitCode {
    let cli = Cli::parse();
    env_logger::Builder::from_env(env_logger::Env::default().default_filter_or(&cli.log)).init();
    let result = match cli.command {
        Command::Demo(a) if a.in_process => cmd_demo::run_in_process(a),
        Command::Demo(a) => cmd_demo_closed_loop::run(a),
        Command::Datagen(a) => cmd_datagen::run(a),
        Command::Render(a) => cmd_render::run(a),
        Command::ModelEval(a) => cmd_model_eval::run(a),
        Command::Eval(a) if a.suite == cmd_eval::Suite::FullSetting => {
            cmd_eval_settings::run_command(a)
        }
        Command::Eval(a) => cmd_eval::run(a),
        Command::Bench(a) => cmd_bench::run(a),
        Command::BenchSettings(a) => cmd_bench_settings::run(a),
        Command::Hil(a) if a.suite.is_some() || a.scenes.is_some() => {
            cmd_hil_suite::run_command(&a)
        }
        Command::Hil(a) => cmd_hil::run(a),
        Command::Replay(a) => cmd_replay::run(a),
        Command::LayoutPicture(a) => cmd_layout_picture::run(a),
        Command::Latency(a) => cmd_latency::run(a),
        Command::Soak(a) => cmd_soak::run(a),
        Command::Merge(a) => cmd_merge::run(a),
        Command::Enable(a) => cmd_enable::run(a),
    };
    match result {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            std::process::ExitCode::FAILURE
        }
    }
}
