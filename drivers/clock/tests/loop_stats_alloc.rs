//! `LoopStats` allocates nothing after construction: recording, percentiles and summaries run
//! under a counting global allocator that counts this thread's allocations.
#![allow(
    unsafe_code,
    reason = "a counting GlobalAlloc proves the loop statistics allocate nothing"
)]

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::time::Duration;

use grop_clock::rt::LoopStats;

struct CountingAlloc;

thread_local! {
    static ALLOCATIONS: Cell<u64> = const { Cell::new(0) };
}

fn count_one() {
    // try_with: no panic even while the thread is being torn down.
    let _ = ALLOCATIONS.try_with(|n| n.set(n.get() + 1));
}

// SAFETY: forwards every call to the system allocator unchanged; only counts.
unsafe impl GlobalAlloc for CountingAlloc {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        count_one();
        // SAFETY: same contract as the caller's.
        unsafe { System.alloc(layout) }
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        count_one();
        // SAFETY: same contract as the caller's.
        unsafe { System.alloc_zeroed(layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        count_one();
        // SAFETY: same contract as the caller's.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: same contract as the caller's.
        unsafe { System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static GLOBAL: CountingAlloc = CountingAlloc;

fn allocations() -> u64 {
    ALLOCATIONS.with(Cell::get)
}

#[test]
fn loop_stats_allocate_nothing_after_construction() {
    let period = Duration::from_millis(2);
    let mut stats = LoopStats::new(period);
    // The counter itself works.
    let before = allocations();
    drop(std::hint::black_box(vec![1u8; 16]));
    assert!(
        allocations() > before,
        "the counting allocator is installed"
    );

    let before = allocations();
    let mut deadline = Duration::from_secs(1);
    let mut checksum = Duration::ZERO;
    for i in 0..100_000u64 {
        // Lateness spread over every bucket range: fine, coarse and overflow.
        let late = Duration::from_nanos((i * 7919) % 150_000_000);
        stats.record(deadline, deadline + late);
        stats.record_end(
            deadline + late + Duration::from_micros(50),
            deadline + period,
        );
        if i % 1000 == 0 {
            checksum += stats.percentile(99.0).unwrap_or_default();
            checksum += stats.summary().p50;
        }
        deadline += period;
    }
    let summary = stats.summary();
    let during = allocations() - before;
    assert_eq!(during, 0, "LoopStats allocated {during} times");
    assert_eq!(summary.count, 100_000);
    assert!(summary.p50 <= summary.p99 && summary.p99 <= summary.max);
    assert!(checksum > Duration::ZERO);
}
