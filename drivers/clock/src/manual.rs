//! A clock for tests: time moves only when the test sets it or a sleep jumps to its deadline.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU32, AtomicU64, Ordering};
use std::time::Duration;

use crate::{Clock, duration_ns};

/// A simulated clock the test drives: [`ManualClock::set`] and [`ManualClock::advance`] move
/// it, and a `sleep_until` jumps to its deadline at once (a loop on it runs as fast as it can,
/// tick for tick). Worker holds are counted ([`ManualClock::holds`]): a test that steps the
/// clock itself waits for them to end, as the simulated clock's host does. Optionally a flag is
/// raised once a sleep reaches an end time ([`ManualClock::until`]), to stop a loop that runs on
/// the clock after so much clock time.
#[derive(Debug, Default)]
pub struct ManualClock {
    now_ns: AtomicU64,
    holds: AtomicU32,
    end: Option<(Duration, Arc<AtomicBool>)>,
}

impl ManualClock {
    /// A clock at zero.
    pub fn new() -> Self {
        Self::default()
    }

    /// A clock at zero that raises the returned flag once a sleep reaches `end`.
    pub fn until(end: Duration) -> (Self, Arc<AtomicBool>) {
        let flag = Arc::new(AtomicBool::new(false));
        (
            Self {
                end: Some((end, Arc::clone(&flag))),
                ..Self::default()
            },
            flag,
        )
    }

    /// Sets the time (it may go back: the test's business).
    pub fn set(&self, now: Duration) {
        self.now_ns.store(duration_ns(now), Ordering::SeqCst);
    }

    /// Moves the time forward by `step`.
    pub fn advance(&self, step: Duration) {
        self.now_ns.fetch_add(duration_ns(step), Ordering::SeqCst);
    }

    /// Worker holds open now.
    pub fn holds(&self) -> u32 {
        self.holds.load(Ordering::Acquire)
    }
}

impl Clock for ManualClock {
    fn now(&self) -> Duration {
        Duration::from_nanos(self.now_ns.load(Ordering::SeqCst))
    }

    fn sleep_until(&self, deadline: Duration) {
        self.now_ns
            .fetch_max(duration_ns(deadline), Ordering::SeqCst);
        if let Some((end, flag)) = &self.end
            && deadline >= *end
        {
            flag.store(true, Ordering::SeqCst);
        }
    }

    fn begin_hold(&self) {
        self.holds.fetch_add(1, Ordering::AcqRel);
    }

    fn end_hold(&self) {
        self.holds.fetch_sub(1, Ordering::AcqRel);
    }

    fn is_simulated(&self) -> bool {
        // Time moves only when the test moves it: a loop must run on its ticks.
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn time_moves_only_when_set_advanced_or_slept_to() {
        let (clock, end) = ManualClock::until(Duration::from_secs(2));
        assert_eq!(clock.now(), Duration::ZERO);
        clock.advance(Duration::from_millis(500));
        clock.sleep_until(Duration::from_millis(200)); // in the past: no change
        assert_eq!(clock.now(), Duration::from_millis(500));
        clock.sleep_until(Duration::from_secs(1));
        assert_eq!(clock.now(), Duration::from_secs(1));
        assert!(!end.load(Ordering::SeqCst));
        clock.sleep_until(Duration::from_secs(2));
        assert!(end.load(Ordering::SeqCst));
        clock.begin_hold();
        assert_eq!(clock.holds(), 1);
        clock.end_hold();
        assert_eq!(clock.holds(), 0);
        clock.set(Duration::ZERO);
        assert_eq!(clock.now(), Duration::ZERO);
    }
}
