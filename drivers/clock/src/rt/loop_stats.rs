//! The loop's lateness histogram and summary: fixed capacity, no allocation.

use core::fmt;
use std::time::Duration;

/// Lateness histogram: 1 us buckets up to this many microseconds ...
const FINE_BUCKETS: usize = 2000;
/// ... then 100 us buckets up to 100 ms ...
const COARSE_BUCKET_US: u64 = 100;
const COARSE_BUCKETS: usize = 980;
/// ... then one bucket for everything later (its exact maximum is kept apart).
pub(super) const BUCKETS: usize = FINE_BUCKETS + COARSE_BUCKETS + 1;
const FINE_LIMIT_US: u64 = FINE_BUCKETS as u64;
const COARSE_LIMIT_US: u64 = FINE_LIMIT_US + COARSE_BUCKETS as u64 * COARSE_BUCKET_US;

/// Period and lateness recorder for a cyclic loop on absolute deadlines: fixed capacity, no
/// allocation (the histogram is an inline array, about 12 KiB), `Copy`-free but cheap to keep
/// in the loop's state.
///
/// Lateness is how long after its deadline a cycle woke; resolution 1 us up to 2 ms, 100 us
/// up to 100 ms, one bucket beyond; the maximum is exact. Percentiles report the upper edge of
/// the bucket holding the rank (never below the truth), capped at the exact maximum.
#[derive(Clone)]
pub struct LoopStats {
    period: Duration,
    buckets: [u32; BUCKETS],
    count: u64,
    overruns: u64,
    early: u64,
    max_ns: u64,
    sum_ns: u128,
}

impl fmt::Debug for LoopStats {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("LoopStats")
            .field("period", &self.period)
            .field("summary", &self.summary())
            .finish_non_exhaustive()
    }
}

/// Lateness percentiles and counters of a [`LoopStats`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct LoopSummary {
    /// The loop's period.
    pub period: Duration,
    /// Cycles recorded.
    pub count: u64,
    /// Median lateness.
    pub p50: Duration,
    /// 99th percentile lateness.
    pub p99: Duration,
    /// 99.9th percentile lateness.
    pub p999: Duration,
    /// Largest lateness (exact).
    pub max: Duration,
    /// Mean lateness.
    pub mean: Duration,
    /// Cycles whose work ended after the next deadline.
    pub overruns: u64,
    /// Wake-ups before the deadline (should be 0 with absolute sleeps; counted as lateness 0).
    pub early: u64,
}

impl fmt::Display for LoopSummary {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let us = |d: Duration| d.as_secs_f64() * 1e6;
        write!(
            f,
            "{} cycles of {:?}: lateness p50 {:.0} us, p99 {:.0} us, p99.9 {:.0} us, max {:.0} us, mean {:.1} us; {} overruns",
            self.count,
            self.period,
            us(self.p50),
            us(self.p99),
            us(self.p999),
            us(self.max),
            us(self.mean),
            self.overruns
        )?;
        if self.early > 0 {
            write!(f, ", {} early wake-ups", self.early)?;
        }
        Ok(())
    }
}

impl LoopStats {
    /// An empty recorder for a loop of `period`.
    pub fn new(period: Duration) -> Self {
        Self {
            period,
            buckets: [0; BUCKETS],
            count: 0,
            overruns: 0,
            early: 0,
            max_ns: 0,
            sum_ns: 0,
        }
    }

    /// Records one wake-up: the cycle's `deadline` and when it woke, on the same clock.
    pub fn record(&mut self, deadline: Duration, woke_at: Duration) {
        if woke_at < deadline {
            self.early += 1;
        }
        let late_ns =
            u64::try_from(woke_at.saturating_sub(deadline).as_nanos()).unwrap_or(u64::MAX);
        self.record_lateness_ns(late_ns);
    }

    /// Records one lateness value directly.
    pub fn record_lateness_ns(&mut self, late_ns: u64) {
        let index = bucket_of(late_ns);
        self.buckets[index] = self.buckets[index].saturating_add(1);
        self.count += 1;
        self.max_ns = self.max_ns.max(late_ns);
        self.sum_ns += u128::from(late_ns);
    }

    /// Counts one overrun: a cycle whose work ended after the next deadline.
    pub fn record_overrun(&mut self) {
        self.overruns += 1;
    }

    /// Records the end of a cycle's work; counts an overrun if it is after `next_deadline`.
    /// Returns whether it overran.
    pub fn record_end(&mut self, end: Duration, next_deadline: Duration) -> bool {
        let overran = end > next_deadline;
        if overran {
            self.record_overrun();
        }
        overran
    }

    /// Cycles recorded.
    pub fn count(&self) -> u64 {
        self.count
    }

    /// Overruns counted.
    pub fn overruns(&self) -> u64 {
        self.overruns
    }

    /// Largest lateness (exact).
    pub fn max(&self) -> Duration {
        Duration::from_nanos(self.max_ns)
    }

    /// The loop's period.
    pub fn period(&self) -> Duration {
        self.period
    }

    /// Lateness at percentile `p` (0..=100, clamped) by nearest rank; `None` before the first
    /// record. `p = 100` is the exact maximum.
    pub fn percentile(&self, p: f64) -> Option<Duration> {
        if self.count == 0 {
            return None;
        }
        let p = if p.is_nan() {
            100.0
        } else {
            p.clamp(0.0, 100.0)
        };
        if p >= 100.0 {
            return Some(self.max());
        }
        // Nearest rank, 1-based: ceil(p/100 * n), at least 1.
        let rank = ((p / 100.0) * self.count as f64).ceil().max(1.0) as u64;
        let mut seen = 0u64;
        for (index, &n) in self.buckets.iter().enumerate() {
            seen += u64::from(n);
            if seen >= rank {
                return Some(Duration::from_nanos(
                    bucket_upper_ns(index).min(self.max_ns),
                ));
            }
        }
        Some(self.max())
    }

    /// p50, p99, p99.9, max, mean and the counters.
    pub fn summary(&self) -> LoopSummary {
        let at = |p| self.percentile(p).unwrap_or_default();
        let mean_ns = if self.count == 0 {
            0
        } else {
            u64::try_from(self.sum_ns / u128::from(self.count)).unwrap_or(u64::MAX)
        };
        LoopSummary {
            period: self.period,
            count: self.count,
            p50: at(50.0),
            p99: at(99.0),
            p999: at(99.9),
            max: self.max(),
            mean: Duration::from_nanos(mean_ns),
            overruns: self.overruns,
            early: self.early,
        }
    }

    /// Forgets every record (keeps the period).
    pub fn reset(&mut self) {
        *self = Self::new(self.period);
    }
}

pub(super) fn bucket_of(late_ns: u64) -> usize {
    let us = late_ns / 1000;
    if us < FINE_LIMIT_US {
        us as usize
    } else if us < COARSE_LIMIT_US {
        FINE_BUCKETS + ((us - FINE_LIMIT_US) / COARSE_BUCKET_US) as usize
    } else {
        BUCKETS - 1
    }
}

/// Upper edge (exclusive) of bucket `index`, ns; the overflow bucket has none (u64::MAX, which
/// the caller caps at the exact maximum).
pub(super) fn bucket_upper_ns(index: usize) -> u64 {
    if index < FINE_BUCKETS {
        (index as u64 + 1) * 1000
    } else if index < BUCKETS - 1 {
        (FINE_LIMIT_US + (index - FINE_BUCKETS + 1) as u64 * COARSE_BUCKET_US) * 1000
    } else {
        u64::MAX
    }
}
