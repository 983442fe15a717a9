//! Navigation: an occupancy grid in the base's configuration space and shortest any-angle paths
//! on it. Path length / speed is the travel time C of a navigation action (paper eq. 3).
//!
//! Queries are answered on the grid's corner visibility graph (module `visibility`: exact
//! shortest paths through cell centres, all-pairs distances between obstacle corners
//! precomputed per map, microseconds per query); Lazy Theta* over 8-connected cells is kept as
//! the reference it is tested against and as the fallback when corners cannot connect two points.
//!
//! A cell is free when the base footprint, centred on the cell centre, fits at one of
//! [`HEADINGS`] headings: the base turns in place, so a place is reachable if some heading
//! fits there (the rectangle is symmetric under a half turn, so headings span 0 .. pi).
//! Paths never cut the corner between two blocked cells.

use std::cmp::Ordering;
use std::collections::BinaryHeap;

use crate::geometry::OrientedRect;
use crate::robot::RobotConfig;
use crate::scene::Scene;

pub mod lattice;
mod visibility;
use visibility::{CornerGraph, SightTable};
pub use visibility::{MAX_GRAPH_CORNERS, NavEndpoint, SightStats};

/// Grid resolution (m): the authors' 0.1 m navigation cells.
pub const NAV_CELL_M: f64 = 0.1;
/// Headings tried per cell: 0, 22.5, ..., 157.5 degrees.
pub const HEADINGS: usize = 8;
/// How far (in cells) an endpoint standing in a blocked cell is moved to the nearest free cell.
pub const ENDPOINT_SNAP_CELLS: i64 = 2;

/// A path for the base: world points from start to goal and its length.
#[derive(Clone, Debug, PartialEq)]
pub struct NavPath {
    /// Corners of the path, start first, goal last (m).
    pub points: Vec<(f64, f64)>,
    /// Sum of the straight segments' lengths (m).
    pub length_m: f64,
}

impl NavPath {
    /// The polyline through `points`, its length summed.
    pub fn through(points: Vec<(f64, f64)>) -> Self {
        let length_m = points
            .windows(2)
            .map(|w| (w[1].0 - w[0].0).hypot(w[1].1 - w[0].1))
            .sum();
        Self { points, length_m }
    }

    /// Travel time at `speed_mps` (s): C of one navigation action.
    pub fn travel_time_s(&self, speed_mps: f64) -> f64 {
        self.length_m / speed_mps
    }
}

/// The base's configuration-space occupancy grid over the room (0.1 m cells).
#[derive(Clone, Debug)]
pub struct OccupancyGrid {
    x_min_m: f64,
    y_min_m: f64,
    cols: usize,
    rows: usize,
    free: Vec<bool>,
    /// Connected part of the free space each cell belongs to (8-connected moves that do not
    /// squeeze between two blocked cells); `u32::MAX` for blocked cells.
    component: Vec<u32>,
    /// Corner visibility graph with all-pairs distances: the fast exact path queries.
    graph: CornerGraph,
    /// Which corners each cell sees, when precomputed
    /// ([`OccupancyGrid::precompute_endpoint_sight`]).
    sight: Option<SightTable>,
    /// Endpoints connected once per map ([`OccupancyGrid::keep_endpoint`]).
    kept_endpoints: Vec<NavEndpoint>,
}

impl OccupancyGrid {
    /// Builds the grid for the scene and the robot's footprint.
    pub fn from_scene(scene: &Scene, robot: &RobotConfig) -> Self {
        let room = scene.room;
        let cols = ((room.x_max_m - room.x_min_m) / NAV_CELL_M).ceil().max(1.0) as usize;
        let rows = ((room.y_max_m - room.y_min_m) / NAV_CELL_M).ceil().max(1.0) as usize;
        let mut grid = Self {
            x_min_m: room.x_min_m,
            y_min_m: room.y_min_m,
            cols,
            rows,
            free: vec![true; cols * rows],
            component: Vec::new(),
            graph: CornerGraph::default(),
            sight: None,
            kept_endpoints: Vec::new(),
        };
        // blocked[i] has bit h set when heading h collides at cell i.
        let mut blocked = vec![0u8; cols * rows];
        // One bit per heading: all eight set means no heading fits.
        const _: () = assert!(HEADINGS == 8);
        let all_blocked = u8::MAX;
        let headings: Vec<f64> = (0..HEADINGS)
            .map(|h| h as f64 * std::f64::consts::PI / HEADINGS as f64)
            .collect();
        let fp = robot.footprint;
        let reach_m = 0.5 * fp.length_m.hypot(fp.width_m);

        let mut test_region = |grid: &OccupancyGrid,
                               x0: f64,
                               x1: f64,
                               y0: f64,
                               y1: f64,
                               hits: &dyn Fn(&OrientedRect) -> bool| {
            let (c0, r0) = grid.cell_of_clamped(x0 - reach_m, y0 - reach_m);
            let (c1, r1) = grid.cell_of_clamped(x1 + reach_m, y1 + reach_m);
            for r in r0..=r1 {
                for c in c0..=c1 {
                    let i = r * grid.cols + c;
                    if blocked[i] == all_blocked {
                        continue;
                    }
                    let (x, y) = grid.cell_center(c, r);
                    for (h, &yaw) in headings.iter().enumerate() {
                        if blocked[i] & (1 << h) == 0 && hits(&fp.at(x, y, yaw)) {
                            blocked[i] |= 1 << h;
                        }
                    }
                }
            }
        };

        // Walls: only cells within the footprint's reach of a wall can leave the room.
        let inside = |r: &OrientedRect| !room.contains_rect(r);
        test_region(
            &grid,
            room.x_min_m,
            room.x_min_m,
            room.y_min_m,
            room.y_max_m,
            &inside,
        );
        test_region(
            &grid,
            room.x_max_m,
            room.x_max_m,
            room.y_min_m,
            room.y_max_m,
            &inside,
        );
        test_region(
            &grid,
            room.x_min_m,
            room.x_max_m,
            room.y_min_m,
            room.y_min_m,
            &inside,
        );
        test_region(
            &grid,
            room.x_min_m,
            room.x_max_m,
            room.y_max_m,
            room.y_max_m,
            &inside,
        );
        for furniture in scene.furniture_footprints() {
            let (x0, x1, y0, y1) = furniture.bounds();
            test_region(&grid, x0, x1, y0, y1, &|r: &OrientedRect| {
                r.overlaps(&furniture)
            });
        }
        for (cell, mask) in grid.free.iter_mut().zip(&blocked) {
            *cell = *mask != all_blocked;
        }
        grid.component = grid.label_components();
        grid.graph = CornerGraph::build(&grid);
        grid
    }

    /// Columns (along x).
    pub fn cols(&self) -> usize {
        self.cols
    }

    /// Rows (along y).
    pub fn rows(&self) -> usize {
        self.rows
    }

    /// Centre of cell (col, row) in world coordinates (m).
    pub fn cell_center(&self, col: usize, row: usize) -> (f64, f64) {
        (
            self.x_min_m + (col as f64 + 0.5) * NAV_CELL_M,
            self.y_min_m + (row as f64 + 0.5) * NAV_CELL_M,
        )
    }

    /// The cell (col, row) containing (x, y), or `None` outside the grid.
    pub fn cell_of(&self, x_m: f64, y_m: f64) -> Option<(usize, usize)> {
        let c = ((x_m - self.x_min_m) / NAV_CELL_M).floor();
        let r = ((y_m - self.y_min_m) / NAV_CELL_M).floor();
        if c >= 0.0 && r >= 0.0 && (c as usize) < self.cols && (r as usize) < self.rows {
            Some((c as usize, r as usize))
        } else {
            None
        }
    }

    fn cell_of_clamped(&self, x_m: f64, y_m: f64) -> (usize, usize) {
        let c = ((x_m - self.x_min_m) / NAV_CELL_M)
            .floor()
            .clamp(0.0, (self.cols - 1) as f64);
        let r = ((y_m - self.y_min_m) / NAV_CELL_M)
            .floor()
            .clamp(0.0, (self.rows - 1) as f64);
        (c as usize, r as usize)
    }

    /// Whether the base can stand at (x, y) with some heading (its cell is free). Outside the
    /// room is never free; non-finite input is not free.
    pub fn is_free(&self, xy: (f64, f64)) -> bool {
        self.cell_of(xy.0, xy.1)
            .is_some_and(|(c, r)| self.free[r * self.cols + c])
    }

    /// Whether cell (col, row) is free.
    pub fn cell_free(&self, col: usize, row: usize) -> bool {
        col < self.cols && row < self.rows && self.free[row * self.cols + col]
    }

    /// Number of free cells.
    pub fn free_cell_count(&self) -> usize {
        self.free.iter().filter(|f| **f).count()
    }

    fn free_i(&self, c: i64, r: i64) -> bool {
        c >= 0
            && r >= 0
            && (c as usize) < self.cols
            && (r as usize) < self.rows
            && self.free[r as usize * self.cols + c as usize]
    }

    /// Nearest free cell to (x, y) within [`ENDPOINT_SNAP_CELLS`], the point's own cell first.
    fn snap(&self, x_m: f64, y_m: f64) -> Option<(usize, usize)> {
        let (c, r) = self.cell_of(x_m, y_m)?;
        if self.free[r * self.cols + c] {
            return Some((c, r));
        }
        let mut best: Option<((usize, usize), f64)> = None;
        for dr in -ENDPOINT_SNAP_CELLS..=ENDPOINT_SNAP_CELLS {
            for dc in -ENDPOINT_SNAP_CELLS..=ENDPOINT_SNAP_CELLS {
                let (cc, rr) = (c as i64 + dc, r as i64 + dr);
                if self.free_i(cc, rr) {
                    let (x, y) = self.cell_center(cc as usize, rr as usize);
                    let d = (x - x_m).hypot(y - y_m);
                    if best.is_none_or(|(_, bd)| d < bd) {
                        best = Some(((cc as usize, rr as usize), d));
                    }
                }
            }
        }
        best.map(|(cell, _)| cell)
    }

    /// Line of sight between two cell centres: every cell the segment passes through is free,
    /// and at an exact corner crossing both side cells are free.
    fn line_of_sight(&self, a: (usize, usize), b: (usize, usize)) -> bool {
        let (mut x, mut y) = (a.0 as i64, a.1 as i64);
        let (dx, dy) = (b.0 as i64 - x, b.1 as i64 - y);
        let (nx, ny) = (dx.abs(), dy.abs());
        let (sx, sy) = (dx.signum(), dy.signum());
        let (mut ix, mut iy) = (0i64, 0i64);
        if !self.free_i(x, y) {
            return false;
        }
        while ix < nx || iy < ny {
            let decision = (1 + 2 * ix) * ny - (1 + 2 * iy) * nx;
            if decision == 0 {
                if !self.free_i(x + sx, y) || !self.free_i(x, y + sy) {
                    return false;
                }
                x += sx;
                y += sy;
                ix += 1;
                iy += 1;
            } else if decision < 0 {
                x += sx;
                ix += 1;
            } else {
                y += sy;
                iy += 1;
            }
            if !self.free_i(x, y) {
                return false;
            }
        }
        true
    }

    /// Shortest any-angle path from `from` to `to`, or `None` when either end is not near a free
    /// cell or no path exists. Corners of the path are cell centres, joined by segments that pass
    /// only free cells; the exact endpoints replace the first and last cell centres. Answered on
    /// the corner visibility graph (exact shortest paths, [`NavEndpoint`]); for many legs between
    /// the same points, build their endpoints once and use
    /// [`OccupancyGrid::path_length_between`].
    pub fn plan(&self, from: (f64, f64), to: (f64, f64)) -> Option<NavPath> {
        let a = self.endpoint(from)?;
        let b = self.endpoint(to)?;
        self.plan_between(&a, &b)
    }

    /// Path length only (m), see [`OccupancyGrid::plan`].
    pub fn path_length_m(&self, from: (f64, f64), to: (f64, f64)) -> Option<f64> {
        let a = self.endpoint(from)?;
        let b = self.endpoint(to)?;
        self.path_length_between(&a, &b)
    }

    /// The same query answered by Lazy Theta* over 8-connected cells (a grid search per query,
    /// ~0.5-1.5 ms in the paper's room): the reference [`OccupancyGrid::plan`] is checked
    /// against, and its fallback.
    pub fn plan_theta_star(&self, from: (f64, f64), to: (f64, f64)) -> Option<NavPath> {
        if !(from.0.is_finite() && from.1.is_finite() && to.0.is_finite() && to.1.is_finite()) {
            return None;
        }
        let start = self.snap(from.0, from.1)?;
        let goal = self.snap(to.0, to.1)?;
        let cells = self.theta_star(start, goal)?;
        Some(self.path_through_cells(from, to, &cells))
    }

    /// The path from `from` through the interior cells of `cells` to `to`.
    fn path_through_cells(
        &self,
        from: (f64, f64),
        to: (f64, f64),
        cells: &[(usize, usize)],
    ) -> NavPath {
        let mut points: Vec<(f64, f64)> = Vec::with_capacity(cells.len() + 2);
        points.push(from);
        for &(c, r) in cells.iter().skip(1).take(cells.len().saturating_sub(2)) {
            points.push(self.cell_center(c, r));
        }
        points.push(to);
        NavPath::through(points)
    }

    fn theta_star(
        &self,
        start: (usize, usize),
        goal: (usize, usize),
    ) -> Option<Vec<(usize, usize)>> {
        let n = self.cols * self.rows;
        let idx = |c: usize, r: usize| r * self.cols + c;
        let dist = |a: usize, b: usize| {
            let (ac, ar) = ((a % self.cols) as f64, (a / self.cols) as f64);
            let (bc, br) = ((b % self.cols) as f64, (b / self.cols) as f64);
            (ac - bc).hypot(ar - br)
        };
        let cell = |i: usize| (i % self.cols, i / self.cols);
        let (s, g) = (idx(start.0, start.1), idx(goal.0, goal.1));
        if s == g {
            return Some(vec![start]);
        }
        if self.line_of_sight(start, goal) {
            return Some(vec![start, goal]);
        }
        let mut g_cost = vec![f64::INFINITY; n];
        let mut parent = vec![usize::MAX; n];
        let mut closed = vec![false; n];
        let mut open = BinaryHeap::new();
        g_cost[s] = 0.0;
        parent[s] = s;
        open.push(OpenEntry {
            f: dist(s, g),
            g: 0.0,
            index: s,
        });
        while let Some(entry) = open.pop() {
            let u = entry.index;
            if closed[u] || entry.g > g_cost[u] {
                continue;
            }
            // Lazy Theta*: the parent was assumed visible when u was reached; check it now and
            // fall back to the best closed neighbour if not.
            if parent[u] != u && !self.line_of_sight(cell(parent[u]), cell(u)) {
                let (uc, ur) = (cell(u).0 as i64, cell(u).1 as i64);
                let mut best = (f64::INFINITY, usize::MAX);
                for (dc, dr) in NEIGHBOURS {
                    let (c, r) = (uc + dc, ur + dr);
                    if !self.free_i(c, r) || !self.step_allowed(uc, ur, dc, dr) {
                        continue;
                    }
                    let v = idx(c as usize, r as usize);
                    if closed[v] {
                        let cand = g_cost[v] + dist(v, u);
                        if cand < best.0 {
                            best = (cand, v);
                        }
                    }
                }
                if best.1 == usize::MAX {
                    continue;
                }
                g_cost[u] = best.0;
                parent[u] = best.1;
            }
            closed[u] = true;
            if u == g {
                let mut path = vec![goal];
                let mut v = g;
                while v != s {
                    v = parent[v];
                    path.push(cell(v));
                }
                path.reverse();
                return Some(path);
            }
            let (uc, ur) = (cell(u).0 as i64, cell(u).1 as i64);
            for (dc, dr) in NEIGHBOURS {
                let (c, r) = (uc + dc, ur + dr);
                if !self.free_i(c, r) || !self.step_allowed(uc, ur, dc, dr) {
                    continue;
                }
                let v = idx(c as usize, r as usize);
                if closed[v] {
                    continue;
                }
                let p = parent[u];
                let cand = g_cost[p] + dist(p, v);
                if cand < g_cost[v] {
                    g_cost[v] = cand;
                    parent[v] = p;
                    open.push(OpenEntry {
                        f: cand + dist(v, g),
                        g: cand,
                        index: v,
                    });
                }
            }
        }
        None
    }

    /// Labels the connected parts of the free space (flood fill with the planner's moves).
    fn label_components(&self) -> Vec<u32> {
        let mut label = vec![u32::MAX; self.cols * self.rows];
        let mut stack = Vec::new();
        let mut next = 0u32;
        for start in 0..label.len() {
            if !self.free[start] || label[start] != u32::MAX {
                continue;
            }
            label[start] = next;
            stack.push(start);
            while let Some(u) = stack.pop() {
                let (uc, ur) = ((u % self.cols) as i64, (u / self.cols) as i64);
                for (dc, dr) in NEIGHBOURS {
                    let (c, r) = (uc + dc, ur + dr);
                    if self.free_i(c, r) && self.step_allowed(uc, ur, dc, dr) {
                        let v = r as usize * self.cols + c as usize;
                        if label[v] == u32::MAX {
                            label[v] = next;
                            stack.push(v);
                        }
                    }
                }
            }
            next += 1;
        }
        label
    }

    /// A diagonal step may not squeeze between two blocked cells.
    fn step_allowed(&self, c: i64, r: i64, dc: i64, dr: i64) -> bool {
        dc == 0 || dr == 0 || (self.free_i(c + dc, r) && self.free_i(c, r + dr))
    }
}

/// The eight moves of the grid search.
const NEIGHBOURS: [(i64, i64); 8] = [
    (1, 0),
    (-1, 0),
    (0, 1),
    (0, -1),
    (1, 1),
    (1, -1),
    (-1, 1),
    (-1, -1),
];

#[derive(Clone, Copy, Debug)]
struct OpenEntry {
    f: f64,
    g: f64,
    index: usize,
}

impl PartialEq for OpenEntry {
    fn eq(&self, other: &Self) -> bool {
        self.cmp(other) == Ordering::Equal
    }
}
impl Eq for OpenEntry {}
impl PartialOrd for OpenEntry {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}
impl Ord for OpenEntry {
    /// Min-heap on f, then larger g first (deeper nodes), then lower index: deterministic.
    fn cmp(&self, other: &Self) -> Ordering {
        other
            .f
            .total_cmp(&self.f)
            .then_with(|| self.g.total_cmp(&other.g))
            .then_with(|| other.index.cmp(&self.index))
    }
}
