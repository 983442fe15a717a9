//! The multi-trip optimiser against brute force over the whole plan family (small tasks, k < n),
//! and its anytime bound against the exact optimum.
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failure panics with its message

use planner::multi_trip::{
    TripSearchLimits, optimise_trips, trip_plan_cost_s, trip_plan_feasibility, trip_plans,
};
use planner::task::PlanningTable;
use proptest::prelude::*;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

fn table_strategy(n: usize) -> impl Strategy<Value = PlanningTable> {
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
}

/// Brute force: every plan of the family, scored by the plan-level F and C.
fn brute_force(t: &PlanningTable, r: f64, k: usize) -> f64 {
    trip_plans(t.n_objects, k)
        .unwrap()
        .iter()
        .map(|p| r * trip_plan_feasibility(t, p) - trip_plan_cost_s(t, p))
        .fold(f64::NEG_INFINITY, f64::max)
}

fn n_and_k() -> impl Strategy<Value = (usize, usize)> {
    prop_oneof![
        Just((2, 1)),
        Just((3, 1)),
        Just((3, 2)),
        Just((4, 2)),
        Just((4, 3)),
        Just((5, 2)),
        Just((5, 3)),
        Just((5, 4)),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 48, ..ProptestConfig::default() })]

    /// Exact == brute force (same utility), and the plan is a valid plan of the family whose
    /// reported F, C, U are its own.
    #[test]
    fn exact_equals_brute_force(
        (n, k, t) in n_and_k().prop_flat_map(|(n, k)| (Just(n), Just(k), table_strategy(n))),
        r in 0.0..80.0f64,
    ) {
        let best = optimise_trips(&t, r, k, TripSearchLimits { max_nodes: u64::MAX }).unwrap();
        let brute = brute_force(&t, r, k);
        prop_assert!(best.proven_optimal);
        prop_assert!((best.utility - brute).abs() < 1e-7, "search {} vs brute force {}", best.utility, brute);
        prop_assert_eq!(best.plan.trips.len(), n.div_ceil(k));
        best.plan.validate(n, k).unwrap();
        let f = trip_plan_feasibility(&t, &best.plan);
        let c = trip_plan_cost_s(&t, &best.plan);
        prop_assert!((best.utility - (r * f - c)).abs() < 1e-9);
        prop_assert!((best.feasibility - f).abs() < 1e-12 && (best.cost_s - c).abs() < 1e-12);
        prop_assert_eq!(best.gap(), 0.0);
    }
}

/// A table from points in the plane (metric travel times, like the navigation planner's).
fn metric_table(n: usize, seed: u64) -> PlanningTable {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut t = PlanningTable::zeros(n);
    let station = (0.0, 1.0);
    let pts: Vec<(f64, f64)> = (0..2 * n)
        .map(|i| {
            let x = rng.random_range(-6.0..6.0);
            let y = if i % 2 == 0 { 5.5 } else { 6.5 };
            (x, y + rng.random_range(-0.3..0.3))
        })
        .collect();
    let d = |a: (f64, f64), b: (f64, f64)| (a.0 - b.0).hypot(a.1 - b.1) / 0.4;
    t.start_to_station_s = 2.5;
    for i in 0..2 * n {
        t.station_to_location_s[i] = d(station, pts[i]);
        t.feasibility[i] = rng.random_range(0.0..1.0);
        for j in 0..2 * n {
            t.location_to_location_s[i * 2 * n + j] = d(pts[i], pts[j]);
        }
    }
    t
}

/// A stopped search returns a valid plan and an upper bound the true optimum respects.
#[test]
fn anytime_bound_holds_the_optimum() {
    for seed in 0..6 {
        let t = metric_table(12, seed);
        let exact = optimise_trips(
            &t,
            40.0,
            3,
            TripSearchLimits {
                max_nodes: u64::MAX,
            },
        )
        .unwrap();
        assert!(exact.proven_optimal);
        for max_nodes in [1, 5, 50] {
            let quick = optimise_trips(&t, 40.0, 3, TripSearchLimits { max_nodes }).unwrap();
            quick.plan.validate(12, 3).unwrap();
            if max_nodes == 1 {
                assert!(
                    !quick.proven_optimal,
                    "one node cannot prove 12 objects optimal"
                );
            }
            assert!(quick.utility <= exact.utility + 1e-9);
            assert!(
                quick.upper_bound >= exact.utility - 1e-9,
                "seed {seed}, {max_nodes} nodes: bound {} below the optimum {}",
                quick.upper_bound,
                exact.utility
            );
            if !quick.proven_optimal {
                assert!(quick.gap() >= exact.utility - quick.utility - 1e-9);
            }
        }
    }
}

/// With k >= n the optimiser is the paper's single-trip optimum.
#[test]
fn one_trip_is_the_single_trip_optimum() {
    let t = metric_table(6, 9);
    let single =
        planner::task::optimise(&t, 40.0, grop_select::FeasibilityAggregation::Sum).unwrap();
    let trips = optimise_trips(&t, 40.0, 6, TripSearchLimits::default()).unwrap();
    assert_eq!(trips.plan.trips.len(), 1);
    assert_eq!(trips.plan.trips[0].unloads, single.plan.unloads);
    assert!((trips.utility - single.utility).abs() < 1e-12);
}
