//! Multi-trip task plans for a robot that carries at most `k` objects (issue 13): whole table
//! settings of up to [`MAX_TRIP_OBJECTS`] objects, `k` from the robot file
//! (`RobotConfig::carry_capacity`, a tray of 3 by default).
//!
//! **Domain.** The section III domain of [`crate::task`] with one more precondition: `load(o)`
//! needs fewer than `k` objects in hand. A plan is a sequence of trips; a trip drives to the
//! station, loads its objects, then drives to each one's unloading location and unloads it. Every
//! trip but the last drives back to the station; the plan ends where its last object is placed, as
//! the paper's single-trip plans do.
//!
//! **Plan family.** Plans with the fewest trips, `T = ceil(n / k)` (the tray is used as fully as
//! the count allows; each trip carries 1..=k objects). For `k >= n` that is one trip, i.e. the
//! paper's load-everything-first family: [`trip_plans`]`(3, 3)` is its 288 plans.
//!
//! **Utility.** Sum aggregation only: `U = R sum F - C` (eq. 1), `C` = start -> station, plus each
//! trip's legs (station -> first goal -> ... -> last goal, and back to the station except for the
//! last trip). Return legs use the station -> location time of the [`PlanningTable`] (travel
//! times are asked in one canonical direction, so they are symmetric).
//!
//! **Optimiser** ([`optimise_trips`]). `U` splits over trips: with the trips fixed as sets, each
//! closed trip's best order and sides are independent of the others, and only the last (open)
//! trip saves its return leg. So: (1) every set of up to `k` objects (a *block*) gets its best
//! closed value `g(A)` and best open value `h(A)` by enumerating its orders and sides; (2) a depth-
//! first branch and bound partitions the objects into `T` blocks (the lowest unassigned object
//! chooses its block), maximising `sum g + max (h - g)`. Bound: each object's *share*
//! `s(o) = max over blocks A containing o of g(A) / |A|` (any partition's `sum g` is at most the
//! sum of its objects' shares), plus the largest saving `h - g` of any block. Children are tried in
//! order of their bound, so the first dive is a greedy plan. When the search finishes, the plan is
//! the exact optimum of the family; when it stops at its node limit, the answer carries a proven
//! upper bound on the optimum (the largest bound among the subtrees left unexplored), hence on the
//! gap. Deterministic: a node limit, not a clock, stops it.
//!
//! Where this stops being the paper's algorithm: the paper enumerates one trip's plans
//! (`n!^2 2^n`); here `k < n` adds trips, and the argmax is found by search, not enumeration.

use grop_select::{FeasibilityAggregation, UTILITY_TIE_EPS, utility};
use world::Side;

use crate::task::{
    Action, ActionError, Location, MAX_ENUMERATED_OBJECTS, MAX_OBJECTS, ObjectId, PlanningTable,
    TaskPlanError, UnloadStep, location_index, optimise, permutations,
};

/// Most objects a multi-trip plan handles (bit sets are `u64`; 12 place settings need 36).
pub const MAX_TRIP_OBJECTS: usize = 64;
/// Most blocks (sets of up to `k` objects) the optimiser tabulates: 36 objects with `k = 4` need
/// 66,045; `k = 5` would need 445,581.
pub const MAX_BLOCKS: usize = 100_000;
/// Most trips (orders x sides over all blocks) tabulated: 36 objects with `k = 4` need 23 M.
pub const MAX_BLOCK_WORK: f64 = 3.0e7;
/// Node limit of the branch and bound by default: 24 objects (k = 3) finish well within it, 36
/// objects stop at it with their bound (docs/planner-bench.md).
pub const DEFAULT_NODE_LIMIT: u64 = 100_000;

/// One trip: load `load_order` at the station, then unload in `unloads` order.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub struct Trip {
    /// Objects loaded, in order.
    pub load_order: Vec<ObjectId>,
    /// Unloading steps in execution order.
    pub unloads: Vec<UnloadStep>,
}

/// A multi-trip plan: trips in execution order.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub struct TripPlan {
    /// The trips.
    pub trips: Vec<Trip>,
}

/// Why a multi-trip plan or task is refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum TripPlanError {
    /// A capacity of zero.
    #[error("carrying capacity must be at least 1")]
    ZeroCapacity,
    /// More objects than the bit sets hold; the value is the limit.
    #[error("{n_objects} objects; the multi-trip planner handles at most {limit}")]
    TooManyObjects {
        /// Objects asked for.
        n_objects: usize,
        /// The limit.
        limit: usize,
    },
    /// The table or the single-trip optimiser refused the task.
    #[error("{0}")]
    Task(#[from] TaskPlanError),
    /// Product aggregation does not split over trips.
    #[error("the multi-trip optimiser maximises the sum aggregation only")]
    ProductAggregation,
    /// Too many object sets to tabulate for this capacity.
    #[error(
        "{n_objects} objects with capacity {capacity}: too many trips to tabulate (more than {MAX_BLOCKS} object sets or {MAX_BLOCK_WORK} orders)"
    )]
    TooManyBlocks {
        /// Objects.
        n_objects: usize,
        /// Capacity.
        capacity: usize,
    },
    /// `load` with a full tray.
    #[error("step {step}: load object {object}: {capacity} objects already in hand")]
    TrayFull {
        /// Index of the action.
        step: usize,
        /// The object.
        object: ObjectId,
        /// The capacity.
        capacity: usize,
    },
    /// An action's precondition fails.
    #[error("step {step}: {error}")]
    Action {
        /// Index of the action.
        step: usize,
        /// The violated precondition.
        error: ActionError,
    },
    /// Objects are not placed at the end (bit set).
    #[error("objects {unplaced_mask:#b} are not placed at the end of the plan")]
    GoalNotReached {
        /// Bit `o` set = object `o` not placed.
        unplaced_mask: u64,
    },
}

fn full_mask(n: usize) -> u64 {
    if n >= 64 { u64::MAX } else { (1u64 << n) - 1 }
}

impl TripPlan {
    /// Objects placed by the plan, in execution order.
    pub fn unloads(&self) -> impl Iterator<Item = &UnloadStep> {
        self.trips.iter().flat_map(|t| t.unloads.iter())
    }

    /// The action sequence: per trip `navigate(station)`, the loads, then `navigate`/`unload`
    /// per object.
    pub fn actions(&self) -> Vec<Action> {
        let mut actions = Vec::new();
        for trip in &self.trips {
            crate::task::push_trip_actions(&mut actions, &trip.load_order, &trip.unloads);
        }
        actions
    }

    /// Checks the plan against the domain with capacity `capacity` from the initial state: every
    /// precondition holds (at most `capacity` in hand) and every object ends placed.
    pub fn validate(&self, n_objects: usize, capacity: usize) -> Result<(), TripPlanError> {
        if n_objects > MAX_TRIP_OBJECTS {
            return Err(TripPlanError::TooManyObjects {
                n_objects,
                limit: MAX_TRIP_OBJECTS,
            });
        }
        if capacity == 0 {
            return Err(TripPlanError::ZeroCapacity);
        }
        let mut at = Location::Start;
        let (mut in_hand, mut placed) = (0u64, 0u64);
        for (step, action) in self.actions().into_iter().enumerate() {
            let fail = |error| TripPlanError::Action { step, error };
            let check = |object: ObjectId| {
                if object < n_objects {
                    Ok(1u64 << object)
                } else {
                    Err(fail(ActionError::UnknownObject { object, n_objects }))
                }
            };
            match action {
                Action::Navigate { to } => {
                    if to == at {
                        return Err(fail(ActionError::AlreadyThere(to)));
                    }
                    if let Location::Unload { object, .. } = to {
                        check(object)?;
                    }
                    at = to;
                }
                Action::Load { object } => {
                    let bit = check(object)?;
                    if at != Location::LoadingStation {
                        return Err(fail(ActionError::LoadAwayFromStation { object, at }));
                    }
                    if (in_hand | placed) & bit != 0 {
                        return Err(fail(ActionError::NotAtStation(object)));
                    }
                    if in_hand.count_ones() as usize >= capacity {
                        return Err(TripPlanError::TrayFull {
                            step,
                            object,
                            capacity,
                        });
                    }
                    in_hand |= bit;
                }
                Action::Unload { object, side } => {
                    let bit = check(object)?;
                    if at != (Location::Unload { object, side }) {
                        return Err(fail(ActionError::UnloadAwayFromTarget { object, side, at }));
                    }
                    if in_hand & bit == 0 {
                        return Err(fail(ActionError::NotInHand(object)));
                    }
                    in_hand &= !bit;
                    placed |= bit;
                }
            }
        }
        let unplaced_mask = full_mask(n_objects) & !placed;
        if unplaced_mask != 0 {
            return Err(TripPlanError::GoalNotReached { unplaced_mask });
        }
        Ok(())
    }
}

/// Trips of the family for `n` objects and capacity `k`: `ceil(n / k)`.
pub fn trip_count(n_objects: usize, capacity: usize) -> usize {
    n_objects.div_ceil(capacity.max(1))
}

/// `C(p)` of a multi-trip plan (s): start -> station, each trip's legs, and the return to the
/// station after every trip but the last.
pub fn trip_plan_cost_s(table: &PlanningTable, plan: &TripPlan) -> f64 {
    let mut cost = table.start_to_station_s;
    for (t, trip) in plan.trips.iter().enumerate() {
        let mut prev: Option<usize> = None;
        for u in &trip.unloads {
            let here = location_index(u.object, u.side);
            cost += match prev {
                None => table.station_to_location_s[here],
                Some(p) => table.leg_s(p, here),
            };
            prev = Some(here);
        }
        if let Some(last) = prev
            && t + 1 < plan.trips.len()
        {
            cost += table.station_to_location_s[last];
        }
    }
    cost
}

/// `F(p)`, sum aggregation: the expected number of objects placed.
pub fn trip_plan_feasibility(table: &PlanningTable, plan: &TripPlan) -> f64 {
    plan.unloads()
        .map(|u| table.feasibility[location_index(u.object, u.side)])
        .sum()
}

/// Every plan of the family (fewest trips, each trip any load order, unload order and sides) for
/// `n_objects <= MAX_ENUMERATED_OBJECTS` and capacity `capacity`: ordered partitions of the
/// objects into `ceil(n/k)` trips of 1..=k objects. `trip_plans(3, 3)` is the paper's 288, in
/// [`crate::task::satisficing_plans`]' order.
pub fn trip_plans(n_objects: usize, capacity: usize) -> Result<Vec<TripPlan>, TripPlanError> {
    if capacity == 0 {
        return Err(TripPlanError::ZeroCapacity);
    }
    if n_objects == 0 {
        return Err(TaskPlanError::NoObjects.into());
    }
    if n_objects > MAX_ENUMERATED_OBJECTS {
        return Err(TripPlanError::TooManyObjects {
            n_objects,
            limit: MAX_ENUMERATED_OBJECTS,
        });
    }
    let trips = trip_count(n_objects, capacity);
    let mut out = Vec::new();
    let mut prefix: Vec<u64> = Vec::new();
    ordered_partitions(
        full_mask(n_objects),
        trips,
        capacity,
        &mut prefix,
        &mut |sets| {
            let per_trip: Vec<Vec<Trip>> = sets.iter().map(|&s| all_trips(s)).collect();
            let mut index = vec![0usize; per_trip.len()];
            loop {
                out.push(TripPlan {
                    trips: index
                        .iter()
                        .zip(&per_trip)
                        .map(|(&i, t)| t[i].clone())
                        .collect(),
                });
                // Odometer, last trip fastest.
                let mut d = per_trip.len();
                loop {
                    if d == 0 {
                        return;
                    }
                    d -= 1;
                    index[d] += 1;
                    if index[d] < per_trip[d].len() {
                        break;
                    }
                    index[d] = 0;
                }
            }
        },
    );
    Ok(out)
}

fn ordered_partitions(
    left: u64,
    trips_left: usize,
    capacity: usize,
    prefix: &mut Vec<u64>,
    emit: &mut dyn FnMut(&[u64]),
) {
    if trips_left == 0 {
        if left == 0 {
            emit(prefix);
        }
        return;
    }
    // Every non-empty subset of `left` that leaves a fillable remainder, in increasing order.
    let mut sub = left;
    let mut subsets = Vec::new();
    while sub != 0 {
        subsets.push(sub);
        sub = (sub - 1) & left;
    }
    subsets.reverse();
    for s in subsets {
        let size = s.count_ones() as usize;
        let rest = (left & !s).count_ones() as usize;
        if size <= capacity && rest <= capacity * (trips_left - 1) && rest >= trips_left - 1 {
            prefix.push(s);
            ordered_partitions(left & !s, trips_left - 1, capacity, prefix, emit);
            prefix.pop();
        }
    }
}

fn objects_of(set: u64) -> Vec<ObjectId> {
    (0..64).filter(|&o| set & (1u64 << o) != 0).collect()
}

/// Every trip over `set`: load orders, unload orders, side masks (as `satisficing_plans`).
fn all_trips(set: u64) -> Vec<Trip> {
    let objects = objects_of(set);
    let m = objects.len();
    let perms = permutations(m);
    let mut out = Vec::new();
    for load in &perms {
        for unload in &perms {
            for mask in 0..(1u32 << m) {
                out.push(Trip {
                    load_order: load.iter().map(|&i| objects[i]).collect(),
                    unloads: unload
                        .iter()
                        .enumerate()
                        .map(|(k, &i)| UnloadStep {
                            object: objects[i],
                            side: if mask & (1 << k) == 0 {
                                Side::Near
                            } else {
                                Side::Far
                            },
                        })
                        .collect(),
                });
            }
        }
    }
    out
}

/// Search limits of [`optimise_trips`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TripSearchLimits {
    /// Branch-and-bound nodes before the search stops with its bound.
    pub max_nodes: u64,
}

impl Default for TripSearchLimits {
    fn default() -> Self {
        Self {
            max_nodes: DEFAULT_NODE_LIMIT,
        }
    }
}

/// The optimiser's answer: a plan, its F, C, U, and how far from the optimum it can be.
#[derive(Debug, Clone, PartialEq)]
pub struct TripSolution {
    /// The plan (load orders in object index order; closed trips first, the open trip last).
    pub plan: TripPlan,
    /// `F(p)` (sum).
    pub feasibility: f64,
    /// `C(p)` (s).
    pub cost_s: f64,
    /// `U(p) = R F(p) - C(p)`.
    pub utility: f64,
    /// A proven upper bound on the optimum's `U`; equals `utility` when the search finished.
    pub upper_bound: f64,
    /// The search finished: `plan` is the exact optimum of the family.
    pub proven_optimal: bool,
    /// Branch-and-bound nodes expanded.
    pub nodes: u64,
    /// Blocks (object sets of up to `k`) tabulated.
    pub blocks: usize,
}

impl TripSolution {
    /// `upper_bound - utility`: how much better than this plan the optimum can be (utility units:
    /// seconds; 0 when proven optimal).
    pub fn gap(&self) -> f64 {
        (self.upper_bound - self.utility).max(0.0)
    }
}

/// A block: a set of up to `k` objects with its best closed and open trip.
#[derive(Debug, Clone)]
struct Block {
    set: u64,
    /// Best `R sum F - legs` returning to the station, with its steps.
    closed: f64,
    closed_steps: Vec<UnloadStep>,
    /// Best `R sum F - legs` ending at the last goal.
    open: f64,
    open_steps: Vec<UnloadStep>,
    /// `closed - lambda(A) - M` (<= 0): the bound drop of choosing it (see `Search::set_prices`).
    reduced: f64,
}

/// `argmax U` over the family for capacity `capacity` (see the module docs). One trip
/// (`k >= n`): the paper's family, solved by [`optimise`] (exact, up to [`MAX_OBJECTS`]).
pub fn optimise_trips(
    table: &PlanningTable,
    success_bonus_r: f64,
    capacity: usize,
    limits: TripSearchLimits,
) -> Result<TripSolution, TripPlanError> {
    table.check()?;
    let n = table.n_objects;
    if capacity == 0 {
        return Err(TripPlanError::ZeroCapacity);
    }
    if n > MAX_TRIP_OBJECTS {
        return Err(TripPlanError::TooManyObjects {
            n_objects: n,
            limit: MAX_TRIP_OBJECTS,
        });
    }
    let trips = trip_count(n, capacity);
    if trips == 1 {
        if n > MAX_OBJECTS {
            return Err(TaskPlanError::TooManyObjects {
                n_objects: n,
                limit: MAX_OBJECTS,
            }
            .into());
        }
        let best = optimise(table, success_bonus_r, FeasibilityAggregation::Sum)?;
        return Ok(TripSolution {
            plan: TripPlan {
                trips: vec![Trip {
                    load_order: best.plan.load_order,
                    unloads: best.plan.unloads,
                }],
            },
            feasibility: best.feasibility,
            cost_s: best.cost_s,
            utility: best.utility,
            upper_bound: best.utility,
            proven_optimal: true,
            nodes: 1,
            blocks: 1,
        });
    }
    let blocks = tabulate_blocks(table, success_bonus_r, capacity, trips)?;
    let mut search = Search::new(n, capacity, trips, blocks, limits);
    search.run();
    let plan = search.best_plan();
    let feasibility = trip_plan_feasibility(table, &plan);
    let cost_s = trip_plan_cost_s(table, &plan);
    let u = utility(success_bonus_r, feasibility, cost_s);
    let finished = !search.aborted;
    Ok(TripSolution {
        plan,
        feasibility,
        cost_s,
        utility: u,
        upper_bound: if finished {
            u
        } else {
            // The bound is over `sum g + max save` net of the constant start leg.
            search.open_bound.max(search.best_value) - table.start_to_station_s
        },
        proven_optimal: finished,
        nodes: search.nodes,
        blocks: search.blocks.len(),
    })
}

/// Every block of a size some partition into `trips` blocks can use, with its best trips.
fn tabulate_blocks(
    table: &PlanningTable,
    r: f64,
    capacity: usize,
    trips: usize,
) -> Result<Vec<Block>, TripPlanError> {
    let n = table.n_objects;
    let sizes: Vec<usize> = (1..=capacity.min(n))
        .filter(|&s| {
            let rest = n - s;
            rest >= trips - 1 && rest <= capacity * (trips - 1)
        })
        .collect();
    let count: f64 = sizes.iter().map(|&s| binomial(n, s)).sum();
    // Each block enumerates its s! 2^s trips.
    let work: f64 = sizes
        .iter()
        .map(|&s| binomial(n, s) * (1..=s).product::<usize>() as f64 * 2f64.powi(s as i32))
        .sum();
    if count > MAX_BLOCKS as f64 || work > MAX_BLOCK_WORK {
        return Err(TripPlanError::TooManyBlocks {
            n_objects: n,
            capacity,
        });
    }
    let mut blocks = Vec::with_capacity(count as usize);
    let gain: Vec<f64> = table.feasibility.iter().map(|f| r * f).collect();
    for &s in &sizes {
        let perms = permutations(s);
        let mut combo: Vec<usize> = (0..s).collect();
        loop {
            blocks.push(best_block(table, &gain, &combo, &perms));
            if !next_combination(&mut combo, n) {
                break;
            }
        }
    }
    Ok(blocks)
}

fn binomial(n: usize, k: usize) -> f64 {
    (0..k).fold(1.0, |acc, i| acc * (n - i) as f64 / (i + 1) as f64)
}

/// Next k-combination of `0..n` in lexicographic order; false after the last.
fn next_combination(c: &mut [usize], n: usize) -> bool {
    let k = c.len();
    let mut i = k;
    while i > 0 {
        i -= 1;
        if c[i] < n - k + i {
            c[i] += 1;
            for j in i + 1..k {
                c[j] = c[j - 1] + 1;
            }
            return true;
        }
    }
    false
}

/// Best closed and open trip over `objects` (every order and side; ties keep the first in
/// permutation-then-side-mask order).
fn best_block(
    table: &PlanningTable,
    gain: &[f64],
    objects: &[usize],
    perms: &[Vec<usize>],
) -> Block {
    let s = objects.len();
    let mut closed = (f64::NEG_INFINITY, 0usize, 0u32);
    let mut open = (f64::NEG_INFINITY, 0usize, 0u32);
    for (pi, perm) in perms.iter().enumerate() {
        for mask in 0..(1u32 << s) {
            let mut value = 0.0;
            let mut prev: Option<usize> = None;
            for (k, &i) in perm.iter().enumerate() {
                let side = if mask & (1 << k) == 0 {
                    Side::Near
                } else {
                    Side::Far
                };
                let here = location_index(objects[i], side);
                value += gain[here]
                    - match prev {
                        None => table.station_to_location_s[here],
                        Some(p) => table.leg_s(p, here),
                    };
                prev = Some(here);
            }
            let back = prev.map_or(0.0, |l| table.station_to_location_s[l]);
            if value > open.0 + UTILITY_TIE_EPS {
                open = (value, pi, mask);
            }
            if value - back > closed.0 + UTILITY_TIE_EPS {
                closed = (value - back, pi, mask);
            }
        }
    }
    let steps = |(_, pi, mask): (f64, usize, u32)| -> Vec<UnloadStep> {
        perms[pi]
            .iter()
            .enumerate()
            .map(|(k, &i)| UnloadStep {
                object: objects[i],
                side: if mask & (1 << k) == 0 {
                    Side::Near
                } else {
                    Side::Far
                },
            })
            .collect()
    };
    Block {
        set: objects.iter().fold(0u64, |m, &o| m | (1u64 << o)),
        closed: closed.0,
        closed_steps: steps(closed),
        open: open.0,
        open_steps: steps(open),
        reduced: 0.0,
    }
}

/// Subgradient iterations of the dual prices.
const DUAL_ITERATIONS: usize = 300;

fn price_of(lambda: &[f64], set: u64) -> f64 {
    let mut p = 0.0;
    let mut rest = set;
    while rest != 0 {
        p += lambda[rest.trailing_zeros() as usize];
        rest &= rest - 1;
    }
    p
}

/// The partition branch and bound.
struct Search {
    n: usize,
    capacity: usize,
    trips: usize,
    blocks: Vec<Block>,
    /// Per object: indices of the blocks whose lowest object it is, by `reduced` descending.
    by_lowest: Vec<Vec<u32>>,
    /// Largest saving `h - g` of any block.
    max_saving: f64,
    /// Root bound: `sum lambda + trips * M + largest saving` (see `set_prices`).
    root_bound: f64,
    max_nodes: u64,
    nodes: u64,
    aborted: bool,
    /// Best `sum closed + max saving` found, and its blocks.
    best_value: f64,
    best: Vec<u32>,
    /// Largest bound among the subtrees left unexplored at the abort.
    open_bound: f64,
    path: Vec<u32>,
}

impl Search {
    fn new(
        n: usize,
        capacity: usize,
        trips: usize,
        blocks: Vec<Block>,
        limits: TripSearchLimits,
    ) -> Self {
        let mut max_saving: f64 = 0.0;
        for b in &blocks {
            max_saving = max_saving.max(b.open - b.closed);
        }
        let mut by_lowest: Vec<Vec<u32>> = vec![Vec::new(); n];
        for (i, b) in blocks.iter().enumerate() {
            by_lowest[b.set.trailing_zeros() as usize].push(i as u32);
        }
        let mut search = Self {
            n,
            capacity,
            trips,
            blocks,
            by_lowest,
            max_saving,
            root_bound: f64::INFINITY,
            max_nodes: limits.max_nodes.max(1),
            nodes: 0,
            aborted: false,
            best_value: f64::NEG_INFINITY,
            best: Vec::new(),
            open_bound: f64::NEG_INFINITY,
            path: Vec::new(),
        };
        // Shares: each object's best per-object value, a first (weak) set of prices.
        let mut share = vec![f64::NEG_INFINITY; n];
        for b in &search.blocks {
            let per = b.closed / f64::from(b.set.count_ones());
            for o in objects_of(b.set) {
                share[o] = share[o].max(per);
            }
        }
        search.set_prices(&share);
        search
    }

    /// Prices `lambda` per object make the bound `sum lambda + trips * M + max saving`, with
    /// `M = max over blocks of (g(A) - lambda(A))`: any partition into `trips` blocks has
    /// `sum g = sum lambda + sum (g(A) - lambda(A)) <= sum lambda + trips * M` (the Lagrangian
    /// relaxation of "every object in exactly one trip"). Re-sorts the children by their bound.
    fn set_prices(&mut self, lambda: &[f64]) {
        let m = self
            .blocks
            .iter()
            .map(|b| b.closed - price_of(lambda, b.set))
            .fold(f64::NEG_INFINITY, f64::max);
        for b in &mut self.blocks {
            b.reduced = b.closed - price_of(lambda, b.set) - m;
        }
        let blocks = &self.blocks;
        for list in &mut self.by_lowest {
            // Stable: equal bounds keep tabulation order (deterministic).
            list.sort_by(|&a, &b| {
                blocks[b as usize]
                    .reduced
                    .total_cmp(&blocks[a as usize].reduced)
            });
        }
        self.root_bound = lambda.iter().sum::<f64>() + self.trips as f64 * m + self.max_saving;
    }

    /// `sum g` of a partition given as sets, if every set is a block.
    fn partition_value(&self, index: &std::collections::HashMap<u64, u32>, sets: &[u64]) -> f64 {
        let mut closed = 0.0;
        let mut saving = f64::NEG_INFINITY;
        for s in sets {
            let b = &self.blocks[index[s] as usize];
            closed += b.closed;
            saving = saving.max(b.open - b.closed);
        }
        closed + saving
    }

    fn run(&mut self) {
        // 1. A first dive (greedy by share) gives a plan.
        let limit = self.max_nodes;
        self.max_nodes = self.trips as u64;
        let root = self.root_bound;
        self.dfs(0, 0.0, root);
        self.max_nodes = limit;
        if self.best.is_empty() {
            // Cannot happen (a dive always completes), but keep searching if it did.
            self.aborted = false;
            self.open_bound = f64::NEG_INFINITY;
            self.dfs(0, 0.0, root);
            return;
        }
        // 2. Improve it by exchanging objects between trips.
        self.local_search();
        // 3. Prices from the Lagrangian dual, by subgradient steps towards the plan's value.
        let lambda = self.dual_prices();
        self.set_prices(&lambda);
        // 4. Branch and bound from the improved plan.
        self.aborted = false;
        self.open_bound = f64::NEG_INFINITY;
        let root = self.root_bound;
        if root > self.best_value + UTILITY_TIE_EPS {
            self.dfs(0, 0.0, root);
        }
    }

    /// Swaps (and, with trips of different sizes, moves) objects between two trips while that
    /// raises `sum g + max saving`; first improvement, deterministic order.
    fn local_search(&mut self) {
        let index: std::collections::HashMap<u64, u32> = self
            .blocks
            .iter()
            .enumerate()
            .map(|(i, b)| (b.set, i as u32))
            .collect();
        let mut sets: Vec<u64> = self
            .best
            .iter()
            .map(|&b| self.blocks[b as usize].set)
            .collect();
        let mut value = self.partition_value(&index, &sets);
        let mut improved = true;
        let mut rounds = 0;
        while improved && rounds < 100 {
            improved = false;
            rounds += 1;
            for i in 0..sets.len() {
                for j in i + 1..sets.len() {
                    for a in objects_of(sets[i]) {
                        // Swaps with each object of the other trip, then a plain move.
                        let mut options: Vec<(u64, u64)> = objects_of(sets[j])
                            .into_iter()
                            .map(|b| {
                                let (ba, bb) = (1u64 << a, 1u64 << b);
                                ((sets[i] & !ba) | bb, (sets[j] & !bb) | ba)
                            })
                            .collect();
                        options.push((sets[i] & !(1u64 << a), sets[j] | (1u64 << a)));
                        for (ni, nj) in options {
                            if ni == 0
                                || nj == 0
                                || !index.contains_key(&ni)
                                || !index.contains_key(&nj)
                            {
                                continue;
                            }
                            let (oi, oj) = (sets[i], sets[j]);
                            sets[i] = ni;
                            sets[j] = nj;
                            let v = self.partition_value(&index, &sets);
                            if v > value + 1e-9 {
                                value = v;
                                improved = true;
                                break;
                            }
                            sets[i] = oi;
                            sets[j] = oj;
                        }
                        if sets[i] & (1u64 << a) == 0 {
                            // `a` left trip i: its object list is stale.
                            break;
                        }
                    }
                }
            }
        }
        if value > self.best_value + UTILITY_TIE_EPS {
            self.best_value = value;
            let mut best: Vec<u32> = sets.iter().map(|s| index[s]).collect();
            best.sort_by_key(|&b| self.blocks[b as usize].set.trailing_zeros());
            self.best = best;
        }
    }

    /// Subgradient descent on the Lagrangian bound `L(lambda) = sum lambda + T max_A (g(A) -
    /// lambda(A))` (Polyak steps towards the best plan's `sum g`); returns the best prices seen.
    fn dual_prices(&self) -> Vec<f64> {
        let n = self.n;
        let t = self.trips as f64;
        let target = self.best_value - self.max_saving;
        // Start from the shares (a feasible dual point: M <= 0).
        let mut lambda: Vec<f64> = vec![f64::NEG_INFINITY; n];
        for b in &self.blocks {
            let per = b.closed / f64::from(b.set.count_ones());
            for o in objects_of(b.set) {
                lambda[o] = lambda[o].max(per);
            }
        }
        let bound = |lambda: &[f64]| -> (f64, u64) {
            let mut m = f64::NEG_INFINITY;
            let mut arg = 0u64;
            for b in &self.blocks {
                let v = b.closed - price_of(lambda, b.set);
                if v > m {
                    m = v;
                    arg = b.set;
                }
            }
            (lambda.iter().sum::<f64>() + t * m, arg)
        };
        let mut best = lambda.clone();
        let (mut best_l, _) = bound(&lambda);
        let mut theta = 1.0;
        let mut stale = 0;
        for _ in 0..DUAL_ITERATIONS {
            let (l, arg) = bound(&lambda);
            if l < best_l - 1e-9 {
                best_l = l;
                best.copy_from_slice(&lambda);
                stale = 0;
            } else {
                stale += 1;
                if stale >= 20 {
                    theta *= 0.5;
                    stale = 0;
                }
            }
            let gap = l - target;
            if gap <= 1e-9 {
                break;
            }
            // d L / d lambda_o = 1 - T [o in arg].
            let inside = f64::from(arg.count_ones());
            let norm2 = (n as f64 - inside) + inside * (1.0 - t).powi(2);
            let step = theta * gap / norm2.max(1e-12);
            for (o, l) in lambda.iter_mut().enumerate() {
                let g = if arg & (1u64 << o) != 0 { 1.0 - t } else { 1.0 };
                *l -= step * g;
            }
        }
        best
    }

    /// Explores the node with `assigned` objects placed by the blocks on `self.path`, whose
    /// closed values sum to `value`, bounded by `bound`. Returns false when aborted.
    fn dfs(&mut self, assigned: u64, value: f64, bound: f64) -> bool {
        let full = full_mask(self.n);
        if assigned == full {
            let saving = self
                .path
                .iter()
                .map(|&b| self.blocks[b as usize].open - self.blocks[b as usize].closed)
                .fold(f64::NEG_INFINITY, f64::max);
            if value + saving > self.best_value + UTILITY_TIE_EPS {
                self.best_value = value + saving;
                self.best = self.path.clone();
            }
            return true;
        }
        if self.nodes >= self.max_nodes && !self.best.is_empty() {
            self.aborted = true;
            self.open_bound = self.open_bound.max(bound);
            return false;
        }
        self.nodes += 1;
        let lowest = (!assigned).trailing_zeros() as usize;
        let remaining = (full & !assigned).count_ones() as usize;
        let trips_left = self.trips - self.path.len();
        let list = std::mem::take(&mut self.by_lowest[lowest]);
        let mut ok = true;
        for (pos, &bi) in list.iter().enumerate() {
            let b = &self.blocks[bi as usize];
            let child_bound = bound + b.reduced;
            if child_bound <= self.best_value + UTILITY_TIE_EPS {
                // Sorted by bound: nothing later can win.
                break;
            }
            if b.set & assigned != 0 {
                continue;
            }
            let rest = remaining - b.set.count_ones() as usize;
            if rest < trips_left - 1 || rest > self.capacity * (trips_left - 1) {
                continue;
            }
            let (set, closed) = (b.set, b.closed);
            self.path.push(bi);
            let done = self.dfs(assigned | set, value + closed, child_bound);
            self.path.pop();
            if !done {
                // The rest of this node's children are bounded by the next one's bound.
                if let Some(&next) = list.get(pos + 1) {
                    self.open_bound = self
                        .open_bound
                        .max(bound + self.blocks[next as usize].reduced);
                }
                ok = false;
                break;
            }
        }
        self.by_lowest[lowest] = list;
        ok
    }

    /// The best partition as a plan: closed trips in the order chosen, the trip with the largest
    /// saving last and open.
    fn best_plan(&self) -> TripPlan {
        let open_at = self
            .best
            .iter()
            .enumerate()
            .fold((0usize, f64::NEG_INFINITY), |acc, (i, &b)| {
                let saving = self.blocks[b as usize].open - self.blocks[b as usize].closed;
                if saving > acc.1 + UTILITY_TIE_EPS {
                    (i, saving)
                } else {
                    acc
                }
            })
            .0;
        let mut trips = Vec::with_capacity(self.best.len());
        for (i, &b) in self.best.iter().enumerate() {
            if i != open_at {
                let block = &self.blocks[b as usize];
                trips.push(Trip {
                    load_order: objects_of(block.set),
                    unloads: block.closed_steps.clone(),
                });
            }
        }
        if let Some(&b) = self.best.get(open_at) {
            let block = &self.blocks[b as usize];
            trips.push(Trip {
                load_order: objects_of(block.set),
                unloads: block.open_steps.clone(),
            });
        }
        TripPlan { trips }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::task::{satisficing_plan_count, satisficing_plans};

    #[test]
    fn three_objects_capacity_three_is_the_papers_288() {
        let plans = trip_plans(3, 3).expect("small");
        assert_eq!(plans.len(), 288);
        assert_eq!(plans.len() as u64, satisficing_plan_count(3));
        let single = satisficing_plans(3).expect("small");
        for (t, s) in plans.iter().zip(&single) {
            assert_eq!(t.trips.len(), 1);
            assert_eq!(t.trips[0].load_order, s.load_order);
            assert_eq!(t.trips[0].unloads, s.unloads);
            assert_eq!(t.actions(), s.actions());
        }
    }

    #[test]
    fn family_counts_and_validity() {
        // 3 objects, k = 2: sets {1, 2} or {2, 1} (6 ordered partitions), a 1-object trip has
        // 2 variants, a 2-object trip 16: 6 * 32.
        assert_eq!(trip_plans(3, 2).expect("small").len(), 192);
        assert_eq!(trip_plans(4, 2).expect("small").len(), 6 * 16 * 16);
        for (n, k) in [(3, 1), (3, 2), (4, 2), (4, 3), (5, 2)] {
            for p in trip_plans(n, k).expect("small") {
                assert_eq!(p.trips.len(), trip_count(n, k));
                p.validate(n, k).expect("family plans are valid");
            }
        }
    }

    #[test]
    fn capacity_is_a_precondition() {
        let plan = trip_plans(3, 3).expect("small").remove(0);
        assert!(matches!(
            plan.validate(3, 2),
            Err(TripPlanError::TrayFull {
                step: 3,
                object: 2,
                capacity: 2
            })
        ));
        assert_eq!(plan.validate(3, 0), Err(TripPlanError::ZeroCapacity));
        let mut missing = plan.clone();
        missing.trips[0].unloads.pop();
        assert!(matches!(
            missing.validate(3, 3),
            Err(TripPlanError::GoalNotReached { .. })
        ));
    }

    #[test]
    fn bad_input_is_an_error() {
        let table = PlanningTable::zeros(3);
        assert_eq!(
            optimise_trips(&table, 40.0, 0, TripSearchLimits::default()),
            Err(TripPlanError::ZeroCapacity)
        );
        let mut nan = PlanningTable::zeros(3);
        nan.feasibility[0] = f64::NAN;
        assert!(matches!(
            optimise_trips(&nan, 40.0, 2, TripSearchLimits::default()),
            Err(TripPlanError::Task(TaskPlanError::NotFinite(_)))
        ));
        assert!(trip_plans(6, 3).is_err());
        // 36 objects with a 6-object tray: too many object sets to tabulate.
        assert!(matches!(
            optimise_trips(
                &PlanningTable::zeros(36),
                40.0,
                6,
                TripSearchLimits::default()
            ),
            Err(TripPlanError::TooManyBlocks { .. })
        ));
    }
}
