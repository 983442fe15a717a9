//! Unloading one object with retries: the first attempt at the commanded goal and, after a
//! failure, as many further attempts as a retry policy asks for (bounded). Every attempt is a
//! trial of [`TrialSimulator::run`], so it meets the same navigation noise model as a first
//! attempt, and its travel and unloading time are counted exactly as a first attempt's are.
//!
//! ```no_run
//! use trial_sim::retry::{AttemptCosts, unload_with_retries};
//! use trial_sim::TrialSimulator;
//! use world::{RobotConfig, Side};
//! # let scene = world::generate::training_scenes(0, 1, 1).remove(0);
//! let robot = RobotConfig::default();
//! let mut sim = TrialSimulator::new(&scene, &robot);
//! let costs = AttemptCosts { speed_mps: 0.4, unload_time_s: 5.0, failed_nav_time_s: 60.0 };
//! let mut rng = <rand_chacha::ChaCha8Rng as rand::SeedableRng>::seed_from_u64(1);
//! let target = scene.targets[0].as_array();
//! let goal = world::view::cell_center_world(target[0], Side::Near, 12, 31);
//! let log = unload_with_retries(
//!     &mut sim, target, (Side::Near, goal), (0.0, 0.0), &costs, 2,
//!     |from, to| Some((to.0 - from.0).hypot(to.1 - from.1)), // path length (m)
//!     |_attempt, _at| Some((Side::Far, world::view::cell_center_world(target[0], Side::Far, 12, 31))),
//!     &mut rng,
//! );
//! println!("placed {} after {} attempts, {:.1} s", log.placed, log.attempts.len(), log.time_s);
//! ```

use rand::Rng;
use world::Side;

use crate::trial::{ArmModel, TrialOutcome, TrialResult, TrialSimulator};

/// Most retries after the first attempt the simulator accepts (a policy's bound must be below).
pub const MAX_RETRIES: usize = 8;

/// What an attempt costs: the evaluation's time model (docs/experiments.md, "Setup").
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AttemptCosts {
    /// Cruise speed of the base (m/s).
    pub speed_mps: f64,
    /// Time of one unloading attempt at the goal (s).
    pub unload_time_s: f64,
    /// Time charged for a navigation that finds no path or ends in collision (s).
    pub failed_nav_time_s: f64,
}

/// One attempt at unloading an object.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Attempt {
    /// Side of the table the base was sent to.
    pub side: Side,
    /// The commanded base position (m).
    pub commanded_xy: (f64, f64),
    /// The trial, `None` when the navigation planner found no path (no trial, no noise drawn).
    pub outcome: Option<TrialOutcome>,
    /// Time the attempt took: travel + unloading, or the failure charge (s).
    pub time_s: f64,
    /// Distance driven (m).
    pub distance_m: f64,
}

impl Attempt {
    /// Did the object get placed?
    pub fn placed(&self) -> bool {
        self.outcome
            .is_some_and(|o| o.result == TrialResult::Success)
    }
}

/// Every attempt at one object, in order; the last is the success if any.
#[derive(Debug, Clone, PartialEq)]
pub struct UnloadLog {
    /// The attempts (1 + retries).
    pub attempts: Vec<Attempt>,
    /// Was the object placed?
    pub placed: bool,
    /// Sum of the attempts' times (s).
    pub time_s: f64,
    /// Sum of the attempts' distances (m).
    pub distance_m: f64,
    /// Where the base stands afterwards: the realised pose after an unloading attempt, the
    /// commanded goal after a collision (the robot continues from there), unchanged after no path.
    pub end_xy: (f64, f64),
}

/// Unloads `target` starting with the attempt `first` (side, commanded position) from `at_xy`;
/// after each failed attempt asks `retry(failed_attempts_so_far, &last_attempt_and_position)` for
/// the next (side, commanded position), at most `max_retries` times (capped at [`MAX_RETRIES`]).
///
/// `path_length_m(from, to)` is the navigation planner's path length (`None`: no path). Time of
/// an attempt, the same for first attempts and retries:
/// * no path: `failed_nav_time_s`, the base stays where it is, no trial is run;
/// * base collision at the realised pose: `failed_nav_time_s`, the base continues from the
///   commanded goal;
/// * otherwise: (path length + the noisy end leg) / speed + `unload_time_s`, the base stands at
///   the realised pose.
#[allow(clippy::too_many_arguments)]
pub fn unload_with_retries<A: ArmModel, R: Rng + ?Sized>(
    sim: &mut TrialSimulator<'_, A>,
    target: [f64; 3],
    first: (Side, (f64, f64)),
    at_xy: (f64, f64),
    costs: &AttemptCosts,
    max_retries: usize,
    mut path_length_m: impl FnMut((f64, f64), (f64, f64)) -> Option<f64>,
    mut retry: impl FnMut(&[Attempt], (f64, f64)) -> Option<(Side, (f64, f64))>,
    rng: &mut R,
) -> UnloadLog {
    let max_retries = max_retries.min(MAX_RETRIES);
    let mut log = UnloadLog {
        attempts: Vec::with_capacity(1 + max_retries),
        placed: false,
        time_s: 0.0,
        distance_m: 0.0,
        end_xy: at_xy,
    };
    let mut next = Some(first);
    while let Some((side, goal)) = next.take() {
        let attempt = attempt_once(
            sim,
            target,
            side,
            goal,
            log.end_xy,
            costs,
            &mut path_length_m,
            rng,
        );
        log.time_s += attempt.time_s;
        log.distance_m += attempt.distance_m;
        log.end_xy = match attempt.outcome {
            None => log.end_xy,
            Some(o) if o.result == TrialResult::BaseCollision => goal,
            Some(o) => (o.realised.x_m, o.realised.y_m),
        };
        log.placed = attempt.placed();
        log.attempts.push(attempt);
        if !log.placed && log.attempts.len() <= max_retries {
            next = retry(&log.attempts, log.end_xy);
        }
    }
    log
}

#[allow(clippy::too_many_arguments)]
fn attempt_once<A: ArmModel, R: Rng + ?Sized>(
    sim: &mut TrialSimulator<'_, A>,
    target: [f64; 3],
    side: Side,
    goal: (f64, f64),
    from: (f64, f64),
    costs: &AttemptCosts,
    path_length_m: &mut impl FnMut((f64, f64), (f64, f64)) -> Option<f64>,
    rng: &mut R,
) -> Attempt {
    let Some(path_m) = path_length_m(from, goal) else {
        return Attempt {
            side,
            commanded_xy: goal,
            outcome: None,
            time_s: costs.failed_nav_time_s,
            distance_m: 0.0,
        };
    };
    let outcome = sim.run(target, side, goal, rng);
    let (time_s, distance_m) = if outcome.result == TrialResult::BaseCollision {
        (costs.failed_nav_time_s, path_m)
    } else {
        // The noisy end point: the robot drove the path and ended off the goal.
        let end_leg = (outcome.realised.x_m - goal.0).hypot(outcome.realised.y_m - goal.1);
        (
            (path_m + end_leg) / costs.speed_mps + costs.unload_time_s,
            path_m + end_leg,
        )
    };
    Attempt {
        side,
        commanded_xy: goal,
        outcome: Some(outcome),
        time_s,
        distance_m,
    }
}
