//! CAN command to feedback through the iceoryx2 virtual CAN bus with the RMP driver in the loop.
//!
//! The simulated base (`sim_rmp::SimRmpNode`) runs in the peer process, asleep in
//! `recv_timeout` like the `sim-rmp` binary. Here, `rmp_base::RmpBase` drives it in tractor
//! mode, a velocity command per tick. The RMP protocol carries no sequence numbers, but the
//! base answers every command with exactly one feedback set (docs/rmp.md), so with one command
//! in flight the next complete set is the reply to it. Measured per command:
//!
//! * `first frame`: the driver's send (the link's `send`) to the first feedback frame of the
//!   reply arriving at this process;
//! * `decoded`: the driver's send to the driver having read and decoded the whole set (the
//!   link's last `try_recv` of the following tick, which the driver calls at once, woken by
//!   the bus).
//!
//! The executive calls `tick` on its 50 Hz period instead, so on the robot a reply waits up to
//! 20 ms for the next tick on top of this; the figure here is the transport and decode path.

use std::collections::VecDeque;
use std::path::Path;
use std::time::{Duration, Instant};

use can_bus::{CanBus, VirtualCanBus};
use motion_control::Twist;
use rmp_base::{BaseMode, LinkError, RmpBase, RmpBaseConfig, RmpLink, from_can, to_can};
use rmp_codec::RawFrame;
use rmp_codec::feedback::{self, FeedbackLayout};
use sim_rmp::{SimConfig, SimRmp, SimRmpNode};

use crate::peer::Peer;
use crate::{BenchError, Summary, names, now_ns};

/// Sizes of the measurement.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CanConfig {
    /// Commands measured.
    pub samples: usize,
    /// Commands before measuring, after the driver reached tractor mode.
    pub warmup: usize,
}

impl Default for CanConfig {
    fn default() -> Self {
        Self {
            samples: 3000,
            warmup: 100,
        }
    }
}

/// The outcome.
#[derive(Debug, Clone, PartialEq)]
pub struct CanResult {
    /// Driver's send -> first reply frame here.
    pub first_frame: Summary,
    /// Driver's send -> driver has decoded the reply set.
    pub decoded: Summary,
    /// Frames per feedback set (the driver's selection).
    pub frames_per_set: usize,
    /// The virtual bus used (unique per run).
    pub bus: String,
    /// Frames the bus reported lost.
    pub lost_frames: u64,
}

/// Longest wait for a reply.
const REPLY_TIMEOUT: Duration = Duration::from_secs(2);
/// Longest start-up (feedback configuration and tractor mode).
const STARTUP_TIMEOUT: Duration = Duration::from_secs(10);

/// An [`RmpLink`] over the virtual bus that stamps the driver's sends and the end of its
/// reads, and can wait (asleep, on the bus's wake-up) for a whole reply before the driver's
/// tick reads it.
struct TimedLink {
    bus: VirtualCanBus,
    inbox: VecDeque<RawFrame>,
    sent_ns: u64,
    delivered: usize,
    drained_ns: Option<u64>,
}

impl RmpLink for TimedLink {
    fn send(&mut self, frame: &RawFrame) -> Result<(), LinkError> {
        self.sent_ns = now_ns();
        self.bus
            .send(&to_can(frame))
            .map_err(|source| LinkError::Send {
                frame: *frame,
                source,
            })
    }

    fn try_recv(&mut self) -> Result<Option<RawFrame>, LinkError> {
        if self.inbox.is_empty() {
            while let Some(frame) = self.bus.try_recv()? {
                if let Some(raw) = from_can(&frame) {
                    self.inbox.push_back(raw);
                    break;
                }
            }
        }
        match self.inbox.pop_front() {
            Some(frame) => {
                self.delivered += 1;
                Ok(Some(frame))
            }
            None => {
                if self.delivered > 0 && self.drained_ns.is_none() {
                    self.drained_ns = Some(now_ns());
                }
                Ok(None)
            }
        }
    }
}

impl TimedLink {
    /// Sleeps on the bus until `frames` feedback frames are in; returns when the first came.
    fn wait_for_reply(&mut self, frames: usize) -> Result<u64, BenchError> {
        let deadline = Instant::now() + REPLY_TIMEOUT;
        let mut first_ns = None;
        let mut got = 0;
        while got < frames {
            let left = deadline.saturating_duration_since(Instant::now());
            if left.is_zero() {
                return Err(BenchError::Timeout {
                    what: format!("feedback set ({got} of {frames} frames)"),
                    after: REPLY_TIMEOUT,
                });
            }
            let frame = self
                .bus
                .recv_timeout(left)
                .map_err(|e| BenchError::setup("receiving from the virtual bus")(&e))?;
            let Some(raw) = frame.as_ref().and_then(from_can) else {
                continue;
            };
            first_ns.get_or_insert_with(now_ns);
            if feedback::is_feedback_id(raw.id()) {
                got += 1;
            }
            self.inbox.push_back(raw);
        }
        Ok(first_ns.unwrap_or_else(now_ns))
    }

    /// Forgets the marks of the previous tick.
    fn rearm(&mut self) {
        self.delivered = 0;
        self.drained_ns = None;
    }
}

/// Runs the measurement against a simulated base in a peer started from `peer_exe`.
pub fn measure(peer_exe: &Path, config: &CanConfig) -> Result<CanResult, BenchError> {
    let bus_name = names::unique("can");
    let bus = VirtualCanBus::join(&bus_name, "latency-driver")
        .map_err(|e| BenchError::setup(format!("joining virtual CAN bus {bus_name}"))(&e))?;
    let (mut peer, _) = Peer::spawn(
        peer_exe,
        &["rmp-sim".to_owned(), "--bus".to_owned(), bus_name.clone()],
    )?;
    let driver_config = RmpBaseConfig::default();
    let frames_per_set = FeedbackLayout::User(driver_config.feedback).frame_count();
    let link = TimedLink {
        bus,
        inbox: VecDeque::with_capacity(4 * feedback::MAX_FRAMES),
        sent_ns: 0,
        delivered: 0,
        drained_ns: None,
    };
    let mut driver = RmpBase::new(link, driver_config)
        .map_err(|e| BenchError::setup("configuring the RMP driver")(&e))?;
    let origin = Instant::now();
    let now = || origin.elapsed();
    driver.request_mode(BaseMode::Tractor, now());

    // Start-up: feedback bitmaps written and verified, tractor mode reached.
    let started = Instant::now();
    while !driver.is_driving() {
        if started.elapsed() > STARTUP_TIMEOUT {
            return Err(BenchError::Timeout {
                what: "the RMP driver reaching tractor mode with the simulated base".into(),
                after: STARTUP_TIMEOUT,
            });
        }
        let _ = driver.tick(now());
        std::thread::sleep(Duration::from_millis(5));
    }
    // Replies to start-up commands still on the way: let them in and drop them.
    std::thread::sleep(Duration::from_millis(20));
    let _ = driver.tick(now());
    std::thread::sleep(Duration::from_millis(20));
    let _ = driver.tick(now());

    let mut first = Vec::with_capacity(config.samples);
    let mut decoded = Vec::with_capacity(config.samples);
    for i in 0..config.warmup + config.samples {
        let link = driver.link_mut();
        let sent_ns = link.sent_ns;
        let first_ns = link.wait_for_reply(frames_per_set)?;
        link.rearm();
        let speed = if i % 2 == 0 { 0.3 } else { 0.2 };
        driver.set_velocity(Twist::new(speed, 0.0), now());
        // Reads and decodes the reply, then sends the next command.
        let tick = driver
            .tick(now())
            .map_err(|e| BenchError::setup("RMP driver tick")(&e))?;
        let link = driver.link_mut();
        let Some(drained_ns) = link.drained_ns else {
            return Err(BenchError::Peer("the driver read no reply".into()));
        };
        if tick.feedback_sets != 1 {
            return Err(BenchError::Peer(format!(
                "the driver decoded {} feedback sets from one reply",
                tick.feedback_sets
            )));
        }
        if i >= config.warmup {
            first.push(first_ns.saturating_sub(sent_ns));
            decoded.push(drained_ns.saturating_sub(sent_ns));
        }
    }
    let lost_frames = driver.link_mut().bus.lost_frame_count();
    peer.finish_ok(Duration::from_secs(5))?;
    Ok(CanResult {
        first_frame: Summary::of(&mut first),
        decoded: Summary::of(&mut decoded),
        frames_per_set,
        bus: bus_name,
        lost_frames,
    })
}

/// The peer side of `rmp-sim`: the simulated base on `bus`, answering until stdin closes.
pub fn run_sim(bus_name: &str) -> Result<(), BenchError> {
    let bus = VirtualCanBus::join(bus_name, "latency-sim-rmp")
        .map_err(|e| BenchError::setup(format!("joining virtual CAN bus {bus_name}"))(&e))?;
    let mut node = SimRmpNode::new(bus, SimRmp::new(SimConfig::default()));
    let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let flag = std::sync::Arc::clone(&stop);
    std::thread::spawn(move || {
        let mut sink = Vec::new();
        let _ = std::io::Read::read_to_end(&mut std::io::stdin(), &mut sink);
        flag.store(true, std::sync::atomic::Ordering::Relaxed);
    });
    let origin = Instant::now();
    println!("ready");
    while !stop.load(std::sync::atomic::Ordering::Relaxed) {
        node.poll_blocking(Duration::from_millis(20), || origin.elapsed())
            .map_err(|e| BenchError::setup("simulated base")(&e))?;
    }
    Ok(())
}
