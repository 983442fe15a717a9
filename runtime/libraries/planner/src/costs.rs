//! Navigation costs `C`: travel time of the navigation motion planner's paths (paper: `Cst(Plnr^m(
//! a^n))`) between the start, the loading station and the chosen navigation goals.
//!
//! [`TravelTime`] is the motion planner as the task-level planners see it; [`GridTravelTime`] is
//! the real one (shortest any-angle paths on the world's 0.1 m occupancy grid at the robot's speed). [`LegCache`]
//! asks it at most once per unordered pair of nodes and counts the calls (PETLON's measure).

use crate::problem::TaskProblem;
use crate::task::PlanningTable;
use world::nav::{NavEndpoint, OccupancyGrid};

/// The navigation motion planner as a cost oracle.
pub trait TravelTime {
    /// Travel time (s) of the planned path from `from` to `to` (world m), `None` when no path
    /// exists.
    fn travel_time_s(&mut self, from: (f64, f64), to: (f64, f64)) -> Option<f64>;
}

impl<T: TravelTime + ?Sized> TravelTime for &mut T {
    fn travel_time_s(&mut self, from: (f64, f64), to: (f64, f64)) -> Option<f64> {
        (**self).travel_time_s(from, to)
    }
}

/// Travel time along the world's occupancy grid paths at a constant cruise speed (the paper's
/// cost; acceleration ignored). Each distinct endpoint is connected to the grid's corner graph
/// once ([`world::nav::NavEndpoint`], tens of microseconds); every further leg from or to it costs
/// a line-of-sight check and a scan over the corners it sees.
#[derive(Debug, Clone)]
pub struct GridTravelTime<'g> {
    grid: &'g OccupancyGrid,
    speed_mps: f64,
    /// Endpoints seen so far, keyed by their exact coordinates (`None`: not near a free cell).
    endpoints: Vec<([u64; 2], Option<NavEndpoint>)>,
}

impl<'g> GridTravelTime<'g> {
    /// Travel times on `grid` at `speed_mps`.
    pub fn new(grid: &'g OccupancyGrid, speed_mps: f64) -> Self {
        Self {
            grid,
            speed_mps,
            endpoints: Vec::new(),
        }
    }

    /// The grid the paths are planned on.
    pub fn grid(&self) -> &'g OccupancyGrid {
        self.grid
    }

    /// Cruise speed (m/s).
    pub fn speed_mps(&self) -> f64 {
        self.speed_mps
    }

    /// Index of the endpoint at `xy` in the cache, connecting it on first use.
    fn endpoint_index(&mut self, xy: (f64, f64)) -> usize {
        let key = [xy.0.to_bits(), xy.1.to_bits()];
        if let Some(i) = self.endpoints.iter().position(|(k, _)| *k == key) {
            return i;
        }
        self.endpoints.push((key, self.grid.endpoint(xy)));
        self.endpoints.len() - 1
    }
}

impl TravelTime for GridTravelTime<'_> {
    fn travel_time_s(&mut self, from: (f64, f64), to: (f64, f64)) -> Option<f64> {
        let a = self.endpoint_index(from);
        let b = self.endpoint_index(to);
        let (Some(a), Some(b)) = (&self.endpoints[a].1, &self.endpoints[b].1) else {
            return None;
        };
        self.grid
            .path_length_between(a, b)
            .map(|length_m| length_m / self.speed_mps)
    }
}

/// Prepares `grid` (the map of `scene`) for many decisions, once per map: which corners each
/// cell where a decision can put an endpoint sees ([`crate::problem::endpoint_regions`]), and
/// the loading station connected with its distances to every corner (a leg from it to every
/// goal, every decision). Every travel time is the same as on the unprepared grid, bit for bit;
/// only faster (docs/planner-bench.md: the `map/sight` row).
pub fn prepare_grid_for_decisions(
    grid: &mut OccupancyGrid,
    scene: &world::Scene,
) -> world::nav::SightStats {
    let stats = grid.precompute_endpoint_sight(&crate::problem::endpoint_regions(scene));
    grid.keep_endpoint((scene.loading_station.x_m, scene.loading_station.y_m));
    stats
}

/// Straight-line travel time: a lower bound on every path's travel time (PETLON's optimistic
/// estimate), and an obstacle-free world for tests.
#[derive(Debug, Clone, Copy)]
pub struct StraightLine {
    /// Cruise speed (m/s).
    pub speed_mps: f64,
}

impl StraightLine {
    /// The lower bound between two points (s).
    pub fn time_s(&self, from: (f64, f64), to: (f64, f64)) -> f64 {
        (to.0 - from.0).hypot(to.1 - from.1) / self.speed_mps
    }
}

impl TravelTime for StraightLine {
    fn travel_time_s(&mut self, from: (f64, f64), to: (f64, f64)) -> Option<f64> {
        Some(self.time_s(from, to))
    }
}

/// A node of the navigation graph of one task: start, station or an unloading location's goal.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum NavNode {
    /// The robot's start.
    Start,
    /// The loading station.
    Station,
    /// The chosen navigation goal of location index `i`.
    Goal(usize),
}

/// Travel times between the nodes of one task, asked of the motion planner at most once per
/// unordered pair (asked in one canonical direction, so the answer does not depend on who asked
/// first), with a count of the
/// calls made. A leg without a path costs `no_path_cost_s`.
#[derive(Debug, Clone)]
pub struct LegCache {
    positions: Vec<(f64, f64)>,
    known: Vec<Option<f64>>,
    no_path: Vec<bool>,
    no_path_cost_s: f64,
    calls: usize,
}

impl LegCache {
    /// A cache for the nodes of `problem` with navigation goals `goals_xy` (one per location).
    pub fn new(problem: &TaskProblem, goals_xy: &[(f64, f64)], no_path_cost_s: f64) -> Self {
        let mut positions = Vec::with_capacity(2 + goals_xy.len());
        positions.push(problem.start_xy);
        positions.push(problem.station_xy);
        positions.extend_from_slice(goals_xy);
        let n = positions.len();
        Self {
            positions,
            known: vec![None; n * n],
            no_path: vec![false; n * n],
            no_path_cost_s,
            calls: 0,
        }
    }

    fn index(node: NavNode) -> usize {
        match node {
            NavNode::Start => 0,
            NavNode::Station => 1,
            NavNode::Goal(i) => 2 + i,
        }
    }

    /// World position of a node.
    pub fn position(&self, node: NavNode) -> (f64, f64) {
        self.positions[Self::index(node)]
    }

    fn slot(&self, a: NavNode, b: NavNode) -> usize {
        let (i, j) = (Self::index(a), Self::index(b));
        let (i, j) = if i <= j { (i, j) } else { (j, i) };
        i * self.positions.len() + j
    }

    /// The travel time if the motion planner was already asked for this leg.
    pub fn known_s(&self, a: NavNode, b: NavNode) -> Option<f64> {
        self.known[self.slot(a, b)]
    }

    /// Was this leg asked and found to have no path?
    pub fn has_no_path(&self, a: NavNode, b: NavNode) -> bool {
        self.no_path[self.slot(a, b)]
    }

    /// Travel time of a leg, asking the motion planner on the first request.
    pub fn leg_s(&mut self, a: NavNode, b: NavNode, travel: &mut dyn TravelTime) -> f64 {
        if a == b {
            return 0.0;
        }
        let slot = self.slot(a, b);
        if let Some(t) = self.known[slot] {
            return t;
        }
        self.calls += 1;
        // Always ask in the canonical direction (lower node first): an any-angle grid planner's
        // path length can differ by a cell or so between directions, and the cost of a leg must
        // not depend on which plan asked for it first.
        let (a, b) = if Self::index(a) <= Self::index(b) {
            (a, b)
        } else {
            (b, a)
        };
        let t = match travel.travel_time_s(self.position(a), self.position(b)) {
            Some(t) if t.is_finite() => t,
            _ => {
                self.no_path[slot] = true;
                self.no_path_cost_s
            }
        };
        self.known[slot] = Some(t);
        t
    }

    /// Motion-planner calls made so far.
    pub fn calls(&self) -> usize {
        self.calls
    }

    /// Fills the travel-time part of a [`PlanningTable`] for `n_objects`, asking every leg a plan
    /// can use: start->station, station->each goal, and goal->goal between different objects
    /// (`1 + 2n + 2n(n-1)` legs; 19 for 3 objects).
    pub fn fill_table(&mut self, table: &mut PlanningTable, travel: &mut dyn TravelTime) {
        let m = 2 * table.n_objects;
        table.start_to_station_s = self.leg_s(NavNode::Start, NavNode::Station, travel);
        for i in 0..m {
            table.station_to_location_s[i] = self.leg_s(NavNode::Station, NavNode::Goal(i), travel);
        }
        for i in 0..m {
            for j in 0..m {
                // Two locations of the same object are never consecutive in a plan.
                table.location_to_location_s[i * m + j] = if i / 2 == j / 2 {
                    0.0
                } else {
                    self.leg_s(NavNode::Goal(i), NavNode::Goal(j), travel)
                };
            }
        }
    }
}

/// Wraps a travel-time oracle and remembers every answer by its (unordered) endpoints, so that
/// several planners on the same task, or a repeated decision, ask the motion planner once per leg.
#[derive(Debug, Clone)]
pub struct MemoTravel<T> {
    inner: T,
    memo: std::collections::HashMap<[u64; 4], Option<f64>>,
    misses: usize,
}

impl<T: TravelTime> MemoTravel<T> {
    /// A memo around `inner`.
    pub fn new(inner: T) -> Self {
        Self {
            inner,
            memo: std::collections::HashMap::new(),
            misses: 0,
        }
    }

    /// Calls that reached the wrapped oracle.
    pub fn misses(&self) -> usize {
        self.misses
    }
}

impl<T: TravelTime> TravelTime for MemoTravel<T> {
    fn travel_time_s(&mut self, from: (f64, f64), to: (f64, f64)) -> Option<f64> {
        let a = [from.0.to_bits(), from.1.to_bits()];
        let b = [to.0.to_bits(), to.1.to_bits()];
        let key = if a <= b {
            [a[0], a[1], b[0], b[1]]
        } else {
            [b[0], b[1], a[0], a[1]]
        };
        if let Some(&t) = self.memo.get(&key) {
            return t;
        }
        self.misses += 1;
        let t = self.inner.travel_time_s(from, to);
        self.memo.insert(key, t);
        t
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::problem::UnloadLocation;
    use world::{Heatmap, Side};

    struct Counting(usize);
    impl TravelTime for Counting {
        fn travel_time_s(&mut self, from: (f64, f64), to: (f64, f64)) -> Option<f64> {
            self.0 += 1;
            if to.0 > 100.0 {
                None
            } else {
                Some((to.0 - from.0).abs() + (to.1 - from.1).abs())
            }
        }
    }

    fn problem(n: usize) -> TaskProblem {
        TaskProblem {
            start_xy: (0.0, 2.0),
            station_xy: (0.0, 1.0),
            locations: (0..2 * n)
                .map(|i| {
                    let side = if i % 2 == 0 { Side::Near } else { Side::Far };
                    UnloadLocation::from_heatmap(
                        i / 2,
                        side,
                        [i as f64, 6.0, 1.3],
                        &Heatmap::zeros(),
                    )
                })
                .collect(),
        }
    }

    #[test]
    fn cache_asks_each_unordered_leg_once() {
        let p = problem(3);
        let goals: Vec<(f64, f64)> = (0..6).map(|i| (i as f64, 5.0)).collect();
        let mut cache = LegCache::new(&p, &goals, 60.0);
        let mut oracle = Counting(0);
        let mut table = PlanningTable::zeros(3);
        cache.fill_table(&mut table, &mut oracle);
        assert_eq!(cache.calls(), 19);
        assert_eq!(oracle.0, 19);
        assert_eq!(table.start_to_station_s, 1.0);
        assert_eq!(table.station_to_location_s[2], 2.0 + 4.0);
        assert_eq!(table.leg_s(0, 5), 5.0);
        assert_eq!(table.leg_s(5, 0), 5.0);
        // Asking again is free.
        cache.fill_table(&mut table, &mut oracle);
        assert_eq!(oracle.0, 19);
        assert_eq!(
            cache.leg_s(NavNode::Goal(1), NavNode::Goal(1), &mut oracle),
            0.0
        );
    }

    /// An oracle whose answer depends on direction: the cache must give the same value whichever
    /// direction is asked first.
    struct Asymmetric;
    impl TravelTime for Asymmetric {
        fn travel_time_s(&mut self, from: (f64, f64), to: (f64, f64)) -> Option<f64> {
            Some(if from.0 < to.0 { 1.0 } else { 2.0 })
        }
    }

    #[test]
    fn leg_cost_does_not_depend_on_request_order() {
        let p = problem(1);
        let goals = vec![(5.0, 5.0), (7.0, 7.0)];
        let mut c1 = LegCache::new(&p, &goals, 60.0);
        let mut c2 = LegCache::new(&p, &goals, 60.0);
        let x = c1.leg_s(NavNode::Goal(0), NavNode::Goal(1), &mut Asymmetric);
        let y = c2.leg_s(NavNode::Goal(1), NavNode::Goal(0), &mut Asymmetric);
        assert_eq!(x, y);
    }

    #[test]
    fn missing_path_costs_the_penalty() {
        let p = problem(1);
        let goals = vec![(0.0, 5.0), (500.0, 5.0)];
        let mut cache = LegCache::new(&p, &goals, 60.0);
        let mut oracle = Counting(0);
        assert_eq!(
            cache.leg_s(NavNode::Station, NavNode::Goal(1), &mut oracle),
            60.0
        );
        assert!(cache.has_no_path(NavNode::Goal(1), NavNode::Station));
        assert!(!cache.has_no_path(NavNode::Goal(0), NavNode::Station));
        assert_eq!(cache.known_s(NavNode::Goal(0), NavNode::Station), None);
    }

    #[test]
    fn memo_asks_once_per_unordered_leg() {
        let mut memo = MemoTravel::new(Counting(0));
        assert_eq!(memo.travel_time_s((0.0, 0.0), (1.0, 2.0)), Some(3.0));
        assert_eq!(memo.travel_time_s((1.0, 2.0), (0.0, 0.0)), Some(3.0));
        assert_eq!(memo.travel_time_s((0.0, 0.0), (500.0, 0.0)), None);
        assert_eq!(memo.travel_time_s((0.0, 0.0), (500.0, 0.0)), None);
        assert_eq!(memo.misses(), 2);
        assert_eq!(memo.inner.0, 2);
    }

    #[test]
    fn straight_line_is_a_lower_bound_example() {
        let s = StraightLine { speed_mps: 0.5 };
        assert_eq!(s.time_s((0.0, 0.0), (3.0, 4.0)), 10.0);
    }
}
