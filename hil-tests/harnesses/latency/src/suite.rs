//! Every measurement in one run, sized by rounds: what `grop latency` runs.

use std::path::Path;
use std::time::{Duration, Instant};

use grop_clock::rt::RtSettings;

use crate::BenchError;
use crate::alloc_count::{self, AllocResult};
use crate::camera::{self, CameraConfig, CameraResult};
use crate::can_loop::{self, CanConfig, CanResult};
use crate::jitter::{self, JitterConfig, LoopResult};
use crate::machine::MachineInfo;

/// Sizes of one run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SuiteConfig {
    /// Camera frames.
    pub camera: CameraConfig,
    /// Loop jitter.
    pub jitter: JitterConfig,
    /// CAN command to feedback.
    pub can: CanConfig,
    /// Counted cycles per allocation case.
    pub alloc_cycles: usize,
    /// Warm-up cycles per allocation case.
    pub alloc_warmup: usize,
}

impl SuiteConfig {
    /// The default run scaled by `rounds` (10 is the default: about 1.5 minutes).
    pub fn with_rounds(rounds: usize, rt: RtSettings) -> Self {
        let rounds = rounds.max(1);
        Self {
            camera: CameraConfig {
                rounds,
                frames_per_round: 50,
                warmup_frames: 30,
                gap: Duration::from_micros(300),
            },
            jitter: JitterConfig {
                cycles_50hz: 50 * rounds,
                cycles_500hz: 250 * rounds,
                rt,
                work: Duration::from_micros(50),
            },
            can: CanConfig {
                samples: 300 * rounds,
                warmup: 100,
            },
            alloc_cycles: 100 * rounds,
            alloc_warmup: 200,
        }
    }

    /// A run of a few seconds (every measurement, few samples).
    pub fn quick(rt: RtSettings) -> Self {
        Self {
            camera: CameraConfig {
                rounds: 2,
                frames_per_round: 10,
                warmup_frames: 10,
                gap: Duration::from_micros(300),
            },
            jitter: JitterConfig {
                cycles_50hz: 25,
                cycles_500hz: 200,
                rt,
                work: Duration::from_micros(50),
            },
            can: CanConfig {
                samples: 200,
                warmup: 20,
            },
            alloc_cycles: 100,
            alloc_warmup: 50,
        }
    }
}

/// Everything one run measured.
#[derive(Debug, Clone, PartialEq)]
pub struct SuiteResults {
    /// The machine, read at the start.
    pub machine: MachineInfo,
    /// The sizes.
    pub config: SuiteConfig,
    /// Camera frames.
    pub camera: CameraResult,
    /// Loop jitter.
    pub jitter: Vec<LoopResult>,
    /// CAN command to feedback.
    pub can: CanResult,
    /// Allocations per cycle.
    pub alloc: Vec<AllocResult>,
    /// Wall time of the run.
    pub wall: Duration,
}

/// Runs every measurement against peers started from `peer_exe`; `progress` is told what runs.
pub fn run(
    peer_exe: &Path,
    config: &SuiteConfig,
    mut progress: impl FnMut(&str),
) -> Result<SuiteResults, BenchError> {
    let started = Instant::now();
    let machine = MachineInfo::now();
    progress("camera frames across two processes (iceoryx2, grop-ipc, Unix socket, TCP)");
    let camera = camera::measure(peer_exe, &config.camera)?;
    progress("CAN command to feedback with the RMP driver in the loop");
    let can = can_loop::measure(peer_exe, &config.can)?;
    progress("allocations per steady-state cycle");
    let alloc = alloc_count::measure(peer_exe, config.alloc_cycles, config.alloc_warmup)?;
    progress("loop jitter at 50 Hz and 500 Hz (idle / loaded, without / with RT settings)");
    let jitter = jitter::measure(peer_exe, &config.jitter)?;
    Ok(SuiteResults {
        machine,
        config: *config,
        camera,
        jitter,
        can,
        alloc,
        wall: started.elapsed(),
    })
}
