//! The executive in one process against the simulated RMP on an in-memory CAN bus, a fake arm,
//! and a test harness that plays the planner and the localiser on iceoryx2 topics: a whole
//! mission, with a counting allocator proving that no cycle allocates after start-up, and the
//! safety reactions to a silent base, a dead planner and missing localisation.
#![allow(
    clippy::too_many_lines,
    reason = "a test scenario (or the fuzz harness's) reads top to bottom as one story"
)]
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failure panics with its message

use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Duration;

use can_bus::{MemoryBus, MemoryBusNode};
use grop_clock::{Clock, ManualClock};
use grop_ipc::{
    BasePoseMsg, BaseStateMsg, EventKind, EventMsg, HeartbeatMsg, IpcNode, PoseFixKind,
    ProcessRole, ReplanRequestMsg, TableSide, TaskPlanMsg, TaskStep, TopicPublisher,
    TopicSubscriber,
};
use grop_onboard::executive::inputs::InputSources;
use grop_onboard::executive::unload::{ArmFault, ArmPort, SkillStatus};
use grop_onboard::executive::{
    AbortReason, ArmDevice, ArmSnapshot, Executive, ExecutiveConfig, MissionState, RmpExecutive,
};
use sim_rmp::{SimConfig, SimRmp, SimRmpNode};
use ur5e_kin::Joints;
use world::{RobotConfig, Scene, UnloadTarget};

// ---- the counting allocator (test-support): counts allocations of threads that opted in -----

#[global_allocator]
static GLOBAL: test_support::CountingAlloc = test_support::CountingAlloc;

// ---- the harness ---------------------------------------------------------------------------

static N: AtomicU64 = AtomicU64::new(0);

fn namespace(test: &str) -> String {
    format!(
        "test-{}-{}-{test}",
        std::process::id(),
        N.fetch_add(1, Ordering::Relaxed)
    )
}

/// An arm whose every skill takes `cycles` cycles; closing grips an object.
struct FakeArm {
    cycles: u32,
    left: u32,
    closed: bool,
    stopped: bool,
    moves: u32,
}

impl ArmPort for FakeArm {
    fn start_move_joints(&mut self, _q: &Joints, _now: Duration) -> Result<(), ArmFault> {
        self.left = self.cycles;
        self.moves += 1;
        Ok(())
    }
    fn start_gripper(&mut self, close: bool, _now: Duration) -> Result<(), ArmFault> {
        self.closed = close;
        self.left = self.cycles;
        Ok(())
    }
    fn poll(&mut self, _now: Duration) -> Result<SkillStatus, ArmFault> {
        if self.left > 0 {
            self.left -= 1;
            return Ok(SkillStatus::Running);
        }
        Ok(SkillStatus::Done {
            object_held: self.closed,
        })
    }
}

impl ArmDevice for FakeArm {
    fn update(&mut self, _now: Duration) -> Result<ArmSnapshot, ArmFault> {
        Ok(ArmSnapshot {
            robot_mode: 7,
            program_running: self.left > 0,
            ..ArmSnapshot::default()
        })
    }
    fn stop(&mut self, _now: Duration) {
        self.stopped = true;
        self.left = 0;
    }
}

fn scene() -> Scene {
    let mut s = Scene::empty_paper_room();
    s.name = "executive-in-process".into();
    s.targets = vec![
        UnloadTarget::on_center_line(-1.0),
        UnloadTarget::on_center_line(0.5),
        UnloadTarget::on_center_line(1.5),
    ];
    s
}

struct Harness {
    exec: RmpExecutive<MemoryBusNode, FakeArm>,
    clock: Arc<ManualClock>,
    base: SimRmpNode<MemoryBusNode>,
    scene: Scene,
    plans: TopicPublisher<TaskPlanMsg>,
    poses: TopicPublisher<grop_ipc::BasePoseMsg>,
    health: TopicPublisher<HeartbeatMsg>,
    /// The operator's enable, given once the executive runs (a start is not an enable).
    enable: TopicPublisher<grop_ipc::OperatorEnableMsg>,
    enabled: bool,
    requests: TopicSubscriber<ReplanRequestMsg>,
    events: TopicSubscriber<EventMsg>,
    states: TopicSubscriber<BaseStateMsg>,
    now: Duration,
    seen: Vec<EventKind>,
    /// True base position at every GoalReached.
    stops: Vec<[f64; 2]>,
    planner_alive: bool,
    fixes_on: bool,
    /// Noisy fixes as the world makes them (None: exact fixes).
    noisy: Option<hil_world::fixes::FixSimulator>,
    /// The plan the harness answers with (None: the default mission).
    custom_plan: Option<Vec<TaskStep>>,
    _nodes: (IpcNode, IpcNode),
    _bus: MemoryBus,
}

impl Harness {
    fn new(test: &str) -> Self {
        let ns = namespace(test);
        let bus = MemoryBus::new();
        let scene = scene();
        let robot = RobotConfig::default();
        let exec_node = IpcNode::new(&ns, "executive").unwrap();
        let test_node = IpcNode::new(&ns, "harness").unwrap();
        let clock = Arc::new(ManualClock::default());
        let exec = Executive::new(
            // The harness plays the planner and the localiser.
            ExecutiveConfig {
                inputs: InputSources::all("harness"),
                ..ExecutiveConfig::for_robot(&robot)
            },
            Arc::clone(&clock) as Arc<dyn Clock>,
            bus.join(),
            FakeArm {
                cycles: 40,
                left: 0,
                closed: false,
                stopped: false,
                moves: 0,
            },
            &exec_node,
            scene.clone(),
            3,
        )
        .unwrap();
        let base = SimRmpNode::new(bus.join(), SimRmp::new(SimConfig::default()));
        Self {
            exec,
            clock,
            base,
            scene,
            plans: test_node.publisher().unwrap(),
            poses: test_node.publisher().unwrap(),
            health: test_node.publisher().unwrap(),
            enable: test_node.publisher().unwrap(),
            enabled: false,
            requests: test_node.subscriber().unwrap(),
            events: test_node.subscriber().unwrap(),
            states: test_node.subscriber().unwrap(),
            now: Duration::ZERO,
            seen: Vec::new(),
            stops: Vec::new(),
            planner_alive: true,
            fixes_on: true,
            noisy: None,
            custom_plan: None,
            _nodes: (exec_node, test_node),
            _bus: bus,
        }
    }

    /// The true base pose in the world (the sim's odometry frame starts at the scene's start).
    fn truth(&self) -> [f64; 3] {
        let p = self.base.sim().pose();
        let s = self.scene.robot_start;
        let (sn, c) = s.yaw_rad.sin_cos();
        [
            s.x_m + c * p.x_m - sn * p.y_m,
            s.y_m + sn * p.x_m + c * p.y_m,
            s.yaw_rad + p.yaw_rad,
        ]
    }

    fn plan_for(&self, request: u64) -> Vec<TaskStep> {
        let st = self.scene.loading_station;
        let mut steps = vec![
            TaskStep::navigate(st.x_m, st.y_m, -std::f64::consts::FRAC_PI_2, 2.5),
            TaskStep::load(0b111, st.x_m, st.y_m),
        ];
        let _ = request;
        for (i, t) in self.scene.targets.iter().enumerate() {
            let goal = [t.x_m, 6.0 - 0.75, std::f64::consts::FRAC_PI_2];
            steps.push(TaskStep::navigate(goal[0], goal[1], goal[2], 10.0));
            steps.push(TaskStep::unload(
                i as u32,
                TableSide::Near,
                t.as_array(),
                goal,
                0.8,
            ));
        }
        steps
    }

    /// One 2 ms cycle of everything; `count` turns the allocation counter on for the
    /// executive's cycle only.
    fn cycle(&mut self, count: bool) {
        let now = self.now;
        if !self.enabled && now > Duration::ZERO {
            self.enabled = true;
            self.enable
                .publish(&grop_ipc::OperatorEnableMsg {
                    seq: 1,
                    stamp_ns: now.as_nanos() as u64,
                    pid: std::process::id(),
                    reserved: 0,
                })
                .unwrap();
        }
        self.base.poll(now).unwrap();
        if let Some(noisy) = &mut self.noisy {
            let (v, w) = self.base.sim().velocity();
            noisy.observe_motion(f64::from(v).abs() + 0.3 * f64::from(w).abs(), 0.002);
        }
        if (now.as_millis() % 100) == 0 {
            let truth = self.truth();
            let t = match &mut self.noisy {
                Some(noisy) => noisy.global_fix(truth),
                None => truth,
            };
            let ns = now.as_nanos() as u64;
            if self.fixes_on {
                self.poses
                    .publish(&BasePoseMsg::fix(
                        ns,
                        ns,
                        PoseFixKind::Global,
                        t,
                        0.01,
                        0.01,
                    ))
                    .unwrap();
                let (v, w) = self.base.sim().velocity();
                if v.abs() < 0.005 && w.abs() < 0.005 && t[1] > 4.5 && self.noisy.is_none() {
                    self.poses
                        .publish(&BasePoseMsg::fix(
                            ns + 1,
                            ns,
                            PoseFixKind::TableRelative,
                            t,
                            0.005,
                            0.005,
                        ))
                        .unwrap();
                }
            }
            if self.planner_alive {
                self.health
                    .publish_with(|h| {
                        // The executive accepts the planner's own pid and an advancing sequence.
                        h.seq = ns;
                        h.pid = std::process::id();
                        h.stamp_ns = ns;
                        h.set_role(ProcessRole::Planner);
                    })
                    .unwrap();
            }
        }
        while let Some(req) = self.requests.try_recv().unwrap() {
            if !self.planner_alive {
                continue;
            }
            let mut steps = match &self.custom_plan {
                Some(p) => p.clone(),
                None => self.plan_for(req.request_id),
            };
            if req.request_id > 1 {
                // A replan: what is left, no station visit (the paper's no-retry: drop it).
                steps.retain(|s| {
                    s.kind() == Ok(grop_ipc::TaskStepKind::Navigate) && s.y_m > 3.0
                        || s.kind() == Ok(grop_ipc::TaskStepKind::Unload)
                });
                steps.clear();
            }
            // What the planner node writes into every plan: how the base docks and backs out.
            grop_onboard::docking::Docking::new(self.scene.clone(), &RobotConfig::default())
                .annotate(
                    &mut steps,
                    req.pose,
                    req.flags & grop_ipc::REQUEST_AT_TABLE != 0,
                );
            grop_onboard::tray_plan::assign_slots(
                &mut steps,
                &grop_onboard::tray_plan::tray_of(&req.tray),
                3,
            )
            .unwrap();
            let id = req.request_id;
            self.plans
                .publish_with(|p| {
                    p.plan_id = id;
                    p.answers_request = id;
                    p.stamp_ns = now.as_nanos() as u64;
                    p.set_steps(&steps).unwrap();
                })
                .unwrap();
        }
        // Time stands still while the executive's worker holds the clock.
        while self.clock.holds() > 0 {
            std::thread::yield_now();
        }
        test_support::count_this_thread(count);
        self.exec.cycle(now);
        test_support::count_this_thread(false);
        while let Some(ev) = self.events.try_recv().unwrap() {
            if let Ok(k) = ev.kind() {
                if k == EventKind::GoalReached {
                    let t = self.truth();
                    self.stops.push([t[0], t[1]]);
                }
                self.seen.push(k);
            }
        }
        self.now += Duration::from_millis(2);
    }

    fn run_until(&mut self, limit: Duration, count: bool, done: impl Fn(&Self) -> bool) -> bool {
        let end = self.now + limit;
        while self.now < end {
            self.cycle(count);
            if done(self) {
                return true;
            }
        }
        false
    }

    /// Runs until the mission has started (base in tractor mode, localised, plan asked for).
    fn start_mission(&mut self) {
        assert!(
            self.run_until(Duration::from_secs(10), false, |h| h.exec.state()
                == MissionState::Running),
            "the mission never started: {:?}",
            self.seen
        );
    }

    /// Runs until the simulated base drives faster than `speed_mps`.
    fn drive_until_faster_than(&mut self, speed_mps: f32) {
        assert!(
            self.run_until(Duration::from_secs(10), false, |h| h
                .base
                .sim()
                .velocity()
                .0
                .abs()
                > speed_mps),
            "the base never reached {speed_mps} m/s"
        );
    }

    fn last_state(&self) -> Option<BaseStateMsg> {
        let mut last = None;
        while let Some(s) = self.states.try_recv().unwrap() {
            last = Some(*s);
        }
        last
    }
}

#[test]
fn a_whole_mission_runs_and_its_cycles_allocate_nothing_but_iceoryx2_loans() {
    let mut h = Harness::new("mission");
    // Start-up: the driver configures the base, enters tractor mode, the first fix arrives.
    h.start_mission();
    let before = test_support::this_thread_allocations();
    test_support::trace_allocations(std::env::var_os("GROP_ALLOC_TRACE").is_some());
    let published_before = h.exec.stats().published;
    let finished = h.run_until(Duration::from_secs(400), true, |h| {
        matches!(
            h.exec.state(),
            MissionState::Finished | MissionState::Aborted(_)
        )
    });
    let allocations = test_support::this_thread_allocations() - before;
    assert!(
        finished,
        "mission did not end: {:?}, events {:?}",
        h.exec.state(),
        h.seen
    );
    assert_eq!(
        h.exec.state(),
        MissionState::Finished,
        "events {:?}",
        h.seen
    );
    let stats = h.exec.stats();
    assert_eq!(stats.unloads_ok, 3, "events {:?}", h.seen);
    assert_eq!(stats.unloads_failed, 0);
    // The executive's own code allocates nothing; iceoryx2 0.10's `loan_uninit` allocates one
    // 104-byte Rc/Arc block per published sample (upstream: ChunkMutSharedState::new), so the
    // count must equal the messages published, exactly: any other allocation shows up here.
    let published = stats.published - published_before;
    assert!(
        published > stats.cycles / 2,
        "arm state is published every cycle"
    );
    assert_eq!(
        allocations, published,
        "the executive allocated {allocations} times over {} cycles, publishing {published} messages",
        stats.cycles
    );
    // Every step reported.
    for kind in [
        EventKind::PlanStarted,
        EventKind::GoalReached,
        EventKind::Loaded,
        EventKind::UnloadSucceeded,
        EventKind::PlanFinished,
    ] {
        assert!(h.seen.contains(&kind), "no {kind:?} in {:?}", h.seen);
    }
    // The base ended near the last goal, standing.
    let t = h.truth();
    assert!(
        (t[0] - 1.5).abs() < 0.1 && (t[1] - 5.25).abs() < 0.1,
        "{t:?}"
    );
}

#[test]
fn a_silent_base_aborts_and_commands_zero() {
    let mut h = Harness::new("silent");
    h.start_mission();
    // Drive until the base moves.
    h.drive_until_faster_than(0.2);
    h.base.sim_mut().set_silent(true);
    assert!(h.run_until(Duration::from_secs(2), false, |h| matches!(
        h.exec.state(),
        MissionState::Aborted(_)
    )));
    assert_eq!(
        h.exec.state(),
        MissionState::Aborted(AbortReason::BaseLinkLost)
    );
    h.run_until(Duration::from_millis(200), false, |_| false);
    let s = h.last_state().unwrap();
    assert_eq!(s.link_up, 0);
    assert!(s.commanded_speed_mps.abs() < 0.3, "ramping down: {s:?}");
    h.run_until(Duration::from_secs(2), false, |_| false);
    let s = h.last_state().unwrap();
    assert_eq!(s.commanded_speed_mps, 0.0);
    assert!(h.seen.contains(&EventKind::LinkLost));
    assert!(h.seen.contains(&EventKind::MissionAborted));
}

/// A restart is not an enable: the enable the topic keeps for late joiners was given before
/// this executive started, and it is refused; only a fresh one arms the base.
#[test]
fn an_enable_given_before_the_executive_started_does_not_arm_it() {
    let mut h = Harness::new("old-enable");
    h.enabled = true;
    // The operator enabled an earlier executive at 0.5 s; this one starts at 1 s.
    h.enable
        .publish(&grop_ipc::OperatorEnableMsg {
            seq: 1,
            stamp_ns: 500_000_000,
            pid: std::process::id(),
            reserved: 0,
        })
        .unwrap();
    h.now = Duration::from_secs(1);
    h.run_until(Duration::from_secs(3), false, |_| false);
    assert_eq!(h.exec.state(), MissionState::Starting, "{:?}", h.seen);
    assert!(h.exec.enables_refused() >= 1);
    assert!(
        h.base.sim().state() != rmp_codec::v3::OperationalState::Tractor,
        "the base was asked for tractor without an enable"
    );
    assert!(h.seen.contains(&EventKind::Enable), "{:?}", h.seen);
    // A fresh enable arms it.
    h.enable
        .publish(&grop_ipc::OperatorEnableMsg {
            seq: 2,
            stamp_ns: h.now.as_nanos() as u64,
            pid: std::process::id(),
            reserved: 0,
        })
        .unwrap();
    h.start_mission();
}

#[test]
fn a_dead_planner_stops_the_base_within_its_deceleration_ramp() {
    let mut h = Harness::new("planner-dead");
    h.start_mission();
    h.drive_until_faster_than(0.3);
    let speed = f64::from(h.base.sim().velocity().0.abs());
    h.planner_alive = false;
    let died = h.now;
    assert!(h.run_until(Duration::from_secs(2), false, |h| matches!(
        h.exec.state(),
        MissionState::Aborted(_)
    )));
    assert_eq!(
        h.exec.state(),
        MissionState::Aborted(AbortReason::PlannerLost)
    );
    // Detection within the planner timeout (+ one heartbeat period and one base period).
    assert!(h.now - died <= Duration::from_millis(500 + 100 + 20 + 2));
    assert!(h.run_until(Duration::from_secs(3), false, |h| {
        let (v, w) = h.base.sim().velocity();
        v.abs() < 0.005 && w.abs() < 0.005
    }));
    // Stopped within timeout + the ramp at the robot's deceleration (+ 0.2 s of margin).
    let ramp = speed / RobotConfig::default().accel_mps2;
    let took = (h.now - died).as_secs_f64();
    assert!(
        took <= 0.62 + ramp + 0.2,
        "took {took:.2} s, ramp {ramp:.2} s"
    );
    assert!(h.seen.contains(&EventKind::PeerLost));
}

#[test]
fn a_safety_stop_brings_the_base_to_rest_at_the_emergency_deceleration() {
    // A dead planner is a latched safety stop: the shell asks the driver for its safety stop,
    // whose ramp is the robot file's emergency deceleration (3.923 m/s^2), not the comfort
    // 0.5 m/s^2 (0.7 s from 0.35 m/s).
    let mut h = Harness::new("safety-stop-ramp");
    h.start_mission();
    h.drive_until_faster_than(0.35);
    h.planner_alive = false;
    assert!(h.run_until(Duration::from_secs(2), false, |h| matches!(
        h.exec.state(),
        MissionState::Aborted(_)
    )));
    let aborted = h.now;
    let speed = f64::from(h.base.sim().velocity().0.abs());
    assert!(h.run_until(Duration::from_secs(3), false, |h| {
        h.base.sim().velocity().0.abs() < 0.005
    }));
    let took = (h.now - aborted).as_secs_f64();
    let robot = RobotConfig::default();
    let emergency = speed / robot.emergency_decel_mps2;
    let comfort = speed / robot.accel_mps2;
    println!(
        "safety stop: {speed:.2} m/s to rest in {took:.3} s (emergency ramp {emergency:.3} s, comfort {comfort:.3} s)"
    );
    // The emergency ramp plus two base periods (the command reaches the base a tick later).
    assert!(
        took <= emergency + 0.045,
        "{speed:.2} m/s to rest took {took:.3} s: the emergency ramp is {emergency:.3} s, the comfort one {comfort:.3} s"
    );
}

#[test]
fn missing_localisation_holds_the_base_until_fixes_return() {
    let mut h = Harness::new("no-fixes");
    h.start_mission();
    h.drive_until_faster_than(0.2);
    h.fixes_on = false;
    assert!(h.run_until(Duration::from_secs(4), false, |h| {
        h.base.sim().velocity().0.abs() < 0.005
    }));
    assert!(h.seen.contains(&EventKind::StaleInput));
    assert_eq!(
        h.exec.state(),
        MissionState::Running,
        "holding, not aborted"
    );
    h.fixes_on = true;
    assert!(h.run_until(
        Duration::from_secs(5),
        false,
        |h| h.base.sim().velocity().0.abs() > 0.1
    ));
}

/// Realised minus commanded stops over many legs in closed loop (localisation with the world's
/// per-leg bias, the follower, the driver, the simulated base) against the trial simulator's
/// N(0, sigma^2 I): same mean and spread (two-sample Kolmogorov-Smirnov at 5 %).
#[test]
fn realised_stops_follow_the_trial_simulators_navigation_noise() {
    use hil_world::fixes::{FixModel, FixSimulator};
    use rand::SeedableRng;
    let mut h = Harness::new("nav-noise");
    let robot = RobotConfig::default();
    let sigma = robot.nav_noise_sigma_m;
    h.noisy = Some(FixSimulator::new(
        FixModel {
            still_before_leg_s: 0.3,
            ..FixModel::for_sigma(sigma)
        },
        11,
    ));
    // 120 legs back and forth across the empty room (2.5 m each).
    let a = [-1.5, 3.5, 0.0];
    let b = [1.0, 3.5, std::f64::consts::PI];
    let goals: Vec<[f64; 3]> = (0..120).map(|k| if k % 2 == 0 { b } else { a }).collect();
    h.custom_plan = Some(
        goals
            .iter()
            .map(|g| TaskStep::navigate(g[0], g[1], g[2], 6.0))
            .collect(),
    );
    h.start_mission();
    let mut residuals = Vec::new();
    let mut seen = h.seen.len();
    let finished = h.run_until(Duration::from_secs(3000), false, |h| {
        matches!(
            h.exec.state(),
            MissionState::Finished | MissionState::Aborted(_)
        )
    });
    let _ = finished;
    // Re-run, recording at every GoalReached (the harness keeps the event list).
    let _ = &mut seen;
    assert_eq!(h.exec.state(), MissionState::Finished, "{:?}", h.seen);
    residuals.extend(h.stops.iter().copied());
    assert!(
        residuals.len() >= 100,
        "{} legs; events {:?}",
        residuals.len(),
        h.seen
    );
    // Pair each stop with its commanded goal.
    let closed: Vec<f64> = residuals
        .iter()
        .enumerate()
        .flat_map(|(k, stop)| {
            let g = goals[k];
            [stop[0] - g[0], stop[1] - g[1]]
        })
        .collect();
    // The trial simulator's draws for as many legs.
    let scene = Scene::empty_paper_room();
    let mut sim = trial_sim::TrialSimulator::new(&scene, &robot);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
    let mut trial = Vec::new();
    for _ in 0..residuals.len() {
        let o = sim.run([0.0, 6.0, 1.3], world::Side::Near, (0.0, 5.2), &mut rng);
        trial.push(o.realised.x_m);
        trial.push(o.realised.y_m - 5.2);
    }
    let stats = |v: &[f64]| {
        let n = v.len() as f64;
        let m = v.iter().sum::<f64>() / n;
        let sd = (v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
        (m, sd)
    };
    let (m_c, sd_c) = stats(&closed);
    let (m_t, sd_t) = stats(&trial);
    println!(
        "closed loop: mean {m_c:+.4} sd {sd_c:.4}; trial simulator: mean {m_t:+.4} sd {sd_t:.4}"
    );
    assert!(
        m_c.abs() < 3.0 * sigma / (closed.len() as f64).sqrt() + 0.005,
        "mean {m_c}"
    );
    assert!(
        (sd_c / sigma - 1.0).abs() < 0.15,
        "sd {sd_c} vs sigma {sigma}"
    );
    // Two-sample KS.
    let mut x = closed.clone();
    let mut y = trial.clone();
    x.sort_by(f64::total_cmp);
    y.sort_by(f64::total_cmp);
    let (mut i, mut j, mut d) = (0usize, 0usize, 0.0f64);
    while i < x.len() && j < y.len() {
        if x[i] <= y[j] {
            i += 1;
        } else {
            j += 1;
        }
        d = d.max((i as f64 / x.len() as f64 - j as f64 / y.len() as f64).abs());
    }
    let (n, m) = (x.len() as f64, y.len() as f64);
    let critical = 1.36 * ((n + m) / (n * m)).sqrt();
    assert!(d < critical, "KS distance {d:.3} >= {critical:.3}");
}

/// A robot file whose tray (`carry_capacity`) is larger than the executive's tray slots is
/// refused at start with an error naming the field (plans would load objects with no slot).
#[test]
fn a_carry_capacity_above_the_tray_slots_is_refused() {
    let ns = namespace("capacity");
    let bus = MemoryBus::new();
    let robot = RobotConfig {
        carry_capacity: 4,
        ..RobotConfig::default()
    };
    let config = ExecutiveConfig::for_robot(&robot);
    assert_eq!(config.tray_slots.len(), 3);
    let node = IpcNode::new(&ns, "executive").unwrap();
    let clock = Arc::new(ManualClock::default());
    let result = Executive::new(
        config,
        clock as Arc<dyn Clock>,
        bus.join(),
        FakeArm {
            cycles: 40,
            left: 0,
            closed: false,
            stopped: false,
            moves: 0,
        },
        &node,
        scene(),
        3,
    );
    let Err(error) = result else {
        panic!("a tray of 4 on 3 slots was accepted");
    };
    let text = error.to_string();
    assert!(
        text.contains("carry_capacity = 4") && text.contains("3 tray slots"),
        "{text}"
    );
}

/// The world refuses the same robot file: its tray (`WorldConfig::tray_slots`) has 3 slots.
#[test]
fn the_world_refuses_a_carry_capacity_above_its_tray_slots() {
    let robot = RobotConfig {
        carry_capacity: 4,
        ..RobotConfig::default()
    };
    let config = hil_world::WorldConfig::new(&namespace("world-capacity"), scene(), robot, 1);
    assert_eq!(config.tray_slots.len(), 3);
    let Err(error) = hil_world::World::new(config) else {
        panic!("a tray of 4 on 3 slots was accepted");
    };
    let text = error.to_string();
    assert!(
        text.contains("carry_capacity = 4") && text.contains("3 tray slots"),
        "{text}"
    );
}
