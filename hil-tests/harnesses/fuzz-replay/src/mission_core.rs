//! The executive's pure core (`MissionCore::update`) under arbitrary input sequences: plans,
//! pose fixes, base readings and ticks, arm states and skill results, worker answers, scan
//! alignments, collision-monitor actions, the operator enable, and time going forward by
//! arbitrary steps (20 ms up to 2^32 s).
//!
//! The harness plays a cooperative world unless the input says otherwise: each cycle the base
//! drives what the core commanded (odometry integrated), a global fix agrees with it, the
//! driver's tick reports what was sent, the planner beats, worker jobs are answered with a
//! straight path or a direct unload plan, and arm skills finish. A cycle's flags replace any of
//! these with values decoded from the input (raw `f64` bit patterns among them, or numbers near
//! the room), so the fuzzer reaches deep mission phases and then feeds them nonsense.
//!
//! Checked every cycle: no panic, and the velocity the core commands is finite and within the
//! robot file's limits (|speed| <= `speed_mps`, |yaw rate| <= `yaw_rate_radps`). The core cuts
//! its output to those limits as its last step (`CoreStats::bounded` counts when it had to);
//! with `MISSION_CORE_STRICT=1` in the environment the target also fails when that cut acted,
//! to hunt the input that made a law produce nonsense.
#![allow(clippy::expect_used)] // a fuzz harness: its fixed setup is constant, and a panic is a finding

use std::sync::{Arc, OnceLock};
use std::time::Duration;

use grop_ipc::{BasePoseMsg, MAX_TASK_STEPS, PoseFixKind, TaskPlanMsg, TaskStep};
use grop_onboard::executive::cycle::MonitorAction;
use grop_onboard::executive::scan_match::Alignment;
use grop_onboard::executive::unload::{
    ArmFault, PlaceJoints, SkillStatus, TrayGeometry, UnloadFailure, UnloadPlan, solve_tray,
};
use grop_onboard::executive::worker::{
    Answer, FollowerPath, Job, MAX_PATH_POINTS, PathFailure, SeenPoints,
};
use grop_onboard::executive::{
    ArmCommand, ArmSnapshot, BaseReading, CycleInputs, CycleOutputs, ExecutiveConfig, MissionCore,
};
use motion_control::Twist;
use planar::Pose2;
use rmp_base::{BaseError, BaseMode, Odometry, Tick};
use world::nav::OccupancyGrid;
use world::{RobotConfig, Scene};

use crate::bytes::Bytes;

/// Cycles one input runs at most (an input of the default 4 KiB has room for ~2,000).
const MAX_CYCLES: usize = 4096;

/// What every input shares: the paper's robot in the paper's empty room (building the grid
/// takes milliseconds, so once per process).
struct Fixture {
    config: ExecutiveConfig,
    grid: Arc<OccupancyGrid>,
    scene: Arc<Scene>,
    tray: TrayGeometry,
}

fn fixture() -> &'static Fixture {
    static FIXTURE: OnceLock<Fixture> = OnceLock::new();
    FIXTURE.get_or_init(|| {
        let robot = RobotConfig::default();
        let config = ExecutiveConfig::for_robot(&robot);
        let scene = Scene::empty_paper_room();
        let grid = Arc::new(OccupancyGrid::from_scene(&scene, &config.robot));
        let tray = solve_tray(&config.robot.place, &config.tray_slots).expect("default tray");
        Fixture {
            config,
            grid,
            scene: Arc::new(scene),
            tray,
        }
    })
}

/// Values the fuzzer would rarely build from raw bits: the edges of f64 and the numbers that
/// once broke conversions (`Duration::from_secs_f64` panics above ~1.8e19 s).
const SPECIAL: [f64; 16] = [
    0.0,
    -0.0,
    1.0,
    -1.0,
    f64::MIN_POSITIVE,
    1e-300,
    1e300,
    f64::MAX,
    f64::MIN,
    6.15e18,
    1.9e19,
    f64::NAN,
    f64::INFINITY,
    f64::NEG_INFINITY,
    std::f64::consts::PI,
    1e9,
];

/// A number: near the room (metres, seconds, radians), a raw bit pattern, or an edge case.
fn num(b: &mut Bytes<'_>) -> f64 {
    match b.u8() % 4 {
        0 => f64::from(b.u16()) / 1000.0,
        1 => f64::from(b.u16() as i16) / 100.0,
        2 => b.f64(),
        _ => SPECIAL[usize::from(b.u8()) % SPECIAL.len()],
    }
}

/// A finite number (what the base driver's odometry always is: sums of finite f32 reports).
fn finite(b: &mut Bytes<'_>) -> f64 {
    let v = num(b);
    if v.is_finite() { v } else { 0.0 }
}

fn joints(b: &mut Bytes<'_>) -> [f64; 6] {
    std::array::from_fn(|_| num(b))
}

fn pose(b: &mut Bytes<'_>) -> Pose2 {
    Pose2::new(num(b), num(b), num(b))
}

fn arm_fault(k: u8) -> ArmFault {
    match k % 5 {
        0 => ArmFault::LinkLost,
        1 => ArmFault::ProtectiveStop,
        2 => ArmFault::EmergencyStop,
        3 => ArmFault::SkillFailed,
        _ => ArmFault::GripperFault,
    }
}

fn twist(b: &mut Bytes<'_>) -> Twist {
    Twist::new(num(b) as f32, num(b) as f32)
}

fn base_error(b: &mut Bytes<'_>) -> BaseError {
    let ms = |b: &mut Bytes<'_>| Duration::from_millis(u64::from(b.u16()));
    match b.u8() % 8 {
        0 => BaseError::Silent {
            silent_for: ms(b),
            timeout: ms(b),
        },
        1 => BaseError::FeedbackUnreadable {
            silent_for: ms(b),
            last_error: None,
            expected_frames: usize::from(b.u8()),
        },
        2 => BaseError::Faulted {
            faults: rmp_codec::faults::FaultStatus::new([b.u32(), b.u32(), b.u32(), b.u32()]),
        },
        3 => BaseError::Overspeed {
            measured_mps: num(b) as f32,
            allowed_mps: num(b) as f32,
            measured_yaw_radps: num(b) as f32,
            allowed_yaw_radps: num(b) as f32,
        },
        4 => BaseError::SecondCommander {
            frames: u64::from(b.u32()),
            last_id: b.u16(),
        },
        // (The limit errors of the base's stored settings are not on main yet: the same bytes
        // make an overspeed.)
        5 => BaseError::Overspeed {
            measured_mps: num(b) as f32,
            allowed_mps: num(b) as f32,
            measured_yaw_radps: 0.0,
            allowed_yaw_radps: 0.0,
        },
        6 => BaseError::ModeTimeout {
            wanted: BaseMode::Tractor,
            reported: None,
            timeout: ms(b),
        },
        _ => {
            let _ = (num(b), num(b));
            BaseError::SecondCommander {
                frames: 1,
                last_id: 0x500,
            }
        }
    }
}

/// A plan; by default it answers the core's request and loads every object of the task.
fn plan(b: &mut Bytes<'_>, request_id: u64, task_mask: u64) -> TaskPlanMsg {
    let flags = b.u8();
    let answers_request = if flags & 1 == 0 {
        request_id
    } else {
        u64::from(b.u32())
    };
    let count = if flags & 2 == 0 {
        u32::from(b.u8()) % (MAX_TASK_STEPS as u32 + 1)
    } else {
        b.u32()
    };
    let mut steps = [TaskStep::navigate(0.0, 0.0, 0.0, 0.0); MAX_TASK_STEPS];
    for step in steps.iter_mut().take((count as usize).min(MAX_TASK_STEPS)) {
        let kind = b.u8();
        let mut s = TaskStep::navigate(num(b), num(b), num(b), num(b));
        s.kind = u32::from(kind % 4);
        s.side = match b.u8() % 4 {
            0 => 1,
            1 => -1,
            2 => 0,
            _ => b.u32() as i32,
        };
        s.object_index = u32::from(b.u8());
        s.load_mask = if kind & 0x80 == 0 {
            task_mask
        } else {
            u64::from(b.u32())
        };
        s.target_m = [num(b), num(b), num(b)];
        s.feasibility = num(b);
        // The plan's tray and docking, as the planner node writes them (or not).
        s.tray_slot = u32::from(b.u8());
        s.approach_m = num(b);
        s.back_out_m = num(b);
        *step = s;
    }
    TaskPlanMsg {
        plan_id: u64::from(b.u16()),
        stamp_ns: 0,
        source_frame_id: 0,
        answers_request,
        utility: num(b),
        feasibility: num(b),
        cost_s: num(b),
        reward: num(b),
        object_count: u32::from(b.u8()),
        step_count: count,
        decision_us: 0,
        steps,
    }
}

/// The worker's answer to the last job: cooperative (a straight path, a direct unload plan) or
/// decoded from the input (`fuzzed`).
fn answer(b: Option<&mut Bytes<'_>>, job: &Job) -> Option<Answer> {
    let Some(b) = b else {
        return Some(match *job {
            Job::Path { id, from, to, .. } => {
                let mut path = FollowerPath::new();
                let _ = path.push([from.0 as f32, from.1 as f32]);
                let _ = path.push([to.0 as f32, to.1 as f32]);
                Answer::Path(id, Ok(path))
            }
            Job::Unload { id, carry, .. } => {
                let joints = PlaceJoints {
                    place: carry,
                    above: carry,
                };
                Answer::Unload(id, Ok(UnloadPlan::direct(joints, carry)))
            }
            Job::Align { .. } => return None,
        });
    };
    let job_id = match *job {
        Job::Path { id, .. } | Job::Unload { id, .. } | Job::Align { id, .. } => id,
    };
    let kind = b.u8();
    let id = if kind & 0x10 == 0 {
        job_id
    } else {
        u64::from(b.u16())
    };
    Some(match kind % 6 {
        0 => {
            let mut path = FollowerPath::new();
            for _ in 0..usize::from(b.u8()) % (MAX_PATH_POINTS + 1) {
                let _ = path.push([num(b) as f32, num(b) as f32]);
            }
            Answer::Path(id, Ok(path))
        }
        1 => Answer::Path(
            id,
            Err(if kind & 0x20 == 0 {
                PathFailure::NoRoute
            } else {
                PathFailure::WorkerGone
            }),
        ),
        2 => {
            let joints = PlaceJoints {
                place: joints(b),
                above: joints(b),
            };
            Answer::Unload(id, Ok(UnloadPlan::direct(joints, self::joints(b))))
        }
        3 => Answer::Unload(
            id,
            Err(match b.u8() % 4 {
                0 => UnloadFailure::NoArmPath,
                1 => UnloadFailure::NothingInSlot,
                2 => UnloadFailure::Dropped,
                k => UnloadFailure::Arm(arm_fault(k)),
            }),
        ),
        _ => {
            let (pose_taken, pairs) = (pose(b), usize::from(b.u16()));
            Answer::Align(
                id,
                Alignment {
                    pose: pose_taken,
                    pairs,
                    // As many points as pairs: no extra input bytes (the corpus keeps its meaning).
                    points: pairs,
                    rms_m: num(b),
                    correction_m: num(b),
                },
                pose(b),
            )
        }
    })
}

/// The `mission_core` target: see the module documentation.
pub fn mission_core(data: &[u8]) {
    run(data);
}

/// What a run did (for the tests: the cooperative seeds must reach the mission's phases).
#[derive(Debug, Default)]
pub(crate) struct Summary {
    cycles: usize,
    top_speed_mps: f32,
    plans_taken: u32,
    unloads_ok: u32,
    state: String,
}

fn strict() -> bool {
    static STRICT: OnceLock<bool> = OnceLock::new();
    *STRICT.get_or_init(|| std::env::var_os("MISSION_CORE_STRICT").is_some_and(|v| v == "1"))
}

#[allow(
    clippy::too_many_lines,
    reason = "the fuzz harness's world loop reads top to bottom as one story"
)]
fn run(data: &[u8]) -> Summary {
    let mut summary = Summary::default();
    let f = fixture();
    let mut b = Bytes::new(data);
    let objects = 1 + usize::from(b.u8() % 8);
    let mut core = MissionCore::new(
        f.config.clone(),
        Arc::clone(&f.grid),
        Arc::clone(&f.scene),
        f.tray.clone(),
        objects,
    );
    let task_mask = if objects >= 64 {
        u64::MAX
    } else {
        (1u64 << objects) - 1
    };
    let robot = &f.config.robot;
    let max_speed = robot.speed_mps as f32;
    let max_yaw = robot.yaw_rate_radps as f32;
    let mut out = CycleOutputs::default();
    let mut now = Duration::ZERO;
    let mut odo = Odometry {
        x_m: 1.0,
        y_m: 1.0,
        ..Odometry::default()
    };
    let mut job: Option<Job> = None;
    let mut arm_busy = false;
    let mut mode_asked = false;
    let mut fix_seq = 0u64;
    let mut tick: Result<Tick, BaseError>;
    for _ in 0..MAX_CYCLES {
        if b.is_empty() {
            break;
        }
        let flags = b.u16();
        let step = match flags & 3 {
            0 => Duration::from_millis(20),
            1 => Duration::from_millis(u64::from(b.u16())),
            2 => Duration::from_micros(u64::from(b.u32())),
            _ => Duration::from_secs(u64::from(b.u32())),
        };
        now = now.saturating_add(step);
        let mut inputs = CycleInputs::quiet(now);
        inputs.base_cycle = flags & 4 == 0;
        inputs.planner_heartbeats = u32::from(flags & 0x400 == 0);
        inputs.sent = out.velocity;

        // The base: drives what it was sent (or reports nonsense).
        if flags & 0x8000 == 0 {
            let dt = step.as_secs_f64().min(1.0);
            let (v, w) = (
                f64::from(out.velocity.speed_mps),
                f64::from(out.velocity.yaw_rate_radps),
            );
            odo.x_m += v * odo.yaw_rad.cos() * dt;
            odo.y_m += v * odo.yaw_rad.sin() * dt;
            odo.yaw_rad += w * dt;
            odo.speed_mps = v;
            odo.yaw_rate_radps = w;
        } else {
            odo.x_m = finite(&mut b);
            odo.y_m = finite(&mut b);
            odo.yaw_rad = finite(&mut b);
            odo.speed_mps = finite(&mut b);
            odo.yaw_rate_radps = finite(&mut b);
        }
        odo.stamp = now;
        inputs.base = BaseReading {
            odometry: odo,
            driving: flags & 8 == 0,
        };
        tick = if flags & 0x10 == 0 {
            Ok(Tick {
                commanded: out.velocity,
                input_stale: false,
                feedback_sets: 1,
                mode_reached: std::mem::take(&mut mode_asked).then_some(BaseMode::Tractor),
                armed: true,
            })
        } else if b.u8() & 1 == 0 {
            Err(base_error(&mut b))
        } else {
            Ok(Tick {
                commanded: twist(&mut b),
                input_stale: b.u8() & 1 == 1,
                feedback_sets: u32::from(b.u8()),
                mode_reached: None,
                armed: b.u8() & 1 == 1,
            })
        };
        if inputs.base_cycle {
            inputs.base_tick = Some(&tick);
        }

        // The arm.
        if flags & 0x20 != 0 {
            let k = b.u8();
            inputs.arm = if k & 1 == 0 {
                Err(arm_fault(k >> 1))
            } else {
                Ok(ArmSnapshot {
                    q_rad: joints(&mut b),
                    qd_radps: joints(&mut b),
                    flange_pose: joints(&mut b),
                    program_running: k & 2 != 0,
                    robot_mode: b.u32() as i32,
                    protective_stop: k & 4 != 0,
                    emergency_stop: k & 8 != 0,
                    // UR safety modes 0..=15 from the same byte (the corpus keeps its meaning).
                    safety_mode: i32::from(k >> 4),
                })
            };
        }
        inputs.skill = if flags & 0x40 != 0 {
            let k = b.u8();
            match k % 4 {
                0 => None,
                1 => Some(Ok(SkillStatus::Running)),
                2 => Some(Ok(SkillStatus::Done {
                    object_held: k & 4 != 0,
                })),
                _ => Some(Err(arm_fault(k >> 2))),
            }
        } else if std::mem::take(&mut arm_busy) {
            Some(Ok(SkillStatus::Done { object_held: true }))
        } else {
            None
        };

        // Pose fixes: one that agrees with the base, or up to three decoded ones.
        let fixes: Vec<BasePoseMsg> = if flags & 0x80 == 0 {
            fix_seq += 1;
            vec![BasePoseMsg::fix(
                fix_seq,
                u64::try_from(now.as_nanos()).unwrap_or(u64::MAX),
                PoseFixKind::Global,
                [odo.x_m, odo.y_m, odo.yaw_rad],
                0.01,
                0.01,
            )]
        } else {
            (0..b.u8() % 4)
                .map(|_| {
                    let k = b.u8();
                    let stamp_ns = if k & 1 == 0 {
                        u64::try_from(now.as_nanos())
                            .unwrap_or(u64::MAX)
                            .saturating_sub(u64::from(b.u32()))
                    } else {
                        b.u32().into()
                    };
                    let mut fix = BasePoseMsg::fix(
                        u64::from(b.u16()),
                        stamp_ns,
                        if k & 2 == 0 {
                            PoseFixKind::Global
                        } else {
                            PoseFixKind::TableRelative
                        },
                        [num(&mut b), num(&mut b), num(&mut b)],
                        num(&mut b),
                        num(&mut b),
                    );
                    if k & 4 != 0 {
                        fix.kind = b.u32();
                    }
                    fix
                })
                .collect()
        };
        inputs.fixes = &fixes;
        let plans: Vec<TaskPlanMsg> = if flags & 0x100 != 0 {
            vec![plan(&mut b, core.request_id(), task_mask)]
        } else {
            Vec::new()
        };
        inputs.plans = &plans;
        let reply = match (&job, flags & 0x200 != 0) {
            (Some(j), fuzzed) => answer(fuzzed.then_some(&mut b), j),
            (None, true) => {
                let any = Job::Path {
                    id: 0,
                    from: (0.0, 0.0),
                    from_yaw: 0.0,
                    to: (0.0, 0.0),
                    seen: SeenPoints::NONE,
                };
                answer(Some(&mut b), &any)
            }
            (None, false) => None,
        };
        if reply.is_some() {
            job = None;
        }
        inputs.answer = reply.as_ref();
        if flags & 0x800 != 0 {
            inputs.monitor = match b.u8() % 6 {
                0 => MonitorAction::Clear,
                1 => MonitorAction::Crawl,
                2 => MonitorAction::Slowdown,
                3 => MonitorAction::Approach,
                4 => MonitorAction::Stop,
                _ => MonitorAction::Stale,
            };
            if b.u8() & 1 == 1 {
                inputs.sent = twist(&mut b);
            }
        }
        if flags & 0x1000 != 0 {
            inputs.aligned = Some((pose(&mut b), pose(&mut b)));
        }
        inputs.operator_enable = flags & 0x2000 == 0;
        if flags & 0x4000 != 0 {
            match b.u8() {
                0 => inputs.shutdown = true,
                1 => inputs.clock_lost = true,
                _ => {}
            }
        }

        out.clear();
        core.update(&inputs, &mut out);

        let v = out.velocity;
        assert!(
            v.speed_mps.is_finite() && v.yaw_rate_radps.is_finite(),
            "non-finite velocity {v:?}"
        );
        assert!(
            v.speed_mps.abs() <= max_speed && v.yaw_rate_radps.abs() <= max_yaw,
            "velocity {v:?} outside the robot file's {max_speed} m/s, {max_yaw} rad/s"
        );
        assert!(
            !strict() || core.stats().bounded == 0,
            "the core's laws produced {:?} before the last cut (strict mode)",
            core.velocity()
        );
        if let Some(j) = out.job {
            job = Some(j);
        }
        if matches!(out.arm, ArmCommand::MoveJoints(_) | ArmCommand::Gripper(_)) {
            arm_busy = true;
        }
        if out.base_mode.is_some() {
            mode_asked = true;
        }
        summary.cycles += 1;
        summary.top_speed_mps = summary.top_speed_mps.max(v.speed_mps.abs());
    }
    summary.plans_taken = core.stats().plans;
    summary.unloads_ok = core.stats().unloads_ok;
    summary.state = format!("{:?}", core.state());
    summary
}

/// Inputs that the cooperative world turns into missions: quiet cycles only; a plan of one
/// leg; a whole plan (leg, load, leg, unload). Used as the target's seeds and by the tests.
pub(crate) fn seeds() -> Vec<Vec<u8>> {
    /// `n` cycles with every flag clear (20 ms each).
    fn quiet(out: &mut Vec<u8>, n: usize) {
        out.extend(std::iter::repeat_n(0u8, 2 * n));
    }
    /// A number near the room: tag 0, thousandths as u16 (0..=65.535).
    fn room(out: &mut Vec<u8>, v: f64) {
        out.push(0);
        out.extend(((v * 1000.0).round() as u16).to_be_bytes());
    }
    /// A step: kind, goal (x, y, yaw, travel cost), object, target, feasibility.
    type Step = (u8, [f64; 4], u8, [f64; 3], f64);
    /// One cycle carrying a plan that answers the core's request.
    fn plan_cycle(out: &mut Vec<u8>, steps: &[Step]) {
        out.extend(0x0100u16.to_be_bytes());
        out.push(0); // cooperative request id, step count from one byte
        out.push(steps.len() as u8);
        for (kind, goal, object, target, feasibility) in steps {
            out.push(*kind);
            for v in goal {
                room(out, *v);
            }
            out.push(0); // side +1
            out.push(*object);
            for v in target {
                room(out, *v);
            }
            room(out, *feasibility);
            // The tray: a load fills slot 0, an unload takes from it. Not docked.
            out.push(u8::from(*kind == 2));
            room(out, 0.0);
            room(out, 0.0);
        }
        out.extend(1u16.to_be_bytes()); // plan id
        for v in [1.0, 1.0, 10.0, 40.0] {
            room(out, v);
        }
        out.push(1); // objects
    }
    let mut quiet_only = vec![0u8];
    quiet(&mut quiet_only, 2000);

    let mut one_leg = vec![0u8];
    quiet(&mut one_leg, 10);
    plan_cycle(
        &mut one_leg,
        &[(1, [2.0, 2.0, 0.0, 10.0], 0, [0.0; 3], 0.0)],
    );
    quiet(&mut one_leg, 1500);

    let mut whole = vec![0u8];
    quiet(&mut whole, 10);
    plan_cycle(
        &mut whole,
        &[
            (1, [0.0, 1.05, 4.712, 5.0], 0, [0.0; 3], 0.0),
            (2, [0.0, 1.05, 0.0, 0.0], 0, [0.0; 3], 0.0),
            (1, [2.0, 4.0, 1.571, 20.0], 0, [0.0; 3], 0.0),
            (3, [2.0, 4.0, 1.571, 0.0], 0, [2.0, 4.6, 0.75], 0.9),
        ],
    );
    quiet(&mut whole, 3000);
    vec![quiet_only, one_leg, whole]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_seeds_reach_the_missions_phases() {
        let runs: Vec<Summary> = seeds().iter().map(|s| run(s)).collect();
        for r in &runs {
            eprintln!("{r:?}");
        }
        assert_eq!(runs[0].cycles, 2000);
        assert_eq!(runs[0].top_speed_mps, 0.0, "no plan, no motion");
        assert_eq!(runs[1].plans_taken, 1);
        assert!(runs[1].top_speed_mps > 0.2, "{:?}", runs[1]);
        assert_eq!(runs[2].plans_taken, 1);
        assert_eq!(runs[2].unloads_ok, 1, "{:?}", runs[2]);
    }

    /// A plan whose travel cost once panicked `Duration::from_secs_f64` (issue 25 item 7).
    #[test]
    fn a_huge_travel_cost_does_not_panic() {
        let mut input = vec![0u8];
        // A few quiet cycles so that the core asks for a plan.
        input.extend(std::iter::repeat_n(0u8, 2 * 5));
        // Then a plan: flags 0x0100, cooperative request id, one navigate step with a travel
        // cost of 6.15e18 s (SPECIAL[9]).
        input.extend([0x01, 0x00]);
        input.extend([0, 1, 1]); // plan flags, one step, kind byte = navigate
        input.extend([0, 0x07, 0xD0, 0, 0x07, 0xD0, 3, 0, 3, 9]); // x, y, yaw, travel cost
        input.extend(std::iter::repeat_n(0u8, 64));
        input.extend(std::iter::repeat_n(0u8, 2 * 200));
        mission_core(&input);
    }
}
