//! HIL in lock-step: the simulator stepped externally (`Stepping::External`) by a test "world"
//! that owns the clock, and the arm driven through its non-blocking skills (`update_at` +
//! `poll`) on that simulated clock. Nothing here depends on how fast the machine is: the same
//! mission takes the same number of steps, and every timeout fires on simulated time.
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failure panics with its message

use std::sync::atomic::{AtomicBool, Ordering};
use std::thread;
use std::time::Duration;

use sim_ur5e::{SimConfig, StepError, Stepping, Ur5eSim};
use ur5e::rtde::{DataPackage, RtdeClient, RtdeTimeouts, RtdeValue};
use ur5e::{
    ArmConfig, GripOutcome, GripperAction, SkillError, SkillOutcome, SkillProgress, Ur5eArm,
};

const H: f64 = std::f64::consts::FRAC_PI_2;
const HOME: [f64; 6] = [0.0, -H, H, -H, -H, 0.0];
const PERIOD: Duration = Duration::from_millis(2);

fn external_sim(f: impl FnOnce(&mut SimConfig)) -> Ur5eSim {
    let mut cfg = SimConfig {
        stepping: Stepping::External,
        ..SimConfig::ephemeral()
    };
    f(&mut cfg);
    Ur5eSim::start(cfg).expect("simulator starts")
}

fn arm_config(sim: &Ur5eSim) -> ArmConfig {
    let p = sim.ports();
    ArmConfig {
        rtde_port: p.rtde.port(),
        dashboard_port: p.dashboard.port(),
        script_port: p.secondary.port(),
        gripper_port: Some(p.gripper.port()),
        ..ArmConfig::default()
    }
}

/// `Ur5eArm::connect` waits for a first state, so the world steps freely (at about real time)
/// until the arm is connected, as a world does before it starts lock-step.
fn connect(sim: &Ur5eSim, cfg: ArmConfig) -> Ur5eArm {
    let connected = AtomicBool::new(false);
    thread::scope(|s| {
        s.spawn(|| {
            while !connected.load(Ordering::Acquire) {
                sim.step().expect("external stepping");
                thread::sleep(Duration::from_millis(1));
            }
        });
        let arm = Ur5eArm::connect(cfg);
        connected.store(true, Ordering::Release);
        arm.expect("arm connects")
    })
}

/// A test world: steps the simulator, then runs one executive cycle at the simulated time.
struct World {
    sim: Ur5eSim,
    arm: Ur5eArm,
    steps: u64,
}

impl World {
    fn new(f: impl FnOnce(&mut SimConfig)) -> Self {
        let sim = external_sim(f);
        let arm = connect(&sim, arm_config(&sim));
        let mut w = Self { sim, arm, steps: 0 };
        // First lock-step cycle: takes the newest state buffered during connect.
        w.cycle().expect("first cycle");
        w
    }

    /// The executive's clock: the simulated controller time.
    fn now(&self) -> Duration {
        self.sim.controller_time()
    }

    /// One world step and one executive cycle (`update_at` + `poll`).
    fn cycle(&mut self) -> Result<SkillProgress, SkillError> {
        let report = self.sim.step().expect("external stepping");
        assert_eq!(report.rtde_lagging, 0, "{report:?}");
        assert_eq!(report.inputs_lagging, 0, "{report:?}");
        self.steps += 1;
        let now = self.now();
        let state = self.arm.update_at(now)?;
        assert_eq!(
            state.timestamp_s, report.time_s,
            "the package of this step was read without waiting"
        );
        self.arm.poll(now)
    }

    /// Cycles until the skill ends; returns the outcome and the number of steps it took.
    fn run_skill(&mut self, limit: u64) -> (Result<SkillOutcome, SkillError>, u64) {
        let start = self.steps;
        loop {
            assert!(
                self.steps - start < limit,
                "skill still running after {limit} steps"
            );
            match self.cycle() {
                Ok(SkillProgress::Running) => {}
                Ok(SkillProgress::Done(o)) => return (Ok(o), self.steps - start),
                Ok(SkillProgress::Idle) => panic!("no skill in progress"),
                Err(e) => return (Err(e), self.steps - start),
            }
        }
    }
}

#[test]
fn step_refuses_a_wall_clock_simulator() {
    let sim = Ur5eSim::start(SimConfig::ephemeral()).unwrap();
    assert_eq!(sim.step(), Err(StepError::NotExternal));
}

#[test]
fn each_step_gives_one_package_readable_at_once_with_exact_timestamps() {
    let sim = external_sim(|_| {});
    let connect = || RtdeClient::connect(sim.ports().rtde, RtdeTimeouts::default()).unwrap();
    let (mut fast, mut half) = (connect(), connect());
    let recipe = fast
        .setup_outputs(&["timestamp", "actual_q"], 500.0)
        .unwrap()
        .clone();
    let half_recipe = half.setup_outputs(&["timestamp"], 250.0).unwrap().clone();
    fast.start().unwrap();
    half.start().unwrap();
    let mut pkg = DataPackage::for_recipe(&recipe);
    let mut half_pkg = DataPackage::for_recipe(&half_recipe);
    // Starting the stream sends the current state at once (cycle 0), as the real controller's
    // first package follows the start; nothing more comes before the first step.
    assert!(
        fast.receive_newest(&mut pkg, Duration::from_secs(1))
            .unwrap(),
        "the state at start"
    );
    assert_eq!(pkg.values[0], RtdeValue::Double(0.0));
    assert!(
        half.receive_newest(&mut half_pkg, Duration::from_secs(1))
            .unwrap()
    );
    assert!(
        !fast.receive_newest(&mut pkg, Duration::ZERO).unwrap(),
        "no second package before the first step"
    );
    let period_s = 1.0 / 500.0;
    let (mut fast_count, mut half_count) = (0, 0);
    for n in 1..=300u64 {
        let report = sim.step().unwrap();
        assert_eq!(report.cycle, n);
        assert_eq!(report.time_s, n as f64 * period_s);
        assert_eq!(report.rtde_packages_written, if n % 2 == 0 { 2 } else { 1 });
        // No wait: the package is in the socket when step() returns.
        assert!(
            fast.receive_newest(&mut pkg, Duration::ZERO).unwrap(),
            "step {n}"
        );
        assert_eq!(pkg.skipped, 0);
        assert_eq!(pkg.values[0], RtdeValue::Double(n as f64 * period_s));
        fast_count += 1;
        if half.receive_newest(&mut half_pkg, Duration::ZERO).unwrap() {
            assert_eq!(n % 2, 0, "250 Hz: every second cycle");
            assert_eq!(half_pkg.values[0], RtdeValue::Double(n as f64 * period_s));
            half_count += 1;
        }
        if n % 50 == 0 {
            // Wall time passing does not make packages.
            thread::sleep(Duration::from_millis(10));
            assert!(!fast.receive_newest(&mut pkg, Duration::ZERO).unwrap());
        }
    }
    assert_eq!((fast_count, half_count), (300, 150));
    assert_eq!(sim.controller_time(), 300 * PERIOD);
}

/// Runs one `movej` in a fresh world, optionally pausing the wall clock now and then; returns
/// (steps from the program first seen running to done, report, final joints).
fn movej_mission(pause_wall: bool) -> (u64, ur5e::MoveReport, [f64; 6]) {
    let mut w = World::new(|_| {});
    let goal = [0.5, -H, H, -H, -H, 0.0];
    let now = w.now();
    w.arm
        .start_move_joints(goal, 1.0, 2.0, Duration::from_secs(10), now)
        .unwrap();
    let start = w.steps;
    let mut first_running = None;
    let outcome = loop {
        if pause_wall && (w.steps - start) % 37 == 0 {
            thread::sleep(Duration::from_millis(4));
        }
        let progress = w.cycle().unwrap();
        if w.arm.state().program_running() {
            first_running.get_or_insert(w.steps);
        }
        match progress {
            SkillProgress::Running => {}
            SkillProgress::Done(o) => break o,
            SkillProgress::Idle => panic!("no skill"),
        }
        assert!(w.steps - start < 2000, "move did not finish");
    };
    let SkillOutcome::Moved(report) = outcome else {
        panic!("{outcome:?}")
    };
    assert_eq!(report.cycles, w.steps - start);
    assert!((report.duration_s - (w.steps - start) as f64 * 0.002).abs() < 1e-9);
    let running_from = first_running.expect("program seen running");
    (w.steps - running_from, report, w.arm.state().q_rad)
}

#[test]
fn movej_takes_the_same_number_of_steps_whatever_the_wall_clock_does() {
    // Counted from the program's first running cycle: the step in which a program sent over
    // 30002 is applied is not yet deterministic under load (docs/ur5e.md, external stepping).
    let (steps, report, q) = movej_mission(false);
    // Trapezoid: 0.5 rad at 1 rad/s, 2 rad/s^2: 0.5 s accelerating and decelerating + 0.25 s
    // cruising = 1.0 s = 500 cycles; the end is seen in the cycle after.
    assert_eq!(steps, 500, "{steps} steps");
    assert!(report.final_error < 0.002);
    let (steps2, _, q2) = movej_mission(true);
    assert_eq!(steps2, steps, "same motion, same number of steps");
    assert_eq!(q2, q, "bit-identical final joints");
}

#[test]
fn a_protective_stop_mid_move_is_an_error() {
    let mut w = World::new(|_| {});
    let now = w.now();
    w.arm
        .start_move_joints(
            [1.5, -H, H, -H, -H, 0.0],
            1.0,
            2.0,
            Duration::from_secs(10),
            now,
        )
        .unwrap();
    for _ in 0..100 {
        assert_eq!(w.cycle().unwrap(), SkillProgress::Running);
    }
    w.sim.trigger_protective_stop("test collision");
    let (result, steps) = w.run_skill(5);
    assert!(
        matches!(result, Err(SkillError::ProtectiveStop { .. })),
        "{result:?}"
    );
    assert_eq!(steps, 1, "seen in the first cycle after the stop");
    assert_eq!(w.arm.active_skill(), None);
    assert_eq!(w.cycle().unwrap(), SkillProgress::Idle);
}

#[test]
fn a_cut_rtde_link_is_connection_lost_and_stopj_reaches_the_controller() {
    let mut w = World::new(|_| {});
    let now = w.now();
    w.arm
        .start_move_joints(
            [2.0, -H, H, -H, -H, 0.0],
            1.0,
            2.0,
            Duration::from_secs(10),
            now,
        )
        .unwrap();
    for _ in 0..200 {
        assert_eq!(w.cycle().unwrap(), SkillProgress::Running);
    }
    assert!(w.sim.snapshot().qd[0] > 0.5, "moving");
    w.sim.cut_rtde_connections();
    let (result, steps) = w.run_skill(5);
    assert!(
        matches!(
            result,
            Err(SkillError::ConnectionLost {
                stop_sent: true,
                ..
            })
        ),
        "{result:?}"
    );
    // EOF is seen in the cycle after the cut (later only if the kernel defers loopback delivery).
    assert!(steps <= 5, "{steps}");
    // The stop program reaches the controller (normally before the next step) and brings the
    // arm to rest.
    let mut waited = 0;
    while w
        .sim
        .with_robot(|r| r.last_program_name() != Some("grop_stop"))
    {
        w.sim.step().unwrap();
        waited += 1;
        assert!(waited < 200, "stopj never arrived");
    }
    for _ in 0..200 {
        w.sim.step().unwrap();
    }
    let s = w.sim.snapshot();
    assert!(s.qd.iter().all(|v| v.abs() < 1e-9), "at rest: {:?}", s.qd);
    assert!(s.q[0] < 1.9, "stopped short of the goal");
    // The loss is reported once; later cycles repeat it without new stops.
    let again = w.arm.update_at(w.now());
    assert!(matches!(again, Err(SkillError::ConnectionLost { .. })));
}

#[test]
fn the_motion_timeout_fires_on_simulated_time_and_stops_the_arm() {
    let mut w = World::new(|_| {});
    let now = w.now();
    let timeout = Duration::from_millis(500);
    w.arm
        .start_move_joints([2.0, -H, H, -H, -H, 0.0], 0.5, 2.0, timeout, now)
        .unwrap();
    // Wall time longer than the timeout passes without a step: nothing fires.
    thread::sleep(Duration::from_millis(600));
    assert_eq!(w.arm.update_at(now).map(|_| ()).ok(), Some(()));
    assert_eq!(w.arm.poll(now).unwrap(), SkillProgress::Running);
    let (result, steps) = w.run_skill(1000);
    assert!(
        matches!(
            result,
            Err(SkillError::Timeout {
                skill: "move_joints",
                ..
            })
        ),
        "{result:?}"
    );
    // 250 cycles to the timeout, then stopj from 0.5 rad/s at 4 rad/s^2 (about 63 cycles).
    assert!((251..=330).contains(&steps), "{steps} steps");
    assert!(w.arm.state().at_rest(0.01), "reported once at rest");
}

#[test]
fn staleness_is_judged_on_the_callers_clock() {
    let mut w = World::new(|_| {});
    let now = w.now();
    // Wall time does not make the state stale ...
    thread::sleep(Duration::from_millis(300));
    w.arm.update_at(now).unwrap();
    assert_eq!(w.arm.state_received_at(), Some(now));
    // ... simulated time without packages does (stale_after = 100 ms).
    w.arm.update_at(now + Duration::from_millis(100)).unwrap();
    let lost = w.arm.update_at(now + Duration::from_millis(102));
    assert!(
        matches!(
            lost,
            Err(SkillError::ConnectionLost {
                stop_sent: true,
                ..
            })
        ),
        "{lost:?}"
    );
}

#[test]
fn the_program_watchdog_runs_on_stepped_time() {
    let mut w = World::new(|_| {});
    let now = w.now();
    w.arm
        .start_move_joints(
            [2.0, -H, H, -H, -H, 0.0],
            0.5,
            2.0,
            Duration::from_secs(20),
            now,
        )
        .unwrap();
    for _ in 0..100 {
        assert_eq!(w.cycle().unwrap(), SkillProgress::Running);
    }
    // The executive stops (no more heartbeats). Wall time alone does not trip the watchdog ...
    thread::sleep(Duration::from_millis(300));
    w.sim.step().unwrap();
    assert_eq!(w.sim.snapshot().runtime_state, 2, "still playing");
    // ... stepped time does: 10 Hz = 0.1 s = 50 cycles after the last heartbeat.
    let mut steps = 1;
    while w.sim.snapshot().runtime_state == 2 {
        w.sim.step().unwrap();
        steps += 1;
        assert!(steps < 100, "watchdog did not stop the program");
    }
    assert!((50..=53).contains(&steps), "stopped after {steps} steps");
}

#[test]
fn gripper_closes_on_an_object_and_times_out_on_simulated_time() {
    let mut w = World::new(|c| c.gripper_object_width_m = Some(0.06));
    let now = w.now();
    w.arm
        .start_gripper(GripperAction::Close, Duration::from_secs(3), now)
        .unwrap();
    // One skill at a time.
    assert!(matches!(
        w.arm
            .start_move_joints(HOME, 1.0, 1.0, Duration::from_secs(1), now),
        Err(SkillError::SkillInProgress { active: "gripper" })
    ));
    let (result, _) = w.run_skill(3000);
    assert_eq!(
        result.unwrap(),
        SkillOutcome::Gripper(GripOutcome::ObjectWhileClosing)
    );
    // Opening 0.06 m wide takes about 0.3 s at full speed; 20 ms of simulated time is too short.
    let now = w.now();
    w.arm
        .start_gripper(GripperAction::Open, Duration::from_millis(20), now)
        .unwrap();
    let (result, steps) = w.run_skill(100);
    assert!(matches!(result, Err(SkillError::Gripper(_))), "{result:?}");
    assert!((10..=16).contains(&steps), "{steps} steps");
}
