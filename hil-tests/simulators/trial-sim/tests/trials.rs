//! The trial simulator: labels 0 on furniture and beyond reach, the table blocks the base,
//! noise has the configured spread, seeds determine everything.

use nalgebra::Point3;
use planar::Pose2;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use trial_sim::{
    ArmModel, HeatmapArea, TrialResult, TrialSimulator, ground_truth_heatmap,
    ground_truth_heatmap_in, run_trial, simulate_cells, task_feasibility,
};
use ur5e_kin::{ObstacleBox, PlaceConfig, PlaceFailure};
use world::scene::{Chair, Scene, UnloadTarget};
use world::view::{CROP_COLS, CROP_ROWS, Side, cell_center_world, in_candidate_area};
use world::{Heatmap, RobotConfig};

fn scene_with_target(x_m: f64) -> Scene {
    let mut scene = Scene::empty_paper_room();
    scene.targets.push(UnloadTarget::on_center_line(x_m));
    scene
}

fn noiseless() -> RobotConfig {
    RobotConfig {
        nav_noise_sigma_m: 0.0,
        ..RobotConfig::default()
    }
}

#[test]
fn same_seed_same_heatmap_other_seed_other_heatmap() {
    let scene = world::generate::training_scenes(4, 1, 1).remove(0);
    let robot = RobotConfig::default();
    let target = scene.targets[0].as_array();
    let a = ground_truth_heatmap(&scene, &robot, target, Side::Near, 5, 11);
    let b = ground_truth_heatmap(&scene, &robot, target, Side::Near, 5, 11);
    let c = ground_truth_heatmap(&scene, &robot, target, Side::Near, 5, 12);
    assert_eq!(a, b);
    assert_ne!(a, c, "noise must depend on the seed");
    for row in 0..CROP_ROWS {
        for col in 0..CROP_COLS {
            if !in_candidate_area(row, col) {
                assert_eq!(
                    a.get(row, col),
                    0.0,
                    "cells outside the candidate area are not labels"
                );
            }
        }
    }
}

#[test]
fn label_is_zero_where_a_chair_stands() {
    let mut scene = scene_with_target(0.0);
    let (x, y) = cell_center_world(0.0, Side::Near, 12, 31);
    scene.chairs.push(Chair::new(x, y, 0.7));
    scene.validate().expect("valid");
    let heatmap = ground_truth_heatmap(
        &scene,
        &RobotConfig::default(),
        scene.targets[0].as_array(),
        Side::Near,
        20,
        1,
    );
    assert_eq!(heatmap.get(12, 31), 0.0);
    // The same cell without the chair is a good place.
    let empty = scene_with_target(0.0);
    let free = ground_truth_heatmap(
        &empty,
        &RobotConfig::default(),
        empty.targets[0].as_array(),
        Side::Near,
        20,
        1,
    );
    assert!(free.get(12, 31) > 0.5, "{}", free.get(12, 31));
}

#[test]
fn labels_are_zero_beyond_reach_and_at_the_table() {
    let scene = scene_with_target(1.0);
    let robot = RobotConfig::default();
    let heatmap = ground_truth_heatmap_in(
        &scene,
        &robot,
        scene.targets[0].as_array(),
        Side::Near,
        HeatmapArea::WholeCrop,
        5,
        3,
    );
    // 1.5 m and more off the centre line: 0.6 m beyond any UR5e reach, 5+ sigma of noise.
    for row in 24..CROP_ROWS {
        for col in 0..CROP_COLS {
            assert_eq!(heatmap.get(row, col), 0.0, "row {row} col {col}");
        }
    }
    // 2 m to the side of the target along the table: out of reach too.
    for row in 0..CROP_ROWS {
        assert_eq!(heatmap.get(row, 0), 0.0);
        assert_eq!(heatmap.get(row, CROP_COLS - 1), 0.0);
    }
    // Base centre within 0.3 m + 0.2 m of the centre line: the footprint is in the table.
    let exact = noiseless();
    let mut sim = TrialSimulator::new(&scene, &exact);
    for row in 0..7 {
        let (x, y) = cell_center_world(1.0, Side::Near, row, 32);
        let result = sim.evaluate(
            scene.targets[0].as_array(),
            Pose2 {
                x_m: x,
                y_m: y,
                yaw_rad: Side::Near.facing_yaw_rad(),
            },
        );
        assert_eq!(result, TrialResult::BaseCollision, "row {row}");
    }
}

#[test]
fn noiseless_base_in_front_of_the_target_succeeds_on_both_sides() {
    let scene = scene_with_target(-2.0);
    let robot = noiseless();
    let mut rng = ChaCha8Rng::seed_from_u64(0);
    for side in Side::BOTH {
        let commanded = cell_center_world(-2.0, side, 11, 31);
        let outcome = run_trial(
            &scene,
            &robot,
            scene.targets[0].as_array(),
            side,
            commanded,
            &mut rng,
        );
        assert_eq!(outcome.result, TrialResult::Success, "{side}");
        assert_eq!((outcome.realised.x_m, outcome.realised.y_m), commanded);
        assert_eq!(outcome.realised.yaw_rad, side.facing_yaw_rad());
        // Far out in the candidate band's corner the arm cannot reach.
        let far_corner = cell_center_world(-2.0, side, 16, 20);
        let outcome = run_trial(
            &scene,
            &robot,
            scene.targets[0].as_array(),
            side,
            far_corner,
            &mut rng,
        );
        assert_eq!(outcome.result, TrialResult::ArmOutOfReach, "{side}");
    }
}

#[test]
fn navigation_noise_has_the_configured_spread() {
    let scene = scene_with_target(0.0);
    let robot = RobotConfig {
        nav_noise_sigma_m: 0.1,
        ..RobotConfig::default()
    };
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let commanded = (0.0, 4.0);
    let n = 4000;
    let (mut sx, mut sy, mut sxx, mut syy) = (0.0, 0.0, 0.0, 0.0);
    for _ in 0..n {
        let o = run_trial(
            &scene,
            &robot,
            scene.targets[0].as_array(),
            Side::Near,
            commanded,
            &mut rng,
        );
        let (dx, dy) = (o.realised.x_m - commanded.0, o.realised.y_m - commanded.1);
        sx += dx;
        sy += dy;
        sxx += dx * dx;
        syy += dy * dy;
    }
    let n = n as f64;
    assert!(
        (sx / n).abs() < 0.01 && (sy / n).abs() < 0.01,
        "mean ({}, {})",
        sx / n,
        sy / n
    );
    let (std_x, std_y) = ((sxx / n).sqrt(), (syy / n).sqrt());
    assert!(
        (std_x - 0.1).abs() < 0.01 && (std_y - 0.1).abs() < 0.01,
        "std ({std_x}, {std_y})"
    );
}

/// An arm that refuses everything with one failure and records what it was asked.
struct RefusingArm(PlaceFailure);

impl ArmModel for RefusingArm {
    fn place(
        &self,
        _: &PlaceConfig,
        base: Pose2,
        goal: Point3<f64>,
        obstacles: &[ObstacleBox],
    ) -> Result<(), PlaceFailure> {
        // The robot's own body is always the first obstacle, at the base pose.
        assert!((obstacles[0].center.x - base.x_m).abs() < 1e-12);
        assert!((goal.z - 1.3).abs() < 1e-12);
        Err(self.0)
    }
}

#[test]
fn arm_failures_map_to_trial_results() {
    let scene = scene_with_target(0.0);
    let robot = noiseless();
    for (failure, expected) in [
        (PlaceFailure::OutOfReach, TrialResult::ArmOutOfReach),
        (PlaceFailure::JointLimits, TrialResult::ArmJointLimits),
        (PlaceFailure::Collision, TrialResult::ArmCollision),
    ] {
        let mut sim = TrialSimulator::with_arm(&scene, &robot, RefusingArm(failure));
        let mut seen = Vec::new();
        let counts = simulate_cells(
            &mut sim,
            scene.targets[0].as_array(),
            Side::Near,
            HeatmapArea::Candidate,
            2,
            9,
            |_, _, _, _, o| seen.push(o.result),
        );
        assert_eq!(seen.len(), 2 * 192);
        assert!(
            seen.iter()
                .all(|r| *r == expected || *r == TrialResult::BaseCollision)
        );
        assert!(seen.contains(&expected));
        assert_eq!(
            counts.successes.iter().map(|&s| u32::from(s)).sum::<u32>(),
            0
        );
        assert_eq!(counts.trials.iter().filter(|&&n| n == 2).count(), 192);
    }
}

#[test]
fn task_feasibility_is_the_closed_form_of_eq_4() {
    let mut heatmap = Heatmap::zeros();
    assert_eq!(task_feasibility(&heatmap, HeatmapArea::Candidate), 0.0);
    heatmap.set(10, 30, 1.0);
    heatmap.set(10, 31, 0.5);
    heatmap.set(0, 0, 1.0); // outside the candidate area: ignored
    let expected = (1.0 + 0.25) / 1.5;
    assert!((task_feasibility(&heatmap, HeatmapArea::Candidate) - expected).abs() < 1e-9);
}
