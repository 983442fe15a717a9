//! The exact optimiser against enumeration, and PETLON against exhaustive cost-optimal search.
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failure panics with its message

mod common;

use grop_select::{Argmax, Candidate, FeasibilityAggregation};
use planner::costs::TravelTime;
use planner::methods::{MethodKind, Planner, PlannerConfig, TaskMotionPlanner};
use planner::task::{PlanningTable, optimise, satisficing_plans};
use proptest::prelude::*;

fn table_strategy(max_n: usize) -> impl Strategy<Value = PlanningTable> {
    (1..=max_n).prop_flat_map(|n| {
        let m = 2 * n;
        (
            0.0..20.0f64,
            prop::collection::vec(1.0..60.0f64, m),
            prop::collection::vec(1.0..60.0f64, m * m),
            prop::collection::vec(prop_oneof![Just(0.0f64), 0.0..1.0f64], m),
        )
            .prop_map(move |(s, st, ll, f)| PlanningTable {
                n_objects: n,
                start_to_station_s: s,
                station_to_location_s: st,
                location_to_location_s: ll,
                feasibility: f,
            })
    })
}

fn enumerated_best(t: &PlanningTable, r: f64, agg: FeasibilityAggregation) -> (usize, f64, f64) {
    let plans = satisficing_plans(t.n_objects).unwrap();
    let mut a = Argmax::new(r);
    for p in &plans {
        a.offer(Candidate {
            feasibility: t.plan_feasibility(p, agg),
            cost_s: t.plan_cost_s(p),
        })
        .unwrap();
    }
    let b = a.best().unwrap();
    (b.index, b.utility, b.cost_s)
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, ..ProptestConfig::default() })]

    /// The DP finds the enumeration's argmax (same utility; the same plan, load order aside,
    /// since random real costs make ties impossible).
    #[test]
    fn exact_equals_enumeration_sum(t in table_strategy(4), r in 0.0..80.0f64) {
        let agg = FeasibilityAggregation::Sum;
        let (idx, u, _) = enumerated_best(&t, r, agg);
        let best = optimise(&t, r, agg).unwrap();
        prop_assert!((best.utility - u).abs() < 1e-7, "dp {} vs enumeration {}", best.utility, u);
        let plans = satisficing_plans(t.n_objects).unwrap();
        prop_assert_eq!(&best.plan.unloads, &plans[idx].unloads);
        prop_assert_eq!(&best.plan, &plans[idx]);
        best.plan.validate(t.n_objects).unwrap();
    }

    #[test]
    fn exact_equals_enumeration_product(t in table_strategy(4), r in 0.0..80.0f64) {
        let agg = FeasibilityAggregation::Product;
        let (_, u, _) = enumerated_best(&t, r, agg);
        let best = optimise(&t, r, agg).unwrap();
        prop_assert!((best.utility - u).abs() < 1e-7, "search {} vs enumeration {}", best.utility, u);
        best.plan.validate(t.n_objects).unwrap();
    }
}

/// Ten objects: the optimiser returns a valid plan no worse than any of many random plans and
/// than every single swap of two steps or flip of one side (a local optimum at least).
#[test]
fn exact_handles_ten_objects() {
    use rand::seq::SliceRandom;
    use rand::{RngExt, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(10);
    for agg in [FeasibilityAggregation::Sum, FeasibilityAggregation::Product] {
        let n = 10;
        let m = 2 * n;
        let table = PlanningTable {
            n_objects: n,
            start_to_station_s: 2.0,
            station_to_location_s: (0..m).map(|_| rng.random_range(5.0..50.0)).collect(),
            location_to_location_s: (0..m * m).map(|_| rng.random_range(1.0..40.0)).collect(),
            feasibility: (0..m).map(|_| rng.random_range(0.5..1.0)).collect(),
        };
        let best = optimise(&table, 40.0, agg).unwrap();
        best.plan.validate(n).unwrap();
        let u = |p: &planner::task::TaskPlan| {
            40.0 * table.plan_feasibility(p, agg) - table.plan_cost_s(p)
        };
        assert!((u(&best.plan) - best.utility).abs() < 1e-9);
        for _ in 0..2000 {
            let mut p = best.plan.clone();
            p.unloads.shuffle(&mut rng);
            for s in p.unloads.iter_mut() {
                if rng.random::<bool>() {
                    s.side = match s.side {
                        world::Side::Near => world::Side::Far,
                        world::Side::Far => world::Side::Near,
                    };
                }
            }
            assert!(u(&p) <= best.utility + 1e-9);
        }
        for i in 0..n {
            for j in 0..n {
                let mut p = best.plan.clone();
                p.unloads.swap(i, j);
                assert!(u(&p) <= best.utility + 1e-9);
            }
            let mut p = best.plan.clone();
            p.unloads[i].side = match p.unloads[i].side {
                world::Side::Near => world::Side::Far,
                world::Side::Far => world::Side::Near,
            };
            assert!(u(&p) <= best.utility + 1e-9);
        }
    }
}

/// PETLON returns an exhaustively cost-optimal plan (over the same goals) and calls the motion
/// planner no more often than exhaustive costing does.
#[test]
fn petlon_equals_exhaustive_cost_optimal() {
    for seed in 0..40u64 {
        let n = 1 + (seed as usize % 4);
        let problem = common::random_problem(n, seed);
        let mut oracle = common::DetourOracle {
            speed_mps: 0.4,
            salt: seed,
            no_path: 0.1,
            calls: 0,
        };
        let cfg = PlannerConfig::default();
        let out = Planner::new(MethodKind::Petlon, cfg)
            .plan(&problem, &mut oracle, seed)
            .unwrap();
        // Exhaustive: every leg costed with the same oracle and goals, then every plan.
        let goals_xy: Vec<(f64, f64)> = out.goals.iter().map(|g| g.xy).collect();
        let mut cache = planner::costs::LegCache::new(&problem, &goals_xy, cfg.no_path_cost_s);
        let mut table = PlanningTable::zeros(n);
        cache.fill_table(&mut table, &mut oracle as &mut dyn TravelTime);
        let min_cost = satisficing_plans(n)
            .unwrap()
            .iter()
            .map(|p| table.plan_cost_s(p))
            .fold(f64::INFINITY, f64::min);
        assert!(
            (out.cost_s - min_cost).abs() < 1e-9,
            "seed {seed}: PETLON {} vs exhaustive {min_cost}",
            out.cost_s
        );
        assert!((table.plan_cost_s(&out.plan) - out.cost_s).abs() < 1e-9);
        assert!(out.motion_planner_calls <= cache.calls(), "seed {seed}");
        assert!(out.refinement_rounds >= 1);
    }
}
