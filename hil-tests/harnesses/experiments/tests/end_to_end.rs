//! A small evaluation end to end: 3 scenes (15/20/25 chairs), 1 task each, every method and the
//! speed sweep; checks shapes, invariants and reproducibility.

use experiments::{EvalConfig, Summary, Workload, evaluate_heatmaps, ground_truth, run};
use psi_eval::heuristics::OracleEvaluator;

fn small() -> EvalConfig {
    EvalConfig {
        scenes_per_chair_count: 1,
        tasks_per_scene: 1,
        gt_trials_per_cell: 1,
        ..EvalConfig::default()
    }
}

#[test]
fn small_evaluation_runs_and_is_reproducible() {
    let cfg = small();
    let workload = Workload::build(&cfg);
    assert_eq!(workload.scenes.len(), 3);
    assert_eq!(workload.tasks.len(), 3);
    let dir = tempfile::tempdir().unwrap();
    let cache = dir.path().join("gt.json");
    let truth = ground_truth(&cfg, &workload, Some(&cache)).unwrap();
    assert!(cache.exists());
    // The cache gives back the same heatmaps.
    let again = ground_truth(&cfg, &workload, Some(&cache)).unwrap();
    assert_eq!(truth.maps, again.maps);
    let mut oracle = OracleEvaluator::new(1, 7);
    let psi = evaluate_heatmaps(&workload, &mut oracle).unwrap();
    let records = run(&cfg, &workload, &psi, &truth).unwrap();
    assert_eq!(records.len(), 3 * cfg.runs().len());
    for r in &records {
        assert!(r.placed <= r.objects);
        assert_eq!(r.objects, 3);
        // Load and unload time is always spent; a failed navigation adds 60 s.
        assert!(r.time_s >= 3.0 * cfg.load_time_s, "{r:?}");
        assert_eq!(r.steps.split('|').count(), 3);
    }
    // Satisficing and PETLON decide without / with few costs; GROP asks every leg once.
    for r in records.iter().filter(|r| r.method == "GROP") {
        assert_eq!(r.motion_planner_calls, 19);
    }
    let summary = Summary::from_records(&cfg, &records);
    let md = summary.markdown(&cfg);
    assert!(md.contains("| GROP |"));
    assert!(md.contains("0.8 m/s"));
    experiments::write_csv(&dir.path().join("t.csv"), &records).unwrap();
    experiments::plot::fig5_svg(&summary, &cfg.methods, &dir.path().join("f.svg")).unwrap();
    assert!(
        std::fs::read_to_string(dir.path().join("f.svg"))
            .unwrap()
            .contains("<svg")
    );

    let records2 = run(&cfg, &workload, &psi, &truth).unwrap();
    let key = |r: &experiments::TaskRecord| {
        (
            r.task,
            r.method,
            r.speed_mps.to_bits(),
            r.placed,
            r.time_s.to_bits(),
            r.steps.clone(),
        )
    };
    assert_eq!(
        records.iter().map(key).collect::<Vec<_>>(),
        records2.iter().map(key).collect::<Vec<_>>()
    );
}

#[test]
fn corrupt_cache_is_recomputed_not_trusted() {
    let cfg = EvalConfig {
        chair_counts: vec![15],
        ..small()
    };
    let workload = Workload::build(&cfg);
    let dir = tempfile::tempdir().unwrap();
    let cache = dir.path().join("gt.json");
    std::fs::write(&cache, "{ not json").unwrap();
    let truth = ground_truth(&cfg, &workload, Some(&cache)).unwrap();
    assert_eq!(truth.maps.len(), 1);
    // Rewritten with valid content.
    assert!(std::fs::read_to_string(&cache).unwrap().starts_with('{'));
}
