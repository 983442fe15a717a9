//! One clock for every process of grop: the onboard runtime, the drivers and the simulated
//! devices read time through [`Clock`] and sleep to absolute deadlines with it.
//!
//! * [`WallClock`]: `CLOCK_MONOTONIC` on the robot; `sleep_until` is an absolute-deadline
//!   `clock_nanosleep`, so a late cycle never pushes the following ones back.
//! * [`SimClock`]: a simulated clock in shared memory that the HIL world owns
//!   ([`SimClockHost`]). Every participant process sleeps on it; the host moves time forward
//!   only when every participant sleeps, and wakes them one at a time in rank order at each
//!   instant. A mission therefore runs in lock-step, as fast as the processes compute (or at a
//!   chosen pace, e.g. wall-clock speed), and a process that computes for a long time simply
//!   holds the clock still. A participant that dies is noticed (its pid is gone) and released.
//!
//! ```no_run
//! use std::time::Duration;
//! let clock = grop_clock::open("wall", "executive", 20)?;
//! let mut deadline = clock.now();
//! for _ in 0..3 {
//!     deadline += Duration::from_millis(20);
//!     clock.sleep_until(deadline); // absolute: no drift
//! }
//! # Ok::<(), grop_clock::ClockError>(())
//! ```
#![allow(
    unsafe_code,
    reason = "clock_gettime, clock_nanosleep and kill(pid, 0) through libc"
)]

mod futex;
mod manual;
pub mod rt;
mod sim;
mod wait;

use std::time::Duration;

pub use manual::ManualClock;
pub use sim::{Departure, HostConfig, MAX_PARTICIPANTS, SimClock, SimClockHost};
pub use wait::{MAX_WAIT_FDS, wait_readable};

/// A monotonic clock with absolute-deadline sleeps.
pub trait Clock: Send + Sync {
    /// Time on this clock. Comparable across the processes that share the clock (the wall
    /// clock is the host's `CLOCK_MONOTONIC`; a simulated clock is shared memory).
    fn now(&self) -> Duration;

    /// Sleeps until `deadline` on this clock; returns at once if it has passed.
    fn sleep_until(&self, deadline: Duration);

    /// True when the clock cannot advance any more (the simulation that owned it ended); the
    /// wall clock never is. A process whose clock is lost should stop what it drives and exit.
    fn is_lost(&self) -> bool {
        false
    }

    /// Marks work handed to another thread of this process (a worker) as in progress: a
    /// simulated clock does not advance until the matching [`Clock::end_hold`], so the work
    /// takes no simulated time, as if done in place; the wall clock ignores it. Lets a control
    /// loop keep allocating work off its thread and stay deterministic in lock-step.
    fn begin_hold(&self) {}

    /// Ends one [`Clock::begin_hold`] (called by the worker when its answer is ready).
    fn end_hold(&self) {}

    /// Waits for this participant's turn at the current instant: on a simulated clock, until
    /// the host runs it, in rank order with everyone else due now (a process calls it once after
    /// joining, so that its first work is ordered like all later work, whatever the order the
    /// processes started in); the wall clock returns at once.
    fn wait_turn(&self) {}

    /// True for a simulated clock: a loop must then run on its ticks (lock-step determinism)
    /// rather than wake on events.
    fn is_simulated(&self) -> bool {
        false
    }
}

/// A clock behind a pointer is that clock.
macro_rules! forward_clock {
    ($($ptr:ty),*) => {$(
        impl<C: Clock + ?Sized> Clock for $ptr {
            fn now(&self) -> Duration {
                (**self).now()
            }
            fn sleep_until(&self, deadline: Duration) {
                (**self).sleep_until(deadline)
            }
            fn is_lost(&self) -> bool {
                (**self).is_lost()
            }
            fn begin_hold(&self) {
                (**self).begin_hold()
            }
            fn end_hold(&self) {
                (**self).end_hold()
            }
            fn wait_turn(&self) {
                (**self).wait_turn()
            }
            fn is_simulated(&self) -> bool {
                (**self).is_simulated()
            }
        }
    )*};
}

forward_clock!(Box<C>, std::sync::Arc<C>);

/// Why a clock could not be opened.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ClockError {
    /// The clock spec is neither `wall` nor `sim:<name>`.
    #[error("clock spec {spec:?} is not `wall` or `sim:<name>`")]
    BadSpec {
        /// The spec given.
        spec: String,
    },
    /// A simulated clock's name has characters other than ASCII letters, digits, `-`, `_`,
    /// `.`, or is empty or longer than 64 bytes.
    #[error("simulated clock name {name:?} must be 1-64 ASCII letters, digits, '-', '_' or '.'")]
    BadName {
        /// The name given.
        name: String,
    },
    /// No host created the simulated clock within the wait.
    #[error("no simulated clock {name:?} appeared within {waited:?} (is the HIL world running?)")]
    NoHost {
        /// Clock name.
        name: String,
        /// How long we waited.
        waited: Duration,
    },
    /// The shared-memory file exists but is not a clock of this version.
    #[error("{path} is not a grop simulated clock of this version")]
    Incompatible {
        /// The file.
        path: String,
    },
    /// Every participant slot is taken.
    #[error("simulated clock {name:?} has no free participant slot (max {max})")]
    Full {
        /// Clock name.
        name: String,
        /// Slots.
        max: usize,
    },
    /// The operating system refused (open, truncate, map).
    #[error("simulated clock {path}: {stage}: {source}")]
    Os {
        /// The file.
        path: String,
        /// What we were doing.
        stage: &'static str,
        /// The error.
        source: std::io::Error,
    },
}

/// Opens the clock a deployment names: `wall`, or `sim:<name>` to join the simulated clock
/// `<name>` as a participant called `participant` with `rank` (lower ranks run first at each
/// instant). Waits up to 10 s for the simulated clock's host to appear.
pub fn open(spec: &str, participant: &str, rank: u32) -> Result<Box<dyn Clock>, ClockError> {
    if spec == "wall" {
        return Ok(Box::new(WallClock));
    }
    match spec.strip_prefix("sim:") {
        Some(name) => Ok(Box::new(SimClock::join(
            name,
            participant,
            rank,
            Duration::from_secs(10),
        )?)),
        None => Err(ClockError::BadSpec {
            spec: spec.to_owned(),
        }),
    }
}

/// Nanoseconds in `d`, saturating at `u64::MAX` (584 years): how every message stamps a
/// [`Duration`] of the runtime clock. The one conversion the workspace uses.
pub fn duration_ns(d: Duration) -> u64 {
    u64::try_from(d.as_nanos()).unwrap_or(u64::MAX)
}

/// The host's `CLOCK_MONOTONIC`: the same time base in every process of the machine.
#[derive(Debug, Clone, Copy, Default)]
pub struct WallClock;

/// `CLOCK_MONOTONIC` now.
pub fn monotonic_now() -> Duration {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: `ts` is a valid, writable timespec; CLOCK_MONOTONIC always exists on Linux.
    unsafe { libc::clock_gettime(libc::CLOCK_MONOTONIC, &mut ts) };
    Duration::new(ts.tv_sec as u64, ts.tv_nsec as u32)
}

impl Clock for WallClock {
    fn now(&self) -> Duration {
        monotonic_now()
    }

    fn sleep_until(&self, deadline: Duration) {
        let ts = libc::timespec {
            tv_sec: deadline.as_secs().min(i64::MAX as u64) as libc::time_t,
            tv_nsec: deadline.subsec_nanos() as libc::c_long,
        };
        loop {
            // SAFETY: `ts` is a valid timespec; a null remainder is allowed with TIMER_ABSTIME.
            let rc = unsafe {
                libc::clock_nanosleep(
                    libc::CLOCK_MONOTONIC,
                    libc::TIMER_ABSTIME,
                    &ts,
                    std::ptr::null_mut(),
                )
            };
            // Interrupted by a signal: the deadline is absolute, so sleep again.
            if rc != libc::EINTR {
                return;
            }
        }
    }
}

/// Checks a simulated clock's name (it becomes a file name under /dev/shm).
pub(crate) fn check_name(name: &str) -> Result<(), ClockError> {
    let ok = !name.is_empty()
        && name.len() <= 64
        && name
            .bytes()
            .all(|b| b.is_ascii_alphanumeric() || b"-_.".contains(&b));
    if ok {
        Ok(())
    } else {
        Err(ClockError::BadName {
            name: name.to_owned(),
        })
    }
}

/// Whether process `pid` exists and is not a zombie (a killed child its parent has not reaped
/// yet still answers `kill(pid, 0)`, so /proc is asked first).
pub(crate) fn pid_alive(pid: u32) -> bool {
    if pid == 0 {
        return false;
    }
    match std::fs::read_to_string(format!("/proc/{pid}/stat")) {
        // The state letter follows the parenthesised command name.
        Ok(stat) => {
            let state = stat
                .rfind(')')
                .and_then(|i| stat[i + 1..].trim_start().chars().next());
            !matches!(state, Some('Z' | 'X' | 'x'))
        }
        Err(_) => {
            // No /proc: fall back to signal 0, which only checks existence and permission.
            // SAFETY: signal 0 sends nothing.
            let rc = unsafe { libc::kill(pid as libc::pid_t, 0) };
            rc == 0 || std::io::Error::last_os_error().raw_os_error() == Some(libc::EPERM)
        }
    }
}
