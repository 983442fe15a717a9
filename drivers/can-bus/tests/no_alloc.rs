//! Allocation budget of the steady-state path: MemoryBus allocates nothing, the virtual bus only
//! the one allocation per sent frame that iceoryx2 0.10 makes inside `loan`. Counted with a
//! global allocator (this test binary only).
#![allow(
    unsafe_code,
    reason = "a counting GlobalAlloc proves the bus allocates nothing per frame"
)]
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failure panics with its message

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::time::Duration;

use can_bus::{CanBus, CanFrame, CanId, MemoryBus, VirtualCanBus};

struct CountingAllocator;

static COUNTING: AtomicBool = AtomicBool::new(false);
static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);

// SAFETY: forwards every call to the system allocator unchanged; only counts.
unsafe impl GlobalAlloc for CountingAllocator {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if COUNTING.load(Ordering::Relaxed) {
            ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        }
        // SAFETY: same contract as the caller's.
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: same contract as the caller's.
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        if COUNTING.load(Ordering::Relaxed) {
            ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        }
        // SAFETY: same contract as the caller's.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: CountingAllocator = CountingAllocator;

fn allocations_during(mut work: impl FnMut()) -> usize {
    ALLOCATIONS.store(0, Ordering::Relaxed);
    COUNTING.store(true, Ordering::Relaxed);
    work();
    COUNTING.store(false, Ordering::Relaxed);
    ALLOCATIONS.load(Ordering::Relaxed)
}

/// One driver cycle: command out, feedback in, both directions, plus a wait that times out.
fn cycles<B: CanBus>(driver: &mut B, base: &mut B, count: u32) {
    let command = CanFrame::new(CanId::Standard(0x500), &[0, 0, 0, 1, 0, 0, 0, 0]).unwrap();
    let feedback = CanFrame::new(CanId::Extended(0x502), &[1, 2, 3, 4, 5, 6, 7, 8]).unwrap();
    for _ in 0..count {
        driver.send(&command).unwrap();
        assert_eq!(
            base.recv_timeout(Duration::from_secs(5)).unwrap(),
            Some(command)
        );
        base.send(&feedback).unwrap();
        assert_eq!(driver.try_recv().unwrap(), Some(feedback));
        assert_eq!(
            driver.recv_timeout(Duration::from_micros(200)).unwrap(),
            None
        );
    }
}

#[test]
fn steady_state_send_and_receive_do_not_allocate() {
    // One test function: the counter is global to the process.
    let bus = format!("t{}-noalloc", std::process::id());
    let mut driver = VirtualCanBus::join(&bus, "driver").unwrap();
    let mut base = VirtualCanBus::join(&bus, "base").unwrap();
    cycles(&mut driver, &mut base, 10); // start-up: connections, per-sender tables
    let virtual_allocations = allocations_during(|| cycles(&mut driver, &mut base, 500));

    let memory = MemoryBus::new();
    let (mut a, mut b) = (memory.join(), memory.join());
    cycles(&mut a, &mut b, 10);
    let memory_allocations = allocations_during(|| cycles(&mut a, &mut b, 500));

    // iceoryx2 0.10 itself allocates exactly one small object per loaned sample (the Arc in
    // `ChunkMutSharedState::new`, behind `Publisher::loan_uninit`/`send_copy`); everything of
    // ours (encoding, reorder heap, sequence tracking, wake-ups) allocates nothing. Two sends
    // per cycle, so any allocation of ours shows up as more than 2 per cycle.
    assert_eq!(
        virtual_allocations,
        2 * 500,
        "VirtualCanBus allocated beyond iceoryx2's one per sent frame"
    );
    assert_eq!(memory_allocations, 0, "MemoryBus allocated in steady state");
}
