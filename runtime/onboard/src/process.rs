//! What both onboard binaries do at start: read the deployment with the command line's
//! overrides, and turn SIGTERM / SIGINT into a flag their loops check (so they stop the robot
//! before exiting instead of dying mid-command).

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};

use anyhow::Context;

use crate::deployment::Deployment;

/// Set by the signal handler, read by the loops.
static STOP: AtomicBool = AtomicBool::new(false);

extern "C" fn on_signal(_signal: libc::c_int) {
    // Only an atomic store: async-signal-safe.
    STOP.store(true, Ordering::Relaxed);
}

/// Installs the SIGTERM and SIGINT handlers and returns the flag they set.
pub fn stop_flag() -> anyhow::Result<&'static AtomicBool> {
    for signal in [libc::SIGTERM, libc::SIGINT] {
        let handler: extern "C" fn(libc::c_int) = on_signal;
        // SAFETY: installs an async-signal-safe handler (one atomic store) for a valid signal.
        let previous = unsafe { libc::signal(signal, handler as libc::sighandler_t) };
        if previous == libc::SIG_ERR {
            anyhow::bail!("installing the handler for signal {signal} failed");
        }
    }
    Ok(&STOP)
}

/// The command-line options both binaries take.
#[derive(clap::Args, Debug, Clone)]
pub struct DeploymentArgs {
    /// Deployment file (TOML).
    #[arg(long, value_name = "FILE")]
    pub deployment: PathBuf,
    /// iceoryx2 namespace instead of the deployment's.
    #[arg(long)]
    pub namespace: Option<String>,
    /// Clock instead of the deployment's: `wall` or `sim:<name>`.
    #[arg(long)]
    pub clock: Option<String>,
}

impl DeploymentArgs {
    /// The deployment these options name, overrides applied and validated.
    pub fn load(&self) -> anyhow::Result<Deployment> {
        load_deployment(&self.deployment, self.namespace.clone(), self.clock.clone())
    }
}

/// Loads the deployment file and applies the `--namespace` / `--clock` overrides, validated
/// together.
pub fn load_deployment(
    path: &Path,
    namespace: Option<String>,
    clock: Option<String>,
) -> anyhow::Result<Deployment> {
    let mut deployment = Deployment::load(path)?;
    if let Some(namespace) = namespace {
        deployment.namespace = namespace;
    }
    if let Some(clock) = clock {
        deployment.clock = clock;
    }
    deployment
        .validate()
        .context("the deployment with the command-line overrides")?;
    Ok(deployment)
}
