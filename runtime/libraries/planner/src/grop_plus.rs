//! GROP+: GROP (Algorithm 1) with four levers that the paper does not have, each switchable, and
//! the retry policy that both the trial simulator's evaluation and the runtime's planning node run
//! after a failed unload.
//!
//! | lever | what it changes | paper |
//! |---|---|---|
//! | [`GropPlusConfig::max_retries`] | after a failed unload, drive to the best remaining cell of either side ([`retry_goal`]) and try again, at most this often | no retry |
//! | [`GropPlusConfig::goal_draws`] | best of n `Smp` draws per (target, side) | one draw |
//! | [`GropPlusConfig::goal_margin_m`] | `Smp`, `Fea^t` (eq. 4) and retries read the heatmap only on cells at least this far from a candidate cell where the base collides | whole heatmap |
//! | [`GropPlusConfig::r_follows_speed`] | `R` of eq. 1 scaled by `reference speed / speed`, so `U = R F - C` trades success against *distance* whatever the speed | fixed `R` |
//!
//! With every lever off ([`GropPlusConfig::OFF`]) GROP+ plans exactly as GROP does (a test
//! checks it). Everything here is pure and deterministic: the retry policy draws nothing.
//!
//! ```no_run
//! use planner::grop_plus::{GropPlusConfig, retry_goal};
//! use planner::methods::{MethodKind, Planner, PlannerConfig, TaskMotionPlanner};
//! # fn demo(problem: &planner::problem::TaskProblem, travel: &mut dyn planner::costs::TravelTime) -> Result<(), planner::methods::PlanError> {
//! let config = PlannerConfig::default(); // its `plus` is GropPlusConfig::DEFAULT
//! let decision = Planner::new(MethodKind::GropPlus, config).plan(problem, travel, 7)?;
//! // Object 0's unload failed at its goal; the robot stands at (1.0, 2.0).
//! let tried = [decision.goals[0].xy];
//! if let Some(goal) = retry_goal(&config, problem, 0, &tried, (1.0, 2.0), 0, travel) {
//!     println!("retry at ({:.2}, {:.2}) on the {} side", goal.xy.0, goal.xy.1, problem.locations[goal.location].side.name());
//! }
//! # Ok(()) }
//! ```

use crate::config::{GoalSource, MethodKind, NavGoal, PlannerConfig};
pub use crate::config::{GropPlusConfig, MAX_RETRIES, R_REFERENCE_SPEED_MPS, effective_r};
use crate::costs::TravelTime;
use crate::problem::{CANDIDATE_CELLS, TaskProblem, UnloadLocation};
use crate::task::location_index;
use world::Side;

impl Default for GropPlusConfig {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// Per candidate cell: is it at least `margin_m` from every candidate cell where the base
/// collides? (Cell centres, Euclidean; with `margin_m = 0` every free cell qualifies.)
pub fn clear_of_obstacles(loc: &UnloadLocation, margin_m: f64) -> [bool; CANDIDATE_CELLS] {
    let mut clear = [false; CANDIDATE_CELLS];
    let blocked: Vec<(f64, f64)> = loc.cells.iter().filter(|c| !c.free).map(|c| c.xy).collect();
    for (ok, c) in clear.iter_mut().zip(&loc.cells) {
        *ok = c.free
            && blocked
                .iter()
                .all(|b| (b.0 - c.xy.0).hypot(b.1 - c.xy.1) >= margin_m);
    }
    clear
}

/// The heatmap GROP+ reads for a location (goal draws, `Fea^t`, retries): GROP's (`grop_heat`,
/// see [`location_heat`]) zeroed on the cells within the goal margin of a
/// collision cell, unless that leaves nothing.
pub fn plus_heat(
    plus: &GropPlusConfig,
    loc: &UnloadLocation,
    grop_heat: [f32; CANDIDATE_CELLS],
) -> [f32; CANDIDATE_CELLS] {
    if plus.goal_margin_m <= 0.0 {
        return grop_heat;
    }
    let clear = clear_of_obstacles(loc, plus.goal_margin_m);
    let mut heat = grop_heat;
    for (h, &ok) in heat.iter_mut().zip(&clear) {
        if !ok {
            *h = 0.0;
        }
    }
    if heat.iter().any(|&h| h > 0.0) {
        heat
    } else {
        grop_heat
    }
}

/// The retry policy: after object `object`'s unload failed (the commanded goals tried so far for
/// it in `tried_xy`, `retries_made` retries already), where to try next from `at_xy`, or `None`
/// to give the object up.
///
/// Per side, the candidate is the cell of highest GROP+ heatmap value (lowest index on ties)
/// among the cells not yet tried; the side whose candidate has the higher `U = R h - C` (eq. 1 for
/// one unload: `h` the cell's success probability, `C` the travel time there from `at_xy`) wins.
/// No retry when the retry budget is spent, when neither side has a cell with `h > 0`, or when
/// the best `U` is not positive (the expected gain does not pay for the drive).
pub fn retry_goal(
    config: &PlannerConfig,
    problem: &TaskProblem,
    object: usize,
    tried_xy: &[(f64, f64)],
    at_xy: (f64, f64),
    retries_made: usize,
    travel: &mut dyn TravelTime,
) -> Option<NavGoal> {
    let plus = config.plus;
    if retries_made >= plus.max_retries || object >= problem.n_objects() {
        return None;
    }
    let effective = plus.effective(config);
    let r = effective.success_bonus_r;
    let mut best: Option<(f64, NavGoal)> = None;
    for side in Side::BOTH {
        let index = location_index(object, side);
        let loc = &problem.locations[index];
        let heat = plus_heat(&plus, loc, location_heat(MethodKind::Grop, config, loc));
        let cell = (0..CANDIDATE_CELLS)
            .filter(|&i| heat[i] > 0.0)
            .filter(|&i| {
                !tried_xy.iter().any(|t| {
                    (t.0 - loc.cells[i].xy.0).abs() < 1e-6 && (t.1 - loc.cells[i].xy.1).abs() < 1e-6
                })
            })
            .fold(None::<usize>, |acc, i| match acc {
                Some(a) if heat[a] >= heat[i] => Some(a),
                _ => Some(i),
            });
        let Some(cell) = cell else { continue };
        let c = loc.cells[cell];
        let cost_s = travel
            .travel_time_s(at_xy, c.xy)
            .unwrap_or(config.no_path_cost_s);
        let u = r * f64::from(heat[cell]) - cost_s;
        let goal = NavGoal {
            location: index,
            cell,
            row_col: (c.row, c.col),
            xy: c.xy,
            yaw_rad: side.facing_yaw_rad(),
            heat_value: heat[cell],
            source: GoalSource::Retry,
        };
        if best.as_ref().is_none_or(|(bu, _)| u > *bu) {
            best = Some((u, goal));
        }
    }
    best.filter(|(u, _)| *u > 0.0).map(|(_, g)| g)
}

/// The heatmap `method` reads for a location (goal draws and `Fea^t`): as predicted, or, for GROP
/// and GROP+ with [`PlannerConfig::free_goals_only`], zero on the cells where the base collides;
/// GROP+ then also applies its goal margin ([`plus_heat`]).
pub fn location_heat(
    method: MethodKind,
    config: &PlannerConfig,
    loc: &UnloadLocation,
) -> [f32; CANDIDATE_CELLS] {
    let mut heat = loc.heat;
    if config.free_goals_only && method.uses_smp_goals() {
        for (h, c) in heat.iter_mut().zip(&loc.cells) {
            if !c.free {
                *h = 0.0;
            }
        }
    }
    if method == MethodKind::GropPlus {
        heat = plus_heat(&config.plus, loc, heat);
    }
    heat
}
