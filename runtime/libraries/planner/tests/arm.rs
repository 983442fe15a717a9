//! Arm trajectories for a chosen plan, on the real UR5e model in an empty paper room.

use planar::Pose2;
use planner::arm::{ArmPlanError, CARRY_JOINTS, arm_trajectories, plan_unload_motion};
use planner::costs::StraightLine;
use planner::methods::{MethodKind, Planner, PlannerConfig, TaskMotionPlanner};
use planner::problem::{TaskProblem, candidate_cells};
use world::{Heatmap, RobotConfig, Scene, Side};

#[test]
fn reachable_goal_gets_a_path_from_the_carry_pose() {
    let scene = Scene::empty_paper_room();
    let robot = RobotConfig::default();
    let base = Pose2 {
        x_m: 0.0,
        y_m: 6.0 - 0.7,
        yaw_rad: Side::Near.facing_yaw_rad(),
    };
    let m = plan_unload_motion(&scene, &robot, 0, base, [0.0, 6.0, 1.3], &CARRY_JOINTS, 1).unwrap();
    assert_eq!(m.path.first(), Some(&CARRY_JOINTS));
    assert_eq!(m.path.last(), Some(&m.place_joints));
    // The placing configuration puts the flange above the goal (tool pointing down).
    let again =
        plan_unload_motion(&scene, &robot, 0, base, [0.0, 6.0, 1.3], &CARRY_JOINTS, 1).unwrap();
    assert_eq!(again, m, "deterministic for the seed");
}

#[test]
fn far_goal_is_reported_not_panicked() {
    let scene = Scene::empty_paper_room();
    let robot = RobotConfig::default();
    let base = Pose2 {
        x_m: 0.0,
        y_m: 3.0,
        yaw_rad: Side::Near.facing_yaw_rad(),
    };
    let err =
        plan_unload_motion(&scene, &robot, 2, base, [0.0, 6.0, 1.3], &CARRY_JOINTS, 1).unwrap_err();
    assert!(matches!(err, ArmPlanError::Place { object: 2, .. }));
}

#[test]
fn chosen_plan_gets_one_motion_per_step() {
    let scene = Scene::empty_paper_room();
    let robot = RobotConfig::default();
    // Heatmaps that favour the rows closest to the table, where the arm reaches.
    let mut h = Heatmap::zeros();
    for (r, c) in candidate_cells() {
        h.set(
            r,
            c,
            if r <= 11 && (28..=35).contains(&c) {
                1.0
            } else {
                0.0
            },
        );
    }
    let targets = [[-2.0, 6.0, 1.3], [1.0, 6.0, 1.3]];
    let heatmaps = vec![h.clone(), h.clone(), h.clone(), h];
    let problem = TaskProblem::from_heatmaps(&scene, &robot, &targets, &heatmaps);
    let planned = Planner::new(MethodKind::Grop, PlannerConfig::default())
        .plan(&problem, &mut StraightLine { speed_mps: 0.4 }, 3)
        .unwrap();
    let motions = arm_trajectories(&scene, &robot, &problem, &planned, 3);
    assert_eq!(motions.len(), 2);
    for (m, step) in motions.iter().zip(&planned.plan.unloads) {
        let m = m.as_ref().unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(m.object, step.object);
        assert!(m.path.len() >= 2);
    }
}
