//! Blocking device I/O off the control thread: an [`IoWorker`] owns a device in its own thread
//! and serves one request at a time; the cycle hands a request over and waits for the answer
//! only up to a deadline. An answer that misses it is picked up by a later cycle
//! ([`IoWorker::late_answer`]), and while a request is out the worker takes no other: the
//! cycle goes on with what it last knew and judges the silence on its own clock.
//!
//! This is the shell's seam for the arm (`ur5e_arm.rs`): the gripper's and the dashboard's
//! replies may take seconds (their sockets' timeouts), the base loop on the cycle's thread may
//! not wait for them. Requests and answers travel through bounded channels, by value: nothing
//! allocates per request.

use std::sync::mpsc::{
    Receiver, RecvTimeoutError, SyncSender, TryRecvError, TrySendError, sync_channel,
};
use std::time::Duration;

/// What became of a request handed to [`IoWorker::call`].
#[derive(Debug)]
pub enum Call<Req, Ans> {
    /// Answered within the wait.
    Answered(Ans),
    /// Handed over but not answered within the wait: the answer comes through
    /// [`IoWorker::late_answer`].
    Pending,
    /// Not handed over: the worker still serves an earlier request (or is gone). The request
    /// comes back to the caller.
    Busy(Req),
}

/// A thread that owns a device and serves requests one at a time.
pub struct IoWorker<Req, Ans> {
    requests: SyncSender<Req>,
    answers: Receiver<Ans>,
    /// A request is out and its answer has not been taken.
    outstanding: bool,
    /// The worker thread has ended (its device is gone).
    gone: bool,
    wait: Duration,
}

impl<Req, Ans> std::fmt::Debug for IoWorker<Req, Ans> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("IoWorker")
            .field("outstanding", &self.outstanding)
            .field("gone", &self.gone)
            .field("wait", &self.wait)
            .finish_non_exhaustive()
    }
}

impl<Req: Send + 'static, Ans: Send + 'static> IoWorker<Req, Ans> {
    /// Starts a thread called `name` that answers every request with `serve` (which owns the
    /// device); the caller waits at most `wait` (wall time) for each answer.
    pub fn spawn(
        name: &str,
        wait: Duration,
        mut serve: impl FnMut(Req) -> Ans + Send + 'static,
    ) -> std::io::Result<Self> {
        let (requests, inbox) = sync_channel::<Req>(1);
        let (outbox, answers) = sync_channel::<Ans>(1);
        std::thread::Builder::new()
            .name(name.to_owned())
            .spawn(move || {
                for request in inbox {
                    if outbox.send(serve(request)).is_err() {
                        return;
                    }
                }
            })?;
        Ok(Self {
            requests,
            answers,
            outstanding: false,
            gone: false,
            wait,
        })
    }
}

impl<Req, Ans> IoWorker<Req, Ans> {
    /// How long [`Self::call`] waits for an answer.
    pub fn wait(&self) -> Duration {
        self.wait
    }

    /// True while a request is out unanswered (the device is busy, perhaps blocked).
    pub fn is_busy(&self) -> bool {
        self.outstanding
    }

    /// True once the worker thread has ended.
    pub fn is_gone(&self) -> bool {
        self.gone
    }

    /// The answer to a request that missed its wait, if it has come since.
    pub fn late_answer(&mut self) -> Option<Ans> {
        if !self.outstanding {
            return None;
        }
        match self.answers.try_recv() {
            Ok(answer) => {
                self.outstanding = false;
                Some(answer)
            }
            Err(TryRecvError::Empty) => None,
            Err(TryRecvError::Disconnected) => {
                self.gone = true;
                None
            }
        }
    }

    /// Hands `request` over if the worker is free and waits up to [`Self::wait`] for its
    /// answer. A late answer still waiting must be taken first ([`Self::late_answer`]):
    /// until then the worker counts as busy.
    pub fn call(&mut self, request: Req) -> Call<Req, Ans> {
        if self.outstanding || self.gone {
            return Call::Busy(request);
        }
        match self.requests.try_send(request) {
            Ok(()) => {}
            // Full cannot happen with one request out at most; either way it is not taken.
            Err(TrySendError::Full(r)) => return Call::Busy(r),
            Err(TrySendError::Disconnected(r)) => {
                self.gone = true;
                return Call::Busy(r);
            }
        }
        self.outstanding = true;
        match self.answers.recv_timeout(self.wait) {
            Ok(answer) => {
                self.outstanding = false;
                Call::Answered(answer)
            }
            Err(RecvTimeoutError::Timeout) => Call::Pending,
            Err(RecvTimeoutError::Disconnected) => {
                self.gone = true;
                Call::Pending
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Instant;

    #[test]
    fn a_fast_device_answers_within_the_call() {
        let mut w = IoWorker::spawn("t-fast", Duration::from_secs(5), |x: u32| x * 2).unwrap();
        for i in 0..100 {
            match w.call(i) {
                Call::Answered(a) => assert_eq!(a, 2 * i),
                other => panic!("{other:?}"),
            }
        }
        assert!(!w.is_busy());
    }

    #[test]
    fn a_blocked_device_does_not_hold_up_the_caller_and_answers_late() {
        let mut w = IoWorker::spawn("t-slow", Duration::from_millis(5), |ms: u64| {
            std::thread::sleep(Duration::from_millis(ms));
            ms
        })
        .unwrap();
        let t0 = Instant::now();
        assert!(matches!(w.call(300), Call::Pending));
        // While it works, further requests come back at once.
        for _ in 0..10 {
            assert!(matches!(w.call(1), Call::Busy(1)));
        }
        assert!(w.is_busy());
        assert!(
            t0.elapsed() < Duration::from_millis(200),
            "the caller waited {:?}",
            t0.elapsed()
        );
        let mut late = None;
        while late.is_none() {
            assert!(t0.elapsed() < Duration::from_secs(10), "no late answer");
            std::thread::sleep(Duration::from_millis(5));
            late = w.late_answer();
        }
        assert_eq!(late, Some(300));
        assert!(matches!(w.call(0), Call::Answered(0)));
    }

    #[test]
    fn a_worker_that_died_is_gone_not_busy_for_ever() {
        let mut w = IoWorker::spawn("t-dies", Duration::from_secs(5), |x: u32| {
            assert!(x != 7, "device panics");
            x
        })
        .unwrap();
        assert!(matches!(w.call(1), Call::Answered(1)));
        assert!(matches!(w.call(7), Call::Pending));
        assert!(w.is_gone());
        assert!(matches!(w.call(1), Call::Busy(1)));
    }
}
