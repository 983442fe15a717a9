//! Conformance suite for [`CanBus`] backends, written once and run against every backend
//! (`tests/conformance.rs`): ordering, no self-reception, several nodes, timeouts, every DLC,
//! standard and extended ids, bursts, and the same over a peer in another thread or process.
//!
//! The suite needs the bus to itself while it runs (on SocketCAN: no other traffic on the
//! interface). Each case joins fresh nodes through the `join` closure and drops them at the end,
//! so frames of one case never leak into the next.
//!
//! Cross-process runs use an *echo peer* ([`echo_peer`], also `vcan echo <bus>`): it announces
//! itself with [`PEER_READY_ID`], echoes every frame unchanged, answers [`PEER_BURST_REQUEST_ID`]
//! with a numbered burst and leaves on [`PEER_STOP_ID`].

use std::time::{Duration, Instant};

use crate::{CanBus, CanFrame, CanId, MAX_DATA_LEN};

/// How long a case waits for a frame that must arrive (generous: CI machines are slow).
pub const RECEIVE_TIMEOUT: Duration = Duration::from_secs(5);
/// How long a case listens to conclude that nothing more arrives.
pub const QUIET_PERIOD: Duration = Duration::from_millis(100);

/// Sent once by the echo peer when it is listening.
pub const PEER_READY_ID: CanId = CanId::Extended(0x1FFF_FF00);
/// Asks the echo peer for a burst; data: burst length, u16 little-endian.
pub const PEER_BURST_REQUEST_ID: CanId = CanId::Extended(0x1FFF_FF01);
/// Frames of the echo peer's burst; data: index, u16 little-endian.
pub const PEER_BURST_FRAME_ID: CanId = CanId::Extended(0x1FFF_FF02);
/// Makes the echo peer return.
pub const PEER_STOP_ID: CanId = CanId::Extended(0x1FFF_FF0F);

/// A failed conformance check.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("CAN bus conformance case `{case}` failed: {detail}")]
pub struct ConformanceError {
    /// The case that failed.
    pub case: &'static str,
    /// What was expected and what happened.
    pub detail: String,
}

/// What the echo peer did before it was stopped.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct EchoStats {
    /// Frames echoed back unchanged.
    pub echoed: u64,
    /// Burst frames sent on request.
    pub burst_frames: u64,
}

type CaseResult = Result<(), ConformanceError>;

fn fail(case: &'static str, detail: impl Into<String>) -> ConformanceError {
    ConformanceError {
        case,
        detail: detail.into(),
    }
}

fn frame(case: &'static str, id: CanId, data: &[u8]) -> Result<CanFrame, ConformanceError> {
    CanFrame::new(id, data).map_err(|error| fail(case, error.to_string()))
}

fn send(case: &'static str, node: &mut impl CanBus, f: &CanFrame) -> CaseResult {
    node.send(f)
        .map_err(|error| fail(case, format!("send {f} failed: {error}")))
}

/// Receives one frame that must arrive within [`RECEIVE_TIMEOUT`].
fn expect_frame(
    case: &'static str,
    node: &mut impl CanBus,
    what: &str,
) -> Result<CanFrame, ConformanceError> {
    match node.recv_timeout(RECEIVE_TIMEOUT) {
        Ok(Some(f)) => Ok(f),
        Ok(None) => Err(fail(
            case,
            format!("{what}: nothing arrived within {RECEIVE_TIMEOUT:?}"),
        )),
        Err(error) => Err(fail(case, format!("{what}: receive failed: {error}"))),
    }
}

fn expect_exact(case: &'static str, node: &mut impl CanBus, expected: &CanFrame) -> CaseResult {
    let got = expect_frame(case, node, &format!("waiting for {expected}"))?;
    if got == *expected {
        Ok(())
    } else {
        Err(fail(case, format!("expected {expected}, received {got}")))
    }
}

fn expect_quiet(case: &'static str, node: &mut impl CanBus, why: &str) -> CaseResult {
    match node.recv_timeout(QUIET_PERIOD) {
        Ok(None) => Ok(()),
        Ok(Some(f)) => Err(fail(case, format!("{why}, but received {f}"))),
        Err(error) => Err(fail(case, format!("{why}, but receive failed: {error}"))),
    }
}

/// Every valid DLC with standard and extended ids at both ends of their ranges, including the
/// same number as a standard and as an extended id (they are different ids).
pub fn dlc_and_id_matrix() -> Vec<CanFrame> {
    let ids = [
        CanId::Standard(0),
        CanId::Standard(0x123),
        CanId::Standard(0x7FF),
        CanId::Extended(0),
        CanId::Extended(0x123),
        CanId::Extended(0x1FFF_FFFF),
    ];
    let mut frames = Vec::new();
    for id in ids {
        for len in 0..=MAX_DATA_LEN {
            let data: Vec<u8> = (0..len)
                .map(|i| (id.raw() as u8) ^ (0xA5u8.wrapping_add(17 * i as u8)))
                .collect();
            // Cannot fail: the ids above are in range and len <= 8.
            if let Ok(f) = CanFrame::new(id, &data) {
                frames.push(f);
            }
        }
    }
    frames
}

fn burst_frame(case: &'static str, id: CanId, index: usize) -> Result<CanFrame, ConformanceError> {
    let index = u16::try_from(index).map_err(|_| fail(case, "burst longer than 65535"))?;
    let [lo, hi] = index.to_le_bytes();
    frame(case, id, &[lo, hi, !lo, !hi])
}

/// A frame reaches the other node exactly once and never comes back to its sender.
pub fn no_self_reception<B: CanBus>(join: &mut impl FnMut() -> B) -> CaseResult {
    const CASE: &str = "no_self_reception";
    let (mut a, mut b) = (join(), join());
    let f = frame(CASE, CanId::Standard(0x321), &[1, 2, 3])?;
    send(CASE, &mut a, &f)?;
    expect_exact(CASE, &mut b, &f)?;
    expect_quiet(CASE, &mut a, "the sender must not receive its own frame")?;
    expect_quiet(CASE, &mut b, "the frame must arrive only once")
}

/// A burst of `burst_len` frames arrives complete and in order.
pub fn burst_in_order<B: CanBus>(join: &mut impl FnMut() -> B, burst_len: usize) -> CaseResult {
    const CASE: &str = "burst_in_order";
    let (mut a, mut b) = (join(), join());
    for index in 0..burst_len {
        send(
            CASE,
            &mut a,
            &burst_frame(CASE, CanId::Standard(0x100), index)?,
        )?;
    }
    for index in 0..burst_len {
        expect_exact(
            CASE,
            &mut b,
            &burst_frame(CASE, CanId::Standard(0x100), index)?,
        )?;
    }
    expect_quiet(CASE, &mut b, "the burst is complete")
}

/// Every DLC and both id kinds arrive bit-exact.
pub fn every_dlc_and_id_kind<B: CanBus>(join: &mut impl FnMut() -> B) -> CaseResult {
    const CASE: &str = "every_dlc_and_id_kind";
    let (mut a, mut b) = (join(), join());
    let frames = dlc_and_id_matrix();
    for f in &frames {
        send(CASE, &mut a, f)?;
    }
    for f in &frames {
        expect_exact(CASE, &mut b, f)?;
    }
    Ok(())
}

/// Three nodes: each receives the others' frames in bus order (a reply after the frame it
/// answers), none its own.
pub fn several_nodes<B: CanBus>(join: &mut impl FnMut() -> B) -> CaseResult {
    const CASE: &str = "several_nodes";
    let (mut a, mut b, mut c) = (join(), join(), join());
    let from_a = frame(CASE, CanId::Standard(0x10A), &[0xA])?;
    let from_b = frame(CASE, CanId::Extended(0x10B), &[0xB])?;
    let from_c = frame(CASE, CanId::Standard(0x10C), &[0xC])?;
    send(CASE, &mut a, &from_a)?;
    expect_exact(CASE, &mut b, &from_a)?;
    // b answers only after it saw a's frame: everybody else must see them in that order.
    send(CASE, &mut b, &from_b)?;
    expect_exact(CASE, &mut c, &from_a)?;
    expect_exact(CASE, &mut c, &from_b)?;
    send(CASE, &mut c, &from_c)?;
    expect_exact(CASE, &mut a, &from_b)?;
    expect_exact(CASE, &mut a, &from_c)?;
    expect_exact(CASE, &mut b, &from_c)?;
    for (name, node) in [("a", &mut a), ("b", &mut b), ("c", &mut c)] {
        expect_quiet(CASE, node, &format!("node {name} got everything, once"))?;
    }
    Ok(())
}

/// `try_recv` returns at once on a quiet bus; `recv_timeout` waits at least its timeout.
pub fn timeouts<B: CanBus>(join: &mut impl FnMut() -> B) -> CaseResult {
    const CASE: &str = "timeouts";
    let (_a, mut b) = (join(), join());
    match b.try_recv() {
        Ok(None) => {}
        other => {
            return Err(fail(
                CASE,
                format!("try_recv on a quiet bus gave {other:?}"),
            ));
        }
    }
    let timeout = Duration::from_millis(50);
    let start = Instant::now();
    match b.recv_timeout(timeout) {
        Ok(None) => {}
        other => {
            return Err(fail(
                CASE,
                format!("recv_timeout on a quiet bus gave {other:?}"),
            ));
        }
    }
    let waited = start.elapsed();
    if waited < timeout {
        return Err(fail(
            CASE,
            format!("recv_timeout({timeout:?}) returned after only {waited:?}"),
        ));
    }
    match b.recv_timeout(Duration::ZERO) {
        Ok(None) => Ok(()),
        other => Err(fail(
            CASE,
            format!("recv_timeout(0) on a quiet bus gave {other:?}"),
        )),
    }
}

/// A receiver blocked in `recv_timeout` wakes up for a frame sent from another thread.
pub fn wakes_blocked_receiver<B: CanBus + Send + 'static>(
    join: &mut impl FnMut() -> B,
) -> CaseResult {
    const CASE: &str = "wakes_blocked_receiver";
    let (mut a, mut b) = (join(), join());
    let f = frame(CASE, CanId::Standard(0x555), &[5, 5])?;
    let receiver =
        std::thread::spawn(move || b.recv_timeout(RECEIVE_TIMEOUT).map_err(|e| e.to_string()));
    // Give the receiver time to block first (correct either way; this exercises the wake-up).
    std::thread::sleep(Duration::from_millis(30));
    send(CASE, &mut a, &f)?;
    match receiver.join() {
        Ok(Ok(Some(got))) if got == f => Ok(()),
        Ok(other) => Err(fail(
            CASE,
            format!("blocked receiver got {other:?}, expected {f}"),
        )),
        Err(_) => Err(fail(CASE, "receiver thread panicked")),
    }
}

/// The echo peer: announces itself, echoes every frame, answers burst requests, returns on stop.
/// Gives up with an error when nothing arrives for `idle_timeout` (an orphaned peer exits).
pub fn echo_peer<B: CanBus>(
    node: &mut B,
    idle_timeout: Duration,
) -> Result<EchoStats, ConformanceError> {
    const CASE: &str = "echo_peer";
    let mut stats = EchoStats::default();
    send(CASE, node, &frame(CASE, PEER_READY_ID, &[])?)?;
    loop {
        let received = node
            .recv_timeout(idle_timeout)
            .map_err(|error| fail(CASE, format!("receive failed: {error}")))?
            .ok_or_else(|| fail(CASE, format!("no frame for {idle_timeout:?}, giving up")))?;
        if received.id() == PEER_STOP_ID {
            return Ok(stats);
        }
        if received.id() == PEER_BURST_REQUEST_ID {
            let len = match received.data() {
                [lo, hi, ..] => usize::from(u16::from_le_bytes([*lo, *hi])),
                _ => {
                    return Err(fail(
                        CASE,
                        format!("burst request {received} lacks a length"),
                    ));
                }
            };
            for index in 0..len {
                send(CASE, node, &burst_frame(CASE, PEER_BURST_FRAME_ID, index)?)?;
                stats.burst_frames += 1;
            }
            continue;
        }
        send(CASE, node, &received)?;
        stats.echoed += 1;
    }
}

/// Runs the cases that need a peer against an [`echo_peer`] on the same bus (another thread or
/// process), which must have been started after `local` joined. Stops the peer at the end.
pub fn against_echo_peer<B: CanBus>(local: &mut B, burst_len: usize) -> CaseResult {
    const CASE: &str = "against_echo_peer";
    expect_exact(CASE, local, &frame(CASE, PEER_READY_ID, &[])?)?;
    // Round trip of every DLC and id kind, one at a time.
    for f in dlc_and_id_matrix() {
        send(CASE, local, &f)?;
        expect_exact(CASE, local, &f)?;
    }
    // Our burst, echoed in order.
    for index in 0..burst_len {
        send(
            CASE,
            local,
            &burst_frame(CASE, CanId::Standard(0x200), index)?,
        )?;
    }
    for index in 0..burst_len {
        expect_exact(
            CASE,
            local,
            &burst_frame(CASE, CanId::Standard(0x200), index)?,
        )?;
    }
    // The peer's burst, in order.
    let len = u16::try_from(burst_len).map_err(|_| fail(CASE, "burst longer than 65535"))?;
    send(
        CASE,
        local,
        &frame(CASE, PEER_BURST_REQUEST_ID, &len.to_le_bytes())?,
    )?;
    for index in 0..burst_len {
        expect_exact(CASE, local, &burst_frame(CASE, PEER_BURST_FRAME_ID, index)?)?;
    }
    // Exactly one echo per frame, and never our own frames.
    expect_quiet(CASE, local, "every echo arrived exactly once")?;
    send(CASE, local, &frame(CASE, PEER_STOP_ID, &[])?)
}

/// Runs every case on nodes made by `join` (all on one bus), including the echo-peer cases with
/// the peer in a thread. `burst_len` must fit the backend's receive queue.
pub fn run_all<B: CanBus + Send + 'static>(
    mut join: impl FnMut() -> B,
    burst_len: usize,
) -> CaseResult {
    no_self_reception(&mut join)?;
    burst_in_order(&mut join, burst_len)?;
    every_dlc_and_id_kind(&mut join)?;
    several_nodes(&mut join)?;
    timeouts(&mut join)?;
    wakes_blocked_receiver(&mut join)?;
    let mut local = join();
    let mut peer_node = join();
    let peer = std::thread::spawn(move || echo_peer(&mut peer_node, RECEIVE_TIMEOUT));
    let result = against_echo_peer(&mut local, burst_len);
    let peer_result = peer
        .join()
        .map_err(|_| fail("echo_peer", "peer thread panicked"))?;
    result?;
    peer_result.map(|_| ())
}
