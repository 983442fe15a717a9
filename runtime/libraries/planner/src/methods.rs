//! GROP (Algorithm 1) and the paper's four baselines behind one interface,
//! [`TaskMotionPlanner`].
//!
//! | method | navigation goal per (target, side) | plan choice |
//! |---|---|---|
//! | GROP+ | best of n `Smp` draws, optionally clear of obstacles by a margin ([`crate::grop_plus`]) | `argmax U = R F - C`, `R` optionally following speed; retries after a failed unload |
//! | GROP | one `Smp` draw from the heatmap (best of n, optional) | `argmax U = R F - C` |
//! | FCN-Planning | uniform among obstacle-free candidate cells | `argmax U = R F - C` |
//! | PETLON | uniform among obstacle-free candidate cells | `argmin C`, optimistic costs refined by the motion planner until stable |
//! | DVH | uniform among obstacle-free candidate cells | `argmax F`, order ties at random (seeded) |
//! | Satisficing | uniform among obstacle-free candidate cells | any valid plan (seeded random) |
//!
//! `F` is the closed-form task-level feasibility (eq. 4) of the heatmap, `C` the travel time of the
//! navigation planner's paths. Goals are drawn once per (target, side) and shared by every plan
//! (authors' implementation). The authors' code drew baseline goals among FCN-nonzero cells and
//! gave Satisficing a fixed, scene-independent region: [`BaselineGoals::AuthorsCode`].

pub use grop_select::FeasibilityAggregation as Aggregation;
use grop_select::{
    Argmax, Candidate, FeasibilityAggregation, Scored, smp_best_of, task_feasibility, utility,
};
use rand::seq::SliceRandom;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use world::Side;
use world::generate::mix_seed;

pub use crate::config::{
    BaselineGoals, GoalSource, MethodKind, NavGoal, PlannerConfig, SearchMode,
};
use crate::costs::{LegCache, NavNode, StraightLine, TravelTime};
pub use crate::grop_plus::location_heat;
use crate::problem::{CANDIDATE_CELLS, ProblemError, TaskProblem, UnloadLocation, candidate_index};
use crate::task::{
    MAX_OBJECTS, PlanningTable, TaskPlan, TaskPlanError, UnloadStep, location_index, optimise,
    satisficing_plans_shared,
};

/// One row of a decision's explanation per (object, side).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LocationRow {
    /// The object.
    pub object: usize,
    /// The side.
    pub side: Side,
    /// Closed-form `Fea^t` of the location's heatmap (eq. 4), whether or not the method uses it.
    pub feasibility: f64,
    /// The navigation goal drawn for it.
    pub goal: NavGoal,
}

/// A planner's answer: the task plan, its navigation goals and why.
#[derive(Debug, Clone, PartialEq)]
pub struct PlannedTask {
    /// Which method planned it.
    pub method: MethodKind,
    /// `p^t`.
    pub plan: TaskPlan,
    /// One goal per location (index = location index); the plan uses `n` of them.
    pub goals: Vec<NavGoal>,
    /// `F(p)` of the chosen plan from the heatmaps (closed form, the configured aggregation), also
    /// for methods that ignore feasibility, so methods can be compared.
    pub feasibility: f64,
    /// `C(p)` of the chosen plan from the motion planner's travel times (s).
    pub cost_s: f64,
    /// `U(p) = R F(p) - C(p)`.
    pub utility: f64,
    /// Per (object, side): `Fea^t` and the goal.
    pub locations: Vec<LocationRow>,
    /// For enumerating utility methods: every plan's F, C, U in enumeration order (see
    /// [`crate::task::satisficing_plans`]); empty otherwise.
    pub candidates: Vec<Scored>,
    /// Index of the chosen plan in `candidates` when enumerated.
    pub chosen_candidate: Option<usize>,
    /// Navigation motion-planner calls made to decide (PETLON's measure; the chosen plan's own
    /// legs are costed afterwards through the same cache and not counted twice).
    pub motion_planner_calls: usize,
    /// PETLON: rounds of refinement until the plan was stable (1 for other methods).
    pub refinement_rounds: usize,
}

impl PlannedTask {
    /// The goal the robot drives to for an unloading step.
    pub fn goal_of(&self, step: &UnloadStep) -> &NavGoal {
        &self.goals[location_index(step.object, step.side)]
    }

    /// A human-readable explanation: the chosen plan, each location's F and goal, and the top
    /// candidates by utility.
    pub fn explain(&self, top: usize) -> String {
        use std::fmt::Write;
        let mut s = String::new();
        let _ = writeln!(
            s,
            "{}: F(p) = {:.3}, C(p) = {:.1} s, U = {:.2}, {} motion-planner calls",
            self.method.name(),
            self.feasibility,
            self.cost_s,
            self.utility,
            self.motion_planner_calls
        );
        let steps: Vec<String> = self
            .plan
            .unloads
            .iter()
            .map(|u| format!("obj{}@{}", u.object, u.side.name()))
            .collect();
        let _ = writeln!(
            s,
            "  plan: load {:?}, unload {}",
            self.plan.load_order,
            steps.join(" -> ")
        );
        for r in &self.locations {
            let _ = writeln!(
                s,
                "  obj{} {:<4} Fea^t = {:.3}  goal ({:.2}, {:.2}) h = {:.2} ({:?})",
                r.object,
                r.side.name(),
                r.feasibility,
                r.goal.xy.0,
                r.goal.xy.1,
                r.goal.heat_value,
                r.goal.source
            );
        }
        if !self.candidates.is_empty() {
            let mut rows = self.candidates.clone();
            rows.sort_by(|a, b| b.utility.total_cmp(&a.utility).then(a.index.cmp(&b.index)));
            let _ = writeln!(
                s,
                "  top {} of {} plans (F, C s, U):",
                top.min(rows.len()),
                rows.len()
            );
            for r in rows.iter().take(top) {
                let mark = if Some(r.index) == self.chosen_candidate {
                    "*"
                } else {
                    " "
                };
                let _ = writeln!(
                    s,
                    "  {mark}#{:<4} {:.3} {:7.1} {:8.2}",
                    r.index, r.feasibility, r.cost_s, r.utility
                );
            }
        }
        s
    }
}

/// Why a planner could not plan.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum PlanError {
    /// The problem is malformed.
    #[error("task problem: {0}")]
    Problem(#[from] ProblemError),
    /// The task planner or optimiser refused it.
    #[error("task planner: {0}")]
    Task(#[from] TaskPlanError),
    /// A configuration value is out of range.
    #[error("planner configuration: {0}")]
    Config(&'static str),
}

/// A task-and-motion planner: GROP or a baseline.
pub trait TaskMotionPlanner {
    /// Which method this is.
    fn kind(&self) -> MethodKind;

    /// Plans `problem`. `travel` is the navigation motion planner; `seed` makes every random
    /// choice (goal draws, random tie-breaks) reproducible.
    fn plan(
        &mut self,
        problem: &TaskProblem,
        travel: &mut dyn TravelTime,
        seed: u64,
    ) -> Result<PlannedTask, PlanError>;
}

/// GROP or one of the baselines with its configuration.
#[derive(Debug, Clone, Copy)]
pub struct Planner {
    /// The method.
    pub kind: MethodKind,
    /// Settings.
    pub config: PlannerConfig,
}

/// Random streams, mixed with the task seed.
const GOAL_STREAM: u64 = 0x676f_616c;
const DECISION_STREAM: u64 = 0x6465_6369;

impl Planner {
    /// A planner of `kind` with `config`.
    pub fn new(kind: MethodKind, config: PlannerConfig) -> Self {
        Self { kind, config }
    }

    pub(crate) fn check_config(&self) -> Result<(), PlanError> {
        let c = &self.config;
        if !(c.success_bonus_r.is_finite() && c.success_bonus_r >= 0.0) {
            return Err(PlanError::Config("success_bonus_r must be finite and >= 0"));
        }
        if c.goal_draws == 0 || c.goal_draws > 64 {
            return Err(PlanError::Config("goal_draws must be in 1..=64"));
        }
        if !(c.no_path_cost_s.is_finite() && c.no_path_cost_s >= 0.0) {
            return Err(PlanError::Config("no_path_cost_s must be finite and >= 0"));
        }
        if !(c.speed_mps.is_finite() && c.speed_mps > 0.0) {
            return Err(PlanError::Config("speed_mps must be finite and > 0"));
        }
        if self.kind == MethodKind::GropPlus {
            c.plus.check().map_err(PlanError::Config)?;
            let e = c.plus.effective(c);
            if e.goal_draws == 0 || e.goal_draws > 64 {
                return Err(PlanError::Config("goal_draws must be in 1..=64"));
            }
        }
        Ok(())
    }

    /// The settings this method plans with: GROP+'s levers applied for GROP+, else as configured.
    pub fn effective_config(&self) -> PlannerConfig {
        if self.kind == MethodKind::GropPlus {
            self.config.plus.effective(&self.config)
        } else {
            self.config
        }
    }

    pub(crate) fn heat_of(&self, loc: &UnloadLocation) -> [f32; CANDIDATE_CELLS] {
        location_heat(self.kind, &self.config, loc)
    }

    /// Chooses the navigation goal of one location (Algorithm 1, line 10 for GROP).
    pub(crate) fn choose_goal(&self, index: usize, loc: &UnloadLocation, seed: u64) -> NavGoal {
        let mut rng = ChaCha8Rng::seed_from_u64(mix_seed(seed, GOAL_STREAM, index as u64));
        let goal_draws = self.effective_config().goal_draws;
        let (cell, source) = match (self.kind, self.config.baseline_goals) {
            (MethodKind::Grop | MethodKind::GropPlus, _) => {
                let mut us = [0.0f64; 64];
                let us = &mut us[..goal_draws];
                for u in us.iter_mut() {
                    *u = rng.random::<f64>();
                }
                match smp_best_of(&self.heat_of(loc), us) {
                    Some(c) => (c, GoalSource::Smp),
                    None => uniform_free(loc, &mut rng),
                }
            }
            (MethodKind::Satisficing, BaselineGoals::AuthorsCode) => {
                let region: Vec<usize> = (11..=14)
                    .flat_map(|r| (26..=37).map(move |c| (r, c)))
                    .filter_map(|(r, c)| candidate_index(r, c))
                    .collect();
                (
                    region[rng.random_range(0..region.len())],
                    GoalSource::FixedRegion,
                )
            }
            (_, BaselineGoals::AuthorsCode) => {
                let nonzero: Vec<usize> = (0..CANDIDATE_CELLS)
                    .filter(|&i| loc.heat[i] > 0.0)
                    .collect();
                if nonzero.is_empty() {
                    uniform_free(loc, &mut rng)
                } else {
                    (
                        nonzero[rng.random_range(0..nonzero.len())],
                        GoalSource::UniformNonzero,
                    )
                }
            }
            (_, BaselineGoals::Paper) => uniform_free(loc, &mut rng),
        };
        let c = loc.cells[cell];
        NavGoal {
            location: index,
            cell,
            row_col: (c.row, c.col),
            xy: c.xy,
            yaw_rad: loc.side.facing_yaw_rad(),
            heat_value: loc.heat[cell],
            source,
        }
    }

    fn enumerate_or_exact(&self, n: usize) -> bool {
        match self.config.search {
            SearchMode::Enumerate => true,
            SearchMode::Exact => false,
            SearchMode::Auto => n <= 4,
        }
    }
}

fn uniform_free(loc: &UnloadLocation, rng: &mut ChaCha8Rng) -> (usize, GoalSource) {
    let free: Vec<usize> = (0..CANDIDATE_CELLS)
        .filter(|&i| loc.cells[i].free)
        .collect();
    if free.is_empty() {
        (rng.random_range(0..CANDIDATE_CELLS), GoalSource::UniformAny)
    } else {
        (
            free[rng.random_range(0..free.len())],
            GoalSource::UniformFree,
        )
    }
}

/// The legs (pairs of nodes) a plan drives.
fn plan_legs(plan: &TaskPlan) -> Vec<(NavNode, NavNode)> {
    let mut legs = vec![(NavNode::Start, NavNode::Station)];
    let mut prev = NavNode::Station;
    for u in &plan.unloads {
        let here = NavNode::Goal(location_index(u.object, u.side));
        legs.push((prev, here));
        prev = here;
    }
    legs
}

impl TaskMotionPlanner for Planner {
    fn kind(&self) -> MethodKind {
        self.kind
    }

    #[allow(
        clippy::too_many_lines,
        reason = "one arm per planning method (the paper's baselines and GROP+)"
    )]
    fn plan(
        &mut self,
        problem: &TaskProblem,
        travel: &mut dyn TravelTime,
        seed: u64,
    ) -> Result<PlannedTask, PlanError> {
        problem.check()?;
        self.check_config()?;
        let n = problem.n_objects();
        if n > MAX_OBJECTS {
            // One trip: the single-trip domain's bit sets and exact optimiser stop here; more
            // objects are the multi-trip planner's (`crate::multi_trip`).
            return Err(TaskPlanError::TooManyObjects {
                n_objects: n,
                limit: MAX_OBJECTS,
            }
            .into());
        }
        let cfg = self.effective_config();
        let m = 2 * n;

        // Per (target, side): Fea^t in closed form (eq. 4) and one goal, shared by all plans.
        let goals: Vec<NavGoal> = problem
            .locations
            .iter()
            .enumerate()
            .map(|(i, l)| self.choose_goal(i, l, seed))
            .collect();
        let location_f: Vec<f64> = problem
            .locations
            .iter()
            .map(|l| task_feasibility(&self.heat_of(l)))
            .collect();
        let goals_xy: Vec<(f64, f64)> = goals.iter().map(|g| g.xy).collect();
        let mut cache = LegCache::new(problem, &goals_xy, cfg.no_path_cost_s);
        let mut decision_rng = ChaCha8Rng::seed_from_u64(mix_seed(seed, DECISION_STREAM, 0));

        let mut candidates = Vec::new();
        let mut chosen_candidate = None;
        let mut refinement_rounds = 1;
        let plan = match self.kind {
            MethodKind::Grop | MethodKind::GropPlus | MethodKind::FcnPlanning => {
                let enumerate = self.enumerate_or_exact(n);
                let plans = if enumerate {
                    satisficing_plans_shared(n)?
                } else {
                    std::borrow::Cow::Owned(Vec::new())
                };
                let mut table = PlanningTable::zeros(n);
                table.feasibility.copy_from_slice(&location_f);
                let mut rounds = 0;
                loop {
                    rounds += 1;
                    if cfg.lazy_costs {
                        fill_estimates(&mut table, &cache, cfg);
                    } else {
                        cache.fill_table(&mut table, travel);
                    }
                    let chosen = if enumerate {
                        let mut argmax = Argmax::new(cfg.success_bonus_r);
                        candidates.clear();
                        candidates.reserve(plans.len());
                        for p in plans.iter() {
                            let c = Candidate {
                                feasibility: table.plan_feasibility(p, cfg.aggregation),
                                cost_s: table.plan_cost_s(p),
                            };
                            // Table values are finite, so offers cannot fail.
                            let row = argmax
                                .offer(c)
                                .map_err(|_| TaskPlanError::NotFinite("plan utility"))?;
                            candidates.push(row);
                        }
                        let best = argmax.best().ok_or(TaskPlanError::NoObjects)?.index;
                        chosen_candidate = Some(best);
                        plans[best].clone()
                    } else {
                        optimise(&table, cfg.success_bonus_r, cfg.aggregation)?.plan
                    };
                    if !cfg.lazy_costs || !refine_legs(&chosen, &mut cache, travel) {
                        refinement_rounds = rounds;
                        break chosen;
                    }
                }
            }
            MethodKind::Petlon => {
                let (plan, rounds) = petlon(problem, &mut cache, travel, cfg)?;
                refinement_rounds = rounds;
                plan
            }
            MethodKind::Dvh => {
                // argmax F(p): per object the side(s) of highest Fea^t (either aggregation is
                // maximised by maximising each factor, as Fea^t >= 0); cost plays no role, so the
                // order and the load order are uniformly random (seeded), as are side ties.
                let mut unloads: Vec<UnloadStep> = (0..n)
                    .map(|object| {
                        let (fn_, ff) = (location_f[2 * object], location_f[2 * object + 1]);
                        let side = if (fn_ - ff).abs() <= 1e-12 {
                            if decision_rng.random::<bool>() {
                                Side::Far
                            } else {
                                Side::Near
                            }
                        } else if ff > fn_ {
                            Side::Far
                        } else {
                            Side::Near
                        };
                        UnloadStep { object, side }
                    })
                    .collect();
                unloads.shuffle(&mut decision_rng);
                let mut load_order: Vec<usize> = (0..n).collect();
                load_order.shuffle(&mut decision_rng);
                TaskPlan {
                    load_order,
                    unloads,
                }
            }
            MethodKind::Satisficing => {
                let mut order: Vec<usize> = (0..n).collect();
                order.shuffle(&mut decision_rng);
                let unloads = order
                    .iter()
                    .map(|&object| UnloadStep {
                        object,
                        side: if decision_rng.random::<bool>() {
                            Side::Far
                        } else {
                            Side::Near
                        },
                    })
                    .collect();
                let mut load_order: Vec<usize> = (0..n).collect();
                load_order.shuffle(&mut decision_rng);
                TaskPlan {
                    load_order,
                    unloads,
                }
            }
        };
        let motion_planner_calls = cache.calls();

        // Report every method's plan with the same F (closed form) and C (motion planner).
        let cost_s: f64 = plan_legs(&plan)
            .into_iter()
            .map(|(a, b)| cache.leg_s(a, b, travel))
            .sum();
        let pair_f: Vec<f64> = plan
            .unloads
            .iter()
            .map(|u| location_f[location_index(u.object, u.side)])
            .collect();
        let feasibility = grop_select::plan_feasibility(cfg.aggregation, &pair_f);
        debug_assert_eq!(goals.len(), m);
        let locations = problem
            .locations
            .iter()
            .enumerate()
            .map(|(i, l)| LocationRow {
                object: l.object,
                side: l.side,
                feasibility: location_f[i],
                goal: goals[i],
            })
            .collect();
        Ok(PlannedTask {
            method: self.kind,
            plan,
            goals,
            feasibility,
            cost_s,
            utility: utility(cfg.success_bonus_r, feasibility, cost_s),
            locations,
            candidates,
            chosen_candidate,
            motion_planner_calls,
            refinement_rounds,
        })
    }
}

/// PETLON's loop: cost-optimal plan under optimistic costs (straight line at the cruise speed,
/// capped at the no-path penalty, so a lower bound on every leg), refine the legs of that plan with
/// the motion planner, repeat until the optimal plan's legs are all refined. Its cost is then
/// exact and no other plan can be cheaper (their estimates are lower bounds): task-level
/// cost-optimal with few motion-planner calls.
fn petlon(
    problem: &TaskProblem,
    cache: &mut LegCache,
    travel: &mut dyn TravelTime,
    cfg: PlannerConfig,
) -> Result<(TaskPlan, usize), PlanError> {
    let mut table = PlanningTable::zeros(problem.n_objects());
    for round in 1.. {
        fill_estimates(&mut table, cache, cfg);
        // R = 0 and F = 0: the optimiser minimises cost alone.
        let best = optimise(&table, 0.0, FeasibilityAggregation::Sum)?.plan;
        if !refine_legs(&best, cache, travel) {
            return Ok((best, round));
        }
    }
    unreachable!("the refinement loop ends: each round refines at least one of finitely many legs")
}

/// Fills a table's costs with what is known: motion-planner travel times where asked, else the
/// optimistic straight line at the cruise speed, capped at the no-path penalty (so a lower bound
/// on the leg's true cost either way).
fn fill_estimates(table: &mut PlanningTable, cache: &LegCache, cfg: PlannerConfig) {
    let bound = StraightLine {
        speed_mps: cfg.speed_mps,
    };
    let estimate = |a: NavNode, b: NavNode| -> f64 {
        cache.known_s(a, b).unwrap_or_else(|| {
            bound
                .time_s(cache.position(a), cache.position(b))
                .min(cfg.no_path_cost_s)
        })
    };
    let m = 2 * table.n_objects;
    table.start_to_station_s = estimate(NavNode::Start, NavNode::Station);
    for i in 0..m {
        table.station_to_location_s[i] = estimate(NavNode::Station, NavNode::Goal(i));
        for j in 0..m {
            table.location_to_location_s[i * m + j] = if i / 2 == j / 2 {
                0.0
            } else {
                estimate(NavNode::Goal(i), NavNode::Goal(j))
            };
        }
    }
}

/// Asks the motion planner for every leg of `plan` not yet known; true if any was asked.
fn refine_legs(plan: &TaskPlan, cache: &mut LegCache, travel: &mut dyn TravelTime) -> bool {
    let mut refined = false;
    for (a, b) in plan_legs(plan) {
        if cache.known_s(a, b).is_none() {
            cache.leg_s(a, b, travel);
            refined = true;
        }
    }
    refined
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::costs::StraightLine;
    use world::Heatmap;

    /// GROP's default Smp never sends the base to a cell it collides at; the paper's does when
    /// the heat is there, and `Fea^t` follows the cells actually drawn from.
    #[test]
    fn free_goals_only_keeps_goals_off_obstacles() {
        let mut p = toy_problem();
        for loc in &mut p.locations {
            // Every cell but the last row's is blocked; the blocked cells carry most heat.
            for (i, c) in loc.cells.iter_mut().enumerate() {
                c.free = i >= CANDIDATE_CELLS - 24;
                loc.heat[i] = if c.free { 0.2 } else { 0.9 };
            }
        }
        let free = PlannerConfig::default();
        assert!(free.free_goals_only);
        let paper = PlannerConfig {
            free_goals_only: false,
            ..free
        };
        let (mut paper_blocked, mut draws) = (0, 0);
        for seed in 0..20 {
            let a = Planner::new(MethodKind::Grop, free)
                .plan(&p, &mut StraightLine { speed_mps: 0.4 }, seed)
                .unwrap();
            let b = Planner::new(MethodKind::Grop, paper)
                .plan(&p, &mut StraightLine { speed_mps: 0.4 }, seed)
                .unwrap();
            for (ga, gb) in a.goals.iter().zip(&b.goals) {
                assert!(p.locations[ga.location].cells[ga.cell].free);
                assert_eq!(ga.source, GoalSource::Smp);
                paper_blocked += usize::from(!p.locations[gb.location].cells[gb.cell].free);
                draws += 1;
            }
            // Fea^t over the free cells only: all 0.2, so 0.2; the paper's mixes in the 0.9s.
            assert!((a.locations[0].feasibility - 0.2).abs() < 1e-6);
            assert!(b.locations[0].feasibility > 0.8);
        }
        assert!(paper_blocked > draws / 2, "{paper_blocked} of {draws}");
        // No heat on any free cell: a uniform free goal, never an obstacle.
        for loc in &mut p.locations {
            for (i, c) in loc.cells.iter().enumerate() {
                loc.heat[i] = if c.free { 0.0 } else { 0.9 };
            }
        }
        let a = Planner::new(MethodKind::Grop, free)
            .plan(&p, &mut StraightLine { speed_mps: 0.4 }, 3)
            .unwrap();
        for g in &a.goals {
            assert!(p.locations[g.location].cells[g.cell].free);
            assert_eq!(g.source, GoalSource::UniformFree);
        }
    }

    fn toy_problem() -> TaskProblem {
        let mut locations = Vec::new();
        for (o, x) in [-3.0, 0.5, 4.0].into_iter().enumerate() {
            for side in Side::BOTH {
                let mut h = Heatmap::zeros();
                for (r, c) in crate::problem::candidate_cells() {
                    // Near sides feasible for objects 0 and 2, the far side for object 1.
                    let good = (side == Side::Near) != (o == 1);
                    h.set(r, c, if good { 0.9 } else { 0.05 });
                }
                locations.push(UnloadLocation::from_heatmap(o, side, [x, 6.0, 1.3], &h));
            }
        }
        TaskProblem {
            start_xy: (0.0, 2.0),
            station_xy: (0.0, 1.05),
            locations,
        }
    }

    #[test]
    fn grop_picks_the_feasible_sides() {
        let p = toy_problem();
        let mut grop = Planner::new(MethodKind::Grop, PlannerConfig::default());
        let out = grop
            .plan(&p, &mut StraightLine { speed_mps: 0.4 }, 1)
            .unwrap();
        let sides: Vec<(usize, Side)> = out
            .plan
            .unloads
            .iter()
            .map(|u| (u.object, u.side))
            .collect();
        assert!(sides.contains(&(0, Side::Near)));
        assert!(sides.contains(&(1, Side::Far)));
        assert!(sides.contains(&(2, Side::Near)));
        assert_eq!(out.candidates.len(), 288);
        assert_eq!(out.motion_planner_calls, 19);
        assert!(out.explain(3).contains("GROP"));
    }

    #[test]
    fn method_names_round_trip() {
        for m in MethodKind::ALL {
            assert_eq!(MethodKind::parse(m.name()), Some(m));
        }
        assert_eq!(
            MethodKind::parse("fcn_planning"),
            Some(MethodKind::FcnPlanning)
        );
        assert_eq!(MethodKind::parse("astar"), None);
    }

    #[test]
    fn bad_config_is_rejected() {
        let p = toy_problem();
        let cfg = PlannerConfig {
            goal_draws: 0,
            ..PlannerConfig::default()
        };
        let err =
            Planner::new(MethodKind::Grop, cfg).plan(&p, &mut StraightLine { speed_mps: 0.4 }, 1);
        assert!(matches!(err, Err(PlanError::Config(_))));
        let empty = TaskProblem {
            start_xy: (0.0, 0.0),
            station_xy: (0.0, 0.0),
            locations: vec![],
        };
        let err = Planner::new(MethodKind::Grop, PlannerConfig::default()).plan(
            &empty,
            &mut StraightLine { speed_mps: 0.4 },
            1,
        );
        assert!(matches!(
            err,
            Err(PlanError::Problem(ProblemError::NoTargets))
        ));
    }
}
