//! The executive's per-cycle arm path in lock-step (`Ur5eArm::update_at` + `Ur5eArm::poll`
//! while a move runs) allocates nothing once the motion program is sent. A counting global
//! allocator counts allocations made by this test's thread while the counter is on; the
//! simulator's threads, and `Ur5eSim::step` (the world's side), are not counted.
#![allow(
    unsafe_code,
    reason = "a counting GlobalAlloc proves the lock-step loop allocates nothing"
)]

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread;
use std::time::Duration;

use sim_ur5e::{SimConfig, Stepping, Ur5eSim};
use ur5e::{ArmConfig, SkillProgress, Ur5eArm};

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
fn lockstep_update_and_poll_do_not_allocate_while_a_move_runs() {
    let sim = Ur5eSim::start(SimConfig {
        stepping: Stepping::External,
        ..SimConfig::ephemeral()
    })
    .unwrap();
    let p = sim.ports();
    let cfg = ArmConfig {
        rtde_port: p.rtde.port(),
        dashboard_port: p.dashboard.port(),
        script_port: p.secondary.port(),
        gripper_port: None,
        ..ArmConfig::default()
    };
    // Connect waits for a first state: step freely meanwhile.
    let connected = AtomicBool::new(false);
    let mut arm = thread::scope(|s| {
        s.spawn(|| {
            while !connected.load(Ordering::Acquire) {
                sim.step().unwrap();
                thread::sleep(Duration::from_millis(1));
            }
        });
        let arm = Ur5eArm::connect(cfg);
        connected.store(true, Ordering::Release);
        arm.unwrap()
    });
    let h = std::f64::consts::FRAC_PI_2;
    sim.step().unwrap();
    arm.update_at(sim.controller_time()).unwrap();
    // A long move (2 rad at 0.5 rad/s: about 4 s, 2000 cycles), sent here (this may allocate).
    arm.start_move_joints(
        [2.0, -h, h, -h, -h, 0.0],
        0.5,
        2.0,
        Duration::from_secs(20),
        sim.controller_time(),
    )
    .unwrap();
    // Warm-up: the first cycles may still grow buffers.
    for _ in 0..50 {
        sim.step().unwrap();
        let now = sim.controller_time();
        arm.update_at(now).unwrap();
        assert_eq!(arm.poll(now).unwrap(), SkillProgress::Running);
    }
    COUNT.with(|c| c.set(0));
    let mut progress = Vec::with_capacity(1000);
    for _ in 0..1000 {
        sim.step().unwrap();
        let now = sim.controller_time();
        COUNTING.with(|c| c.set(true));
        let updated = arm.update_at(now).map(|s| s.program_running());
        let polled = arm.poll(now);
        COUNTING.with(|c| c.set(false));
        progress.push((updated.unwrap(), polled.unwrap()));
    }
    assert_eq!(
        COUNT.with(Cell::get),
        0,
        "allocations in 1000 lock-step cycles"
    );
    assert!(
        progress
            .iter()
            .all(|&(running, p)| running && p == SkillProgress::Running),
        "the move ran throughout"
    );
}
