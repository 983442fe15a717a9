//! The world's step as an ordered list of systems (as copper-rs's task list).
//!
//! [`World::run`] builds the list once and, every step of simulated time, runs each system's
//! [`System::step`] in the fixed order below. The systems share one [`Ctx`]: the world's
//! devices and ports, the running truth (chairs move), the report, the fault injector's state,
//! this step's readings of the devices and the mission's shared state. What only one system
//! needs (its schedule, sequence numbers, buffers) is its own.
//!
//! The order is part of the world's behaviour: the missions are deterministic and logged
//! byte for byte, so every publish and every draw of a random number happens in this order,
//! and a change of order changes the logs.
//!
//! | # | System | What it does |
//! |---|--------|--------------|
//! | 1 | [`clock::Join`] | waits (simulated time held at zero) until the onboard processes joined, then lets the mission clock run at its pace |
//! | 2 | [`faults::Inject`] | the fault injector's hooks: strikes when the trigger comes, keeps up what lasts, releases |
//! | 3 | [`faults::EnableAfterRelease`] | the operator enables once a released fault is clear |
//! | 4 | [`scene::ChairMoves`] | moves chairs when due (the sensor sees the new truth) |
//! | 5 | [`devices::Base`] | the CAN bus's injector and the simulated RMP; contact stalls the drives |
//! | 6 | [`devices::Arm`] | one RTDE cycle of the simulated UR5e |
//! | 7 | [`devices::Lidar`] | the range sensor's packets fired by now |
//! | 8 | [`devices::Readings`] | this step's readings: base speed (and the fixes' motion model), arm state, tool point |
//! | 9 | [`faults::Watch`] | after a fault: when base and arm stopped, the stops asked, motion after a release |
//! | 10 | [`progress::Legs`] | leg bookkeeping: a start after standing still begins a leg; realised vs commanded goal |
//! | 11 | [`scene::Contacts`] | base and arm against the furniture, every 10 ms (world events) |
//! | 12 | [`objects::Loads`] | the station loads what the executive asked for once the base stands there |
//! | 13 | [`objects::Tray`] | tray, gripper, release and judgement |
//! | 14 | [`publish::Truth`] | `world/truth` at 20 Hz (the log's ground truth) |
//! | 15 | [`publish::Fixes`] | localisation fixes on `base/pose` |
//! | 16 | [`publish::Heartbeat`] | the world's heartbeat, with each round of fixes |
//! | 17 | [`publish::Operator`] | the operator's enable, when due |
//! | 18 | [`publish::Camera`] | the overhead camera's frames |
//! | 19 | [`intake::Plans`] | the task plans (report, the goal of the legs) |
//! | 20 | [`intake::Events`] | the onboard events (report, end of mission, the operator asked for) |
//! | 21 | [`intake::Deaths`] | participants the clock saw die, and when base and arm stopped afterwards |
//! | 22 | [`progress::Trajectory`] | the true pose every 200 ms |
//! | 23 | [`progress::Progress`] | a progress line (when asked for) |
//! | 24 | [`clock::End`] | step timing, end conditions (end of mission and linger, time limit) |
//! | 25 | [`clock::Advance`] | moves the simulated clock one step on (or jumps it: a fault) |
//!
//! The stop flag of [`World::run`] is polled before the first system of every step.

mod clock;
mod context;
mod devices;
mod faults;
mod intake;
mod objects;
mod progress;
mod publish;
mod scene;

use std::time::{Duration, Instant};

use nalgebra::{Isometry3, Point3};

use crate::injector::Injector;
use crate::report::{LoopTiming, MissionEnd, WorldReport};
use crate::{World, WorldConfig, faults::FaultRecord, objects as obj, secs};
use context::{Ctx, Flow, Mission, Reading, System};

/// The systems in their order (the table in the module docs).
fn systems(cfg: &WorldConfig) -> Vec<Box<dyn System>> {
    vec![
        Box::new(clock::Join),
        Box::new(faults::Inject),
        Box::new(faults::EnableAfterRelease),
        Box::new(scene::ChairMoves::new(cfg)),
        Box::new(devices::Base),
        Box::new(devices::Arm),
        Box::new(devices::Lidar),
        Box::new(devices::Readings),
        Box::new(faults::Watch),
        Box::new(progress::Legs::new()),
        Box::new(scene::Contacts::default()),
        Box::new(objects::Loads::default()),
        Box::new(objects::Tray),
        Box::new(publish::Truth::default()),
        Box::new(publish::Fixes::default()),
        Box::new(publish::Heartbeat::default()),
        Box::new(publish::Operator::default()),
        Box::new(publish::Camera::new(cfg)),
        Box::new(intake::Plans),
        Box::new(intake::Events),
        Box::new(intake::Deaths),
        Box::new(progress::Trajectory::default()),
        Box::new(progress::Progress::default()),
        Box::new(clock::End),
        Box::new(clock::Advance),
    ]
}

impl World {
    /// Runs the mission to its end and returns the report. `stop` is polled every step (a
    /// signal handler's flag). Every step runs the systems of [`crate::systems`] in their
    /// order.
    pub fn run(&mut self, stop: &dyn Fn() -> bool) -> WorldReport {
        let wall_start = Instant::now();
        // The truth may change during the run (chairs moved); the configuration keeps the start.
        let cfg = self.config.clone();
        let report = new_report(&cfg);
        let mut systems = systems(&cfg);
        let reading = Reading {
            pose: self.base_pose(),
            v: 0.0,
            w: 0.0,
            speed: 0.0,
            world_from_base: Isometry3::identity(),
            snap: self.arm.snapshot(),
            tcp: Point3::origin(),
        };
        let dt = cfg.step;
        let mut ctx = Ctx {
            world: self,
            cfg,
            report,
            injector: Injector::default(),
            mission: Mission::default(),
            reading,
            now: Duration::ZERO,
            dt,
            wall_start,
            work_started: wall_start,
        };
        'steps: loop {
            ctx.now = ctx.world.host.now();
            ctx.work_started = Instant::now();
            if stop() {
                break;
            }
            for system in &mut systems {
                match system.step(&mut ctx) {
                    Flow::Next => {}
                    Flow::Wait => continue 'steps,
                    Flow::Stop => break 'steps,
                }
            }
        }
        finish(ctx)
    }
}

/// The report before the first step.
fn new_report(cfg: &WorldConfig) -> WorldReport {
    WorldReport {
        scene: cfg.scene.name.clone(),
        seed: cfg.seed,
        end: MissionEnd::NeverStarted,
        placed: 0,
        placed_end_state: 0,
        objects: Vec::new(),
        collisions: Vec::new(),
        legs: Vec::new(),
        trajectory: Vec::new(),
        events: Vec::new(),
        plans: Vec::new(),
        deaths: Vec::new(),
        timing: LoopTiming::default(),
        fault: cfg.fault.map(|f| FaultRecord {
            spec: f.to_string(),
            ..FaultRecord::default()
        }),
        commands: crate::faults::CommandMonitor::default(),
        max_base_speed: (0.0, 0.0),
        min_base_clearance: None,
        base_blocks: 0,
        not_attempted: Vec::new(),
    }
}

/// The report at the end of the run: the bus's and the base's counts, the objects and their
/// verdicts, the timing.
fn finish(ctx: Ctx<'_>) -> WorldReport {
    let Ctx {
        world,
        mut report,
        injector,
        mission,
        wall_start,
        ..
    } = ctx;
    report.commands = world.base.bus_mut().monitor();
    report.base_blocks = world.base.sim().stats().blocks;
    if let (Some(rec), Some(at)) = (report.fault.as_mut(), injector.at) {
        rec.can = world.base.bus_mut().counts();
        rec.can.intruder = injector.intruder_frames;
        let at_s = secs(at);
        rec.commanded_zero_at_s = report.commands.zero_since_s.map(|z| z.max(at_s));
        rec.first_zero_command_at_s = report.commands.first_zero_after_mark_s;
    }

    report.objects = world.objects.objects().to_vec();
    report.not_attempted = report
        .objects
        .iter()
        .filter(|o| o.state == obj::ObjectState::AtStation)
        .map(|o| o.index)
        .collect();
    let verdicts: Vec<obj::Verdict> = report
        .objects
        .iter()
        .filter_map(|o| match o.state {
            obj::ObjectState::Released { verdict, .. } => Some(verdict),
            _ => None,
        })
        .collect();
    report.placed = verdicts.iter().filter(|v| v.placed_strictly()).count();
    report.placed_end_state = verdicts.iter().filter(|v| v.placed_end_state()).count();
    report.timing.sim_time_s = secs(world.host.now());
    report.timing.wall_time_s = wall_start.elapsed().as_secs_f64();
    report.timing.world_step_us =
        mission.step_wall.as_secs_f64() * 1e6 / report.timing.steps.max(1) as f64;
    report.timing.request_to_plan_s = match (mission.first_request, mission.first_plan) {
        (Some(r), Some(p)) => Some((p - r).max(0.0)),
        _ => None,
    };
    report.timing.plan_to_motion_s = match (mission.first_plan, mission.first_motion) {
        (Some(p), Some(m)) => Some(m - p),
        _ => None,
    };
    report
}

#[cfg(test)]
mod tests {
    /// The list runs in the order the module docs give (the table is the documentation of
    /// the world's behaviour, so it must not drift from the code).
    #[test]
    fn the_list_is_the_documented_order() {
        let docs = include_str!("mod.rs");
        let documented: Vec<&str> = docs
            .lines()
            .filter_map(|l| l.strip_prefix("//! | "))
            .filter_map(|l| l.split("[`").nth(1))
            .filter_map(|l| l.split("`]").next())
            .filter_map(|path| path.rsplit("::").next())
            .collect();
        let cfg = crate::WorldConfig::new(
            "order",
            world::Scene::empty_paper_room(),
            world::RobotConfig::default(),
            0,
        );
        let names: Vec<&str> = super::systems(&cfg).iter().map(|s| s.name()).collect();
        assert_eq!(names, documented);
    }
}
