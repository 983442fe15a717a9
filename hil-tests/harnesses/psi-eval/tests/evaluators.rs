//! Conformance suite run against every evaluator in this crate, plus what each heuristic must
//! get right on its own.

use planner::feasibility::{FeasibilityError, FeasibilityEvaluator, FeasibilityQuery};
use psi_eval::evalset::{EvalSpec, build_eval_set, evaluate};
use psi_eval::heuristics::{
    BinaryAnnulusEvaluator, BlurredAnnulusEvaluator, OracleEvaluator, ReachAnnulus,
};
use world::view::{in_candidate_area, render_crop};
use world::{Heatmap, RobotConfig, Side};

fn evaluators() -> Vec<Box<dyn FeasibilityEvaluator>> {
    vec![
        Box::new(BinaryAnnulusEvaluator::new()),
        Box::new(BlurredAnnulusEvaluator::new()),
        Box::new(OracleEvaluator::new(3, 11)),
    ]
}

fn scene() -> world::Scene {
    world::generate::evaluation_scene(4242, 20, 2)
}

#[test]
fn every_evaluator_checks_the_output_count() {
    let robot = RobotConfig::default();
    let scene = scene();
    let t = scene.targets[0].as_array();
    let crop = render_crop(&scene, t[0], Side::Near);
    let q = FeasibilityQuery {
        scene: &scene,
        robot: &robot,
        target: t,
        side: Side::Near,
        crop: &crop,
    };
    for mut e in evaluators() {
        let mut out = vec![Heatmap::zeros(); 2];
        let err = e.evaluate(&[q], &mut out).unwrap_err();
        assert!(
            matches!(
                err,
                FeasibilityError::OutputCount {
                    queries: 1,
                    outputs: 2
                }
            ),
            "{}",
            e.name()
        );
    }
}

#[test]
fn every_evaluator_gives_deterministic_probabilities_on_the_candidate_area() {
    let robot = RobotConfig::default();
    let scene = scene();
    let crops: Vec<_> = scene
        .targets
        .iter()
        .flat_map(|t| Side::BOTH.map(|s| (t.as_array(), s, render_crop(&scene, t.x_m, s))))
        .collect();
    let queries: Vec<_> = crops
        .iter()
        .map(|(t, s, c)| FeasibilityQuery {
            scene: &scene,
            robot: &robot,
            target: *t,
            side: *s,
            crop: c,
        })
        .collect();
    for mut e in evaluators() {
        let mut a = vec![Heatmap::zeros(); queries.len()];
        let mut b = vec![Heatmap::from_values([0.5; 2048]); queries.len()];
        e.evaluate(&queries, &mut a).unwrap();
        e.evaluate(&queries, &mut b).unwrap();
        assert_eq!(a, b, "{} is not deterministic", e.name());
        for h in &a {
            for r in 0..32 {
                for c in 0..64 {
                    let v = h.get(r, c);
                    assert!((0.0..=1.0).contains(&v), "{}: {v}", e.name());
                    if !in_candidate_area(r, c) {
                        assert_eq!(v, 0.0, "{} writes outside the candidate area", e.name());
                    }
                }
            }
        }
        assert!(
            a.iter().any(|h| h.values().iter().any(|&v| v > 0.0)),
            "{} predicts nothing feasible",
            e.name()
        );
    }
}

#[test]
fn reach_annulus_matches_a_ur5e_at_table_height() {
    let robot = RobotConfig::default();
    let a = ReachAnnulus::probe(&robot.place, 1.3).expect("the default arm reaches a 1.3 m goal");
    assert!(a.min_m < a.max_m);
    // UR5e: 0.85 m reach; with the object 0.25 m above a 1.05 m arm base the horizontal reach is
    // a little less; close in, the arm folds into itself.
    assert!((0.6..0.95).contains(&a.max_m), "{a:?}");
    assert!(a.min_m < 0.4, "{a:?}");
}

#[test]
fn binary_heuristic_is_zero_on_furniture_and_blur_is_between_zero_and_one() {
    let robot = RobotConfig::default();
    let mut scene = world::generate::evaluation_scene(7, 15, 1);
    // A chair right in the middle of the candidate area of the near side.
    let t = scene.targets[0].as_array();
    let (cx, cy) = world::view::cell_center_world(t[0], Side::Near, 12, 31);
    scene.chairs.push(world::Chair {
        x_m: cx,
        y_m: cy,
        yaw_rad: 0.0,
        ..scene.chairs[0]
    });
    let crop = render_crop(&scene, t[0], Side::Near);
    let q = [FeasibilityQuery {
        scene: &scene,
        robot: &robot,
        target: t,
        side: Side::Near,
        crop: &crop,
    }];
    let mut bin = [Heatmap::zeros()];
    BinaryAnnulusEvaluator::new()
        .evaluate(&q, &mut bin)
        .unwrap();
    assert_eq!(bin[0].get(12, 31), 0.0);
    let mut blur = [Heatmap::zeros()];
    BlurredAnnulusEvaluator::new()
        .evaluate(&q, &mut blur)
        .unwrap();
    assert!(blur[0].get(12, 31) < 0.05);
    // Blur never exceeds 1 and is positive somewhere the binary map is 1 near an edge.
    let some_partial = (9..=16)
        .flat_map(|r| (20..=43).map(move |c| (r, c)))
        .any(|(r, c)| {
            let v = blur[0].get(r, c);
            v > 0.05 && v < 0.95
        });
    assert!(some_partial, "blurred map has no partial cells");
}

#[test]
fn oracle_agrees_with_the_ground_truth_it_approximates() {
    let robot = RobotConfig::default();
    let spec = EvalSpec {
        seed: 5,
        scenes: 1,
        targets_per_scene: 1,
        trials_per_cell: 10,
        chairs: vec![15],
    };
    let set = build_eval_set(&robot, &spec).unwrap();
    let oracle = evaluate(&mut OracleEvaluator::new(10, 99), &set).unwrap();
    let binary = evaluate(&mut BinaryAnnulusEvaluator::new(), &set).unwrap();
    // Two independent 10-trial estimates differ by sampling noise only.
    assert!(oracle.mae < 0.15, "{oracle:?}");
    assert!(
        oracle.mae < binary.mae,
        "oracle {oracle:?} binary {binary:?}"
    );
}
