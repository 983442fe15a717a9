//! What both onboard binaries do at start: read the deployment with the command line's
//! overrides, and turn SIGTERM / SIGINT into a flag their loops check (so they stop the robot
//! before exiting instead of dying mid-command).
#![allow(
    unsafe_code,
    reason = "libc::signal installs the SIGTERM/SIGINT flag handler"
)]

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};

use crate::deployment::{Deployment, DeploymentError};

/// Why a process could not start.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum StartError {
    /// The signal handler could not be installed.
    #[error("installing the handler for signal {signal} failed")]
    Signal {
        /// The signal number.
        signal: i32,
        /// What the system said.
        source: std::io::Error,
    },
    /// The deployment file could not be read or is invalid.
    #[error(transparent)]
    Deployment(#[from] DeploymentError),
    /// The command line's `--namespace` / `--clock` made the deployment invalid.
    #[error("the deployment with the command-line overrides")]
    Overrides(#[source] DeploymentError),
}

/// Set by the signal handler, read by the loops.
static STOP: AtomicBool = AtomicBool::new(false);

extern "C" fn on_signal(_signal: libc::c_int) {
    // Only an atomic store: async-signal-safe.
    STOP.store(true, Ordering::Relaxed);
}

/// Installs the SIGTERM and SIGINT handlers and returns the flag they set.
pub fn stop_flag() -> Result<&'static AtomicBool, StartError> {
    for signal in [libc::SIGTERM, libc::SIGINT] {
        let handler: extern "C" fn(libc::c_int) = on_signal;
        // SAFETY: installs an async-signal-safe handler (one atomic store) for a valid signal.
        let previous = unsafe { libc::signal(signal, handler as libc::sighandler_t) };
        if previous == libc::SIG_ERR {
            return Err(StartError::Signal {
                signal,
                source: std::io::Error::last_os_error(),
            });
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
    /// Real-time settings of the process: `off`, `on` (memory locked and pre-faulted, timer
    /// slack 1 ns, SCHED_FIFO 50), or a list such as `fifo=80,cpu=1,lock,slack=1`
    /// (docs/runtime.md, "Real time"). What the system refuses is reported, not fatal.
    #[arg(long, default_value = "off")]
    pub rt: grop_clock::rt::RtSettings,
}

impl DeploymentArgs {
    /// Applies `--rt` to this process (before its loops start) and logs what was applied and
    /// what the system refused, and why.
    pub fn apply_rt(&self, process: &str) {
        if self.rt.is_off() {
            return;
        }
        let report = grop_clock::rt::apply(&self.rt);
        if report.all_applied() {
            log::info!("{process}: real-time settings applied: {}", self.rt);
        } else {
            for line in report.to_string().lines() {
                log::warn!("{process}: {line}");
            }
        }
    }

    /// The deployment these options name, overrides applied and validated.
    pub fn load(&self) -> Result<Deployment, StartError> {
        load_deployment(&self.deployment, self.namespace.clone(), self.clock.clone())
    }
}

/// Loads the deployment file and applies the `--namespace` / `--clock` overrides, validated
/// together.
pub fn load_deployment(
    path: &Path,
    namespace: Option<String>,
    clock: Option<String>,
) -> Result<Deployment, StartError> {
    let mut deployment = Deployment::load(path)?;
    if let Some(namespace) = namespace {
        deployment.namespace = namespace;
    }
    if let Some(clock) = clock {
        deployment.clock = clock;
    }
    deployment.validate().map_err(StartError::Overrides)?;
    Ok(deployment)
}
