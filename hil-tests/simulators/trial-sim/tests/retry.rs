//! The retry model: every attempt is a trial with the same noise model as a first attempt, its
//! time is counted by the same rule, and the number of retries is bounded.

use proptest::prelude::*;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use trial_sim::retry::{AttemptCosts, MAX_RETRIES, unload_with_retries};
use trial_sim::{TrialResult, TrialSimulator};
use world::view::cell_center_world;
use world::{RobotConfig, Side};

const COSTS: AttemptCosts = AttemptCosts {
    speed_mps: 0.4,
    unload_time_s: 5.0,
    failed_nav_time_s: 60.0,
};

fn straight(from: (f64, f64), to: (f64, f64)) -> Option<f64> {
    Some((to.0 - from.0).hypot(to.1 - from.1))
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]

    /// Retrying the same goal again and again: attempt k realises exactly the k-th trial the
    /// simulator runs on the same random stream (same noise model, same draws), and each
    /// attempt's time follows the first attempt's rule.
    #[test]
    fn retries_meet_the_same_noise_and_count_their_time(
        scene_seed in 0u64..40,
        seed in 0u64..1_000,
        row in 9usize..=16,
        col in 20usize..=43,
        max_retries in 0usize..4,
    ) {
        let scene = world::generate::evaluation_scene(scene_seed, 20, 3);
        let robot = RobotConfig::default();
        let target = scene.targets[0].as_array();
        let goal = cell_center_world(target[0], Side::Near, row, col);
        let start = (0.0, 2.0);
        let mut sim = TrialSimulator::new(&scene, &robot);
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut asked = 0;
        let log = unload_with_retries(
            &mut sim, target, (Side::Near, goal), start, &COSTS, max_retries, straight,
            |attempts, _at| {
                asked += 1;
                assert!(attempts.iter().all(|a| !a.placed()), "no retry after a success");
                Some((Side::Near, goal))
            },
            &mut rng,
        );
        // Bounded, and no retry after a success.
        prop_assert!(!log.attempts.is_empty() && log.attempts.len() <= 1 + max_retries);
        prop_assert_eq!(log.placed, log.attempts.last().unwrap().placed());
        if log.placed || log.attempts.len() < 1 + max_retries {
            prop_assert!(log.placed);
        }
        prop_assert_eq!(asked, log.attempts.len() - 1);

        // The same stream through plain trials gives the same realised poses and results.
        let mut twin = ChaCha8Rng::seed_from_u64(seed);
        let mut plain = TrialSimulator::new(&scene, &robot);
        let mut at = start;
        let mut total = 0.0;
        for a in &log.attempts {
            let o = plain.run(target, Side::Near, goal, &mut twin);
            prop_assert_eq!(a.outcome, Some(o));
            let expected = if o.result == TrialResult::BaseCollision {
                COSTS.failed_nav_time_s
            } else {
                let end_leg = (o.realised.x_m - goal.0).hypot(o.realised.y_m - goal.1);
                (straight(at, goal).unwrap() + end_leg) / COSTS.speed_mps + COSTS.unload_time_s
            };
            prop_assert!((a.time_s - expected).abs() < 1e-9);
            at = if o.result == TrialResult::BaseCollision {
                goal
            } else {
                (o.realised.x_m, o.realised.y_m)
            };
            total += a.time_s;
        }
        prop_assert!((log.time_s - total).abs() < 1e-9);
        prop_assert_eq!(log.end_xy, at);
    }
}

/// No path: the failure charge, no trial (no noise drawn), the base stays; a retry to the other
/// side then runs a normal trial.
#[test]
fn no_path_charges_and_draws_no_noise() {
    let scene = world::generate::evaluation_scene(3, 15, 3);
    let robot = RobotConfig::default();
    let target = scene.targets[1].as_array();
    let near = cell_center_world(target[0], Side::Near, 12, 31);
    let far = cell_center_world(target[0], Side::Far, 12, 31);
    let mut sim = TrialSimulator::new(&scene, &robot);
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let start = (0.5, 1.5);
    let log = unload_with_retries(
        &mut sim,
        target,
        (Side::Near, near),
        start,
        &COSTS,
        1,
        |from, to| (to != near).then(|| straight(from, to).unwrap()),
        |_, at| {
            assert_eq!(at, start, "after no path the base has not moved");
            Some((Side::Far, far))
        },
        &mut rng,
    );
    assert_eq!(log.attempts.len(), 2);
    assert_eq!(log.attempts[0].outcome, None);
    assert_eq!(log.attempts[0].time_s, COSTS.failed_nav_time_s);
    assert_eq!(log.attempts[0].distance_m, 0.0);
    // The far attempt used the first draws of the stream.
    let mut twin = ChaCha8Rng::seed_from_u64(5);
    let o = TrialSimulator::new(&scene, &robot).run(target, Side::Far, far, &mut twin);
    assert_eq!(log.attempts[1].outcome, Some(o));
    assert_eq!(log.attempts[1].side, Side::Far);
}

/// Without retries the model is one trial, exactly as the evaluation ran before retries existed.
#[test]
fn zero_retries_is_one_trial_and_the_bound_is_capped() {
    let scene = world::generate::evaluation_scene(9, 25, 3);
    let robot = RobotConfig::default();
    let target = scene.targets[2].as_array();
    let goal = cell_center_world(target[0], Side::Far, 16, 20);
    let mut sim = TrialSimulator::new(&scene, &robot);
    for seed in 0..20 {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let log = unload_with_retries(
            &mut sim,
            target,
            (Side::Far, goal),
            (0.0, 0.0),
            &COSTS,
            0,
            straight,
            |_, _| panic!("no retry with a bound of 0"),
            &mut rng,
        );
        assert_eq!(log.attempts.len(), 1);
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let never = unload_with_retries(
            &mut sim,
            target,
            (Side::Far, goal),
            (0.0, 0.0),
            &COSTS,
            1000,
            straight,
            |_, _| Some((Side::Far, goal)),
            &mut rng,
        );
        assert!(never.attempts.len() <= 1 + MAX_RETRIES);
    }
}
