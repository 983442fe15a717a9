//! The problem's free cells against the per-cell reference, and the decisions on either: a
//! check across the planner (problem, methods, costs), so it lives beside the crate, not in one
//! of its files.

use planner::costs::StraightLine;
use planner::methods::{MethodKind, PlannedTask, Planner, PlannerConfig, TaskMotionPlanner};
use planner::problem::{TaskProblem, UnloadLocation, candidate_cells};
use world::{Heatmap, RobotConfig, Scene};

/// Free cells as first computed: the base footprint at every cell against the whole scene.
fn reference_free(l: &UnloadLocation, scene: &Scene, robot: &RobotConfig) -> Vec<bool> {
    l.cells
        .iter()
        .map(|c| {
            !world::base_collides(
                scene,
                robot,
                planar::Pose2 {
                    x_m: c.xy.0,
                    y_m: c.xy.1,
                    yaw_rad: l.side.facing_yaw_rad(),
                },
            )
        })
        .collect()
}

/// `mark_free_cells` marks exactly the cells the per-cell `base_collides` reference marks,
/// and GROP and GROP+ decide the same (plan, goals, utility) on problems marked either way:
/// evaluation scenes of 5 seeds x 4 chair counts, every target, both sides.
#[test]
fn free_cells_and_decisions_equal_the_per_cell_reference() {
    let robot = RobotConfig::default();
    let heat = |k: usize| {
        let mut h = Heatmap::zeros();
        for (i, (r, c)) in candidate_cells().enumerate() {
            h.set(r, c, ((i * 37 + k * 11) % 101) as f32 / 100.0);
        }
        h
    };
    let (mut free, mut blocked) = (0, 0);
    for seed in 0..5 {
        for chairs in [10, 15, 20, 25] {
            let scene = world::generate::evaluation_scene(seed, chairs, 30);
            let targets: Vec<[f64; 3]> = scene.targets.iter().map(|t| t.as_array()).collect();
            for task in targets.chunks(3) {
                let heatmaps: Vec<Heatmap> = (0..2 * task.len()).map(heat).collect();
                let fast = TaskProblem::from_heatmaps(&scene, &robot, task, &heatmaps);
                let mut reference = fast.clone();
                for l in reference.locations.iter_mut() {
                    let marks = reference_free(l, &scene, &robot);
                    for (c, f) in l.cells.iter_mut().zip(marks) {
                        c.free = f;
                    }
                }
                for (a, b) in fast.locations.iter().zip(&reference.locations) {
                    assert_eq!(a.cells, b.cells, "seed {seed}, {chairs} chairs");
                    free += a.cells.iter().filter(|c| c.free).count();
                    blocked += a.cells.iter().filter(|c| !c.free).count();
                }
                for kind in [MethodKind::Grop, MethodKind::GropPlus] {
                    let mut planner = Planner::new(kind, PlannerConfig::for_robot(&robot));
                    let mut travel = StraightLine { speed_mps: 0.4 };
                    let a = planner.plan(&fast, &mut travel, seed).unwrap();
                    let b = planner.plan(&reference, &mut travel, seed).unwrap();
                    assert_eq!(a.plan, b.plan);
                    assert_eq!(a.utility, b.utility);
                    let goals = |p: &PlannedTask| p.goals.iter().map(|g| g.xy).collect::<Vec<_>>();
                    assert_eq!(goals(&a), goals(&b));
                }
            }
        }
    }
    assert!(
        free > 1000 && blocked > 1000,
        "free {free}, blocked {blocked}"
    );
}
