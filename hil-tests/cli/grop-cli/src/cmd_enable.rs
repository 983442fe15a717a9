//! `grop enable`: the operator's enable on `operator/enable` (docs/runtime.md, "Safety stops
//! and holds"). A started (or restarted) executive arms the base only after an enable given
//! after its start, and a mission paused by a safeguard stop goes on only after one given once
//! the stop has cleared. The deployment has one operator: while another one holds the topic (in
//! HIL the world plays the operator), this is refused with the reason.

use std::path::PathBuf;
use std::time::Duration;

use anyhow::Context;
use grop_clock::Clock;
use grop_ipc::{IpcNode, OperatorEnableMsg};

/// Arguments of `grop enable`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Deployment file: its namespace and runtime clock.
    #[arg(long, value_name = "FILE")]
    pub deployment: PathBuf,
    /// iceoryx2 namespace instead of the deployment's.
    #[arg(long)]
    pub namespace: Option<String>,
    /// Keep the enable on the topic this long (an executive reads it on its next base cycle).
    #[arg(long, default_value_t = 0.5)]
    pub hold_s: f64,
}

/// Runs `grop enable`.
pub fn run(args: Args) -> anyhow::Result<()> {
    let deployment = grop_onboard::process::load_deployment(&args.deployment, args.namespace, None)
        .with_context(|| format!("the deployment {}", args.deployment.display()))?;
    if !(args.hold_s.is_finite() && (0.0..=60.0).contains(&args.hold_s)) {
        anyhow::bail!("--hold-s {} must be between 0 and 60 s", args.hold_s);
    }
    if deployment.clock != "wall" {
        // Joining a simulated clock would make this a lock-step participant of the mission.
        anyhow::bail!(
            "the deployment {} runs on the simulated clock {}: in HIL the world plays the operator and gives the enable itself",
            args.deployment.display(),
            deployment.clock
        );
    }
    let clock = grop_clock::WallClock;
    let node = IpcNode::new(&deployment.namespace, "grop-enable")
        .with_context(|| format!("iceoryx2 namespace {}", deployment.namespace))?;
    let publisher = node.publisher::<OperatorEnableMsg>().with_context(|| {
        format!(
            "opening {}/operator/enable: the deployment has one operator, and another one (a console, the HIL world) may hold it",
            deployment.namespace
        )
    })?;
    let stamp_ns = u64::try_from(clock.now().as_nanos()).unwrap_or(u64::MAX);
    publisher
        .publish(&OperatorEnableMsg {
            seq: 1,
            stamp_ns,
            pid: std::process::id(),
            reserved: 0,
        })
        .context("publishing the enable")?;
    println!(
        "enable given on {}/operator/enable at {:.3} s ({})",
        deployment.namespace,
        stamp_ns as f64 * 1e-9,
        deployment.clock
    );
    std::thread::sleep(Duration::from_secs_f64(args.hold_s));
    Ok(())
}
