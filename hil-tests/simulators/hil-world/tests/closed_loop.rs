//! The closed loop as processes: `grop-world` and the unchanged onboard binaries
//! (`grop-planner`, `grop-executive`) run a mission in simulated time; killing a process mid-
//! mission stops the base and the arm by the mechanism DESIGN.md names, and the report says so.
//!
//! The binaries are the ones `cargo test --workspace` (or `cargo build`) put next to this test's
//! folder.
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failure panics with its message

use std::time::Duration;

use hil_world::mission::{self, MissionSpec, RunningMission};
use hil_world::objects::ObjectState;
use hil_world::report::{MissionEnd, WorldReport};
use world::RobotConfig;

mod common;
use common::spec;

fn start(spec: &MissionSpec) -> RunningMission {
    let bins = mission::binaries(true).expect("the world and onboard binaries build");
    mission::start(spec, &bins).expect("mission starts")
}

fn finish(running: RunningMission) -> WorldReport {
    running
        .finish(Duration::from_secs(600), &mut |_| {})
        .expect("the world reports")
}

/// Starts a mission and waits until the world reports `key` above `above` (the base driving,
/// the arm moving).
fn start_and_wait_for(spec: &MissionSpec, key: &str, above: f64, timeout_s: u64) -> RunningMission {
    let running = start(spec);
    let seen = running.wait_for_line(
        Duration::from_secs(timeout_s),
        |l| value(l, key).is_some_and(|v| v > above),
        &mut |_| {},
    );
    assert!(seen.is_some(), "{key} never exceeded {above}");
    running
}

/// The world's record of `name`'s death.
fn death_of<'a>(report: &'a WorldReport, name: &str) -> &'a hil_world::report::DeathRecord {
    report
        .deaths
        .iter()
        .find(|d| d.name == name)
        .unwrap_or_else(|| panic!("the world did not notice {name} die: {:?}", report.deaths))
}

/// A progress line's value of `key` (`progress t=1.0 x=.. v=0.35 arm=0.0 ...`).
fn value(line: &str, key: &str) -> Option<f64> {
    line.split_whitespace()
        .find_map(|kv| kv.strip_prefix(&format!("{key}=")))
        .and_then(|v| v.split('/').next())
        .and_then(|v| v.parse().ok())
}

#[test]
fn a_mission_runs_from_camera_frame_to_can_frame_and_is_reported() {
    let spec = spec("mission", 4);
    let running = start(&spec);
    let report = finish(running);
    assert_eq!(
        report.end,
        MissionEnd::Finished,
        "events: {:#?}",
        report.events
    );
    assert!(!report.plans.is_empty());
    let first = &report.plans[0];
    assert_eq!(
        first.unloads.len(),
        3,
        "the first plan unloads every object"
    );
    assert!(first.decision_us > 0);
    assert!(report.timing.frames >= 1, "camera frames were published");
    // Every object was loaded and then either released (and judged) or given up on the tray.
    for o in &report.objects {
        assert!(
            !matches!(o.state, ObjectState::AtStation | ObjectState::Held),
            "{o:?}"
        );
    }
    // The legs ended near their goals, as the localisation noise allows (10 sigma).
    assert!(
        report.legs.len() >= 2,
        "{:?} {:#?}",
        report.legs,
        report.events
    );
    for leg in &report.legs {
        let d = (leg.realised[0] - leg.commanded[0]).hypot(leg.realised[1] - leg.commanded[1]);
        assert!(d < 1.0, "{leg:?}");
    }
    let kinds: Vec<&str> = report.events.iter().map(|e| e.kind.as_str()).collect();
    for k in [
        "ReplanRequested",
        "PlanStarted",
        "GoalReached",
        "Loaded",
        "PlanFinished",
    ] {
        assert!(kinds.contains(&k), "no {k} in {kinds:?}");
    }
    assert_eq!(
        report.placed,
        report
            .events
            .iter()
            .filter(|e| e.kind == "ObjectJudged" && e.detail.contains(": Placed,"))
            .count()
    );
}

#[test]
fn killing_the_executive_while_driving_stops_the_base_by_its_own_timeout() {
    let mut running = start_and_wait_for(&spec("kill-exec-base", 5), "v", 0.3, 120);
    running.kill_executive();
    let report = finish(running);
    assert_eq!(report.end, MissionEnd::ExecutiveDied);
    let death = death_of(&report, "grop-executive");
    assert!(death.base_speed_then_mps > 0.2, "{death:?}");
    let stopped = death.base_stopped_at_s.expect("the base stopped");
    // The base's own loss-of-command timeout (0.5 s) plus its deceleration ramp (NVM 3.9 m/s^2)
    // plus the clock's detection poll; generous margin, no wall time involved.
    let ramp = death.base_speed_then_mps / 3.9;
    println!(
        "executive killed at {:.3} s driving {:.2} m/s: base stopped after {:.3} s",
        death.t_s,
        death.base_speed_then_mps,
        stopped - death.t_s
    );
    assert!(
        stopped - death.t_s <= 0.5 + ramp + 0.2,
        "stopped {:.2} s after the death",
        stopped - death.t_s
    );
    assert!(
        stopped - death.t_s >= 0.4,
        "the base should coast on its last command until its own timeout"
    );
}

#[test]
fn killing_the_executive_while_the_arm_moves_stops_the_arm_by_the_controller_watchdog() {
    let mut running = start_and_wait_for(&spec("kill-exec-arm", 4), "arm", 0.3, 300);
    running.kill_executive();
    let report = finish(running);
    let death = death_of(&report, "grop-executive");
    assert!(death.arm_speed_then_radps > 0.2, "{death:?}");
    let stopped = death.arm_stopped_at_s.expect("the arm stopped");
    println!(
        "executive killed at {:.3} s, arm at {:.2} rad/s: arm stopped after {:.3} s",
        death.t_s,
        death.arm_speed_then_radps,
        stopped - death.t_s
    );
    // The RTDE watchdog demands 10 Hz (0.1 s), then stopj at 4 rad/s^2 (a joint at 1.5 rad/s
    // needs 0.4 s); margin for the detection poll.
    assert!(
        stopped - death.t_s <= 0.1 + death.arm_speed_then_radps / 4.0 + 0.3,
        "arm stopped {:.2} s after the death",
        stopped - death.t_s
    );
}

#[test]
fn killing_the_planner_makes_the_executive_stop_the_base_and_abort() {
    let spec = spec("kill-planner", 5);
    let mut running = start(&spec);
    let moving = running.wait_for_line(
        Duration::from_secs(120),
        |l| value(l, "v").is_some_and(|v| v > 0.3),
        &mut |_| {},
    );
    assert!(moving.is_some(), "the base never drove");
    running.kill_planner();
    let report = finish(running);
    assert_eq!(
        report.end,
        MissionEnd::Aborted,
        "events: {:#?}",
        report.events
    );
    let (death, lost_t_s) = common::planner_death_noticed(&report, "killed planner");
    let stopped = death.base_stopped_at_s.expect("the base stopped");
    let ramp = death.base_speed_then_mps / RobotConfig::default().accel_mps2;
    println!(
        "planner killed at {:.3} s: executive noticed after {:.3} s, base ({:.2} m/s) stopped {:.3} s after the death",
        death.t_s,
        lost_t_s - death.t_s,
        death.base_speed_then_mps,
        stopped - death.t_s
    );
    assert!(
        stopped - lost_t_s <= ramp + 0.2,
        "the base stopped {:.2} s after the executive noticed (ramp {ramp:.2} s)",
        stopped - lost_t_s
    );
    assert!(report.events.iter().any(|e| e.kind == "MissionAborted"));
}

/// A whole table setting over two trips: 6 objects with the robot file's tray of 3. The first
/// plan unloads all 6; the executive loads twice at the station (each time at most 3 objects,
/// as the world's tray holds) and the mission finishes with every object off the station.
#[test]
fn six_objects_with_a_tray_of_three_are_set_in_two_trips() {
    let mut spec = spec("two-trips", 4);
    // No chairs: the test is about the trips (loading, the tray, the plan over both), and it
    // runs the base blind (no range sensor: see `common::spec`), where a spot between chairs
    // costs a contact and a stall; `tests/lidar.rs` and `tests/layouts.rs` drive among chairs.
    spec.scene = world::generate::evaluation_scene(4, 0, 6);
    spec.max_sim_s = 800.0;
    assert_eq!(spec.robot.carry_capacity, 3);
    let report = finish(start(&spec));
    assert_eq!(
        report.end,
        MissionEnd::Finished,
        "events: {:#?}",
        report.events
    );
    assert_eq!(report.plans[0].unloads.len(), 6, "one plan for both trips");
    // The executive's loading phases ("objects 0x.. on the tray"), not the world's.
    let loads: Vec<&str> = report
        .events
        .iter()
        .filter(|e| e.kind == "Loaded" && !e.detail.contains("put on"))
        .map(|e| e.detail.as_str())
        .collect();
    assert!(loads.len() >= 2, "loading phases: {loads:?}");
    let world_loads: Vec<&str> = report
        .events
        .iter()
        .filter(|e| e.kind == "Loaded" && e.detail.contains("put on"))
        .map(|e| e.detail.as_str())
        .collect();
    assert!(world_loads.len() >= 2, "world loads: {world_loads:?}");
    for o in &report.objects {
        assert!(
            !matches!(o.state, ObjectState::AtStation | ObjectState::Held),
            "{o:?}"
        );
    }
    println!(
        "two trips: placed {} of 6, {} plans, loads {loads:?}, world {world_loads:?}",
        report.placed,
        report.plans.len()
    );
}
