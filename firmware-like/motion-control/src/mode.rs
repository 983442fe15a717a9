//! Mode changes on a device that reports its mode in feedback: send the request, resend it at a
//! fixed interval until the device reports the wanted mode, give up after a timeout.
//!
//! Generic over the mode type so the same sequencer serves the RMP (requested "tractor",
//! reported state 4) and other devices; the caller maps request to expected report.

/// What the caller should do this period.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ModeStep<M> {
    /// Nothing requested, or the target is reached and confirmed.
    Idle,
    /// Send this request now.
    Send(M),
    /// Request sent; waiting for the report.
    Waiting,
    /// The device now reports the target (returned once, then `Idle`).
    Reached(M),
    /// The device did not report the target in time (returned once, then `Idle`).
    TimedOut {
        /// The mode that was wanted.
        target: M,
        /// The last mode the device reported, if any.
        reported: Option<M>,
    },
}

/// Mode-request sequencer.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ModeSequencer<M> {
    resend_us: u64,
    timeout_us: u64,
    target: Option<M>,
    reported: Option<M>,
    requested_at_us: u64,
    last_sent_us: Option<u64>,
    reached: bool,
}

impl<M: Copy + PartialEq> ModeSequencer<M> {
    /// Resend every `resend_us`, give up after `timeout_us`.
    pub const fn new(resend_us: u64, timeout_us: u64) -> Self {
        Self {
            resend_us,
            timeout_us,
            target: None,
            reported: None,
            requested_at_us: 0,
            last_sent_us: None,
            reached: false,
        }
    }

    /// Starts a request for `target` (restarts the timeout).
    pub fn request(&mut self, target: M, now_us: u64) {
        self.target = Some(target);
        self.requested_at_us = now_us;
        self.last_sent_us = None;
        self.reached = false;
    }

    /// Abandons the request in progress.
    pub fn cancel(&mut self) {
        self.target = None;
    }

    /// Records the mode the device reported.
    pub fn on_reported(&mut self, mode: M) {
        self.reported = Some(mode);
    }

    /// Last reported mode.
    pub const fn reported(&self) -> Option<M> {
        self.reported
    }

    /// The pending target, if a request is in progress.
    pub const fn pending(&self) -> Option<M> {
        if self.reached { None } else { self.target }
    }

    /// Decides this period's action.
    pub fn poll(&mut self, now_us: u64) -> ModeStep<M> {
        let Some(target) = self.target else {
            return ModeStep::Idle;
        };
        if self.reached {
            return ModeStep::Idle;
        }
        if self.reported == Some(target) && self.last_sent_us.is_some() {
            self.reached = true;
            return ModeStep::Reached(target);
        }
        if now_us.saturating_sub(self.requested_at_us) > self.timeout_us {
            self.target = None;
            return ModeStep::TimedOut {
                target,
                reported: self.reported,
            };
        }
        match self.last_sent_us {
            Some(t) if now_us.saturating_sub(t) < self.resend_us => ModeStep::Waiting,
            _ => {
                self.last_sent_us = Some(now_us);
                ModeStep::Send(target)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug, Clone, Copy, PartialEq, Eq)]
    enum Mode {
        Standby,
        Tractor,
    }

    #[test]
    fn sends_resends_and_confirms() {
        let mut s = ModeSequencer::new(100_000, 1_000_000);
        assert_eq!(s.poll(0), ModeStep::Idle);
        s.on_reported(Mode::Standby);
        s.request(Mode::Tractor, 0);
        assert_eq!(s.poll(0), ModeStep::Send(Mode::Tractor));
        assert_eq!(s.poll(50_000), ModeStep::Waiting);
        assert_eq!(s.poll(100_000), ModeStep::Send(Mode::Tractor));
        s.on_reported(Mode::Tractor);
        assert_eq!(s.poll(120_000), ModeStep::Reached(Mode::Tractor));
        assert_eq!(s.poll(140_000), ModeStep::Idle);
        assert_eq!(s.pending(), None);
    }

    #[test]
    fn already_in_mode_still_sends_once() {
        // The report may predate a device reset; confirm with at least one request.
        let mut s = ModeSequencer::new(100_000, 1_000_000);
        s.on_reported(Mode::Tractor);
        s.request(Mode::Tractor, 0);
        assert_eq!(s.poll(0), ModeStep::Send(Mode::Tractor));
        assert_eq!(s.poll(10), ModeStep::Reached(Mode::Tractor));
    }

    #[test]
    fn times_out_with_the_last_report() {
        let mut s = ModeSequencer::new(100_000, 300_000);
        s.on_reported(Mode::Standby);
        s.request(Mode::Tractor, 0);
        let mut sends = 0;
        let mut t = 0;
        loop {
            match s.poll(t) {
                ModeStep::Send(_) => sends += 1,
                ModeStep::TimedOut { target, reported } => {
                    assert_eq!(target, Mode::Tractor);
                    assert_eq!(reported, Some(Mode::Standby));
                    break;
                }
                other => assert_eq!(other, ModeStep::Waiting),
            }
            t += 20_000;
        }
        assert_eq!(sends, 4);
        assert_eq!(s.poll(t), ModeStep::Idle);
    }
}
