//! `grop latency`: the latency suite (hil-tests/harnesses/latency) in one run: camera frames across two
//! processes (iceoryx2 vs sockets), loop jitter without and with real-time settings, CAN
//! command to feedback with the driver in the loop, allocations per steady-state cycle, camera
//! frame to plan, plan to motion, the range sensor's path to the base; a
//! markdown report to `out/latency.md`, or `docs/latency.md` with `--write-docs`.

use std::path::PathBuf;

use anyhow::Context;
use grop_clock::rt::RtSettings;
use latency::suite::SuiteConfig;

/// Arguments of `grop latency`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Measurement rounds: scales every sample count (10: about 1.5 minutes on 2 cores).
    #[arg(long, default_value_t = 10)]
    pub rounds: usize,
    /// A run of a few seconds (few samples of everything), to check the suite works.
    #[arg(long)]
    pub quick: bool,
    /// Real-time settings of the loop-jitter configurations that use them (`on`, or e.g.
    /// `fifo=50,cpu=1,lock,slack=1`; see grop_clock::rt).
    #[arg(long, default_value = "on")]
    pub rt: RtSettings,
    /// Markdown report.
    #[arg(long, default_value = "out/latency.md")]
    pub out: PathBuf,
    /// Write the report to docs/latency.md instead (regenerates the committed doc).
    #[arg(long)]
    pub write_docs: bool,
    /// Do not run `cargo build` for grop-latency-peer first.
    #[arg(long)]
    pub no_build: bool,
}

/// The command line that reproduces a run with these arguments.
fn reproduce(args: &Args) -> String {
    let mut cmd = String::from("cargo run --release -p grop-cli -- latency");
    if args.quick {
        cmd.push_str(" --quick");
    } else if args.rounds != 10 {
        cmd.push_str(&format!(" --rounds {}", args.rounds));
    }
    if args.rt != RtSettings::ON {
        cmd.push_str(&format!(" --rt {}", args.rt));
    }
    if args.write_docs {
        cmd.push_str(" --write-docs");
    }
    cmd
}

/// Runs `grop latency`.
pub fn run(args: Args) -> anyhow::Result<()> {
    let peer = latency::peer::locate_built_with(!args.no_build, &[env!("CARGO_PKG_NAME")])
        .context("finding grop-latency-peer")?;
    let config = if args.quick {
        SuiteConfig::quick(args.rt)
    } else {
        SuiteConfig::with_rounds(args.rounds, args.rt)
    };
    let results = latency::suite::run(&peer, &config, |step| eprintln!("latency: {step}"))
        .context("running the latency suite")?;
    eprintln!("latency: camera frame to plan (planner node on the wall clock)");
    let model = crate::common::committed_file(std::path::Path::new("models/psi-fcn.onnx"));
    let samples = if args.quick {
        5
    } else {
        20 * args.rounds.max(1)
    };
    let namespace = format!("latency-pipeline-{}", std::process::id());
    let mut pipeline = Vec::new();
    for (i, rt) in [None, Some(args.rt)].into_iter().enumerate() {
        pipeline.push(
            latency::pipeline::frame_to_plan(samples, &model, &format!("{namespace}-{i}"), rt)
                .context("measuring camera frame to plan")?,
        );
    }
    eprintln!("latency: plan to the first motion frame (executive on the wall clock)");
    let motion = latency::plan_motion::plan_to_motion(
        if args.quick {
            3
        } else {
            2 * args.rounds.max(1)
        },
        &format!("{namespace}-motion"),
    )
    .context("measuring plan to motion")?;
    eprintln!("latency: the range sensor's path (UDP revolution, monitor check, stop to CAN)");
    let n = if args.quick {
        5
    } else {
        20 * args.rounds.max(1)
    };
    let lidar = latency::lidar::measure(&latency::lidar::LidarConfig {
        revolutions: n,
        stops: n,
    })
    .context("measuring the range sensor's path")?;
    let md = latency::report::markdown(
        &results,
        &reproduce(&args),
        Some(format!(
            "{}\n{}",
            latency::pipeline::markdown(&pipeline, &motion),
            latency::lidar::markdown(&lidar)
        )),
    );
    let out = if args.write_docs {
        PathBuf::from("docs/latency.md")
    } else {
        args.out.clone()
    };
    if let Some(dir) = out.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    std::fs::write(&out, &md).with_context(|| format!("writing {}", out.display()))?;
    println!("{md}");
    println!("wrote {}", out.display());
    Ok(())
}
