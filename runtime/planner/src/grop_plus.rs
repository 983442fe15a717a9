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

use crate::costs::TravelTime;
use crate::methods::{GoalSource, NavGoal, PlannerConfig};
use crate::problem::{CANDIDATE_CELLS, TaskProblem, UnloadLocation};
use crate::task::location_index;
use world::Side;

/// Speed at which `R` keeps its configured value when [`GropPlusConfig::r_follows_speed`] is on:
/// the authors' 0.4 m/s, where R = 40 was chosen.
pub const R_REFERENCE_SPEED_MPS: f64 = 0.4;

/// Most retries a configuration may ask for.
pub const MAX_RETRIES: usize = 8;

/// GROP+'s levers. [`GropPlusConfig::DEFAULT`] is the combination chosen by measurement
/// (docs/experiments.md, "GROP+").
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GropPlusConfig {
    /// Retries after a failed unload (0: none, as GROP).
    pub max_retries: usize,
    /// `Smp` draws per (target, side), keeping the best; `None`: GROP's
    /// ([`PlannerConfig::goal_draws`]).
    pub goal_draws: Option<usize>,
    /// Goals only on cells at least this far (m) from every candidate cell where the base would
    /// collide (0: off). When no cell of a location clears the margin with a nonzero heatmap
    /// value, the location falls back to GROP's cells.
    pub goal_margin_m: f64,
    /// `R` scaled by [`R_REFERENCE_SPEED_MPS`] / speed.
    pub r_follows_speed: bool,
}

impl GropPlusConfig {
    /// Every lever off: GROP.
    pub const OFF: GropPlusConfig = GropPlusConfig {
        max_retries: 0,
        goal_draws: None,
        goal_margin_m: 0.0,
        r_follows_speed: false,
    };

    /// The default GROP+, chosen by measurement on the 4,200-task set (docs/experiments.md,
    /// "GROP+"): one retry, best of 20 draws, goals 0.2 m (two noise sigmas) clear of collision
    /// cells. A second retry places more (hard third 0.94 vs 0.91) but costs more time than GROP
    /// on the hard third; fewer draws or a smaller margin cost time too. R following speed stays
    /// off: it changes nothing at 0.4 m/s and only moves completion between the slow and the
    /// fast end of the sweep (+0.015 at 0.2 m/s, -0.018 at 0.8 m/s).
    pub const DEFAULT: GropPlusConfig = GropPlusConfig {
        max_retries: 1,
        goal_draws: Some(20),
        goal_margin_m: 0.2,
        r_follows_speed: false,
    };

    /// Checks the values a user can set.
    pub fn check(&self) -> Result<(), &'static str> {
        if self.max_retries > MAX_RETRIES {
            return Err("GROP+ retries must be at most 8");
        }
        if self.goal_draws.is_some_and(|n| n == 0 || n > 64) {
            return Err("GROP+ goal draws must be in 1..=64");
        }
        if !(self.goal_margin_m.is_finite() && (0.0..=1.0).contains(&self.goal_margin_m)) {
            return Err("GROP+ goal margin must be in 0..=1 m");
        }
        Ok(())
    }

    /// The planner settings GROP+ plans with: GROP's with the goal draws and `R` of the levers.
    pub fn effective(&self, base: &PlannerConfig) -> PlannerConfig {
        PlannerConfig {
            goal_draws: self.goal_draws.unwrap_or(base.goal_draws),
            success_bonus_r: effective_r(base, self.r_follows_speed),
            ..*base
        }
    }
}

impl Default for GropPlusConfig {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// `R` of eq. 1 at the configured speed: as configured, or scaled by
/// [`R_REFERENCE_SPEED_MPS`] / speed when it follows speed.
pub fn effective_r(config: &PlannerConfig, follows_speed: bool) -> f64 {
    if follows_speed {
        config.success_bonus_r * R_REFERENCE_SPEED_MPS / config.speed_mps
    } else {
        config.success_bonus_r
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
/// see [`crate::methods::location_heat`]) zeroed on the cells within the goal margin of a
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
        let heat = plus_heat(
            &plus,
            loc,
            crate::methods::location_heat(crate::methods::MethodKind::Grop, config, loc),
        );
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
