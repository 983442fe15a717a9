//! Heap allocations per steady-state cycle, counted by a global allocator that counts the
//! calling thread's allocations inside [`counted`] scopes.
//!
//! `grop-latency-peer` installs [`CountingAlloc`] (a counting allocator must be the global one,
//! and the `grop` CLI should not pay for it), runs every case after a warm-up and prints the
//! counts; [`measure`] runs it and reads them. Cases:
//!
//! * the RMP driver's tick (feedback read and decoded, one command sent) and the simulated
//!   base's poll, both in this process, over the iceoryx2 virtual CAN bus and over the
//!   in-process `MemoryBus`;
//! * one frame sent / received through the virtual CAN bus on its own;
//! * a camera frame through iceoryx2: `loan_uninit` + write + `send`, and `receive` + release;
//! * `LoopStats::record` + `summary`.
//!
//! The allocation sizes of the first allocations in each case are kept, which names the
//! culprit when a count is not zero (iceoryx2 0.10's `loan_uninit` allocates 104 bytes).
#![allow(
    unsafe_code,
    reason = "the counting GlobalAlloc of the latency harness"
)]

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::path::Path;
use std::time::Duration;

use can_bus::{CanBus, CanFrame, CanId, MemoryBus, VirtualCanBus};
use grop_clock::rt::LoopStats;
use iceoryx2::prelude::*;
use motion_control::Twist;
use rmp_base::{BaseMode, CanLink, RmpBase, RmpBaseConfig};
use sim_rmp::{SimConfig, SimRmp, SimRmpNode};

use crate::peer::{Peer, field};
use crate::{BenchError, names};

/// Sizes remembered per scope.
const KEPT_SIZES: usize = 16;

thread_local! {
    static ARMED: Cell<bool> = const { Cell::new(false) };
    static COUNT: Cell<u64> = const { Cell::new(0) };
    static BYTES: Cell<u64> = const { Cell::new(0) };
    static SIZES: [Cell<u32>; KEPT_SIZES] = const { [const { Cell::new(0) }; KEPT_SIZES] };
}

/// A global allocator that forwards to the system allocator and counts the allocations (and
/// reallocations) the current thread makes inside [`counted`].
pub struct CountingAlloc;

fn note(size: usize) {
    // try_with: never panic, even while the thread's locals are torn down.
    let armed = ARMED.try_with(Cell::get).unwrap_or(false);
    if !armed {
        return;
    }
    let n = COUNT.try_with(|c| {
        let n = c.get();
        c.set(n + 1);
        n
    });
    let _ = BYTES.try_with(|b| b.set(b.get() + size as u64));
    if let Ok(n) = n {
        let _ = SIZES.try_with(|s| {
            if let Some(slot) = s.get(n as usize) {
                slot.set(u32::try_from(size).unwrap_or(u32::MAX));
            }
        });
    }
}

// SAFETY: every call is forwarded unchanged to the system allocator; counting touches only
// thread-local cells and never allocates.
unsafe impl GlobalAlloc for CountingAlloc {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        note(layout.size());
        // SAFETY: the caller's contract is passed on.
        unsafe { System.alloc(layout) }
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        note(layout.size());
        // SAFETY: the caller's contract is passed on.
        unsafe { System.alloc_zeroed(layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        note(new_size);
        // SAFETY: the caller's contract is passed on.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: the caller's contract is passed on.
        unsafe { System.dealloc(ptr, layout) }
    }
}

/// What a [`counted`] scope allocated.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct AllocCount {
    /// Allocations and reallocations.
    pub allocs: u64,
    /// Bytes asked for.
    pub bytes: u64,
    /// Sizes of the first allocations (0 = none).
    pub first_sizes: [u32; KEPT_SIZES],
}

/// Runs `f`, counting this thread's allocations meanwhile (zero unless [`CountingAlloc`] is
/// the global allocator).
pub fn counted<R>(f: impl FnOnce() -> R) -> (R, AllocCount) {
    let _ = COUNT.try_with(|c| c.set(0));
    let _ = BYTES.try_with(|b| b.set(0));
    let _ = SIZES.try_with(|s| s.iter().for_each(|c| c.set(0)));
    let _ = ARMED.try_with(|a| a.set(true));
    let r = f();
    let _ = ARMED.try_with(|a| a.set(false));
    let mut first_sizes = [0u32; KEPT_SIZES];
    let _ = SIZES.try_with(|s| {
        for (out, c) in first_sizes.iter_mut().zip(s) {
            *out = c.get();
        }
    });
    let count = AllocCount {
        allocs: COUNT.try_with(Cell::get).unwrap_or(0),
        bytes: BYTES.try_with(Cell::get).unwrap_or(0),
        first_sizes,
    };
    (r, count)
}

/// Whether [`CountingAlloc`] is the global allocator of this program.
pub fn is_installed() -> bool {
    let (_, count) = counted(|| drop(std::hint::black_box(Box::new(7u64))));
    count.allocs > 0
}

/// One case's count.
#[derive(Debug, Clone, PartialEq)]
pub struct AllocResult {
    /// Case id (see [`case_label`]).
    pub case: String,
    /// Cycles counted (after the warm-up).
    pub cycles: u64,
    /// Allocations in those cycles.
    pub allocs: u64,
    /// Bytes asked for in those cycles.
    pub bytes: u64,
    /// Sizes of the first allocations, bytes.
    pub first_sizes: Vec<u32>,
}

impl AllocResult {
    /// Allocations per cycle.
    pub fn per_cycle(&self) -> f64 {
        self.allocs as f64 / self.cycles.max(1) as f64
    }

    /// Bytes per cycle.
    pub fn bytes_per_cycle(&self) -> f64 {
        self.bytes as f64 / self.cycles.max(1) as f64
    }
}

/// The report's name of a case.
pub fn case_label(case: &str) -> &'static str {
    match case {
        "driver-tick-vcan" => {
            "rmp-base `RmpBase::tick` over the virtual CAN bus (read + decode a feedback set, send a command)"
        }
        "sim-poll-vcan" => {
            "sim-rmp `SimRmpNode::poll` over the virtual CAN bus (answer one command: 8 frames)"
        }
        "driver-tick-memory" => "rmp-base `RmpBase::tick` over `MemoryBus` (in-process)",
        "sim-poll-memory" => "sim-rmp `SimRmpNode::poll` over `MemoryBus`",
        "vcan-send" => "`VirtualCanBus::send` of one frame (iceoryx2 `send_copy` + wake-up)",
        "vcan-recv" => "`VirtualCanBus::try_recv` of one frame",
        "frame-publish" => {
            "camera frame through iceoryx2: `loan_uninit` + write 921,600 B + `send`"
        }
        "frame-receive" => "camera frame through iceoryx2: `receive` + release",
        "loop-stats" => "`grop_clock::rt::LoopStats::record` + `record_end`",
        _ => "unknown case",
    }
}

/// Runs the cases in a peer (which has the counting allocator) with `cycles` counted cycles
/// each after `warmup`.
pub fn measure(
    peer_exe: &Path,
    cycles: usize,
    warmup: usize,
) -> Result<Vec<AllocResult>, BenchError> {
    let args = vec![
        "alloc".to_owned(),
        "--cycles".to_owned(),
        cycles.to_string(),
        "--warmup".to_owned(),
        warmup.to_string(),
    ];
    let (mut peer, ready) = Peer::spawn(peer_exe, &args)?;
    if field::<u8>(&ready, "installed")? != 1 {
        return Err(BenchError::Peer(
            "the counting allocator is not the peer's global allocator".into(),
        ));
    }
    let done = peer.expect("done", Duration::from_secs(120))?;
    let expected: usize = field(&done, "cases")?;
    peer.finish_ok(Duration::from_secs(5))?;
    let mut results = Vec::new();
    for line in peer.notes() {
        let Some(rest) = line.strip_prefix("result ") else {
            continue;
        };
        let sizes: String = field(rest, "sizes")?;
        results.push(AllocResult {
            case: field(rest, "case")?,
            cycles: field(rest, "cycles")?,
            allocs: field(rest, "allocs")?,
            bytes: field(rest, "bytes")?,
            first_sizes: sizes
                .split(',')
                .filter_map(|s| s.parse().ok())
                .filter(|s| *s > 0)
                .collect(),
        });
    }
    if results.len() != expected {
        return Err(BenchError::Peer(format!(
            "{} allocation results, {expected} announced",
            results.len()
        )));
    }
    Ok(results)
}

/// Accumulates the counts of the cycles of one case.
#[derive(Default)]
struct Tally {
    allocs: u64,
    bytes: u64,
    first_sizes: Vec<u32>,
}

impl Tally {
    fn add(&mut self, count: &AllocCount) {
        self.allocs += count.allocs;
        self.bytes += count.bytes;
        for size in count.first_sizes.iter().filter(|s| **s > 0) {
            if self.first_sizes.len() < KEPT_SIZES {
                self.first_sizes.push(*size);
            }
        }
    }

    fn print(&self, case: &str, cycles: usize) {
        let sizes: Vec<String> = self.first_sizes.iter().map(u32::to_string).collect();
        let sizes = if sizes.is_empty() {
            "-".to_owned()
        } else {
            sizes.join(",")
        };
        println!(
            "result case={case} cycles={cycles} allocs={} bytes={} sizes={sizes}",
            self.allocs, self.bytes
        );
    }
}

/// The peer side of `alloc`: every case, warm-up then `cycles` counted; one `result` line per
/// case and a final `done cases=N`.
pub fn run_cases(cycles: usize, warmup: usize) -> Result<(), BenchError> {
    println!("ready installed={}", u8::from(is_installed()));
    let mut cases = 0;
    let vcan = names::unique("alloc-can");
    let driver_bus = VirtualCanBus::join(&vcan, "driver")
        .map_err(|e| BenchError::setup("joining the virtual bus")(&e))?;
    let sim_bus = VirtualCanBus::join(&vcan, "sim")
        .map_err(|e| BenchError::setup("joining the virtual bus")(&e))?;
    driver_cycle(driver_bus, sim_bus, "vcan", cycles, warmup)?;
    cases += 2;
    let memory = MemoryBus::new();
    driver_cycle(memory.join(), memory.join(), "memory", cycles, warmup)?;
    cases += 2;
    bus_frames(cycles, warmup)?;
    cases += 2;
    camera_frames(cycles, warmup)?;
    cases += 2;
    loop_stats(cycles, warmup);
    cases += 1;
    println!("done cases={cases}");
    Ok(())
}

/// The driver and the simulated base alternating on one thread, as in lock-step HIL: tick
/// (reads the previous reply, sends a command), poll (answers it).
fn driver_cycle<B: CanBus>(
    driver_bus: B,
    sim_bus: B,
    label: &str,
    cycles: usize,
    warmup: usize,
) -> Result<(), BenchError> {
    let mut driver = RmpBase::new(CanLink::new(driver_bus), RmpBaseConfig::default())
        .map_err(|e| BenchError::setup("configuring the RMP driver")(&e))?;
    let mut sim = SimRmpNode::new(sim_bus, SimRmp::new(SimConfig::default()));
    let period = driver.config().command_period;
    let mut now = Duration::ZERO;
    driver.request_mode(BaseMode::Tractor, now);
    let sim_error = |e: &dyn std::fmt::Debug| BenchError::setup("simulated base")(e);
    // Start-up on simulated time: at most 5 s of ticks to reach tractor mode.
    for _ in 0..250 {
        if driver.is_driving() {
            break;
        }
        let _ = driver.tick(now);
        sim.poll(now).map_err(|e| sim_error(&e))?;
        now += period;
    }
    if !driver.is_driving() {
        return Err(BenchError::Setup {
            what: format!("driver over {label}"),
            detail: "did not reach tractor mode".into(),
        });
    }
    let mut tick_tally = Tally::default();
    let mut poll_tally = Tally::default();
    for i in 0..warmup + cycles {
        let speed = if i % 2 == 0 { 0.3 } else { 0.2 };
        let (tick, tick_count) = counted(|| {
            driver.set_velocity(Twist::new(speed, 0.0), now);
            driver.tick(now)
        });
        tick.map_err(|e| BenchError::setup("RMP driver tick")(&e))?;
        let (poll, poll_count) = counted(|| sim.poll(now));
        poll.map_err(|e| sim_error(&e))?;
        if i >= warmup {
            tick_tally.add(&tick_count);
            poll_tally.add(&poll_count);
        }
        now += period;
    }
    tick_tally.print(&format!("driver-tick-{label}"), cycles);
    poll_tally.print(&format!("sim-poll-{label}"), cycles);
    Ok(())
}

fn bus_frames(cycles: usize, warmup: usize) -> Result<(), BenchError> {
    let bus = names::unique("alloc-frames");
    let join = |node: &str| {
        VirtualCanBus::join(&bus, node)
            .map_err(|e| BenchError::setup("joining the virtual bus")(&e))
    };
    let (mut a, mut b) = (join("a")?, join("b")?);
    let frame = CanFrame::new(CanId::Standard(0x500), &[1, 2, 3, 4, 5, 6, 7, 8])
        .map_err(|e| BenchError::setup("a CAN frame")(&e))?;
    let mut send = Tally::default();
    let mut recv = Tally::default();
    for i in 0..warmup + cycles {
        let (sent, send_count) = counted(|| a.send(&frame));
        sent.map_err(|e| BenchError::setup("virtual bus send")(&e))?;
        let (got, recv_count) = counted(|| b.try_recv());
        if !matches!(got, Ok(Some(_))) {
            return Err(BenchError::Peer(format!(
                "virtual bus frame {i} not received: {got:?}"
            )));
        }
        if i >= warmup {
            send.add(&send_count);
            recv.add(&recv_count);
        }
    }
    send.print("vcan-send", cycles);
    recv.print("vcan-recv", cycles);
    Ok(())
}

fn camera_frames(cycles: usize, warmup: usize) -> Result<(), BenchError> {
    let node = NodeBuilder::new()
        .signal_handling_mode(SignalHandlingMode::Disabled)
        .create::<ipc::Service>()
        .map_err(|e| BenchError::setup("creating the iceoryx2 node")(&e))?;
    let service = names::unique("alloc-cam");
    // The same service settings as the frame-latency measurement.
    let (frames, _wake) = crate::camera::open_service(&node, &service)?;
    let publisher = frames
        .publisher_builder()
        .max_loaned_samples(1)
        .create()
        .map_err(|e| BenchError::setup("creating the publisher")(&e))?;
    let subscriber = frames
        .subscriber_builder()
        .buffer_size(1)
        .create()
        .map_err(|e| BenchError::setup("creating the subscriber")(&e))?;
    let mut publish = Tally::default();
    let mut receive = Tally::default();
    for i in 0..warmup + cycles {
        let seq = i as u64 + 1;
        let (sent, publish_count) = counted(|| crate::camera::publish_frame(&publisher, seq));
        sent?;
        let (got, receive_count) = counted(|| match subscriber.receive() {
            Ok(Some(sample)) => Ok(sample.user_header().seq),
            Ok(None) => Err(BenchError::Peer(format!("camera frame {seq} not received"))),
            Err(e) => Err(BenchError::setup("receive")(&e)),
        });
        if got? != seq {
            return Err(BenchError::Peer(format!("camera frame {seq} out of order")));
        }
        if i >= warmup {
            publish.add(&publish_count);
            receive.add(&receive_count);
        }
    }
    publish.print("frame-publish", cycles);
    receive.print("frame-receive", cycles);
    Ok(())
}

fn loop_stats(cycles: usize, warmup: usize) {
    let period = Duration::from_millis(20);
    let mut stats = LoopStats::new(period);
    let mut tally = Tally::default();
    let mut deadline = Duration::from_secs(1);
    for i in 0..warmup + cycles {
        let late = Duration::from_nanos((i as u64 * 7919) % 500_000);
        let ((), count) = counted(|| {
            stats.record(deadline, deadline + late);
            stats.record_end(deadline + late, deadline + period);
        });
        if i >= warmup {
            tally.add(&count);
        }
        deadline += period;
    }
    std::hint::black_box(stats.summary());
    tally.print("loop-stats", cycles);
}
