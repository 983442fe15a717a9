//! Input freshness: an input older than the timeout (or never received) is stale, and whoever
//! moves hardware treats a stale input as "stop".

/// A deadline watchdog on a monotonic microsecond clock.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Watchdog {
    timeout_us: u64,
    last_feed_us: Option<u64>,
}

impl Watchdog {
    /// A watchdog that has never been fed (so it starts stale).
    pub const fn new(timeout_us: u64) -> Self {
        Self {
            timeout_us,
            last_feed_us: None,
        }
    }

    /// The timeout.
    pub const fn timeout_us(&self) -> u64 {
        self.timeout_us
    }

    /// Records a fresh input at `now_us`.
    pub fn feed(&mut self, now_us: u64) {
        self.last_feed_us = Some(now_us);
    }

    /// Forgets the last input (stale until fed again).
    pub fn clear(&mut self) {
        self.last_feed_us = None;
    }

    /// Age of the last input, `None` when never fed. A clock that went backwards reads as 0.
    pub fn age_us(&self, now_us: u64) -> Option<u64> {
        self.last_feed_us.map(|t| now_us.saturating_sub(t))
    }

    /// True when never fed or the last input is older than the timeout.
    pub fn is_stale(&self, now_us: u64) -> bool {
        match self.age_us(now_us) {
            None => true,
            Some(age) => age > self.timeout_us,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stale_until_fed_and_after_timeout() {
        let mut w = Watchdog::new(100_000);
        assert!(w.is_stale(0));
        w.feed(1_000);
        assert!(!w.is_stale(101_000));
        assert!(w.is_stale(101_001));
        assert_eq!(w.age_us(50_000), Some(49_000));
        // A clock step backwards does not make an old input look stale forever, nor panic.
        assert_eq!(w.age_us(0), Some(0));
        w.clear();
        assert!(w.is_stale(1_000));
    }
}
