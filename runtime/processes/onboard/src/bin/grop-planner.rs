//! `grop-planner --deployment FILE [--namespace NS] [--clock SPEC]`: the perception and planning
//! node (camera frame -> views -> Psi -> GROP -> `plan/task`, `heatmaps`) as a process. Runs its
//! 10 ms loop on the deployment's clock until SIGTERM or SIGINT, then exits cleanly. Logs with
//! env_logger (`RUST_LOG`, default `info`).

use anyhow::Context;
use clap::Parser;
use grop_onboard::planner_node::{PLANNER_CLOCK_RANK, PlannerNode};

#[derive(Parser, Debug)]
#[command(
    name = "grop-planner",
    about = "grop perception and planning node",
    version
)]
struct Args {
    #[command(flatten)]
    deployment: grop_onboard::process::DeploymentArgs,
}

fn main() -> anyhow::Result<()> {
    env_logger::Builder::from_env(env_logger::Env::default().default_filter_or("info")).init();
    let args = Args::parse();
    let deployment = args.deployment.load()?;
    let stop = grop_onboard::process::stop_flag()?;
    args.deployment.apply_rt("grop-planner");
    log::info!(
        "grop-planner: deployment {}, namespace `{}`, clock {}, map {}, model {}",
        args.deployment.deployment.display(),
        deployment.namespace,
        deployment.clock,
        deployment.map.display(),
        deployment.model.display()
    );
    let mut node =
        PlannerNode::from_deployment(&deployment).context("starting the planner node")?;
    let clock = grop_clock::open(&deployment.clock, "grop-planner", PLANNER_CLOCK_RANK)
        .with_context(|| format!("opening clock {}", deployment.clock))?;
    node.run(clock.as_ref(), stop)
        .context("running the planner node")?;
    let (failures, last) = node.failures();
    log::info!(
        "grop-planner: stopped; {} loop overruns, {failures} unanswered requests{}",
        node.overruns(),
        last.map(|e| format!(" (last: {e})")).unwrap_or_default()
    );
    Ok(())
}
