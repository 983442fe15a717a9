//! Helpers for the workspace's tests, a dev-dependency only (nothing the robot runs links it):
//! the counting global allocator behind every "allocates nothing" test.
//!
//! ```ignore
//! #[global_allocator]
//! static GLOBAL: test_support::CountingAlloc = test_support::CountingAlloc;
//!
//! let (_, allocations) = test_support::allocations_on_this_thread(|| steady_state_work());
//! assert_eq!(allocations, 0);
//! ```
//!
//! Counted are `alloc` and `realloc` calls (a `realloc` may move the block: it is an allocation
//! on the path). Two ways to count: on the calling thread only (tests in one binary run in
//! parallel threads, so each counts its own), or on every thread while a closure runs (for work
//! that spans threads; the binary's other tests must not run then).
#![allow(
    unsafe_code,
    reason = "the GlobalAlloc implementation forwards to the system allocator"
)]

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};

/// The counting allocator: install it with `#[global_allocator]` in a test binary.
#[derive(Debug, Clone, Copy, Default)]
pub struct CountingAlloc;

thread_local! {
    static COUNTING: Cell<bool> = const { Cell::new(false) };
    static COUNT: Cell<u64> = const { Cell::new(0) };
}
static EVERY_THREAD: AtomicBool = AtomicBool::new(false);
static EVERY_THREAD_COUNT: AtomicU64 = AtomicU64::new(0);
static TRACE: AtomicBool = AtomicBool::new(false);

fn counted() {
    if EVERY_THREAD.load(Ordering::Relaxed) {
        EVERY_THREAD_COUNT.fetch_add(1, Ordering::Relaxed);
    }
    // `try_with`: a thread being torn down has no locals left; not counted then.
    if COUNTING.try_with(Cell::get).unwrap_or(false) {
        let _ = COUNT.try_with(|n| n.set(n.get() + 1));
        if TRACE.load(Ordering::Relaxed) {
            // The backtrace allocates: not counted.
            let _ = COUNTING.try_with(|c| c.set(false));
            eprintln!(
                "counted allocation at:\n{}",
                std::backtrace::Backtrace::force_capture()
            );
            let _ = COUNTING.try_with(|c| c.set(true));
        }
    }
}

// SAFETY: every call is forwarded unchanged to the system allocator; the counting touches only
// atomics and const-initialised thread locals, which do not allocate.
unsafe impl GlobalAlloc for CountingAlloc {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        counted();
        // SAFETY: the caller's contract is the system allocator's.
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: the caller's contract is the system allocator's.
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        counted();
        // SAFETY: the caller's contract is the system allocator's.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

/// Turns counting on or off for the calling thread (for a counted region that spans calls;
/// [`allocations_on_this_thread`] is the closure form).
pub fn count_this_thread(on: bool) {
    COUNTING.with(|c| c.set(on));
}

/// Allocations counted on the calling thread so far (only while counting was on).
pub fn this_thread_allocations() -> u64 {
    COUNT.with(Cell::get)
}

/// Runs `f` and returns what it returned and the allocations the calling thread made meanwhile.
pub fn allocations_on_this_thread<R>(f: impl FnOnce() -> R) -> (R, u64) {
    let before = this_thread_allocations();
    let was = COUNTING.with(Cell::get);
    count_this_thread(true);
    let result = f();
    count_this_thread(was);
    (result, this_thread_allocations() - before)
}

/// Runs `f` and returns what it returned and the allocations every thread made meanwhile.
pub fn allocations_by_any_thread<R>(f: impl FnOnce() -> R) -> (R, u64) {
    let before = EVERY_THREAD_COUNT.load(Ordering::Relaxed);
    EVERY_THREAD.store(true, Ordering::Relaxed);
    let result = f();
    EVERY_THREAD.store(false, Ordering::Relaxed);
    (result, EVERY_THREAD_COUNT.load(Ordering::Relaxed) - before)
}

/// Prints a backtrace for every allocation counted on a thread that counts (a debugging aid,
/// e.g. from an environment variable in the test).
pub fn trace_allocations(on: bool) {
    TRACE.store(on, Ordering::Relaxed);
}
