//! GROP and the baselines over multi-trip plans ([`crate::multi_trip`]): whole table settings with
//! a tray of `k` objects.
//!
//! Goals are drawn exactly as the single-trip methods draw them ([`Planner`]'s goal choice, same
//! seeds and streams), so a task's goals are the same whichever planner family runs. Then:
//!
//! | method | trips |
//! |---|---|
//! | GROP | `Smp` goals; argmax `U = R F - C` over the fewest-trips family ([`optimise_trips`]) |
//! | FCN-Planning | uniform free goals; argmax `U` likewise |
//! | PETLON | uniform free goals; argmin `C` over the family (its task-level objective; every leg is costed, there is no lazy refinement here) |
//! | DVH | per object the side of highest `Fea^t`; objects dealt into trips at random (seeded) |
//! | Satisficing | random sides; objects dealt into trips at random |
//!
//! Every answer reports `F` (sum) and `C` of its plan from the same heatmaps and travel times,
//! and, for the searching methods, the optimiser's bound on its distance to the optimum.

use grop_select::{FeasibilityAggregation, task_feasibility, utility};
use rand::seq::SliceRandom;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use world::Side;
use world::generate::mix_seed;

use crate::costs::{LegCache, TravelTime};
use crate::methods::{LocationRow, MethodKind, NavGoal, PlanError, Planner, PlannerConfig};
use crate::multi_trip::{
    MAX_TRIP_OBJECTS, Trip, TripPlan, TripPlanError, TripSearchLimits, optimise_trips, trip_count,
    trip_plan_cost_s, trip_plan_feasibility,
};
use crate::problem::TaskProblem;
use crate::task::{PlanningTable, UnloadStep, location_index};

/// Random stream of the baselines' trip choices (mixed with the task seed).
const TRIP_STREAM: u64 = 0x7472_6970;

/// Why a multi-trip planner could not plan.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum MultiTripError {
    /// The problem or the configuration is malformed.
    #[error("{0}")]
    Plan(#[from] PlanError),
    /// The multi-trip optimiser refused the task.
    #[error("multi-trip planner: {0}")]
    Trips(#[from] TripPlanError),
}

/// What the optimiser says about the chosen plan (searching methods only).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SearchReport {
    /// Proven upper bound on the optimum's objective (`U` for GROP and FCN-Planning, `-C` for
    /// PETLON).
    pub upper_bound: f64,
    /// The plan is the exact optimum of the family.
    pub proven_optimal: bool,
    /// Branch-and-bound nodes.
    pub nodes: u64,
    /// Object sets tabulated.
    pub blocks: usize,
    /// `upper_bound` minus the plan's objective (>= 0).
    pub gap: f64,
}

/// A multi-trip planner's answer.
#[derive(Debug, Clone, PartialEq)]
pub struct PlannedTrips {
    /// Which method planned it.
    pub method: MethodKind,
    /// Tray capacity planned for.
    pub capacity: usize,
    /// The trips.
    pub plan: TripPlan,
    /// One goal per location (index = location index).
    pub goals: Vec<NavGoal>,
    /// `F(p)`, sum of the placed pairs' `Fea^t`.
    pub feasibility: f64,
    /// `C(p)` (s), station returns included.
    pub cost_s: f64,
    /// `U(p) = R F(p) - C(p)`.
    pub utility: f64,
    /// Per (object, side): `Fea^t` and the goal.
    pub locations: Vec<LocationRow>,
    /// The optimiser's report (GROP, FCN-Planning, PETLON).
    pub search: Option<SearchReport>,
    /// Navigation legs asked of the motion planner.
    pub motion_planner_calls: usize,
}

impl PlannedTrips {
    /// The goal the robot drives to for an unloading step.
    pub fn goal_of(&self, step: &UnloadStep) -> &NavGoal {
        &self.goals[location_index(step.object, step.side)]
    }
}

/// GROP or a baseline planning trips of at most `capacity` objects.
#[derive(Debug, Clone, Copy)]
pub struct MultiTripPlanner {
    /// The method.
    pub kind: MethodKind,
    /// Settings (aggregation must be Sum; `lazy_costs` and `search` do not apply).
    pub config: PlannerConfig,
    /// Objects per trip (the robot file's `carry_capacity`).
    pub capacity: usize,
    /// The optimiser's node limit.
    pub limits: TripSearchLimits,
}

impl MultiTripPlanner {
    /// A planner of `kind` for a tray of `capacity`, default search limits.
    pub fn new(kind: MethodKind, config: PlannerConfig, capacity: usize) -> Self {
        Self {
            kind,
            config,
            capacity,
            limits: TripSearchLimits::default(),
        }
    }

    /// Plans `problem` (all its objects) with goals drawn from `seed`.
    #[allow(
        clippy::too_many_lines,
        reason = "one arm per planning method of the multi-trip planner"
    )]
    pub fn plan(
        &self,
        problem: &TaskProblem,
        travel: &mut dyn TravelTime,
        seed: u64,
    ) -> Result<PlannedTrips, MultiTripError> {
        problem.check().map_err(PlanError::from)?;
        let single = Planner::new(self.kind, self.config);
        single.check_config()?;
        if self.config.aggregation != FeasibilityAggregation::Sum {
            return Err(TripPlanError::ProductAggregation.into());
        }
        if self.capacity == 0 {
            return Err(TripPlanError::ZeroCapacity.into());
        }
        let n = problem.n_objects();
        if n > MAX_TRIP_OBJECTS {
            return Err(TripPlanError::TooManyObjects {
                n_objects: n,
                limit: MAX_TRIP_OBJECTS,
            }
            .into());
        }
        let cfg = self.config;
        let goals: Vec<NavGoal> = problem
            .locations
            .iter()
            .enumerate()
            .map(|(i, l)| single.choose_goal(i, l, seed))
            .collect();
        let location_f: Vec<f64> = problem
            .locations
            .iter()
            .map(|l| task_feasibility(&single.heat_of(l)))
            .collect();
        let goals_xy: Vec<(f64, f64)> = goals.iter().map(|g| g.xy).collect();
        let mut cache = LegCache::new(problem, &goals_xy, cfg.no_path_cost_s);
        let mut table = PlanningTable::zeros(n);
        table.feasibility.copy_from_slice(&location_f);
        let mut rng = ChaCha8Rng::seed_from_u64(mix_seed(seed, TRIP_STREAM, 0));
        let (plan, search) = match self.kind {
            MethodKind::Grop
            | MethodKind::GropPlus
            | MethodKind::FcnPlanning
            | MethodKind::Petlon => {
                cache.fill_table(&mut table, travel);
                let r = if self.kind == MethodKind::Petlon {
                    0.0
                } else {
                    cfg.success_bonus_r
                };
                let best = optimise_trips(&table, r, self.capacity, self.limits)?;
                let objective = r * best.feasibility - best.cost_s;
                let report = SearchReport {
                    upper_bound: best.upper_bound,
                    proven_optimal: best.proven_optimal,
                    nodes: best.nodes,
                    blocks: best.blocks,
                    gap: (best.upper_bound - objective).max(0.0),
                };
                (best.plan, Some(report))
            }
            MethodKind::Dvh => {
                let steps: Vec<UnloadStep> = (0..n)
                    .map(|object| {
                        let (near, far) = (location_f[2 * object], location_f[2 * object + 1]);
                        let side = if (near - far).abs() <= 1e-12 {
                            random_side(&mut rng)
                        } else if far > near {
                            Side::Far
                        } else {
                            Side::Near
                        };
                        UnloadStep { object, side }
                    })
                    .collect();
                (deal_into_trips(steps, self.capacity, &mut rng), None)
            }
            MethodKind::Satisficing => {
                let steps: Vec<UnloadStep> = (0..n)
                    .map(|object| UnloadStep {
                        object,
                        side: random_side(&mut rng),
                    })
                    .collect();
                (deal_into_trips(steps, self.capacity, &mut rng), None)
            }
        };
        // Report every method's plan with the same F and C (legs costed through the same cache).
        let mut legs = PlanningTable::zeros(n);
        legs.feasibility.copy_from_slice(&location_f);
        let motion_planner_calls = cache.calls();
        cache.fill_plan_legs(&plan, &mut legs, travel);
        let feasibility = trip_plan_feasibility(&legs, &plan);
        let cost_s = trip_plan_cost_s(&legs, &plan);
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
        Ok(PlannedTrips {
            method: self.kind,
            capacity: self.capacity,
            plan,
            goals,
            feasibility,
            cost_s,
            utility: utility(cfg.success_bonus_r, feasibility, cost_s),
            locations,
            search,
            motion_planner_calls,
        })
    }
}

fn random_side(rng: &mut ChaCha8Rng) -> Side {
    if rng.random::<bool>() {
        Side::Far
    } else {
        Side::Near
    }
}

/// Shuffles the steps and deals them into `ceil(n/k)` trips of `k` (the last holds the rest).
fn deal_into_trips(mut steps: Vec<UnloadStep>, capacity: usize, rng: &mut ChaCha8Rng) -> TripPlan {
    steps.shuffle(rng);
    let trips = trip_count(steps.len(), capacity);
    let mut out = Vec::with_capacity(trips);
    for chunk in steps.chunks(capacity) {
        let mut load_order: Vec<usize> = chunk.iter().map(|s| s.object).collect();
        load_order.shuffle(rng);
        out.push(Trip {
            load_order,
            unloads: chunk.to_vec(),
        });
    }
    TripPlan { trips: out }
}

impl LegCache {
    /// Fills the legs `plan` drives into `table` (start -> station, station <-> goals, goal ->
    /// goal), asking the motion planner only for legs not yet known.
    pub fn fill_plan_legs(
        &mut self,
        plan: &TripPlan,
        table: &mut PlanningTable,
        travel: &mut dyn TravelTime,
    ) {
        use crate::costs::NavNode;
        let m = 2 * table.n_objects;
        table.start_to_station_s = self.leg_s(NavNode::Start, NavNode::Station, travel);
        for trip in &plan.trips {
            let mut prev: Option<usize> = None;
            for u in &trip.unloads {
                let here = location_index(u.object, u.side);
                table.station_to_location_s[here] =
                    self.leg_s(NavNode::Station, NavNode::Goal(here), travel);
                if let Some(p) = prev {
                    table.location_to_location_s[p * m + here] =
                        self.leg_s(NavNode::Goal(p), NavNode::Goal(here), travel);
                }
                prev = Some(here);
            }
        }
    }
}
