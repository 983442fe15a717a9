//! GROP+ (`planner::grop_plus`): with every lever off it is GROP, it is deterministic per seed,
//! each lever does what it says, and the retry policy keeps its bounds.

mod common;

use planner::grop_plus::{GropPlusConfig, clear_of_obstacles, effective_r, retry_goal};
use planner::methods::{GoalSource, MethodKind, Planner, PlannerConfig, TaskMotionPlanner};
use planner::task::location_index;
use world::Side;

fn oracle(salt: u64) -> common::DetourOracle {
    common::DetourOracle {
        speed_mps: 0.4,
        salt,
        no_path: 0.05,
        calls: 0,
    }
}

#[test]
fn with_every_lever_off_grop_plus_is_grop() {
    for paper_smp in [false, true] {
        for goal_draws in [1, 3] {
            let cfg = PlannerConfig {
                plus: GropPlusConfig::OFF,
                free_goals_only: !paper_smp,
                goal_draws,
                ..PlannerConfig::default()
            };
            for seed in 0..24u64 {
                let problem = common::random_problem(1 + seed as usize % 4, 500 + seed);
                let grop = Planner::new(MethodKind::Grop, cfg)
                    .plan(&problem, &mut oracle(seed), seed)
                    .unwrap();
                let plus = Planner::new(MethodKind::GropPlus, cfg)
                    .plan(&problem, &mut oracle(seed), seed)
                    .unwrap();
                assert_eq!(plus.method, MethodKind::GropPlus);
                assert_eq!(
                    planner::methods::PlannedTask {
                        method: MethodKind::Grop,
                        ..plus
                    },
                    grop,
                    "seed {seed}, paper Smp {paper_smp}, draws {goal_draws}"
                );
            }
        }
    }
}

#[test]
fn grop_plus_is_deterministic_per_seed_and_seeds_matter() {
    let cfg = PlannerConfig::default();
    assert_eq!(cfg.plus, GropPlusConfig::DEFAULT);
    let mut differ = 0;
    for seed in 0..16u64 {
        let problem = common::random_problem(3, 900 + seed);
        let a = Planner::new(MethodKind::GropPlus, cfg)
            .plan(&problem, &mut oracle(seed), seed)
            .unwrap();
        let b = Planner::new(MethodKind::GropPlus, cfg)
            .plan(&problem, &mut oracle(seed), seed)
            .unwrap();
        assert_eq!(a, b, "seed {seed}");
        let c = Planner::new(MethodKind::GropPlus, cfg)
            .plan(&problem, &mut oracle(seed), seed + 1000)
            .unwrap();
        if c.goals != a.goals {
            differ += 1;
        }
        // The retry policy draws nothing: same question, same answer.
        let tried = [a.goals[0].xy];
        let r1 = retry_goal(&cfg, &problem, 0, &tried, (0.0, 2.0), 0, &mut oracle(seed));
        let r2 = retry_goal(&cfg, &problem, 0, &tried, (0.0, 2.0), 0, &mut oracle(seed));
        assert_eq!(r1, r2);
    }
    assert!(
        differ > 8,
        "the seed drives the goal draws ({differ} of 16 differ)"
    );
}

#[test]
fn best_of_n_draws_raise_the_goal_values() {
    let mut sum_one = 0.0;
    let mut sum_many = 0.0;
    for seed in 0..40u64 {
        let problem = common::random_problem(3, 2000 + seed);
        for (draws, sum) in [(None, &mut sum_one), (Some(8), &mut sum_many)] {
            let cfg = PlannerConfig {
                plus: GropPlusConfig {
                    goal_draws: draws,
                    ..GropPlusConfig::OFF
                },
                ..PlannerConfig::default()
            };
            let out = Planner::new(MethodKind::GropPlus, cfg)
                .plan(&problem, &mut oracle(seed), seed)
                .unwrap();
            *sum += out
                .goals
                .iter()
                .map(|g| f64::from(g.heat_value))
                .sum::<f64>();
        }
    }
    assert!(
        sum_many > sum_one,
        "best of 8 {sum_many} vs one draw {sum_one}"
    );
}

#[test]
fn goal_margin_keeps_goals_clear_of_obstacles() {
    let margin = 0.15;
    let cfg = PlannerConfig {
        plus: GropPlusConfig {
            goal_margin_m: margin,
            ..GropPlusConfig::OFF
        },
        ..PlannerConfig::default()
    };
    let mut checked = 0;
    for seed in 0..40u64 {
        let problem = common::random_problem(2, 3000 + seed);
        let out = Planner::new(MethodKind::GropPlus, cfg)
            .plan(&problem, &mut oracle(seed), seed)
            .unwrap();
        for g in &out.goals {
            let loc = &problem.locations[g.location];
            let clear = clear_of_obstacles(loc, margin);
            let usable = loc.heat.iter().zip(&clear).any(|(&h, &ok)| ok && h > 0.0);
            if usable && g.source == GoalSource::Smp {
                assert!(clear[g.cell], "seed {seed}: goal within the margin");
                let c = loc.cells[g.cell].xy;
                for b in loc.cells.iter().filter(|c| !c.free) {
                    assert!((b.xy.0 - c.0).hypot(b.xy.1 - c.1) >= margin);
                }
                checked += 1;
            }
        }
    }
    assert!(checked > 20, "only {checked} goals checked");
}

#[test]
fn r_follows_speed() {
    let slow = PlannerConfig {
        speed_mps: 0.2,
        ..PlannerConfig::default()
    };
    assert_eq!(effective_r(&slow, false), slow.success_bonus_r);
    assert!((effective_r(&slow, true) - 2.0 * slow.success_bonus_r).abs() < 1e-12);
    let fast = PlannerConfig {
        speed_mps: 0.8,
        ..slow
    };
    assert!((effective_r(&fast, true) - 0.5 * fast.success_bonus_r).abs() < 1e-12);
    // The plan's U uses it.
    let problem = common::random_problem(2, 7);
    let cfg = PlannerConfig {
        plus: GropPlusConfig {
            r_follows_speed: true,
            ..GropPlusConfig::OFF
        },
        ..slow
    };
    let out = Planner::new(MethodKind::GropPlus, cfg)
        .plan(&problem, &mut oracle(1), 1)
        .unwrap();
    assert!(
        (out.utility - (2.0 * cfg.success_bonus_r * out.feasibility - out.cost_s)).abs() < 1e-9
    );
}

#[test]
fn retry_goes_to_the_best_untried_cell_and_keeps_its_bounds() {
    let cfg = PlannerConfig {
        plus: GropPlusConfig {
            max_retries: 2,
            ..GropPlusConfig::OFF
        },
        ..PlannerConfig::default()
    };
    let mut retried = 0;
    for seed in 0..40u64 {
        let problem = common::random_problem(3, 4000 + seed);
        let at = (0.0, 2.0);
        let object = seed as usize % 3;
        let Some(first) = retry_goal(&cfg, &problem, object, &[], at, 0, &mut oracle(seed)) else {
            // No retry: nowhere positive on either side, or nothing worth the drive.
            continue;
        };
        retried += 1;
        assert_eq!(first.source, GoalSource::Retry);
        assert_eq!(first.location / 2, object);
        let loc = &problem.locations[first.location];
        assert!(
            loc.cells[first.cell].free,
            "retries never go into obstacles"
        );
        assert!(first.heat_value > 0.0);
        // The best cell of its side (free cells).
        let best = loc
            .heat
            .iter()
            .zip(&loc.cells)
            .filter(|(_, c)| c.free)
            .map(|(&h, _)| h)
            .fold(0.0f32, f32::max);
        assert_eq!(first.heat_value, best);
        // A tried cell is not offered again.
        let second = retry_goal(
            &cfg,
            &problem,
            object,
            &[first.xy],
            at,
            1,
            &mut oracle(seed),
        );
        if let Some(second) = second {
            assert_ne!(second.xy, first.xy);
        }
        // The budget: after max_retries retries, none.
        assert_eq!(
            retry_goal(
                &cfg,
                &problem,
                object,
                &[first.xy],
                at,
                2,
                &mut oracle(seed)
            ),
            None
        );
        let off = PlannerConfig {
            plus: GropPlusConfig::OFF,
            ..cfg
        };
        assert_eq!(
            retry_goal(&off, &problem, object, &[], at, 0, &mut oracle(seed)),
            None
        );
        // An object that does not exist.
        assert_eq!(
            retry_goal(&cfg, &problem, 7, &[], at, 0, &mut oracle(seed)),
            None
        );
    }
    assert!(retried > 15, "only {retried} retries");
}

#[test]
fn retry_prefers_the_other_side_when_it_is_better() {
    let mut problem = common::random_problem(1, 11);
    for side in Side::BOTH {
        let loc = &mut problem.locations[location_index(0, side)];
        for c in loc.cells.iter_mut() {
            c.free = true;
        }
        loc.heat = [if side == Side::Far { 0.9 } else { 0.2 }; 192];
    }
    let cfg = PlannerConfig::default();
    let at = problem.locations[location_index(0, Side::Near)].cells[100].xy;
    let goal = retry_goal(&cfg, &problem, 0, &[at], at, 0, &mut oracle(3)).unwrap();
    assert_eq!(problem.locations[goal.location].side, Side::Far);
}

#[test]
fn bad_lever_values_are_refused() {
    let problem = common::random_problem(2, 1);
    for plus in [
        GropPlusConfig {
            max_retries: 9,
            ..GropPlusConfig::OFF
        },
        GropPlusConfig {
            goal_draws: Some(0),
            ..GropPlusConfig::OFF
        },
        GropPlusConfig {
            goal_margin_m: f64::NAN,
            ..GropPlusConfig::OFF
        },
    ] {
        let cfg = PlannerConfig {
            plus,
            ..PlannerConfig::default()
        };
        assert!(
            Planner::new(MethodKind::GropPlus, cfg)
                .plan(&problem, &mut oracle(1), 1)
                .is_err()
        );
        // GROP ignores GROP+'s levers.
        assert!(
            Planner::new(MethodKind::Grop, cfg)
                .plan(&problem, &mut oracle(1), 1)
                .is_ok()
        );
    }
}
