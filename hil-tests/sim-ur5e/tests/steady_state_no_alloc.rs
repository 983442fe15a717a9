//! The arm's steady-state cycle (`Ur5eArm::update`: newest RTDE state in, watchdog heartbeat
//! out) allocates nothing after start-up. A counting global allocator counts allocations made
//! by this test's thread only (the simulator's threads allocate freely).
#![allow(
    unsafe_code,
    reason = "a counting GlobalAlloc proves the steady state allocates nothing"
)]

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::time::Duration;

use sim_ur5e::{SimConfig, Ur5eSim};
use ur5e::{ArmConfig, Ur5eArm};

struct CountingAlloc;

thread_local! {
    static COUNTING: Cell<bool> = const { Cell::new(false) };
    static COUNT: Cell<u64> = const { Cell::new(0) };
}

// SAFETY: forwards to the system allocator; the bookkeeping touches only const-initialised
// thread-locals, which never allocate.
unsafe impl GlobalAlloc for CountingAlloc {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if COUNTING.with(Cell::get) {
            COUNT.with(|c| c.set(c.get() + 1));
        }
        // SAFETY: same contract as the caller's.
        unsafe { System.alloc(layout) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: same contract as the caller's.
        unsafe { System.dealloc(ptr, layout) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        if COUNTING.with(Cell::get) {
            COUNT.with(|c| c.set(c.get() + 1));
        }
        // SAFETY: same contract as the caller's.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static ALLOC: CountingAlloc = CountingAlloc;

#[test]
fn arm_update_cycle_does_not_allocate() {
    let sim = Ur5eSim::start(SimConfig::ephemeral()).unwrap();
    let p = sim.ports();
    let mut arm = Ur5eArm::connect(ArmConfig {
        rtde_port: p.rtde.port(),
        dashboard_port: p.dashboard.port(),
        script_port: p.secondary.port(),
        gripper_port: None,
        stale_after: Duration::from_secs(1),
        ..ArmConfig::default()
    })
    .unwrap();
    // Warm-up: the first cycles may still grow buffers.
    for _ in 0..50 {
        arm.update().unwrap();
    }
    COUNT.with(|c| c.set(0));
    COUNTING.with(|c| c.set(true));
    let mut last = f64::NEG_INFINITY;
    for _ in 0..500 {
        let s = arm.update().unwrap();
        assert!(s.timestamp_s > last);
        last = s.timestamp_s;
    }
    COUNTING.with(|c| c.set(false));
    assert_eq!(
        COUNT.with(Cell::get),
        0,
        "allocations in 500 steady-state cycles"
    );
}
