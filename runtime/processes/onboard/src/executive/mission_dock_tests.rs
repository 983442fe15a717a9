//! The core's check of the way in to a standing spot against what the range sensor sees at the
//! pre-goal (docs/lidar.md, "Docking and back-outs"), on the same bench as the other reactions.

use super::*;

/// Drives a docking leg (to an unload at `goal`, empty room) to its pre-goal and hands the core
/// `scan` (base frame) from then on; returns the bench once the core either drives in or
/// fails the leg, and the goal it drives in to.
fn dock_with_scan(scan: &[[f32; 2]]) -> (Bench, Option<[f64; 3]>) {
    let goal = [1.0, 5.2, std::f64::consts::FRAC_PI_2];
    let mut b = Bench::in_scene(Scene::empty_paper_room(), 1);
    // The object rides on the tray already (loaded on an earlier trip).
    b.core.slots[0] = Some(0);
    let steps = [
        TaskStep::navigate(goal[0], goal[1], goal[2], 20.0),
        TaskStep::unload(0, grop_ipc::TableSide::Near, [goal[0], 6.0, 1.3], goal, 0.8),
    ];
    let Some(Job::Path { id, from, to, .. }) = b.running_with(&steps) else {
        panic!("expected a path job");
    };
    let answer = Answer::Path(id, Ok(straight_path(from, to)));
    b.step(|i| i.answer = Some(&answer));
    let mut obstacles = motion_control::collision::Obstacles::new();
    for p in scan {
        obstacles.add(p[0], p[1], [0.1, 0.1]);
    }
    let obstacles: &'static motion_control::collision::Obstacles = Box::leak(Box::new(obstacles));
    for _ in 0..3000 {
        b.step(|i| i.scan = Some(obstacles));
        if let Some(line) = b.core.dock_goal {
            return (b, Some(line));
        }
        if b.saw(EventKind::LegFinished) {
            return (b, None);
        }
    }
    panic!("the leg neither docked nor failed: {:?}", b.events);
}

#[test]
fn a_chair_the_scan_sees_in_the_standing_spot_fails_the_leg_before_the_base_drives_in() {
    // Nothing in the way: in to the goal as planned.
    let (b, line) = dock_with_scan(&[]);
    let line = line.expect("docks");
    assert!(
        (line[0] - 1.0).abs() < 1e-9 && (line[1] - 5.2).abs() < 1e-9,
        "{line:?}"
    );
    assert!(!b.saw(EventKind::LegFinished), "{:?}", b.events);
    // A chair across the way in, 0.6 m ahead of the pre-goal (base frame: x ahead): no shift
    // along the table clears it, the leg fails where the base stands.
    let chair: Vec<[f32; 2]> = (0..9).map(|k| [0.6, -0.2 + 0.05 * k as f32]).collect();
    let (b, line) = dock_with_scan(&chair);
    assert!(line.is_none(), "did not drive in: {line:?}");
    // It waited first (an operational hold: the chair may be pulled away), then gave up.
    assert!(
        b.events.iter().any(|(k, d)| *k == EventKind::Obstacle
            && d.contains("blocked (the scan sees something): waiting")),
        "{:?}",
        b.events
    );
    assert!(
        b.events
            .iter()
            .any(|(k, d)| *k == EventKind::LegFinished && d.contains("the standing spot is taken")),
        "{:?}",
        b.events
    );
    assert!(
        b.out.velocity.speed_mps.abs() < 1e-6,
        "the base stays: {:?}",
        b.out.velocity
    );
}

#[test]
fn a_chair_the_scan_sees_at_the_edge_of_the_way_in_moves_the_goal_along_the_table() {
    // A chair leg just inside the footprint's left edge (+y in the base frame) on the way in:
    // a few centimetres to the right along the table clears it; the move is reported.
    let (b, line) = dock_with_scan(&[[0.6, 0.28], [0.65, 0.28], [0.7, 0.29]]);
    let line = line.expect("docks");
    // Facing +y (the table) the base's left is -x in the world: the goal moves to +x.
    assert!(line[0] > 1.0 + 0.015 && line[0] <= 1.0 + 0.1, "{line:?}");
    assert!(
        b.events
            .iter()
            .any(|(k, d)| *k == EventKind::Obstacle && d.contains("standing spot moved")),
        "{:?}",
        b.events
    );
}

/// The core docks and backs out as the plan says (the planner works both out on the map): it
/// drives to the pre-goal `approach_m` behind a docked goal, straight to a goal that is not
/// docked, fails the leg before any motion where the plan says there is no way in, and backs
/// straight out as far as `back_out_m` before it asks for the path.
#[test]
fn the_core_docks_and_backs_out_as_the_plan_says() {
    let goal = [1.0, 5.2, std::f64::consts::FRAC_PI_2];
    let unload = TaskStep::unload(0, grop_ipc::TableSide::Near, [goal[0], 6.0, 1.3], goal, 0.8);
    let leg = |approach_m: f64, back_out_m: f64| {
        let mut nav = TaskStep::navigate(goal[0], goal[1], goal[2], 20.0);
        nav.approach_m = approach_m;
        nav.back_out_m = back_out_m;
        [nav, unload]
    };
    for (approach, pre_goal_y) in [(0.45, goal[1] - 0.45), (0.3, goal[1] - 0.3), (0.0, goal[1])] {
        let mut b = Bench::in_scene(Scene::empty_paper_room(), 1);
        b.core.slots[0] = Some(0);
        let Some(Job::Path { to, .. }) = b.running_with_as_planned(&leg(approach, 0.0)) else {
            panic!("expected a path job");
        };
        assert!(
            (to.0 - goal[0]).abs() < 1e-9 && (to.1 - pre_goal_y).abs() < 1e-9,
            "approach {approach}: {to:?}"
        );
        assert_eq!(b.core.dock.is_some(), approach > 0.0);
    }
    // No way in: the leg fails at once, nothing moved.
    let mut b = Bench::in_scene(Scene::empty_paper_room(), 1);
    b.core.slots[0] = Some(0);
    let start = (b.odo.x_m, b.odo.y_m);
    assert!(
        b.running_with_as_planned(&leg(crate::docking::NO_WAY_IN, 0.0))
            .is_none()
    );
    assert!(
        b.events
            .iter()
            .any(|(k, d)| *k == EventKind::LegFinished && d.contains("no straight way in")),
        "{:?}",
        b.events
    );
    assert_eq!((b.odo.x_m, b.odo.y_m), start);
    // Backing out 0.3 m first: reverse, then ask for the path from where it stopped.
    let mut b = Bench::in_scene(Scene::empty_paper_room(), 1);
    b.core.slots[0] = Some(0);
    let start = (b.odo.x_m, b.odo.y_m);
    assert!(
        b.running_with_as_planned(&leg(0.45, 0.3)).is_none(),
        "no path before backing out"
    );
    let mut reversed = false;
    let from = loop {
        b.step(|_| {});
        reversed |= b.core.velocity().speed_mps < 0.0;
        if let Some(Job::Path { from, .. }) = b.out.job {
            break from;
        }
        assert!(b.now < Duration::from_secs(10), "never asked for the path");
    };
    assert!(reversed);
    let backed = (from.0 - start.0).hypot(from.1 - start.1);
    assert!((0.3..0.36).contains(&backed), "backed out {backed} m");
}
