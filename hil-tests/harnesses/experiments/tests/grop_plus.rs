//! GROP+ in the evaluation: with every lever off it executes exactly as GROP (same plans, same
//! noise, same records); with retries, a retried step lists one outcome per attempt, only failed
//! attempts are retried, the bound holds, and the run is reproducible.
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failure panics with its message

use experiments::{EvalConfig, TaskRecord, Workload, evaluate_heatmaps, ground_truth, run};
use planner::grop_plus::GropPlusConfig;
use planner::methods::{MethodKind, PlannerConfig};
use psi_eval::heuristics::OracleEvaluator;

fn config(plus: GropPlusConfig) -> EvalConfig {
    let d = EvalConfig::default();
    EvalConfig {
        scenes_per_chair_count: 1,
        tasks_per_scene: 4,
        gt_trials_per_cell: 1,
        methods: vec![MethodKind::GropPlus, MethodKind::Grop],
        sweep_speeds_mps: Vec::new(),
        planner: PlannerConfig { plus, ..d.planner },
        ..d
    }
}

fn records(cfg: &EvalConfig) -> Vec<TaskRecord> {
    let workload = Workload::build(cfg);
    let truth = ground_truth(cfg, &workload, None).unwrap();
    let psi = evaluate_heatmaps(&workload, &mut OracleEvaluator::new(1, 7)).unwrap();
    run(cfg, &workload, &psi, &truth).unwrap()
}

fn of<'a>(rs: &'a [TaskRecord], method: &str) -> Vec<&'a TaskRecord> {
    rs.iter().filter(|r| r.method == method).collect()
}

#[test]
fn levers_off_executes_as_grop_and_retries_keep_their_bounds() {
    let off = records(&config(GropPlusConfig::OFF));
    let (plus, grop) = (of(&off, "GROP+"), of(&off, "GROP"));
    assert_eq!(plus.len(), 12);
    for (p, g) in plus.iter().zip(&grop) {
        assert_eq!(p.task, g.task);
        assert_eq!(
            (p.placed, p.time_s, p.distance_m, &p.steps, p.retries),
            (g.placed, g.time_s, g.distance_m, &g.steps, 0)
        );
        assert_eq!(
            (p.predicted_f, p.predicted_cost_s),
            (g.predicted_f, g.predicted_cost_s)
        );
    }

    let cfg = config(GropPlusConfig {
        max_retries: 2,
        ..GropPlusConfig::OFF
    });
    let with = records(&cfg);
    let mut retried = 0;
    for r in of(&with, "GROP+") {
        let mut attempts = 0;
        for step in r.steps.split('|') {
            let outcomes: Vec<&str> = step.split(':').nth(1).unwrap().split('>').collect();
            assert!(outcomes.len() <= 3, "{step}: at most 2 retries");
            // Only the last attempt may be a success.
            assert!(
                outcomes[..outcomes.len() - 1]
                    .iter()
                    .all(|o| *o != "placed"),
                "{step}"
            );
            attempts += outcomes.len() - 1;
        }
        assert_eq!(attempts, r.retries);
        retried += r.retries;
    }
    assert!(retried > 0, "some failure was retried");
    // GROP itself does not retry, and is unchanged by GROP+'s levers.
    for (a, b) in of(&with, "GROP").iter().zip(of(&off, "GROP")) {
        assert_eq!(
            (a.placed, a.time_s, &a.steps),
            (b.placed, b.time_s, &b.steps)
        );
        assert_eq!(a.retries, 0);
    }
    // Reproducible.
    let again = records(&cfg);
    for (a, b) in with.iter().zip(&again) {
        assert_eq!(
            (a.task, a.method, a.placed, a.time_s, &a.steps),
            (b.task, b.method, b.placed, b.time_s, &b.steps)
        );
    }
}
