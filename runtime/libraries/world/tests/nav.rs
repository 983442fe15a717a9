//! Occupancy grid and any-angle planning.

use planar::Pose2;
use world::nav::{NAV_CELL_M, OccupancyGrid};
use world::scene::{Chair, Scene};
use world::{RobotConfig, base_collides};

#[test]
fn open_floor_path_is_the_straight_line() {
    let scene = Scene::empty_paper_room();
    let grid = OccupancyGrid::from_scene(&scene, &RobotConfig::default());
    let path = grid.plan((0.0, 2.0), (3.0, 4.0)).expect("open floor");
    assert_eq!(path.points.len(), 2);
    assert!((path.length_m - 13f64.sqrt()).abs() < 1e-9);
    assert!((path.travel_time_s(0.4) - 13f64.sqrt() / 0.4).abs() < 1e-9);
}

#[test]
fn path_around_the_table_to_the_far_side() {
    let scene = Scene::empty_paper_room();
    let robot = RobotConfig::default();
    let grid = OccupancyGrid::from_scene(&scene, &robot);
    let from = (0.0, 5.0);
    let to = (0.0, 7.0);
    let path = grid.plan(from, to).expect("around the table end");
    // Must go round an end of the 13.5 m table: at least 2 * 6.75 m of detour along x.
    assert!(path.length_m > 13.5, "{}", path.length_m);
    assert!(
        path.length_m < 16.5,
        "any-angle path should be near-optimal: {}",
        path.length_m
    );
    // Every corner is free and every segment stays on free cells (sampled finely).
    for w in path.points.windows(2) {
        let steps =
            ((w[1].0 - w[0].0).hypot(w[1].1 - w[0].1) / (0.25 * NAV_CELL_M)).ceil() as usize;
        for s in 0..=steps {
            let t = s as f64 / steps.max(1) as f64;
            let p = (
                w[0].0 + t * (w[1].0 - w[0].0),
                w[0].1 + t * (w[1].1 - w[0].1),
            );
            assert!(grid.is_free(p), "path crosses a blocked cell at {p:?}");
        }
    }
}

#[test]
fn cells_next_to_furniture_and_walls_are_blocked() {
    let mut scene = Scene::empty_paper_room();
    scene.chairs.push(Chair::new(2.0, 4.0, 0.0));
    let robot = RobotConfig::default();
    let grid = OccupancyGrid::from_scene(&scene, &robot);
    assert!(!grid.is_free((2.0, 4.0)), "chair");
    assert!(!grid.is_free((0.0, 5.75)), "table edge");
    assert!(!grid.is_free((-9.95, 0.0)), "wall");
    assert!(!grid.is_free((30.0, 0.0)), "outside the room");
    assert!(!grid.is_free((f64::NAN, 0.0)));
    assert!(grid.is_free((2.0, 3.0)));
    // A base facing the table 0.6 m off its centre line fits (front edge 0.1 m from the table).
    assert!(grid.is_free((0.0, 5.4)));
    assert!(!base_collides(
        &scene,
        &robot,
        Pose2 {
            x_m: 0.0,
            y_m: 5.4,
            yaw_rad: std::f64::consts::FRAC_PI_2
        }
    ));
}

#[test]
fn enclosed_goal_has_no_path() {
    let mut scene = Scene::empty_paper_room();
    // A pocket in the room's south-west corner (x -10 .. -9.225, y -2.1 .. -0.75) closed by a
    // column of chairs and a bench: big enough for the base, but walled in.
    for y in [-1.875, -1.425, -0.975] {
        scene.chairs.push(Chair::new(-9.0, y, 0.0));
    }
    scene.chairs.push(Chair {
        x_m: -9.6,
        y_m: -0.525,
        yaw_rad: 0.0,
        depth_m: 0.8,
        width_m: 0.45,
        height_m: 0.9,
    });
    scene.validate().expect("valid pocket");
    let grid = OccupancyGrid::from_scene(&scene, &RobotConfig::default());
    assert!(
        grid.is_free((-9.6, -1.4)),
        "the pocket itself has room for the base"
    );
    assert!(grid.plan((0.0, 2.0), (-9.6, -1.4)).is_none());
    assert!(
        grid.plan((-9.6, -1.6), (-9.6, -1.2)).is_some(),
        "inside the pocket it can move"
    );
}

#[test]
fn base_collision_follows_the_footprint() {
    let scene = Scene::empty_paper_room();
    let robot = RobotConfig::default();
    let facing = std::f64::consts::FRAC_PI_2;
    let half_length = 0.5 * robot.footprint.length_m;
    let edge = 5.8 - half_length;
    assert!(!base_collides(
        &scene,
        &robot,
        Pose2 {
            x_m: 0.0,
            y_m: edge - 0.01,
            yaw_rad: facing
        }
    ));
    assert!(base_collides(
        &scene,
        &robot,
        Pose2 {
            x_m: 0.0,
            y_m: edge + 0.01,
            yaw_rad: facing
        }
    ));
    // Turned sideways the narrower side faces the table.
    let half_width = 0.5 * robot.footprint.width_m;
    assert!(!base_collides(
        &scene,
        &robot,
        Pose2 {
            x_m: 0.0,
            y_m: 5.8 - half_width - 0.01,
            yaw_rad: 0.0
        }
    ));
    assert!(
        base_collides(
            &scene,
            &robot,
            Pose2 {
                x_m: 9.8,
                y_m: 2.0,
                yaw_rad: 0.0
            }
        ),
        "wall"
    );
}

#[test]
fn obstacle_boxes_hold_the_base_table_and_near_chairs_only() {
    let mut scene = Scene::empty_paper_room();
    scene.chairs.push(Chair::new(0.6, 5.0, 0.0));
    scene.chairs.push(Chair::new(5.0, 5.0, 0.0));
    let robot = RobotConfig::default();
    let base = Pose2 {
        x_m: 0.0,
        y_m: 5.2,
        yaw_rad: std::f64::consts::FRAC_PI_2,
    };
    let boxes = scene.obstacle_boxes(&robot, base);
    assert_eq!(boxes.len(), 3, "own base, table, the near chair");
    assert!(
        (boxes[0].center.x - 0.0).abs() < 1e-12
            && (boxes[0].half_extents.z * 2.0 - robot.footprint.body_height_m).abs() < 1e-12
    );
    assert!(
        (boxes[1].center.y - 6.0).abs() < 1e-12 && (boxes[1].half_extents.z - 0.5).abs() < 1e-12
    );
    assert!((boxes[2].center.x - 0.6).abs() < 1e-12);
}

#[test]
fn authors_chair_disc_model_is_a_point_robot() {
    let mut scene = Scene::empty_paper_room();
    scene.chairs.push(Chair::new(1.0, 4.5, 0.0));
    let robot = RobotConfig {
        base_collision: world::BaseCollisionModel::ChairDiscs { radius_m: 0.3 },
        ..RobotConfig::default()
    };
    let facing = std::f64::consts::FRAC_PI_2;
    // 0.35 m from the chair centre: clear for a point with a 0.3 m disc, not for the footprint.
    let pose = Pose2 {
        x_m: 1.35,
        y_m: 4.5,
        yaw_rad: facing,
    };
    assert!(!base_collides(&scene, &robot, pose));
    assert!(base_collides(&scene, &RobotConfig::default(), pose));
    assert!(base_collides(
        &scene,
        &robot,
        Pose2 {
            x_m: 1.25,
            y_m: 4.5,
            yaw_rad: facing
        }
    ));
    // The point still may not stand on the table.
    assert!(base_collides(
        &scene,
        &robot,
        Pose2 {
            x_m: 0.0,
            y_m: 5.9,
            yaw_rad: facing
        }
    ));
    assert!(!base_collides(
        &scene,
        &robot,
        Pose2 {
            x_m: 0.0,
            y_m: 5.7,
            yaw_rad: facing
        }
    ));
}

/// Every segment of `path` between cell centres stays on free cells (sampled at a fifth of a
/// cell). The first and last segments start from the exact endpoints, which replace the centres
/// of the cells the search used (at most half a cell's diagonal away): their samples must lie on
/// or next to a free cell beyond the snapping distance.
fn assert_path_on_free_cells(grid: &OccupancyGrid, path: &world::nav::NavPath) {
    let segments = path.points.len() - 1;
    for (k, w) in path.points.windows(2).enumerate() {
        let steps = ((w[1].0 - w[0].0).hypot(w[1].1 - w[0].1) / (0.2 * NAV_CELL_M)).ceil() as usize;
        for s in 0..=steps {
            let t = s as f64 / steps.max(1) as f64;
            let p = (
                w[0].0 + t * (w[1].0 - w[0].0),
                w[0].1 + t * (w[1].1 - w[0].1),
            );
            let (first, last) = (path.points[0], path.points[segments]);
            let near_end = (p.0 - first.0).hypot(p.1 - first.1) < 0.3
                || (p.0 - last.0).hypot(p.1 - last.1) < 0.3;
            if near_end {
                // An endpoint in a blocked cell snaps to a free cell up to two cells away.
                continue;
            }
            if k == 0 || k + 1 == segments {
                let d = 0.5 * NAV_CELL_M * std::f64::consts::SQRT_2;
                let near_free = [(0.0, 0.0), (d, 0.0), (-d, 0.0), (0.0, d), (0.0, -d)]
                    .iter()
                    .any(|&(dx, dy)| grid.is_free((p.0 + dx, p.1 + dy)));
                assert!(near_free, "end segment far from free cells at {p:?}");
            } else {
                assert!(grid.is_free(p), "path crosses a blocked cell at {p:?}");
            }
        }
    }
}

/// Query points of an evaluation scene: start, station, and a near and a far point in front of
/// each target.
fn query_points(scene: &Scene) -> Vec<(f64, f64)> {
    let mut points = vec![
        (scene.robot_start.x_m, scene.robot_start.y_m),
        (scene.loading_station.x_m, scene.loading_station.y_m),
    ];
    for t in &scene.targets {
        points.push((t.x_m, 5.2));
        points.push((t.x_m, 6.8));
    }
    points
}

/// The visibility-graph planner against the Lazy Theta* reference on evaluation scenes: the same
/// pairs are connected, its paths stay on free cells, are never more than 5% longer and are
/// shorter on average (measured: 0.88..1.031, mean 0.996 over 17k pairs, `cargo run --release -p
/// world --example nav_compare`).
#[test]
fn visibility_graph_agrees_with_theta_star() {
    let robot = RobotConfig::default();
    let (mut n, mut sum) = (0usize, 0.0);
    for (seed, chairs) in [(11u64, 15usize), (12, 20), (13, 25)] {
        let scene = world::generate::evaluation_scene(seed, chairs, 12);
        let grid = OccupancyGrid::from_scene(&scene, &robot);
        assert!(grid.corner_count() > 0);
        let points = query_points(&scene);
        for i in 0..points.len() {
            for j in (i + 1..points.len()).step_by(3) {
                let theta = grid.plan_theta_star(points[i], points[j]);
                let vg = grid.plan(points[i], points[j]);
                match (&theta, &vg) {
                    (Some(a), Some(b)) => {
                        let r = b.length_m / a.length_m;
                        assert!(r <= 1.05, "{:?} -> {:?}: {r}", points[i], points[j]);
                        n += 1;
                        sum += r;
                        assert_eq!(b.points[0], points[i]);
                        assert_eq!(*b.points.last().unwrap(), points[j]);
                        let straight = (points[j].0 - points[i].0).hypot(points[j].1 - points[i].1);
                        assert!(b.length_m >= straight - 1e-9);
                        assert_path_on_free_cells(&grid, b);
                    }
                    (None, None) => {}
                    _ => panic!(
                        "connectivity differs {:?} -> {:?}: theta* {} vg {}",
                        points[i],
                        points[j],
                        theta.is_some(),
                        vg.is_some()
                    ),
                }
            }
        }
    }
    assert!(n >= 150, "{n} pairs with a path");
    assert!(sum / (n as f64) < 1.0, "mean ratio {}", sum / n as f64);
}

/// Lengths between connected endpoints equal the planned paths' lengths, whichever end asks.
#[test]
fn endpoint_lengths_match_plans_both_ways() {
    let scene = world::generate::evaluation_scene(5, 20, 8);
    let grid = OccupancyGrid::from_scene(&scene, &RobotConfig::default());
    let points = query_points(&scene);
    let endpoints: Vec<_> = points.iter().map(|&p| grid.endpoint(p)).collect();
    let mut checked = 0;
    for i in 0..points.len() {
        for j in 0..points.len() {
            let (Some(a), Some(b)) = (&endpoints[i], &endpoints[j]) else {
                assert!(grid.plan(points[i], points[j]).is_none());
                continue;
            };
            let ab = grid.path_length_between(a, b);
            let ba = grid.path_length_between(b, a);
            let planned = grid.plan(points[i], points[j]).map(|p| p.length_m);
            match (ab, ba, planned) {
                (Some(x), Some(y), Some(z)) => {
                    assert!((x - y).abs() < 1e-9 && (x - z).abs() < 1e-12, "{x} {y} {z}");
                    assert!(grid.path_length_m(points[i], points[j]) == Some(x));
                    checked += 1;
                }
                (None, None, None) => {}
                other => panic!("{other:?}"),
            }
        }
    }
    assert!(checked > 50);
    assert!(grid.endpoint((f64::NAN, 1.0)).is_none());
    assert!(grid.endpoint((50.0, 1.0)).is_none());
}

/// The reduced scene of `Scene::chairs_near` answers every base collision inside its box exactly
/// as the whole scene does, for both collision models.
#[test]
fn chairs_near_gives_the_same_collisions_in_its_box() {
    let scene = world::generate::evaluation_scene(21, 25, 10);
    for robot in [
        RobotConfig::default(),
        RobotConfig {
            base_collision: world::BaseCollisionModel::ChairDiscs { radius_m: 0.3 },
            ..RobotConfig::default()
        },
    ] {
        let mut checked = 0;
        for (k, target) in scene.targets.iter().enumerate() {
            let (x0, x1) = (target.x_m - 0.75, target.x_m + 0.75);
            let (y0, y1) = if k % 2 == 0 { (4.35, 5.5) } else { (6.5, 7.65) };
            let near = scene.chairs_near(&robot, x0, x1, y0, y1);
            assert!(near.chairs.len() <= scene.chairs.len());
            for i in 0..=20 {
                for j in 0..=10 {
                    let base = Pose2 {
                        x_m: x0 + (x1 - x0) * i as f64 / 20.0,
                        y_m: y0 + (y1 - y0) * j as f64 / 10.0,
                        yaw_rad: 0.37 * (i + j) as f64,
                    };
                    assert_eq!(
                        base_collides(&scene, &robot, base),
                        base_collides(&near, &robot, base),
                        "{base:?}"
                    );
                    checked += 1;
                }
            }
        }
        assert!(checked > 1000);
    }
}
