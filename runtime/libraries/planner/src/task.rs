//! The symbolic task domain of the paper's section III and the task planner `Plnr^t`.
//!
//! Domain: `n` objects wait at the loading station; each goes to its own unloading target, served
//! from the table's near or far side. Locations: the robot's start, the loading station and one
//! unloading location per (object, side). Actions, with preconditions and effects:
//!
//! | action | preconditions | effects |
//! |---|---|---|
//! | `navigate(l)` | robot not at `l` | `at(robot, l)` |
//! | `load(o)` | `at(robot, station)`, `at(o, station)` | `inhand(o)`, not `at(o, station)` |
//! | `unload(o, s)` | `at(robot, unload(o, s))`, `inhand(o)` | `placed(o)`, not `inhand(o)` |
//!
//! The robot holds several objects at once. Goal: every object placed.
//!
//! [`satisficing_plans`] enumerates the plans that load everything first and then unload, which is
//! what the authors' ASP encoding returns: `n!` load orders x `n!` unload orders x `2^n` sides
//! (288 for 3 objects). [`optimise`] finds the utility-optimal plan of that family without
//! enumerating it (dynamic programming over subsets x last unloading location), for up to
//! [`MAX_OBJECTS`] objects.

use grop_select::{FeasibilityAggregation, UTILITY_TIE_EPS, utility};
use world::Side;

/// Most objects the domain (bit sets) and the exact optimiser handle.
pub const MAX_OBJECTS: usize = 12;
/// Most objects [`satisficing_plans`] enumerates (`5!^2 * 2^5` = 460,800 plans).
pub const MAX_ENUMERATED_OBJECTS: usize = 5;

/// Index of an object (and of its unloading target) in the task.
pub type ObjectId = usize;

/// A symbolic location.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Location {
    /// Where the robot starts.
    Start,
    /// The loading station at the loading table.
    LoadingStation,
    /// The unloading location of `object` on `side` of the banquet table.
    Unload {
        /// Which object's target.
        object: ObjectId,
        /// Which side of the table.
        side: Side,
    },
}

/// A task-level action.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Action {
    /// `a^n_{l,l'}`: drive to `to`.
    Navigate {
        /// Destination.
        to: Location,
    },
    /// `a^{m+}_o`: take `object` from the loading table.
    Load {
        /// The object.
        object: ObjectId,
    },
    /// `a^{m-}_{o,l'}`: put `object` at its target from `side`.
    Unload {
        /// The object.
        object: ObjectId,
        /// The side the robot stands on.
        side: Side,
    },
}

/// Why an action cannot be applied in a state.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum ActionError {
    /// The object index is outside the task.
    #[error("object {object} does not exist (the task has {n_objects})")]
    UnknownObject {
        /// The index.
        object: ObjectId,
        /// Objects in the task.
        n_objects: usize,
    },
    /// `navigate(l)` while already at `l`.
    #[error("navigate to {0:?}: already there")]
    AlreadyThere(Location),
    /// `load` away from the loading station.
    #[error("load object {object}: robot is at {at:?}, not the loading station")]
    LoadAwayFromStation {
        /// The object.
        object: ObjectId,
        /// Where the robot is.
        at: Location,
    },
    /// `load` of an object that is no longer at the station.
    #[error("load object {0}: it is not at the loading station")]
    NotAtStation(ObjectId),
    /// `unload(o, s)` away from `o`'s unloading location on side `s`.
    #[error("unload object {object} from {side:?}: robot is at {at:?}")]
    UnloadAwayFromTarget {
        /// The object.
        object: ObjectId,
        /// The side asked for.
        side: Side,
        /// Where the robot is.
        at: Location,
    },
    /// `unload` of an object the robot does not hold.
    #[error("unload object {0}: not in hand")]
    NotInHand(ObjectId),
}

/// Why a task plan is not a valid solution.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum PlanValidationError {
    /// Action `step` violates its preconditions.
    #[error("step {step}: {error}")]
    Action {
        /// Index of the failing action.
        step: usize,
        /// The violated precondition.
        error: ActionError,
    },
    /// All actions apply, but these objects (bit set) are not placed at the end.
    #[error("objects {unplaced_mask:#b} are not placed at the end of the plan")]
    GoalNotReached {
        /// Bit `o` set = object `o` not placed.
        unplaced_mask: u32,
    },
}

/// Why the planner cannot plan this task.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum TaskPlanError {
    /// No objects.
    #[error("the task has no objects")]
    NoObjects,
    /// More objects than the planner handles; the value is the limit.
    #[error("{n_objects} objects; this planner handles at most {limit}")]
    TooManyObjects {
        /// Objects asked for.
        n_objects: usize,
        /// The limit.
        limit: usize,
    },
    /// The cost/feasibility table does not match the task.
    #[error("planning table is malformed: {0}")]
    BadTable(&'static str),
    /// A feasibility or cost in the table is NaN or infinite.
    #[error("planning table holds a non-finite value in {0}")]
    NotFinite(&'static str),
}

/// The world state of the symbolic domain.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DomainState {
    /// Objects in the task.
    pub n_objects: usize,
    /// `at(robot, l)`.
    pub robot_at: Location,
    /// Bit `o` set = `inhand(o)`.
    pub in_hand: u32,
    /// Bit `o` set = `placed(o)`.
    pub placed: u32,
}

impl DomainState {
    /// The initial state: robot at its start, every object at the loading station.
    pub fn initial(n_objects: usize) -> Self {
        Self {
            n_objects,
            robot_at: Location::Start,
            in_hand: 0,
            placed: 0,
        }
    }

    /// Is every object placed?
    pub fn goal_reached(&self) -> bool {
        self.placed == full_mask(self.n_objects)
    }

    /// `at(o, station)`: neither held nor placed.
    pub fn at_station(&self, object: ObjectId) -> bool {
        (self.in_hand | self.placed) & (1 << object) == 0
    }

    fn check_object(&self, object: ObjectId) -> Result<(), ActionError> {
        if object >= self.n_objects {
            return Err(ActionError::UnknownObject {
                object,
                n_objects: self.n_objects,
            });
        }
        Ok(())
    }

    /// Applies `action` if its preconditions hold, returning the successor state.
    pub fn apply(&self, action: Action) -> Result<DomainState, ActionError> {
        let mut next = *self;
        match action {
            Action::Navigate { to } => {
                if let Location::Unload { object, .. } = to {
                    self.check_object(object)?;
                }
                if to == self.robot_at {
                    return Err(ActionError::AlreadyThere(to));
                }
                next.robot_at = to;
            }
            Action::Load { object } => {
                self.check_object(object)?;
                if self.robot_at != Location::LoadingStation {
                    return Err(ActionError::LoadAwayFromStation {
                        object,
                        at: self.robot_at,
                    });
                }
                if !self.at_station(object) {
                    return Err(ActionError::NotAtStation(object));
                }
                next.in_hand |= 1 << object;
            }
            Action::Unload { object, side } => {
                self.check_object(object)?;
                if self.robot_at != (Location::Unload { object, side }) {
                    return Err(ActionError::UnloadAwayFromTarget {
                        object,
                        side,
                        at: self.robot_at,
                    });
                }
                if self.in_hand & (1 << object) == 0 {
                    return Err(ActionError::NotInHand(object));
                }
                next.in_hand &= !(1 << object);
                next.placed |= 1 << object;
            }
        }
        Ok(next)
    }
}

fn full_mask(n: usize) -> u32 {
    if n >= 32 { u32::MAX } else { (1u32 << n) - 1 }
}

/// One unloading step of a plan: which object, from which side.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct UnloadStep {
    /// The object.
    pub object: ObjectId,
    /// The side of the table the robot unloads from.
    pub side: Side,
}

/// A load-everything-first task plan `p^t`: navigate to the station, load in `load_order`, then
/// for each step navigate to its unloading location and unload.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub struct TaskPlan {
    /// The order in which objects are loaded.
    pub load_order: Vec<ObjectId>,
    /// The unloading steps in execution order.
    pub unloads: Vec<UnloadStep>,
}

impl TaskPlan {
    /// The plan as the action sequence `<a^n_0, a^m_0, a^n_1, ...>` of the paper.
    pub fn actions(&self) -> Vec<Action> {
        let mut actions = Vec::with_capacity(1 + self.load_order.len() + 2 * self.unloads.len());
        push_trip_actions(&mut actions, &self.load_order, &self.unloads);
        actions
    }

    /// Checks that the plan solves the `n_objects` task from the initial state: every action's
    /// preconditions hold and every object ends placed.
    pub fn validate(&self, n_objects: usize) -> Result<(), PlanValidationError> {
        validate_actions(&self.actions(), n_objects)
    }
}

/// Checks an action sequence against the domain from the initial state.
pub fn validate_actions(actions: &[Action], n_objects: usize) -> Result<(), PlanValidationError> {
    let mut state = DomainState::initial(n_objects);
    for (step, &a) in actions.iter().enumerate() {
        state = state
            .apply(a)
            .map_err(|error| PlanValidationError::Action { step, error })?;
    }
    if !state.goal_reached() {
        return Err(PlanValidationError::GoalNotReached {
            unplaced_mask: full_mask(n_objects) & !state.placed,
        });
    }
    Ok(())
}

/// Number of load-everything-first plans for `n` objects: `n!^2 * 2^n` (288 for 3).
pub fn satisficing_plan_count(n_objects: usize) -> u64 {
    let f: u64 = (1..=n_objects as u64).product();
    f * f * (1u64 << n_objects)
}

/// Rearranges `p` into the next permutation in lexicographic order; false after the last.
fn next_permutation(p: &mut [usize]) -> bool {
    if p.len() < 2 {
        return false;
    }
    let mut i = p.len() - 1;
    while i > 0 && p[i - 1] >= p[i] {
        i -= 1;
    }
    if i == 0 {
        return false;
    }
    let mut j = p.len() - 1;
    while p[j] <= p[i - 1] {
        j -= 1;
    }
    p.swap(i - 1, j);
    p[i..].reverse();
    true
}

/// All permutations of `0..n` in lexicographic order.
pub fn permutations(n: usize) -> Vec<Vec<usize>> {
    let mut p: Vec<usize> = (0..n).collect();
    let mut out = vec![p.clone()];
    while next_permutation(&mut p) {
        out.push(p.clone());
    }
    out
}

/// Side of the k-th unloading step in side mask `mask`: bit k clear = near, set = far.
fn side_of(mask: u32, k: usize) -> Side {
    if mask & (1 << k) == 0 {
        Side::Near
    } else {
        Side::Far
    }
}

/// `Plnr^t(T)`: every load-everything-first plan for `n_objects`, in a fixed order: load orders
/// (lexicographic) outermost, then unload orders (lexicographic), then side masks counting up
/// (bit k of the mask = side of the k-th unloading step, 0 = near). Valid plans only (each is
/// checked against the domain in debug builds). 288 plans for 3 objects.
pub fn satisficing_plans(n_objects: usize) -> Result<Vec<TaskPlan>, TaskPlanError> {
    if n_objects == 0 {
        return Err(TaskPlanError::NoObjects);
    }
    if n_objects > MAX_ENUMERATED_OBJECTS {
        return Err(TaskPlanError::TooManyObjects {
            n_objects,
            limit: MAX_ENUMERATED_OBJECTS,
        });
    }
    let perms = permutations(n_objects);
    let mut plans = Vec::with_capacity(satisficing_plan_count(n_objects) as usize);
    for load in &perms {
        for unload in &perms {
            for mask in 0..(1u32 << n_objects) {
                let plan = TaskPlan {
                    load_order: load.clone(),
                    unloads: unload
                        .iter()
                        .enumerate()
                        .map(|(k, &object)| UnloadStep {
                            object,
                            side: side_of(mask, k),
                        })
                        .collect(),
                };
                debug_assert!(plan.validate(n_objects).is_ok());
                plans.push(plan);
            }
        }
    }
    Ok(plans)
}

/// Up to this many objects [`satisficing_plans_shared`] keeps its plans for the process (288
/// plans for 3; 4 objects are 9,216 plans, about 1 MiB, built per call instead).
const SHARED_PLANS_MAX_OBJECTS: usize = 3;

/// [`satisficing_plans`], the same plans in the same order, built once per object count (up to
/// 3 objects) and kept for the process: a decision enumerates the same plans every time, and
/// building them is two allocations per plan (576 for 3 objects). More objects are built per
/// call.
pub fn satisficing_plans_shared(
    n_objects: usize,
) -> Result<std::borrow::Cow<'static, [TaskPlan]>, TaskPlanError> {
    use std::borrow::Cow;
    use std::sync::OnceLock;
    static PLANS: [OnceLock<Vec<TaskPlan>>; SHARED_PLANS_MAX_OBJECTS] =
        [const { OnceLock::new() }; SHARED_PLANS_MAX_OBJECTS];
    match n_objects.checked_sub(1).and_then(|i| PLANS.get(i)) {
        Some(slot) => {
            if let Some(plans) = slot.get() {
                return Ok(Cow::Borrowed(plans));
            }
            let plans = satisficing_plans(n_objects)?;
            Ok(Cow::Borrowed(slot.get_or_init(|| plans)))
        }
        None => satisficing_plans(n_objects).map(Cow::Owned),
    }
}

/// Index of (object, side) in the per-location arrays of a [`PlanningTable`]:
/// `2 * object + (0 near, 1 far)`.
pub fn location_index(object: ObjectId, side: Side) -> usize {
    2 * object + usize::from(side == Side::Far)
}

/// The numbers a plan's utility depends on, per leg and per location: navigation costs `C`
/// (seconds) between the start, the station and the `2n` unloading locations, and the
/// task-level feasibility `Fea^t` of each unloading location.
#[derive(Debug, Clone, PartialEq)]
pub struct PlanningTable {
    /// Objects in the task.
    pub n_objects: usize,
    /// Travel time start -> loading station (s); the same for every plan.
    pub start_to_station_s: f64,
    /// Travel time station -> unloading location `location_index(o, s)` (s), `2n` entries.
    pub station_to_location_s: Vec<f64>,
    /// Travel time between unloading locations (s), `2n x 2n` row-major (`from * 2n + to`).
    pub location_to_location_s: Vec<f64>,
    /// `Fea^t` of each unloading location, `2n` entries.
    pub feasibility: Vec<f64>,
}

impl PlanningTable {
    /// A table of zeros for `n_objects` (fill it in).
    pub fn zeros(n_objects: usize) -> Self {
        let m = 2 * n_objects;
        Self {
            n_objects,
            start_to_station_s: 0.0,
            station_to_location_s: vec![0.0; m],
            location_to_location_s: vec![0.0; m * m],
            feasibility: vec![0.0; m],
        }
    }

    /// Checks sizes and finiteness.
    pub fn check(&self) -> Result<(), TaskPlanError> {
        let m = 2 * self.n_objects;
        if self.n_objects == 0 {
            return Err(TaskPlanError::NoObjects);
        }
        if self.station_to_location_s.len() != m {
            return Err(TaskPlanError::BadTable(
                "station_to_location_s must have 2n entries",
            ));
        }
        if self.location_to_location_s.len() != m * m {
            return Err(TaskPlanError::BadTable(
                "location_to_location_s must have 2n x 2n entries",
            ));
        }
        if self.feasibility.len() != m {
            return Err(TaskPlanError::BadTable("feasibility must have 2n entries"));
        }
        if !self.start_to_station_s.is_finite() {
            return Err(TaskPlanError::NotFinite("start_to_station_s"));
        }
        if !self.station_to_location_s.iter().all(|v| v.is_finite()) {
            return Err(TaskPlanError::NotFinite("station_to_location_s"));
        }
        if !self.location_to_location_s.iter().all(|v| v.is_finite()) {
            return Err(TaskPlanError::NotFinite("location_to_location_s"));
        }
        if !self.feasibility.iter().all(|v| v.is_finite()) {
            return Err(TaskPlanError::NotFinite("feasibility"));
        }
        Ok(())
    }

    /// Travel time between two unloading locations (s).
    pub fn leg_s(&self, from: usize, to: usize) -> f64 {
        self.location_to_location_s[from * 2 * self.n_objects + to]
    }

    /// `C(p)`: the plan's travel time (s): start -> station -> each unloading location in order.
    pub fn plan_cost_s(&self, plan: &TaskPlan) -> f64 {
        let mut cost = self.start_to_station_s;
        let mut prev: Option<usize> = None;
        for u in &plan.unloads {
            let here = location_index(u.object, u.side);
            cost += match prev {
                None => self.station_to_location_s[here],
                Some(p) => self.leg_s(p, here),
            };
            prev = Some(here);
        }
        cost
    }

    /// `F(p)`: the plan's feasibility from its pairs' `Fea^t` (Algorithm 1, line 9).
    pub fn plan_feasibility(&self, plan: &TaskPlan, aggregation: FeasibilityAggregation) -> f64 {
        let pairs = plan
            .unloads
            .iter()
            .map(|u| self.feasibility[location_index(u.object, u.side)]);
        match aggregation {
            FeasibilityAggregation::Sum => pairs.sum(),
            FeasibilityAggregation::Product => pairs.product(),
        }
    }
}

/// A plan found by [`optimise`] with its F, C and U.
#[derive(Debug, Clone, PartialEq)]
pub struct ScoredPlan {
    /// The plan (load order: object index order).
    pub plan: TaskPlan,
    /// `F(p)`.
    pub feasibility: f64,
    /// `C(p)` (s).
    pub cost_s: f64,
    /// `U(p) = R F(p) - C(p)` (eq. 1).
    pub utility: f64,
}

/// Exact `argmax_p U(p)` over the load-everything-first plans, without enumerating them.
///
/// Sum aggregation (the default): `U = R sum_i F_i - C` is additive over the unloading steps, so a
/// dynamic programme over (set of placed objects, last unloading location) is exact:
/// `O(2^n (2n)^2)` time, `O(2^n 2n)` memory (10 objects: ~0.4 M transitions).
///
/// Product aggregation: `F(p)` depends only on the side assignment, and for fixed sides the best
/// order is the cheapest one. Up to 10 objects one DP over (objects placed with their sides, last
/// object) gives every assignment's cheapest order at once (`3^n n` states; 10 objects ~5 ms).
/// Beyond, branch and bound: assignments in order of decreasing `R prod F`, each bounded by a
/// per-assignment cost lower bound and solved by the fixed-sides DP only if it can still win; the
/// search stops once `R prod F - C_min` cannot beat the best found.
///
/// The load order does not change `U` (every object is at the station), so it is returned in
/// object index order, which is also what the enumeration's tie-break picks.
pub fn optimise(
    table: &PlanningTable,
    success_bonus_r: f64,
    aggregation: FeasibilityAggregation,
) -> Result<ScoredPlan, TaskPlanError> {
    table.check()?;
    let n = table.n_objects;
    if n > MAX_OBJECTS {
        return Err(TaskPlanError::TooManyObjects {
            n_objects: n,
            limit: MAX_OBJECTS,
        });
    }
    let unloads = match aggregation {
        FeasibilityAggregation::Sum => {
            let gain: Vec<f64> = table
                .feasibility
                .iter()
                .map(|f| success_bonus_r * f)
                .collect();
            best_order(table, &gain).1
        }
        FeasibilityAggregation::Product => best_product_plan(table, success_bonus_r),
    };
    let plan = TaskPlan {
        load_order: (0..n).collect(),
        unloads,
    };
    let feasibility = table.plan_feasibility(&plan, aggregation);
    let cost_s = table.plan_cost_s(&plan);
    Ok(ScoredPlan {
        plan,
        feasibility,
        cost_s,
        utility: utility(success_bonus_r, feasibility, cost_s),
    })
}

/// One unloading option of [`order_dp`]: placing `object` at unloading location `location`
/// (`location_index` order) earns `gain`.
#[derive(Clone, Copy, Debug)]
struct OrderItem {
    object: usize,
    location: usize,
    gain: f64,
}

/// Buffers of [`order_dp`], reused across calls.
#[derive(Default)]
struct OrderScratch {
    items: Vec<OrderItem>,
    value: Vec<f64>,
    parent: Vec<u32>,
}

/// DP over (set of placed objects, last item): maximises `sum gain - travel` from the station
/// over the orders that place every object once, each through one of its items.
/// `O(2^n k^2)` for k items. Masks only grow, so increasing numeric order visits every subset
/// before its supersets; ties keep the first found (lower last item, lower predecessor).
/// Returns (best value net of the start -> station leg, the steps).
fn order_dp(table: &PlanningTable, scratch: &mut OrderScratch) -> (f64, Vec<UnloadStep>) {
    let n = table.n_objects;
    let full = full_mask(n) as usize;
    let OrderScratch {
        items,
        value,
        parent,
    } = scratch;
    let k = items.len();
    let states = (full + 1) * k;
    value.clear();
    value.resize(states, f64::NEG_INFINITY);
    parent.clear();
    parent.resize(states, u32::MAX);
    for (i, it) in items.iter().enumerate() {
        value[(1usize << it.object) * k + i] = it.gain - table.station_to_location_s[it.location];
    }
    for mask in 1..=full {
        for (last, from) in items.iter().enumerate() {
            let v = value[mask * k + last];
            if v == f64::NEG_INFINITY {
                continue;
            }
            for (next, to) in items.iter().enumerate() {
                if mask & (1 << to.object) != 0 {
                    continue;
                }
                let nm = mask | (1 << to.object);
                let nv = v + to.gain - table.leg_s(from.location, to.location);
                let slot = nm * k + next;
                if nv > value[slot] + UTILITY_TIE_EPS * 1e-3 {
                    value[slot] = nv;
                    parent[slot] = last as u32;
                }
            }
        }
    }
    let mut best_last = 0;
    let mut best = f64::NEG_INFINITY;
    for last in 0..k {
        let v = value[full * k + last];
        if v > best {
            best = v;
            best_last = last;
        }
    }
    let mut steps = Vec::with_capacity(n);
    let mut mask = full;
    let mut i = best_last;
    loop {
        let it = items[i];
        steps.push(UnloadStep {
            object: it.object,
            side: if it.location % 2 == 0 {
                Side::Near
            } else {
                Side::Far
            },
        });
        let p = parent[mask * k + i];
        mask &= !(1 << it.object);
        if p == u32::MAX || mask == 0 {
            break;
        }
        i = p as usize;
    }
    steps.reverse();
    (best - table.start_to_station_s, steps)
}

/// The best order and sides for additive gains (`gain[loc]`, `2n` entries): [`order_dp`] over
/// every unloading location.
fn best_order(table: &PlanningTable, gain: &[f64]) -> (f64, Vec<UnloadStep>) {
    let mut scratch = OrderScratch {
        items: (0..2 * table.n_objects)
            .map(|location| OrderItem {
                object: location / 2,
                location,
                gain: gain[location],
            })
            .collect(),
        ..OrderScratch::default()
    };
    order_dp(table, &mut scratch)
}

/// The cheapest unloading order when every object's side is fixed (`far` bit o set: object o
/// from the far side): [`order_dp`] over one item per object, `O(2^n n^2)`.
fn cheapest_order_with_sides(
    table: &PlanningTable,
    far: u32,
    scratch: &mut OrderScratch,
) -> (f64, Vec<UnloadStep>) {
    scratch.items.clear();
    scratch
        .items
        .extend((0..table.n_objects).map(|object| OrderItem {
            object,
            location: 2 * object + ((far >> object) & 1) as usize,
            gain: 0.0,
        }));
    order_dp(table, scratch)
}

/// A lower bound on the cost of every plan with the sides `far` (bit o set: object o from the far
/// side), in `O(n^2)`: each location is entered once, from the station or from another chosen
/// location, so the sum of each location's cheapest entry bounds the unloading legs; and if some
/// objects are on the far side, at least one far location is entered from the station or the near
/// side (the robot starts near), so the cheapest such crossing replaces one far entry.
fn sides_cost_lower_bound(table: &PlanningTable, far: u32) -> f64 {
    let n = table.n_objects;
    let loc = |o: usize| 2 * o + ((far >> o) & 1) as usize;
    let is_far = |o: usize| (far >> o) & 1 == 1;
    let mut total = table.start_to_station_s;
    let mut upgrade = f64::INFINITY;
    for o in 0..n {
        let to = loc(o);
        let mut entry = table.station_to_location_s[to];
        let mut crossing = entry;
        for p in (0..n).filter(|&p| p != o) {
            let leg = table.leg_s(loc(p), to);
            entry = entry.min(leg);
            if !is_far(p) {
                crossing = crossing.min(leg);
            }
        }
        total += entry;
        if is_far(o) {
            upgrade = upgrade.min(crossing - entry);
        }
    }
    if upgrade.is_finite() {
        total += upgrade;
    }
    total
}

/// Objects up to which the product search runs the side-aware DP ([`product_plan_by_sides_dp`]);
/// beyond, its `3^n n` table (12 objects: 51 MB) gives way to branch and bound.
const SIDES_DP_MAX_OBJECTS: usize = 10;

fn best_product_plan(table: &PlanningTable, success_bonus_r: f64) -> Vec<UnloadStep> {
    if table.n_objects <= SIDES_DP_MAX_OBJECTS {
        product_plan_by_sides_dp(table, success_bonus_r)
    } else {
        product_plan_by_branch_and_bound(table, success_bonus_r)
    }
}

/// Product aggregation, exactly and in one pass: a DP over (objects placed *with their sides*,
/// last object) gives the cheapest order for every side assignment at once (`3^n n` states:
/// 10 objects 0.6 M, ~2.6 M transitions), then `R prod F - C` is maximised over the `2^n`
/// complete assignments. Ties (within [`UTILITY_TIE_EPS`]) keep the lower side mask, then the
/// lower last object.
fn product_plan_by_sides_dp(table: &PlanningTable, success_bonus_r: f64) -> Vec<UnloadStep> {
    let n = table.n_objects;
    if n == 0 {
        return Vec::new();
    }
    // State t: base-3 digits, digit o = 0 (not placed), 1 (placed from the near side), 2 (far).
    let pow3: Vec<usize> = (0..=n).map(|k| 3usize.pow(k as u32)).collect();
    let total = pow3[n];
    let mut cost = vec![f64::INFINITY; total * n];
    let mut parent = vec![u8::MAX; total * n];
    for o in 0..n {
        for side in 0..2 {
            cost[(side + 1) * pow3[o] * n + o] = table.station_to_location_s[2 * o + side];
        }
    }
    let mut digits = vec![0usize; n];
    for t in 1..total {
        let mut rest = t;
        for d in digits.iter_mut() {
            *d = rest % 3;
            rest /= 3;
        }
        for last in 0..n {
            if digits[last] == 0 {
                continue;
            }
            let c = cost[t * n + last];
            if c == f64::INFINITY {
                continue;
            }
            let from = 2 * last + digits[last] - 1;
            for o in (0..n).filter(|&o| digits[o] == 0) {
                for side in 0..2 {
                    let t2 = t + (side + 1) * pow3[o];
                    let c2 = c + table.leg_s(from, 2 * o + side);
                    let slot = t2 * n + o;
                    if c2 < cost[slot] - UTILITY_TIE_EPS * 1e-3 {
                        cost[slot] = c2;
                        parent[slot] = last as u8;
                    }
                }
            }
        }
    }
    let (mut best_u, mut best_t, mut best_last) = (f64::NEG_INFINITY, 0usize, 0usize);
    for far in 0..=full_mask(n) {
        let mut t = 0;
        let mut f = 1.0;
        for (o, p) in pow3.iter().take(n).enumerate() {
            let side = ((far >> o) & 1) as usize;
            t += (side + 1) * p;
            f *= table.feasibility[2 * o + side];
        }
        for last in 0..n {
            let u = success_bonus_r * f - (table.start_to_station_s + cost[t * n + last]);
            if u > best_u + UTILITY_TIE_EPS {
                (best_u, best_t, best_last) = (u, t, last);
            }
        }
    }
    let mut steps = Vec::with_capacity(n);
    let (mut t, mut o) = (best_t, best_last);
    loop {
        let digit = (t / pow3[o]) % 3;
        steps.push(UnloadStep {
            object: o,
            side: if digit == 1 { Side::Near } else { Side::Far },
        });
        let p = parent[t * n + o];
        t -= digit * pow3[o];
        if p == u8::MAX || t == 0 {
            break;
        }
        o = p as usize;
    }
    steps.reverse();
    steps
}

fn product_plan_by_branch_and_bound(
    table: &PlanningTable,
    success_bonus_r: f64,
) -> Vec<UnloadStep> {
    let n = table.n_objects;
    let zero_gain = vec![0.0; 2 * n];
    // Cheapest plan over every side assignment: a lower bound on each plan's cost.
    let (neg_min_cost, cheapest) = best_order(table, &zero_gain);
    let min_cost_s = -neg_min_cost;
    let mut assignments: Vec<(f64, u32)> = (0..=full_mask(n))
        .map(|far| {
            let f: f64 = (0..n)
                .map(|o| table.feasibility[2 * o + ((far >> o) & 1) as usize])
                .product();
            (success_bonus_r * f, far)
        })
        .collect();
    // Highest bound first; equal bounds in mask order, so the search is deterministic.
    assignments.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
    // The cheapest plan is a plan: its utility is a floor for the optimum from the start, so
    // the search stops at the first assignment whose reward cannot lift it past that floor.
    // Assignments below the floor cannot win or tie, so the result is the one the search
    // without the floor finds.
    let cheapest_far = cheapest
        .iter()
        .filter(|u| u.side == Side::Far)
        .fold(0u32, |far, u| far | (1 << u.object));
    let cheapest_reward = success_bonus_r
        * (0..n)
            .map(|o| table.feasibility[2 * o + ((cheapest_far >> o) & 1) as usize])
            .product::<f64>();
    let floor_u = cheapest_reward - min_cost_s;
    let mut best_u = f64::NEG_INFINITY;
    let mut best_steps = cheapest;
    let mut scratch = OrderScratch::default();
    for (reward, far) in assignments {
        if reward - min_cost_s < best_u.max(floor_u) - UTILITY_TIE_EPS {
            break;
        }
        if reward - sides_cost_lower_bound(table, far) < best_u.max(floor_u) - UTILITY_TIE_EPS {
            continue;
        }
        let (neg_cost, steps) = cheapest_order_with_sides(table, far, &mut scratch);
        let u = reward + neg_cost;
        if u > best_u + UTILITY_TIE_EPS {
            best_u = u;
            best_steps = steps;
        }
    }
    best_steps
}

/// One trip's actions: to the station, load `load_order`, then navigate to and unload each of
/// `unloads` (a single-trip plan is one trip; the multi-trip planner plans several).
pub(crate) fn push_trip_actions(
    actions: &mut Vec<Action>,
    load_order: &[ObjectId],
    unloads: &[UnloadStep],
) {
    actions.push(Action::Navigate {
        to: Location::LoadingStation,
    });
    actions.extend(load_order.iter().map(|&object| Action::Load { object }));
    for u in unloads {
        actions.push(Action::Navigate {
            to: Location::Unload {
                object: u.object,
                side: u.side,
            },
        });
        actions.push(Action::Unload {
            object: u.object,
            side: u.side,
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The side-aware DP and the branch and bound find plans of the same utility.
    #[test]
    fn product_dp_and_branch_and_bound_agree() {
        use rand::{RngExt, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(23);
        for n in 1..=7 {
            for _ in 0..8 {
                let mut t = PlanningTable::zeros(n);
                t.start_to_station_s = rng.random_range(0.0..20.0);
                for v in t.station_to_location_s.iter_mut() {
                    *v = rng.random_range(1.0..30.0);
                }
                for v in t.location_to_location_s.iter_mut() {
                    *v = rng.random_range(1.0..40.0);
                }
                for v in t.feasibility.iter_mut() {
                    *v = rng.random_range(0.3..1.0);
                }
                for r in [0.0, 40.0, 400.0] {
                    let score = |steps: Vec<UnloadStep>| {
                        let plan = TaskPlan {
                            load_order: (0..n).collect(),
                            unloads: steps,
                        };
                        plan.validate(n).unwrap();
                        r * t.plan_feasibility(&plan, FeasibilityAggregation::Product)
                            - t.plan_cost_s(&plan)
                    };
                    let a = score(product_plan_by_sides_dp(&t, r));
                    let b = score(product_plan_by_branch_and_bound(&t, r));
                    assert!((a - b).abs() < 1e-9, "n {n} r {r}: dp {a} vs b&b {b}");
                }
            }
        }
    }

    /// The fixed-sides DP returns the cheapest order (checked against every permutation), and
    /// the product search's pruning bound never exceeds it.
    #[test]
    fn cheapest_order_with_sides_is_the_cheapest_permutation() {
        use rand::{RngExt, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(17);
        let mut scratch = OrderScratch::default();
        for n in 1..=5 {
            for _ in 0..5 {
                let mut t = PlanningTable::zeros(n);
                t.start_to_station_s = rng.random_range(0.0..20.0);
                for v in t.station_to_location_s.iter_mut() {
                    *v = rng.random_range(1.0..30.0);
                }
                for v in t.location_to_location_s.iter_mut() {
                    // Integer seconds make ties common.
                    *v = f64::from(rng.random_range(1u8..6));
                }
                for far in 0..=full_mask(n) {
                    let (neg_cost, steps) = cheapest_order_with_sides(&t, far, &mut scratch);
                    let plan = TaskPlan {
                        load_order: (0..n).collect(),
                        unloads: steps,
                    };
                    plan.validate(n).unwrap();
                    assert!((t.plan_cost_s(&plan) + neg_cost).abs() < 1e-9);
                    for u in &plan.unloads {
                        assert_eq!(u.side == Side::Far, (far >> u.object) & 1 == 1);
                    }
                    let mut best = f64::INFINITY;
                    for_each_permutation(n, &mut |order: &[usize]| {
                        let unloads = order
                            .iter()
                            .map(|&o| UnloadStep {
                                object: o,
                                side: if (far >> o) & 1 == 1 {
                                    Side::Far
                                } else {
                                    Side::Near
                                },
                            })
                            .collect();
                        let p = TaskPlan {
                            load_order: (0..n).collect(),
                            unloads,
                        };
                        best = best.min(t.plan_cost_s(&p));
                    });
                    assert!((best + neg_cost).abs() < 1e-9, "n {n} far {far:b}");
                    let lb = sides_cost_lower_bound(&t, far);
                    assert!(lb <= best + 1e-9, "n {n} far {far:b}: bound {lb} > {best}");
                }
            }
        }
    }

    fn for_each_permutation(n: usize, f: &mut dyn FnMut(&[usize])) {
        fn go(prefix: &mut Vec<usize>, n: usize, f: &mut dyn FnMut(&[usize])) {
            if prefix.len() == n {
                f(prefix);
                return;
            }
            for o in 0..n {
                if !prefix.contains(&o) {
                    prefix.push(o);
                    go(prefix, n, f);
                    prefix.pop();
                }
            }
        }
        go(&mut Vec::with_capacity(n), n, f);
    }

    #[test]
    fn domain_preconditions_and_effects() {
        let s = DomainState::initial(2);
        assert_eq!(
            s.apply(Action::Load { object: 0 }),
            Err(ActionError::LoadAwayFromStation {
                object: 0,
                at: Location::Start
            })
        );
        let s = s
            .apply(Action::Navigate {
                to: Location::LoadingStation,
            })
            .unwrap();
        assert_eq!(
            s.apply(Action::Navigate {
                to: Location::LoadingStation
            }),
            Err(ActionError::AlreadyThere(Location::LoadingStation))
        );
        let s = s.apply(Action::Load { object: 1 }).unwrap();
        assert_eq!(s.in_hand, 0b10);
        assert_eq!(
            s.apply(Action::Load { object: 1 }),
            Err(ActionError::NotAtStation(1))
        );
        assert_eq!(
            s.apply(Action::Load { object: 2 }),
            Err(ActionError::UnknownObject {
                object: 2,
                n_objects: 2
            })
        );
        let far1 = Location::Unload {
            object: 1,
            side: Side::Far,
        };
        let s = s.apply(Action::Navigate { to: far1 }).unwrap();
        assert_eq!(
            s.apply(Action::Unload {
                object: 1,
                side: Side::Near
            }),
            Err(ActionError::UnloadAwayFromTarget {
                object: 1,
                side: Side::Near,
                at: far1
            })
        );
        let s = s
            .apply(Action::Unload {
                object: 1,
                side: Side::Far,
            })
            .unwrap();
        assert_eq!((s.in_hand, s.placed), (0, 0b10));
        assert!(!s.goal_reached());
        assert_eq!(
            s.apply(Action::Unload {
                object: 1,
                side: Side::Far
            }),
            Err(ActionError::NotInHand(1))
        );
        // The robot holds several objects: load both, then unload both.
        let plan = TaskPlan {
            load_order: vec![1, 0],
            unloads: vec![
                UnloadStep {
                    object: 0,
                    side: Side::Near,
                },
                UnloadStep {
                    object: 1,
                    side: Side::Far,
                },
            ],
        };
        plan.validate(2).unwrap();
        let bad = TaskPlan {
            load_order: vec![1],
            unloads: plan.unloads.clone(),
        };
        assert!(matches!(
            bad.validate(2),
            Err(PlanValidationError::Action {
                step: 3,
                error: ActionError::NotInHand(0)
            })
        ));
        let short = TaskPlan {
            load_order: vec![0, 1],
            unloads: plan.unloads[..1].to_vec(),
        };
        assert_eq!(
            short.validate(2),
            Err(PlanValidationError::GoalNotReached {
                unplaced_mask: 0b10
            })
        );
    }

    #[test]
    fn enumeration_counts_and_validity() {
        assert_eq!(satisficing_plan_count(3), 288);
        let plans = satisficing_plans(3).unwrap();
        assert_eq!(plans.len(), 288);
        let distinct: std::collections::HashSet<_> = plans.iter().collect();
        assert_eq!(distinct.len(), 288);
        for p in &plans {
            p.validate(3).unwrap();
            assert_eq!(p.actions().len(), 1 + 3 + 6);
        }
        assert_eq!(satisficing_plans(1).unwrap().len(), 2);
        for n in 0..=6 {
            let shared = satisficing_plans_shared(n).map(|p| p.into_owned());
            assert_eq!(shared, satisficing_plans(n), "{n} objects");
            // The second call reads what the first kept.
            let again = satisficing_plans_shared(n).map(|p| p.into_owned());
            assert_eq!(again, satisficing_plans(n), "{n} objects, again");
        }
        assert_eq!(satisficing_plans(4).unwrap().len(), 9216);
        assert_eq!(satisficing_plans(0), Err(TaskPlanError::NoObjects));
        assert!(matches!(
            satisficing_plans(6),
            Err(TaskPlanError::TooManyObjects { .. })
        ));
        assert_eq!(permutations(3).len(), 6);
        assert_eq!(permutations(0), vec![Vec::<usize>::new()]);
    }

    #[test]
    fn plan_cost_and_feasibility() {
        let mut t = PlanningTable::zeros(2);
        t.start_to_station_s = 2.0;
        t.station_to_location_s = vec![10.0, 20.0, 30.0, 40.0];
        for i in 0..4 {
            for j in 0..4 {
                t.location_to_location_s[i * 4 + j] = (i * 4 + j) as f64;
            }
        }
        t.feasibility = vec![0.5, 0.1, 0.8, 0.2];
        let p = TaskPlan {
            load_order: vec![0, 1],
            unloads: vec![
                UnloadStep {
                    object: 1,
                    side: Side::Far,
                },
                UnloadStep {
                    object: 0,
                    side: Side::Near,
                },
            ],
        };
        // start->station 2 + station->(1,far)=loc 3: 40 + loc3->loc0: 12
        assert_eq!(t.plan_cost_s(&p), 54.0);
        assert_eq!(t.plan_feasibility(&p, FeasibilityAggregation::Sum), 0.7);
        assert_eq!(t.plan_feasibility(&p, FeasibilityAggregation::Product), 0.1);
    }

    #[test]
    fn malformed_tables_are_rejected() {
        let mut t = PlanningTable::zeros(2);
        t.feasibility.pop();
        assert!(matches!(
            optimise(&t, 40.0, FeasibilityAggregation::Sum),
            Err(TaskPlanError::BadTable(_))
        ));
        let mut t = PlanningTable::zeros(2);
        t.location_to_location_s[3] = f64::NAN;
        assert_eq!(
            optimise(&t, 40.0, FeasibilityAggregation::Sum),
            Err(TaskPlanError::NotFinite("location_to_location_s"))
        );
        assert_eq!(
            optimise(&PlanningTable::zeros(0), 40.0, FeasibilityAggregation::Sum),
            Err(TaskPlanError::NoObjects)
        );
        assert!(matches!(
            optimise(&PlanningTable::zeros(13), 40.0, FeasibilityAggregation::Sum),
            Err(TaskPlanError::TooManyObjects { limit: 12, .. })
        ));
    }
}
