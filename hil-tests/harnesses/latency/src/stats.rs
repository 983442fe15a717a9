//! Latency samples summarised as the report wants them: count, p50, p99, max (nearest rank).

use core::fmt;

/// Summary of latency samples, nanoseconds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Summary {
    /// Samples.
    pub count: usize,
    /// Median.
    pub p50_ns: u64,
    /// 99th percentile.
    pub p99_ns: u64,
    /// Largest.
    pub max_ns: u64,
}

impl Summary {
    /// Summarises `samples` (sorted in place). An empty slice gives all zeros.
    pub fn of(samples: &mut [u64]) -> Self {
        samples.sort_unstable();
        Self {
            count: samples.len(),
            p50_ns: nearest_rank(samples, 50.0),
            p99_ns: nearest_rank(samples, 99.0),
            max_ns: samples.last().copied().unwrap_or(0),
        }
    }

    /// p50 in microseconds.
    pub fn p50_us(&self) -> f64 {
        self.p50_ns as f64 / 1e3
    }

    /// p99 in microseconds.
    pub fn p99_us(&self) -> f64 {
        self.p99_ns as f64 / 1e3
    }

    /// max in microseconds.
    pub fn max_us(&self) -> f64 {
        self.max_ns as f64 / 1e3
    }

    /// Whether p50 <= p99 <= max (always true of a summary made by [`Summary::of`]).
    pub fn is_ordered(&self) -> bool {
        self.p50_ns <= self.p99_ns && self.p99_ns <= self.max_ns
    }
}

impl fmt::Display for Summary {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "p50 {} / p99 {} / max {} (n = {})",
            format_us(self.p50_ns),
            format_us(self.p99_ns),
            format_us(self.max_ns),
            self.count
        )
    }
}

/// Nearest-rank percentile of sorted samples (0 for none).
pub fn nearest_rank(sorted: &[u64], p: f64) -> u64 {
    if sorted.is_empty() {
        return 0;
    }
    let rank = ((p.clamp(0.0, 100.0) / 100.0) * sorted.len() as f64).ceil() as usize;
    sorted[rank.clamp(1, sorted.len()) - 1]
}

/// Nanoseconds as microseconds with a precision that suits the size (`0.42 us`, `37.1 us`,
/// `1,204 us`).
pub fn format_us(ns: u64) -> String {
    let us = ns as f64 / 1e3;
    if us < 10.0 {
        format!("{us:.2} us")
    } else if us < 1000.0 {
        format!("{us:.1} us")
    } else {
        format!("{} us", thousands(us.round() as u64))
    }
}

/// `1234567` as `1,234,567`.
pub fn thousands(n: u64) -> String {
    let digits = n.to_string();
    let mut out = String::with_capacity(digits.len() + digits.len() / 3);
    for (i, c) in digits.chars().enumerate() {
        if i > 0 && (digits.len() - i) % 3 == 0 {
            out.push(',');
        }
        out.push(c);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nearest_rank_percentiles() {
        let mut v: Vec<u64> = (1..=100).rev().collect();
        let s = Summary::of(&mut v);
        assert_eq!((s.count, s.p50_ns, s.p99_ns, s.max_ns), (100, 50, 99, 100));
        assert!(s.is_ordered());
        let s = Summary::of(&mut [7]);
        assert_eq!((s.p50_ns, s.p99_ns, s.max_ns), (7, 7, 7));
        assert_eq!(Summary::of(&mut []), Summary::default());
    }

    #[test]
    fn formatting() {
        assert_eq!(format_us(420), "0.42 us");
        assert_eq!(format_us(37_149), "37.1 us");
        assert_eq!(format_us(1_204_400), "1,204 us");
        assert_eq!(thousands(1_234_567), "1,234,567");
        assert_eq!(thousands(12), "12");
    }
}
