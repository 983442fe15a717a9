//! One conformance suite for every `TaskMotionPlanner` (GROP and the four baselines): the
//! invariants any of them must keep, run on random problems with a travel oracle that has detours
//! and missing paths.
#![allow(
    clippy::too_many_lines,
    reason = "a test scenario (or the fuzz harness's) reads top to bottom as one story"
)]

mod common;

use grop_select::{FeasibilityAggregation, UTILITY_TIE_EPS};
use planner::costs::{LegCache, TravelTime};
use planner::methods::{
    BaselineGoals, GoalSource, MethodKind, Planner, PlannerConfig, SearchMode, TaskMotionPlanner,
    location_heat,
};
use planner::task::{PlanningTable, location_index, satisficing_plans};

fn configs() -> Vec<PlannerConfig> {
    let d = PlannerConfig::default();
    vec![
        d,
        PlannerConfig {
            aggregation: FeasibilityAggregation::Product,
            goal_draws: 4,
            ..d
        },
        PlannerConfig {
            baseline_goals: BaselineGoals::AuthorsCode,
            search: SearchMode::Exact,
            ..d
        },
        PlannerConfig {
            lazy_costs: true,
            ..d
        },
        // The paper's Smp: goals from the whole heatmap.
        PlannerConfig {
            free_goals_only: false,
            ..d
        },
        PlannerConfig {
            lazy_costs: true,
            search: SearchMode::Exact,
            aggregation: FeasibilityAggregation::Product,
            ..d
        },
    ]
}

#[test]
fn every_method_keeps_the_invariants() {
    for cfg in configs() {
        for method in MethodKind::ALL {
            for seed in 0..12u64 {
                let n = 1 + (seed as usize % 3);
                let problem = common::random_problem(n, 1000 + seed);
                let mut oracle = common::DetourOracle {
                    speed_mps: cfg.speed_mps,
                    salt: seed,
                    no_path: 0.05,
                    calls: 0,
                };
                let mut planner = Planner::new(method, cfg);
                assert_eq!(planner.kind(), method);
                let out = planner.plan(&problem, &mut oracle, seed).unwrap();
                let ctx = format!("{} seed {seed} cfg {cfg:?}", method.name());

                // 1. The task plan is a valid solution of the symbolic domain.
                out.plan
                    .validate(n)
                    .unwrap_or_else(|e| panic!("{ctx}: {e}"));
                assert_eq!(out.method, method);

                // 2. One goal per (object, side), on a candidate cell of that location.
                assert_eq!(out.goals.len(), 2 * n, "{ctx}");
                for (i, g) in out.goals.iter().enumerate() {
                    let loc = &problem.locations[i];
                    assert_eq!(g.location, i);
                    assert_eq!(loc.cells[g.cell].xy, g.xy, "{ctx}");
                    assert_eq!(loc.heat[g.cell], g.heat_value);
                    assert_eq!(g.yaw_rad, loc.side.facing_yaw_rad());
                    let any_positive = loc.heat.iter().any(|&v| v > 0.0);
                    let any_free = loc.cells.iter().any(|c| c.free);
                    match (method, cfg.baseline_goals) {
                        // GROP draws with Smp, so never a zero cell when a positive one exists,
                        // and with free_goals_only never a cell where the base collides.
                        (MethodKind::Grop | MethodKind::GropPlus, _) => {
                            let read = location_heat(method, &cfg, loc);
                            if read.iter().any(|&v| v > 0.0) {
                                assert_eq!(g.source, GoalSource::Smp, "{ctx}");
                                assert!(g.heat_value > 0.0, "{ctx}");
                                if cfg.free_goals_only {
                                    assert!(
                                        loc.cells[g.cell].free,
                                        "{ctx}: GROP goal on an obstacle"
                                    );
                                }
                            }
                        }
                        (MethodKind::Satisficing, BaselineGoals::AuthorsCode) => {
                            assert_eq!(g.source, GoalSource::FixedRegion)
                        }
                        (_, BaselineGoals::Paper) => {
                            if any_free {
                                assert!(
                                    loc.cells[g.cell].free,
                                    "{ctx}: baseline goal on an obstacle"
                                );
                            }
                        }
                        (_, BaselineGoals::AuthorsCode) => {
                            if any_positive {
                                assert!(g.heat_value > 0.0, "{ctx}");
                            }
                        }
                    }
                }

                // 3. Reported F, C, U are those of the plan under the same goals and oracle.
                let goals_xy: Vec<(f64, f64)> = out.goals.iter().map(|g| g.xy).collect();
                let mut cache = LegCache::new(&problem, &goals_xy, cfg.no_path_cost_s);
                let mut table = PlanningTable::zeros(n);
                for (i, l) in problem.locations.iter().enumerate() {
                    table.feasibility[i] =
                        grop_select::task_feasibility(&location_heat(method, &cfg, l));
                }
                cache.fill_table(&mut table, &mut oracle as &mut dyn TravelTime);
                assert!(
                    (table.plan_cost_s(&out.plan) - out.cost_s).abs() < 1e-9,
                    "{ctx}"
                );
                assert!(
                    (table.plan_feasibility(&out.plan, cfg.aggregation) - out.feasibility).abs()
                        < 1e-12,
                    "{ctx}"
                );
                // GROP+ plans with its effective R (its lever may scale it with speed).
                let r = planner.effective_config().success_bonus_r;
                assert!((out.utility - (r * out.feasibility - out.cost_s)).abs() < 1e-9);
                assert_eq!(out.locations.len(), 2 * n);

                // 4. Each method's optimality claim, checked against every plan.
                let plans = satisficing_plans(n).unwrap();
                let u = |p| r * table.plan_feasibility(p, cfg.aggregation) - table.plan_cost_s(p);
                match method {
                    MethodKind::Grop | MethodKind::GropPlus | MethodKind::FcnPlanning => {
                        let best = plans.iter().map(u).fold(f64::NEG_INFINITY, f64::max);
                        assert!(
                            out.utility >= best - 1e-7,
                            "{ctx}: U {} < best {best}",
                            out.utility
                        );
                        if cfg.search == SearchMode::Exact {
                            assert!(out.candidates.is_empty());
                        } else {
                            assert_eq!(out.candidates.len(), plans.len());
                            let chosen = out.chosen_candidate.unwrap();
                            assert_eq!(plans[chosen], out.plan);
                            assert!(
                                out.candidates
                                    .iter()
                                    .all(|c| c.utility <= out.utility + UTILITY_TIE_EPS)
                            );
                        }
                        assert!(out.motion_planner_calls <= 1 + 2 * n + 2 * n * (n - 1));
                    }
                    MethodKind::Petlon => {
                        let min_cost = plans
                            .iter()
                            .map(|p| table.plan_cost_s(p))
                            .fold(f64::INFINITY, f64::min);
                        assert!((out.cost_s - min_cost).abs() < 1e-9, "{ctx}");
                    }
                    MethodKind::Dvh => {
                        let max_f = plans
                            .iter()
                            .map(|p| table.plan_feasibility(p, cfg.aggregation))
                            .fold(0.0, f64::max);
                        assert!(out.feasibility >= max_f - 1e-12, "{ctx}");
                        assert_eq!(out.motion_planner_calls, 0, "DVH decides without costs");
                    }
                    MethodKind::Satisficing => assert_eq!(out.motion_planner_calls, 0),
                }

                // 5. Deterministic for the seed.
                let mut oracle2 = common::DetourOracle {
                    speed_mps: cfg.speed_mps,
                    salt: seed,
                    no_path: 0.05,
                    calls: 0,
                };
                let again = Planner::new(method, cfg)
                    .plan(&problem, &mut oracle2, seed)
                    .unwrap();
                assert_eq!(again, out, "{ctx}: not reproducible");
            }
        }
    }
}

/// Different seeds give different random choices (goal draws are random, not fixed).
#[test]
fn seeds_change_goal_draws() {
    let problem = common::random_problem(3, 5);
    for method in MethodKind::ALL {
        let mut distinct = std::collections::HashSet::new();
        for seed in 0..20 {
            let mut oracle = common::DetourOracle {
                speed_mps: 0.4,
                salt: 1,
                no_path: 0.0,
                calls: 0,
            };
            let out = Planner::new(method, PlannerConfig::default())
                .plan(&problem, &mut oracle, seed)
                .unwrap();
            distinct.insert(out.goals.iter().map(|g| g.cell).collect::<Vec<_>>());
        }
        assert!(
            distinct.len() > 5,
            "{}: only {} distinct goal sets",
            method.name(),
            distinct.len()
        );
    }
}

/// GROP's goals follow the heatmap: over many seeds the mean heat value at GROP's goals beats
/// the uniform baselines' on the same problem.
#[test]
fn smp_goals_beat_uniform_goals_on_average() {
    let problem = common::random_problem(3, 77);
    let mean_heat = |method| {
        let mut acc = 0.0;
        for seed in 0..200 {
            let mut oracle = common::DetourOracle {
                speed_mps: 0.4,
                salt: 1,
                no_path: 0.0,
                calls: 0,
            };
            let out = Planner::new(method, PlannerConfig::default())
                .plan(&problem, &mut oracle, seed)
                .unwrap();
            acc += out.goals.iter().map(|g| g.heat_value as f64).sum::<f64>();
        }
        acc
    };
    assert!(mean_heat(MethodKind::Grop) > mean_heat(MethodKind::FcnPlanning));
    let _ = location_index(0, world::Side::Near);
}

/// Lazy costing finds the same utility as costing every leg, with no more motion-planner calls.
#[test]
fn lazy_costs_keep_the_argmax() {
    for seed in 0..30u64 {
        let n = 1 + (seed as usize % 4);
        let problem = common::random_problem(n, 5000 + seed);
        for search in [SearchMode::Enumerate, SearchMode::Exact] {
            let full_cfg = PlannerConfig {
                search,
                ..PlannerConfig::default()
            };
            let lazy_cfg = PlannerConfig {
                lazy_costs: true,
                ..full_cfg
            };
            let mut o1 = common::DetourOracle {
                speed_mps: 0.4,
                salt: seed,
                no_path: 0.1,
                calls: 0,
            };
            let mut o2 = common::DetourOracle {
                speed_mps: 0.4,
                salt: seed,
                no_path: 0.1,
                calls: 0,
            };
            let full = Planner::new(MethodKind::Grop, full_cfg)
                .plan(&problem, &mut o1, seed)
                .unwrap();
            let lazy = Planner::new(MethodKind::Grop, lazy_cfg)
                .plan(&problem, &mut o2, seed)
                .unwrap();
            assert!(
                (full.utility - lazy.utility).abs() < 1e-7,
                "seed {seed}: {} vs {}",
                full.utility,
                lazy.utility
            );
            assert!(lazy.motion_planner_calls <= full.motion_planner_calls);
        }
    }
}
