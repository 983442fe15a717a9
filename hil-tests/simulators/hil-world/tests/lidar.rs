//! The range sensor in the closed loop: the world's simulated VLP-16 feeds the executive's
//! collision monitor over UDP, and the monitor keeps the base off what the map does not know.
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failure panics with its message

use std::time::Duration;

use hil_world::mission::{self, MissionSpec};
use hil_world::report::{Part, WorldReport};
use world::{Chair, Scene};

mod common;
use common::spec;

fn run(spec: &MissionSpec) -> WorldReport {
    let bins = mission::binaries(true).expect("the world and onboard binaries build");
    mission::start(spec, &bins)
        .expect("mission starts")
        .finish(Duration::from_secs(600), &mut |_| {})
        .expect("the world reports")
}

/// The example scene with the robot `west_m` west of the loading station, facing east: its
/// first leg is the straight line to the station's pre-goal, 1 m behind the station (the base
/// docks at the station as at a table).
fn west_of_the_station(west_m: f64) -> Scene {
    let mut scene = Scene::from_toml_str(
        include_str!("../../../../runtime/libraries/world/data/example-scene.toml"),
        "example-scene.toml",
    )
    .expect("the example scene loads");
    scene.robot_start.x_m = scene.loading_station.x_m - west_m;
    scene.robot_start.y_m = scene.loading_station.y_m;
    scene.robot_start.yaw_rad = 0.0;
    scene
}

/// A chair pulled after the map was made onto the first leg (from the start to the station's
/// pre-goal), `along_m` from the start.
fn chair_on_the_first_leg(scene: &Scene, along_m: f64) -> Chair {
    let (s, g) = (scene.robot_start, scene.loading_station);
    let (dx, dy) = (g.x_m - s.x_m, g.y_m + 1.0 - s.y_m);
    let t = along_m / dx.hypot(dy);
    Chair::new(s.x_m + t * dx, s.y_m + t * dy, 0.3)
}

/// No contact of the base with furniture; its closest call.
fn no_base_contact(report: &WorldReport) -> f64 {
    let base_contacts: Vec<_> = report
        .collisions
        .iter()
        .filter(|c| c.part == Part::Base)
        .collect();
    assert!(
        base_contacts.is_empty(),
        "the base touched furniture: {base_contacts:?}"
    );
    report
        .min_base_clearance
        .expect("the world measured the clearance")
        .0
}

/// Whether an event's text contains `needle`, and the time of the first that does.
fn said(report: &WorldReport, needle: &str) -> Option<f64> {
    report
        .events
        .iter()
        .find(|e| e.detail.contains(needle))
        .map(|e| e.t_s)
}

#[test]
fn the_monitor_stops_the_base_before_a_chair_the_map_does_not_know() {
    // The chair stands 5 m down the first leg, beyond what a path is planned around (4 m), so
    // the leg is planned straight at it: the collision monitor must stop the base, the leg
    // fails cleanly, and the next path, planned with what the scan now sees, goes round it.
    let scene = west_of_the_station(7.0);
    let chair = chair_on_the_first_leg(&scene, 5.0);
    let base = spec("lidar-unmapped-chair", 5);
    let spec = MissionSpec {
        scene,
        unmapped_chairs: vec![chair],
        max_sim_s: 150.0,
        lidar: true,
        log: Some(base.dir.join("mission.mcap")),
        ..base
    };
    let report = run(&spec);
    // The log's `/base/state` says what the monitor did: clear while the way was, then scaling
    // the command down to nothing in front of the chair (the approach check: the footprint
    // never reached the stop zone), with its clearance to the nearest point.
    let log = grop_onboard::mission_log::MissionLog::read(spec.log.as_deref().expect("logged"))
        .expect("the log reads");
    let mut seen = std::collections::BTreeMap::new();
    let mut closest = f64::INFINITY;
    for m in log.channel(grop_onboard::mission_log::Channel::BaseState) {
        let v: serde_json::Value = serde_json::from_slice(&m.data).expect("JSON");
        let name = v["monitor_name"].as_str().expect("monitor_name").to_owned();
        if let Some(c) = v["monitor_clearance_m"].as_f64() {
            closest = closest.min(c);
        }
        *seen.entry(name).or_insert(0) += 1;
    }
    assert!(
        seen.contains_key("Clear") && seen.contains_key("Approach"),
        "{seen:?}"
    );
    assert!(!seen.contains_key("Off"), "the sensor was on: {seen:?}");
    assert!(
        (0.0..0.3).contains(&closest),
        "the monitor's closest clearance {closest} m ({seen:?})"
    );
    let gap = no_base_contact(&report);
    assert!(
        report.max_base_speed.0 > 0.1,
        "the base drove toward the chair ({:?})",
        report.max_base_speed
    );
    // It stopped short: at least half the monitor's 2 cm stop zone from the chair (the rest is
    // range noise and the last cycle's motion).
    assert!(gap >= 0.01, "closest call {gap:.3} m");
    let held = said(&report, "collision monitor: base held");
    assert!(
        held.is_some(),
        "the executive reports the hold: {:?}",
        report.events
    );
    let failed = said(&report, "blocked by an obstacle the scan sees");
    assert!(
        failed.is_some(),
        "the leg fails cleanly: {:?}",
        report.events
    );
    // Then round the chair to the station, and on with the mission.
    let loaded = said(&report, "on the tray");
    assert!(
        loaded.is_some_and(|t| Some(t) > failed),
        "the base got round the chair to the station: {:?}",
        report.events
    );
    let _ = std::fs::remove_dir_all(&spec.dir);
}

#[test]
fn a_chair_the_scan_sees_before_the_leg_is_planned_around_without_a_stop() {
    // The same chair 1.5 m down the first leg: in sight when the leg is planned, so the path
    // goes round it and the monitor never has to hold the base.
    let scene = west_of_the_station(3.0);
    let chair = chair_on_the_first_leg(&scene, 1.5);
    let spec = MissionSpec {
        scene,
        unmapped_chairs: vec![chair],
        max_sim_s: 60.0,
        lidar: true,
        ..spec("lidar-seen-chair", 5)
    };
    let report = run(&spec);
    let gap = no_base_contact(&report);
    assert!(gap >= 0.05, "closest call {gap:.3} m");
    assert!(
        said(&report, "collision monitor: base held").is_none(),
        "no hold on a path planned round the chair: {:?}",
        report.events
    );
    assert!(
        said(&report, "on the tray").is_some(),
        "the base reached the station and loaded: {:?}",
        report.events
    );
    let _ = std::fs::remove_dir_all(&spec.dir);
}

#[test]
fn without_the_lidar_the_same_mission_drives_into_the_chair() {
    // The same mission blind (the executive without its monitor): the world holds the base at
    // the chair and counts the contact. Shows the test above can fail.
    let scene = west_of_the_station(3.0);
    let chair = chair_on_the_first_leg(&scene, 1.5);
    let spec = MissionSpec {
        scene,
        unmapped_chairs: vec![chair],
        max_sim_s: 40.0,
        lidar: false,
        ..spec("lidar-blind-chair", 5)
    };
    let report = run(&spec);
    assert!(
        report.collisions.iter().any(|c| c.part == Part::Base),
        "a blind base runs into the chair: {:?}",
        report.min_base_clearance
    );
    assert!(
        report.base_blocks > 0,
        "the world held the base at the chair"
    );
    // The executive notices: motion sent, none measured.
    assert!(
        report.events.iter().any(|e| e.detail.starts_with("stall")),
        "the executive reports the stall: {:?}",
        report.events
    );
    let _ = std::fs::remove_dir_all(&spec.dir);
}

#[test]
fn a_chair_pushed_into_the_standing_spot_holds_the_leg_until_it_is_pulled_away() {
    // Things move: 4 s into the mission, on the way to the loading station, a chair is pushed
    // into the station's standing spot (the map, and the frame the plan came from, have it
    // elsewhere); at 26 s it is pulled away again. At the pre-goal the scan shows the way in
    // blocked at every shift along the table: the base waits there (3 s), the leg fails, the
    // next plan comes back to the same spot; once the chair is gone the base drives in and
    // loads. It never drives in while the chair is there.
    let scene = west_of_the_station(3.0);
    let station = scene.loading_station;
    let home = scene.chairs[0];
    let moved = |at_s: f64, x_m: f64, y_m: f64, yaw_rad: f64| hil_world::moves::ChairMove {
        at_s,
        chair: 0,
        x_m,
        y_m,
        yaw_rad,
    };
    let spec = MissionSpec {
        scene,
        chair_moves: vec![
            moved(4.0, station.x_m, station.y_m + 0.25, 0.0),
            moved(26.0, home.x_m, home.y_m, home.yaw_rad),
        ],
        max_sim_s: 60.0,
        lidar: true,
        ..spec("lidar-moved-chair", 5)
    };
    let report = run(&spec);
    let gap = no_base_contact(&report);
    assert!(gap >= 0.01, "closest call {gap:.3} m");
    let waited = said(&report, "blocked (the scan sees something): waiting");
    assert!(
        waited.is_some_and(|t| t > 4.0 && t < 26.0),
        "the base waits at the pre-goal: {:?}",
        report.events
    );
    let loaded = said(&report, "on the tray");
    assert!(
        loaded.is_some_and(|t| t > 26.0),
        "loaded once the chair was gone, not before: {:?}",
        report.events
    );
    let _ = std::fs::remove_dir_all(&spec.dir);
}
