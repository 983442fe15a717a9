//! The corner visibility graph of an occupancy grid: exact shortest any-angle paths between cell
//! centres, answered in microseconds after a per-map precomputation.
//!
//! A shortest path among obstacles bends only where it wraps around a convex corner of an
//! obstacle. On the grid such a corner is a free cell whose diagonal neighbour is blocked while
//! the two cells between them are free: the path passes through that cell's centre. The graph's
//! nodes are these corner cells, its edges the pairs that see each other under the grid's
//! line-of-sight rule, weighted by Euclidean length. All-pairs shortest distances between corners
//! (Floyd-Warshall, with next hops for the paths) are computed once per grid; a query then only
//! connects its two endpoints to the corners they see. Computing that connection once per
//! endpoint ([`NavEndpoint`]) makes every further leg from it a scan over the corners its partner
//! sees.
//!
//! Cost per map: `O(V^2)` line-of-sight checks and `O(V^3)` for the distances, V the number of
//! corner cells (about 160-240 in the paper's room with 15-25 chairs: ~10 ms). Memory `12 V^2`
//! bytes.

use super::{NAV_CELL_M, OccupancyGrid};

/// Corner cells and their all-pairs shortest distances.
#[derive(Clone, Debug, Default)]
pub(super) struct CornerGraph {
    /// Corner cells (col, row).
    pub(super) corners: Vec<(usize, usize)>,
    /// `dist[i * V + j]`: shortest path length (m) from corner i to corner j through corners,
    /// infinite when they are not connected.
    dist: Vec<f64>,
    /// `next[i * V + j]`: the corner after i on the shortest path from i to j.
    next: Vec<u32>,
}

/// Most bend cells the graph is built for: Floyd-Warshall is `O(V^3)` (1,500: a few seconds), so a
/// map with more keeps no graph and every query runs Lazy Theta* (correct, ~1 ms a query).
pub const MAX_GRAPH_CORNERS: usize = 1500;

impl CornerGraph {
    /// Builds the graph of `grid`'s free space (empty beyond [`MAX_GRAPH_CORNERS`] bend cells).
    pub(super) fn build(grid: &OccupancyGrid) -> Self {
        Self::build_limited(grid, MAX_GRAPH_CORNERS)
    }

    /// Builds the graph, or an empty one when the map has more than `max_corners` bend cells.
    pub(super) fn build_limited(grid: &OccupancyGrid, max_corners: usize) -> Self {
        // Bend cells: each corner cell (a free cell whose diagonal neighbour is blocked while
        // the two cells between them are free) and those two cells, which are orthogonally next
        // to the blocked cell: a segment through their centres can pass the blocked cell's
        // corner closer than one through the corner cell's centre.
        let mut bend = vec![false; grid.cols * grid.rows];
        for r in 0..grid.rows as i64 {
            for c in 0..grid.cols as i64 {
                if !grid.free_i(c, r) {
                    continue;
                }
                for (dc, dr) in DIAGONALS {
                    if !grid.free_i(c + dc, r + dr)
                        && grid.free_i(c + dc, r)
                        && grid.free_i(c, r + dr)
                    {
                        for (x, y) in [(c, r), (c + dc, r), (c, r + dr)] {
                            bend[y as usize * grid.cols + x as usize] = true;
                        }
                    }
                }
            }
        }
        let corners: Vec<(usize, usize)> = (0..grid.cols * grid.rows)
            .filter(|&i| bend[i])
            .map(|i| (i % grid.cols, i / grid.cols))
            .collect();
        if corners.len() > max_corners {
            log::warn!(
                "navigation map has {} bend cells (limit {max_corners}): no corner graph, every \
                 path query runs Lazy Theta*",
                corners.len()
            );
            return Self::default();
        }
        let v = corners.len();
        let mut dist = vec![f64::INFINITY; v * v];
        let mut next = vec![u32::MAX; v * v];
        for i in 0..v {
            dist[i * v + i] = 0.0;
            next[i * v + i] = i as u32;
            for j in i + 1..v {
                if grid.line_of_sight(corners[i], corners[j]) {
                    let d = cell_distance_m(corners[i], corners[j]);
                    dist[i * v + j] = d;
                    dist[j * v + i] = d;
                    next[i * v + j] = j as u32;
                    next[j * v + i] = i as u32;
                }
            }
        }
        // Floyd-Warshall; strict improvement keeps the result deterministic.
        let mut row_k = vec![0.0; v];
        for k in 0..v {
            row_k.copy_from_slice(&dist[k * v..(k + 1) * v]);
            for i in 0..v {
                let dik = dist[i * v + k];
                if !dik.is_finite() {
                    continue;
                }
                let next_ik = next[i * v + k];
                let row = &mut dist[i * v..(i + 1) * v];
                let nrow = &mut next[i * v..(i + 1) * v];
                for j in 0..v {
                    let cand = dik + row_k[j];
                    if cand < row[j] {
                        row[j] = cand;
                        nrow[j] = next_ik;
                    }
                }
            }
        }
        Self {
            corners,
            dist,
            next,
        }
    }

    /// Number of corner cells.
    pub(super) fn len(&self) -> usize {
        self.corners.len()
    }

    /// Corners from i to j inclusive along the shortest path (i first).
    fn corner_path(&self, i: usize, j: usize, out: &mut Vec<(usize, usize)>) {
        let v = self.corners.len();
        let mut k = i;
        out.push(self.corners[k]);
        while k != j {
            k = self.next[k * v + j] as usize;
            out.push(self.corners[k]);
        }
    }
}

const DIAGONALS: [(i64, i64); 4] = [(1, 1), (1, -1), (-1, 1), (-1, -1)];

fn cell_distance_m(a: (usize, usize), b: (usize, usize)) -> f64 {
    let dc = a.0 as f64 - b.0 as f64;
    let dr = a.1 as f64 - b.1 as f64;
    (dc * dc + dr * dr).sqrt() * NAV_CELL_M
}

/// One endpoint of navigation queries (a start or a goal), connected to the corner graph once:
/// which corners its cell sees, and its shortest distance to every corner. Build it once and
/// ask [`OccupancyGrid::path_length_between`] for every leg that starts or ends there.
#[derive(Clone, Debug)]
pub struct NavEndpoint {
    xy: (f64, f64),
    cell: (usize, usize),
    /// Corners this endpoint's cell sees, with the distance from the exact point (m).
    visible: Vec<(u32, f64)>,
    /// Shortest distance (m) from the point to each corner, and the visible corner it enters by.
    to_corner: Vec<(f64, u32)>,
}

impl NavEndpoint {
    /// The exact point (m).
    pub fn xy(&self) -> (f64, f64) {
        self.xy
    }
}

impl OccupancyGrid {
    /// Connects a point to the corner graph, or `None` when the point is not within
    /// [`super::ENDPOINT_SNAP_CELLS`] of a free cell (or not finite).
    pub fn endpoint(&self, xy: (f64, f64)) -> Option<NavEndpoint> {
        if !(xy.0.is_finite() && xy.1.is_finite()) {
            return None;
        }
        let cell = self.snap(xy.0, xy.1)?;
        let g = &self.graph;
        let v = g.len();
        let mut visible = Vec::new();
        for (i, &corner) in g.corners.iter().enumerate() {
            if self.line_of_sight(cell, corner) {
                let (x, y) = self.cell_center(corner.0, corner.1);
                visible.push((i as u32, (x - xy.0).hypot(y - xy.1)));
            }
        }
        let mut to_corner = vec![(f64::INFINITY, u32::MAX); v];
        for &(i, d) in &visible {
            let row = &g.dist[i as usize * v..(i as usize + 1) * v];
            for (slot, &dij) in to_corner.iter_mut().zip(row) {
                let cand = d + dij;
                if cand < slot.0 {
                    *slot = (cand, i);
                }
            }
        }
        Some(NavEndpoint {
            xy,
            cell,
            visible,
            to_corner,
        })
    }

    /// Length (m) of the shortest any-angle path between two endpoints, `None` when there is
    /// none. Symmetric up to rounding; the same answer as [`OccupancyGrid::plan`]'s path length.
    pub fn path_length_between(&self, a: &NavEndpoint, b: &NavEndpoint) -> Option<f64> {
        match self.route(a, b) {
            Route::Direct => Some((b.xy.0 - a.xy.0).hypot(b.xy.1 - a.xy.1)),
            Route::Corners { length_m, .. } => Some(length_m),
            Route::GridSearch => self.theta_star_path(a, b).map(|p| p.length_m),
            Route::None => None,
        }
    }

    /// The shortest any-angle path between two endpoints.
    pub fn plan_between(&self, a: &NavEndpoint, b: &NavEndpoint) -> Option<NavPath> {
        match self.route(a, b) {
            Route::Direct => Some(NavPath::through(vec![a.xy, b.xy])),
            Route::Corners { enter, leave, .. } => {
                let mut cells = Vec::new();
                self.graph
                    .corner_path(enter as usize, leave as usize, &mut cells);
                let mut points = Vec::with_capacity(cells.len() + 2);
                points.push(a.xy);
                points.extend(cells.iter().map(|&(c, r)| self.cell_center(c, r)));
                points.push(b.xy);
                Some(NavPath::through(points))
            }
            Route::GridSearch => self.theta_star_path(a, b),
            Route::None => None,
        }
    }

    fn route(&self, a: &NavEndpoint, b: &NavEndpoint) -> Route {
        if self.component[a.cell.1 * self.cols + a.cell.0]
            != self.component[b.cell.1 * self.cols + b.cell.0]
        {
            return Route::None;
        }
        if a.cell == b.cell || self.line_of_sight(a.cell, b.cell) {
            return Route::Direct;
        }
        let mut best = (f64::INFINITY, u32::MAX, u32::MAX);
        for &(j, d) in &b.visible {
            let (dj, enter) = a.to_corner[j as usize];
            let cand = dj + d;
            if cand < best.0 {
                best = (cand, enter, j);
            }
        }
        if best.0.is_finite() {
            Route::Corners {
                length_m: best.0,
                enter: best.1,
                leave: best.2,
            }
        } else {
            // Corners cannot connect them (no corner in sight of one end, or separate
            // components): the grid search decides, so connectivity is never lost.
            Route::GridSearch
        }
    }

    fn theta_star_path(&self, a: &NavEndpoint, b: &NavEndpoint) -> Option<NavPath> {
        self.theta_star(a.cell, b.cell)
            .map(|cells| self.path_through_cells(a.xy, b.xy, &cells))
    }

    /// Number of corner cells in the visibility graph (the size of the per-map precomputation).
    pub fn corner_count(&self) -> usize {
        self.graph.len()
    }
}

enum Route {
    /// The endpoints lie in different connected parts of the free space.
    None,
    Direct,
    Corners {
        length_m: f64,
        enter: u32,
        leave: u32,
    },
    GridSearch,
}

use super::NavPath;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::generate::evaluation_scene;
    use crate::robot::RobotConfig;

    /// A map over the corner limit keeps no graph; every query that needs a bend then goes to
    /// the grid search: the same answers as Theta*, connectivity kept.
    #[test]
    fn without_a_corner_graph_the_grid_search_answers() {
        let scene = evaluation_scene(3, 15, 6);
        let mut grid = OccupancyGrid::from_scene(&scene, &RobotConfig::default());
        assert!(grid.corner_count() > 10);
        grid.graph = CornerGraph::build_limited(&grid, 10);
        assert_eq!(grid.corner_count(), 0);
        let from = (scene.robot_start.x_m, scene.robot_start.y_m);
        for to in [(0.0, 7.0), (scene.targets[0].x_m, 6.8), (3.0, 3.0)] {
            let planned = grid.plan(from, to).map(|p| p.points);
            let reference = grid.plan_theta_star(from, to).map(|p| p.points);
            assert_eq!(planned, reference, "to {to:?}");
        }
        assert!(grid.plan(from, (0.0, 7.0)).is_some());
    }

    /// Floyd-Warshall's next hops give a chain of mutually visible corners whose length is the
    /// stored distance.
    #[test]
    fn corner_paths_are_visible_chains_of_the_stored_length() {
        let scene = evaluation_scene(4, 20, 6);
        let grid = OccupancyGrid::from_scene(&scene, &RobotConfig::default());
        let g = &grid.graph;
        let v = g.len();
        let mut out = Vec::new();
        for i in (0..v).step_by(37) {
            for j in (0..v).step_by(29) {
                let d = g.dist[i * v + j];
                if !d.is_finite() {
                    continue;
                }
                out.clear();
                g.corner_path(i, j, &mut out);
                let mut length = 0.0;
                for w in out.windows(2) {
                    assert!(grid.line_of_sight(w[0], w[1]));
                    length += cell_distance_m(w[0], w[1]);
                }
                assert!((length - d).abs() < 1e-9, "{length} vs {d}");
            }
        }
    }
}
