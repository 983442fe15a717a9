//! The arm's steady-state cycle (`Ur5eArm::update`: newest RTDE state in, watchdog heartbeat
//! out) allocates nothing after start-up. A counting global allocator counts allocations made
//! by this test's thread only (the simulator's threads allocate freely).

use std::time::Duration;

use sim_ur5e::{SimConfig, Ur5eSim};
use ur5e::{ArmConfig, Ur5eArm};

#[global_allocator]
static GLOBAL: test_support::CountingAlloc = test_support::CountingAlloc;

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
    let before = test_support::this_thread_allocations();
    test_support::count_this_thread(true);
    let mut last = f64::NEG_INFINITY;
    for _ in 0..500 {
        let s = arm.update().unwrap();
        assert!(s.timestamp_s > last);
        last = s.timestamp_s;
    }
    test_support::count_this_thread(false);
    assert_eq!(
        test_support::this_thread_allocations() - before,
        0,
        "allocations in 500 steady-state cycles"
    );
}
