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

/// The example scene with the robot 3 m west of the loading station, facing east: its first leg
/// is the straight line to the station's pre-goal, 1 m behind the station (the base docks at
/// the station as at a table).
fn west_of_the_station() -> Scene {
    let mut scene = Scene::from_toml_str(
        include_str!("../../../runtime/world/data/example-scene.toml"),
        "example-scene.toml",
    )
    .expect("the example scene loads");
    scene.robot_start.x_m = scene.loading_station.x_m - 3.0;
    scene.robot_start.y_m = scene.loading_station.y_m;
    scene.robot_start.yaw_rad = 0.0;
    scene
}

/// A chair pulled after the map was made into the middle of the first leg (from the start to the
/// station's pre-goal).
fn chair_on_the_first_leg(scene: &Scene) -> Chair {
    let (s, g) = (scene.robot_start, scene.loading_station);
    Chair::new(0.5 * (s.x_m + g.x_m), 0.5 * (s.y_m + g.y_m + 1.0), 0.3)
}

#[test]
fn the_monitor_stops_the_base_before_a_chair_the_map_does_not_know() {
    let scene = west_of_the_station();
    let chair = chair_on_the_first_leg(&scene);
    let spec = MissionSpec {
        scene,
        unmapped_chairs: vec![chair],
        max_sim_s: 120.0,
        lidar: true,
        ..spec("lidar-unmapped-chair", 5)
    };
    let report = run(&spec);
    let base_contacts: Vec<_> = report
        .collisions
        .iter()
        .filter(|c| c.part == Part::Base)
        .collect();
    assert!(
        base_contacts.is_empty(),
        "the base touched furniture: {base_contacts:?}"
    );
    assert!(
        report.max_base_speed.0 > 0.1,
        "the base drove toward the chair ({:?})",
        report.max_base_speed
    );
    // It stopped short: at least half the monitor's 2 cm stop zone from the chair (the rest is
    // range noise and the last cycle's motion).
    let (gap, at) = report
        .min_base_clearance
        .expect("the world measured the clearance");
    assert!(gap >= 0.01, "closest call {gap:.3} m at {at:?}");
    let said = |needle: &str| report.events.iter().any(|e| e.detail.contains(needle));
    assert!(
        said("collision monitor: base held"),
        "the executive reports the hold: {:?}",
        report.events
    );
    assert!(
        said("blocked by an obstacle the scan sees"),
        "the leg fails cleanly: {:?}",
        report.events
    );
    let _ = std::fs::remove_dir_all(&spec.dir);
}

#[test]
fn without_the_lidar_the_same_mission_drives_into_the_chair() {
    // The same mission blind (the executive without its monitor): the world holds the base at
    // the chair and counts the contact. Shows the test above can fail.
    let scene = west_of_the_station();
    let chair = chair_on_the_first_leg(&scene);
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
