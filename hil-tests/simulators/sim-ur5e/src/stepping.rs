//! Lock-step support: how the simulator is clocked, and the two hand-shakes that make an
//! externally stepped controller deterministic.
//!
//! With [`Stepping::External`] no control thread runs; the owner (the HIL world, which owns the
//! simulated clock) calls [`crate::Ur5eSim::step`]. For a step to mean the same thing however
//! fast or slow the machine is, two races with the per-connection threads are closed:
//!
//! - **Input before the step.** Whatever a client had written before `step()` was called
//!   (a URScript program on 30001/30002/30003, RTDE inputs such as the watchdog heartbeat) is
//!   applied before the model advances. Each such reader thread waits for data with a blocking
//!   `peek` while marked idle and marks itself busy before it consumes the bytes; `step()` waits
//!   until every reader is idle *and* its socket's receive queue is empty (`FIONREAD`). On an
//!   idle machine a loopback `write` has put its bytes into our receive queue by the time it
//!   returns, so "written before `step()`" is "applied in this step"; under load the kernel
//!   may defer loopback delivery by milliseconds, and such bytes are applied a few steps later
//!   (a known gap, docs/ur5e.md).
//! - **Output after the step.** Every RTDE streamer acknowledges each sequence number it has
//!   handled (written its data package, or decided it was not due: paused, not started, output
//!   divisor), and `step()` returns only when every streamer has handled the new one. So when
//!   `step()` returns, the package of this cycle is already in the client's receive queue.
//!
//! Both waits are bounded ([`STEP_WAIT`]) so a stuck client cannot hang the world; a step that
//! gave up says so in its [`StepReport`].
//!
//! Request/reply services (dashboard, gripper socket) answer from their threads at once: their
//! clients wait for the reply, so they are never in flight across a step.
#![allow(
    unsafe_code,
    reason = "ioctl(FIONREAD): bytes waiting on a socket, without reading them"
)]

use std::io;
use std::net::TcpStream;
use std::os::fd::AsRawFd;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use thiserror::Error;

/// How the controller model is clocked.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum Stepping {
    /// A control thread steps the model every `1 / rate_hz` of wall time on absolute
    /// deadlines, as the real controller does (the simulator as its own process, ur_rtde checks,
    /// jitter benchmark).
    #[default]
    WallClock,
    /// No control thread: the owner calls [`crate::Ur5eSim::step`], one period per call, so a
    /// world with a simulated clock runs the arm in lock-step, faster than real time, and a
    /// stopped world stops everything the model does (motion, `sleep`, gripper, RTDE watchdog).
    External,
}

/// Longest wall time `step()` waits for readers to drain and for streamers to write, each.
pub const STEP_WAIT: Duration = Duration::from_millis(200);

/// What one external step did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepReport {
    /// Controller cycle after the step (1 after the first step).
    pub cycle: u64,
    /// Controller time after the step (s): `cycle / rate_hz`, the RTDE `timestamp`.
    pub time_s: f64,
    /// RTDE connections that wrote a data package for this cycle.
    pub rtde_packages_written: usize,
    /// RTDE connections that had not handled this cycle within [`STEP_WAIT`] (a client that
    /// does not read until its socket buffer is full); 0 in a healthy lock-step.
    pub rtde_lagging: usize,
    /// Input readers still holding unapplied bytes after [`STEP_WAIT`]; 0 when healthy.
    pub inputs_lagging: usize,
}

/// Why [`crate::Ur5eSim::step`] refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Error)]
#[non_exhaustive]
pub enum StepError {
    /// The simulator runs its own control thread ([`Stepping::WallClock`]).
    #[error("the simulator is wall-clock stepped; external step() needs Stepping::External")]
    NotExternal,
}

/// The idle/busy hand-shake of one connection's reader thread (see the module docs).
#[derive(Debug)]
pub(crate) struct ReaderSync {
    /// True from the moment the reader saw data until it has processed what it read. Starts
    /// true: a reader that has not reached its first wait has not drained anything.
    busy: AtomicBool,
    /// A clone of the connection's socket, so the descriptor stays valid while registered.
    socket: TcpStream,
}

impl ReaderSync {
    pub fn new(stream: &TcpStream) -> io::Result<Self> {
        Ok(Self {
            busy: AtomicBool::new(true),
            socket: stream.try_clone()?,
        })
    }

    /// Called by the reader before each read: marks it idle, waits until data (or EOF) is
    /// there without consuming it, then marks it busy. Returns 0 on EOF.
    pub fn wait_for_data(&self, stream: &TcpStream) -> io::Result<usize> {
        self.busy.store(false, Ordering::SeqCst);
        let mut probe = [0u8; 1];
        let result = loop {
            match stream.peek(&mut probe) {
                Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
                other => break other,
            }
        };
        self.busy.store(true, Ordering::SeqCst);
        result
    }

    /// Everything that arrived has been processed. The queue is read before the flag: bytes
    /// consumed before an empty queue was seen were consumed while busy, and busy clears only
    /// after they were processed.
    pub fn drained(&self) -> bool {
        pending_bytes(&self.socket) == 0 && !self.busy.load(Ordering::SeqCst)
    }
}

/// Bytes in the socket's receive queue (`FIONREAD`); 0 when it cannot be asked (closed).
fn pending_bytes(socket: &TcpStream) -> usize {
    let mut n: libc::c_int = 0;
    // SAFETY: FIONREAD writes one c_int through the pointer, which points at `n`; the
    // descriptor is owned by `socket` and open for the duration of the call.
    let rc = unsafe { libc::ioctl(socket.as_raw_fd(), libc::FIONREAD, &mut n) };
    if rc == 0 {
        usize::try_from(n).unwrap_or(0)
    } else {
        0
    }
}

/// One RTDE streamer's acknowledgement: the newest sequence number it has handled and the
/// newest it has written to its socket.
#[derive(Debug, Clone, Copy)]
pub(crate) struct AckSlot {
    pub conn: u64,
    pub handled: u64,
    pub written: u64,
}

/// Waits (bounded by `deadline`, wall) until every reader is drained; returns how many are not.
pub(crate) fn wait_drained(
    readers: &std::sync::Mutex<Vec<(u64, std::sync::Arc<ReaderSync>)>>,
) -> usize {
    let deadline = Instant::now() + STEP_WAIT;
    loop {
        let pending = lock(readers).iter().filter(|(_, r)| !r.drained()).count();
        if pending == 0 || Instant::now() >= deadline {
            return pending;
        }
        std::thread::yield_now();
    }
}

/// Locks a mutex, recovering from a panicked holder (the data is plain state).
pub(crate) fn lock<T>(m: &std::sync::Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}
