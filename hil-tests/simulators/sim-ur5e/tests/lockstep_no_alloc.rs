//! The executive's per-cycle arm path in lock-step (`Ur5eArm::update_at` + `Ur5eArm::poll`
//! while a move runs) allocates nothing once the motion program is sent. A counting global
//! allocator counts allocations made by this test's thread while the counter is on; the
//! simulator's threads, and `Ur5eSim::step` (the world's side), are not counted.

use std::sync::atomic::{AtomicBool, Ordering};
use std::thread;
use std::time::Duration;

use sim_ur5e::{SimConfig, Stepping, Ur5eSim};
use ur5e::{ArmConfig, SkillProgress, Ur5eArm};

#[global_allocator]
static GLOBAL: test_support::CountingAlloc = test_support::CountingAlloc;

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
    let before = test_support::this_thread_allocations();
    let mut progress = Vec::with_capacity(1000);
    for _ in 0..1000 {
        sim.step().unwrap();
        let now = sim.controller_time();
        test_support::count_this_thread(true);
        let updated = arm.update_at(now).map(|s| s.program_running());
        let polled = arm.poll(now);
        test_support::count_this_thread(false);
        progress.push((updated.unwrap(), polled.unwrap()));
    }
    assert_eq!(
        test_support::this_thread_allocations() - before,
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
