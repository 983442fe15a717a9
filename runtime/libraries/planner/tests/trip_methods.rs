//! Conformance of GROP and the baselines over multi-trip plans: valid plans of the family for the
//! capacity, each method's claim (FCN-Planning max U, PETLON min C, DVH max F among methods with
//! the same goals), reported F and C equal to the plan's, determinism, and typed errors.

mod common;

use common::{DetourOracle, random_problem};
use grop_select::FeasibilityAggregation;
use planner::methods::{MethodKind, PlannerConfig};
use planner::multi_trip::{TripPlanError, trip_count};
use planner::trip_methods::{MultiTripError, MultiTripPlanner};

const METHODS: [MethodKind; 5] = [
    MethodKind::Grop,
    MethodKind::FcnPlanning,
    MethodKind::Petlon,
    MethodKind::Dvh,
    MethodKind::Satisficing,
];

fn oracle(salt: u64) -> DetourOracle {
    DetourOracle {
        speed_mps: 0.4,
        salt,
        no_path: 0.02,
        calls: 0,
    }
}

#[test]
fn every_method_plans_valid_trips_and_keeps_its_claim() {
    for (n, k, seed) in [
        (7, 3, 1u64),
        (9, 3, 2),
        (8, 2, 3),
        (6, 4, 4),
        (3, 3, 5),
        (12, 3, 6),
    ] {
        let problem = random_problem(n, seed);
        let mut answers = Vec::new();
        for kind in METHODS {
            let planner = MultiTripPlanner::new(kind, PlannerConfig::default(), k);
            let a = planner
                .plan(&problem, &mut oracle(seed), seed)
                .expect("plans");
            a.plan.validate(n, k).expect("valid");
            assert_eq!(a.plan.trips.len(), trip_count(n, k), "{kind:?}");
            let again = planner
                .plan(&problem, &mut oracle(seed), seed)
                .expect("plans");
            assert_eq!(a, again, "{kind:?} is deterministic");
            if let Some(s) = a.search {
                assert!(s.gap >= 0.0);
                if s.proven_optimal {
                    assert!(s.gap < 1e-7, "{kind:?}: proven optimal with gap {}", s.gap);
                }
            }
            answers.push(a);
        }
        let fcn = &answers[1];
        assert!(fcn.search.expect("searched").proven_optimal, "n = {n}");
        for other in &answers[2..] {
            // Same uniform goals as FCN-Planning: it has the highest U, PETLON the lowest C,
            // DVH the highest F.
            assert!(fcn.utility >= other.utility - 1e-7, "{:?}", other.method);
            assert!(
                answers[2].cost_s <= other.cost_s + 1e-7,
                "{:?}",
                other.method
            );
            assert!(
                answers[3].feasibility >= other.feasibility - 1e-7,
                "{:?}",
                other.method
            );
        }
        assert_eq!(
            answers[1].goals, answers[4].goals,
            "baselines share their goals"
        );
    }
}

#[test]
fn three_objects_with_a_tray_of_three_is_grops_single_trip_plan() {
    use planner::costs::TravelTime;
    use planner::methods::{Planner, TaskMotionPlanner};
    let problem = random_problem(3, 11);
    let cfg = PlannerConfig::default();
    let trips = MultiTripPlanner::new(MethodKind::Grop, cfg, 3)
        .plan(&problem, &mut oracle(11), 11)
        .expect("plans");
    let mut travel = oracle(11);
    let travel: &mut dyn TravelTime = &mut travel;
    let single = Planner::new(MethodKind::Grop, cfg)
        .plan(&problem, travel, 11)
        .expect("plans");
    assert_eq!(trips.plan.trips.len(), 1);
    assert_eq!(trips.plan.trips[0].unloads, single.plan.unloads);
    assert!((trips.utility - single.utility).abs() < 1e-9);
    assert_eq!(trips.goals, single.goals);
}

#[test]
fn bad_settings_are_typed_errors() {
    let problem = random_problem(4, 1);
    let zero = MultiTripPlanner::new(MethodKind::Grop, PlannerConfig::default(), 0);
    assert!(matches!(
        zero.plan(&problem, &mut oracle(1), 1),
        Err(MultiTripError::Trips(TripPlanError::ZeroCapacity))
    ));
    let product = MultiTripPlanner::new(
        MethodKind::Grop,
        PlannerConfig {
            aggregation: FeasibilityAggregation::Product,
            ..PlannerConfig::default()
        },
        2,
    );
    assert!(matches!(
        product.plan(&problem, &mut oracle(1), 1),
        Err(MultiTripError::Trips(TripPlanError::ProductAggregation))
    ));
    let bad_r = MultiTripPlanner::new(
        MethodKind::Grop,
        PlannerConfig {
            success_bonus_r: f64::NAN,
            ..PlannerConfig::default()
        },
        2,
    );
    assert!(matches!(
        bad_r.plan(&problem, &mut oracle(1), 1),
        Err(MultiTripError::Plan(_))
    ));
}
