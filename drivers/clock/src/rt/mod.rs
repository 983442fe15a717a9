//! Real-time hygiene for a cyclic control thread: lock and pre-fault memory, shrink the timer
//! slack, run under `SCHED_FIFO`, pin to a CPU ([`RtSettings`], [`apply`]); and measure the loop
//! that results ([`LoopStats`]: lateness histogram, overruns, percentiles, no allocation).
//!
//! Every step the system refuses is reported, never fatal: a loop without real-time rights
//! still runs, and the [`RtReport`] says which call was refused, why, and what to grant.
//!
//! ```no_run
//! use std::time::Duration;
//! use grop_clock::{Clock, WallClock};
//! use grop_clock::rt::{self, LoopStats, RtSettings};
//!
//! let settings: RtSettings = "fifo=50,cpu=1,lock,slack=1".parse()?; // or "on"
//! let report = rt::apply(&settings); // on the loop's own thread: priority, slack and CPU are per thread
//! eprintln!("{report}");
//! let period = Duration::from_millis(20);
//! let mut stats = LoopStats::new(period);
//! let mut deadline = WallClock.now() + period;
//! for _ in 0..50 {
//!     WallClock.sleep_until(deadline);
//!     stats.record(deadline, WallClock.now());
//!     // ... the cycle's work ...
//!     stats.record_end(WallClock.now(), deadline + period);
//!     deadline += period;
//! }
//! println!("{}", stats.summary());
//! # Ok::<(), grop_clock::rt::RtSpecError>(())
//! ```

mod apply;
mod loop_stats;
mod settings;
#[cfg(test)]
mod tests;

pub use apply::{RtOutcome, RtRefusal, RtReport, RtStep, apply, current_policy};
pub use loop_stats::{LoopStats, LoopSummary};
pub use settings::{
    DEFAULT_FIFO_PRIORITY, DEFAULT_PREFAULT_HEAP_BYTES, DEFAULT_PREFAULT_STACK_BYTES,
    MAX_CPU_INDEX, MAX_PREFAULT_BYTES, RtSettings, RtSpecError,
};
