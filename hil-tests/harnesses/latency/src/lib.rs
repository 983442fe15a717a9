//! Latency benchmarks of the onboard runtime's paths, each a function that runs one
//! measurement and returns its samples summarised (count, p50, p99, max):
//!
//! * [`camera::measure`]: a 921,600-byte camera frame (640 x 480 RGB8 in the runtime's
//!   `CameraFrameMsg`) from a second process, from the publisher starting to write it to the
//!   subscriber holding it: iceoryx2 (loan, write in place, publish), the runtime's own
//!   `grop_ipc` publisher, a Unix stream socket and loopback TCP, interleaved in rounds, with a
//!   polling and a sleeping (event-woken) subscriber;
//! * [`jitter::measure`]: lateness of 50 Hz and 500 Hz loops on absolute deadlines, idle and
//!   with the other core loaded, without and with the real-time settings of
//!   [`grop_clock::rt`];
//! * [`can_loop::measure`]: the RMP driver's velocity command to the driver having decoded the
//!   feedback set the simulated base (another process) sent in reply, over the iceoryx2 virtual
//!   CAN bus;
//! * [`alloc_count::measure`]: heap allocations per steady-state cycle (driver tick, frame
//!   publish, loop statistics) under a counting allocator.
//!
//! Cross-process measurements run against `grop-latency-peer`, this crate's binary, which
//! [`peer::locate`] finds next to the running program (or builds). [`suite::run`] runs them
//! all and [`report::markdown`] writes the report (`grop latency`, docs/latency.md).
//!
//! ```no_run
//! let peer = latency::peer::locate(true)?;
//! let result = latency::can_loop::measure(&peer, &latency::can_loop::CanConfig::default())?;
//! println!("command to decoded feedback: {}", result.decoded);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
#![allow(unsafe_code, reason = "getrusage for the CPU time of a run")]

pub mod alloc_count;
pub mod camera;
pub mod can_loop;
pub mod jitter;
pub mod lidar;
pub mod machine;
pub mod names;
pub mod peer;
pub mod pipeline;
pub mod plan_motion;
pub mod report;
pub mod stats;
pub mod suite;

pub use stats::Summary;

use std::time::Duration;

/// What a fallible step of a measurement was, for its error (the typed counterpart of a
/// binary's `anyhow::Context`).
pub trait Step<T> {
    /// The error, if any, as [`BenchError::Setup`] naming `what` was being done.
    fn step(self, what: &str) -> Result<T, BenchError>;
}

impl<T, E: std::fmt::Display> Step<T> for Result<T, E> {
    fn step(self, what: &str) -> Result<T, BenchError> {
        self.map_err(|e| BenchError::Setup {
            what: what.to_owned(),
            detail: e.to_string(),
        })
    }
}

/// Why a measurement could not be made.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum BenchError {
    /// A system call or file operation failed.
    #[error("{what}: {source}")]
    Io {
        /// What was being done.
        what: String,
        /// The error.
        #[source]
        source: std::io::Error,
    },
    /// Setting up a transport, bus, driver or service failed (iceoryx2, the CAN bus, the
    /// driver's configuration).
    #[error("{what}: {detail}")]
    Setup {
        /// What was being set up.
        what: String,
        /// The reason.
        detail: String,
    },
    /// The peer process misbehaved: did not start, died, or answered something unreadable.
    #[error("grop-latency-peer: {0}")]
    Peer(String),
    /// Something did not arrive in time.
    #[error("{what}: nothing within {after:?}")]
    Timeout {
        /// What was awaited.
        what: String,
        /// How long we waited.
        after: Duration,
    },
}

impl BenchError {
    pub(crate) fn io(what: impl Into<String>) -> impl FnOnce(std::io::Error) -> Self {
        let what = what.into();
        move |source| Self::Io { what, source }
    }

    pub(crate) fn setup(what: impl Into<String>) -> impl FnOnce(&dyn std::fmt::Debug) -> Self {
        let what = what.into();
        move |detail| Self::Setup {
            what,
            detail: format!("{detail:?}"),
        }
    }
}

/// CLOCK_MONOTONIC in nanoseconds: the host-wide clock both processes stamp with.
pub fn now_ns() -> u64 {
    u64::try_from(grop_clock::monotonic_now().as_nanos()).unwrap_or(u64::MAX)
}

/// Minor and major page faults and involuntary context switches of the calling thread.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct ThreadUsage {
    /// Minor page faults (a page mapped on first touch, no I/O).
    pub minor_faults: u64,
    /// Major page faults (I/O).
    pub major_faults: u64,
    /// Times the thread was preempted.
    pub involuntary_switches: u64,
}

impl ThreadUsage {
    /// The calling thread's counters now (zeros if the kernel refuses).
    pub fn now() -> Self {
        // SAFETY: rusage is plain data; getrusage fills it; RUSAGE_THREAD is Linux's.
        let mut usage: libc::rusage = unsafe { std::mem::zeroed() };
        // SAFETY: `usage` is a valid, writable rusage.
        let rc = unsafe { libc::getrusage(libc::RUSAGE_THREAD, &mut usage) };
        if rc != 0 {
            return Self::default();
        }
        let n = |v: libc::c_long| u64::try_from(v).unwrap_or(0);
        Self {
            minor_faults: n(usage.ru_minflt),
            major_faults: n(usage.ru_majflt),
            involuntary_switches: n(usage.ru_nivcsw),
        }
    }

    /// Counts since `earlier`.
    pub fn since(&self, earlier: &Self) -> Self {
        Self {
            minor_faults: self.minor_faults.saturating_sub(earlier.minor_faults),
            major_faults: self.major_faults.saturating_sub(earlier.major_faults),
            involuntary_switches: self
                .involuntary_switches
                .saturating_sub(earlier.involuntary_switches),
        }
    }
}
