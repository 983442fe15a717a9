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
#![allow(
    unsafe_code,
    reason = "AVX2 min-relaxation of the all-pairs distances, behind runtime feature detection"
)]

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

/// Which corners some cells see, one bit per (cell, corner): the line-of-sight checks of
/// [`OccupancyGrid::endpoint`] done once per map for the cells where endpoints will be
/// ([`OccupancyGrid::precompute_endpoint_sight`]), so that connecting an endpoint there is a
/// scan over its cell's bits.
#[derive(Clone, Debug, Default)]
pub(super) struct SightTable {
    /// 64-bit words per cell.
    words: usize,
    /// Per cell (row-major): its row of `bits`, or `u32::MAX` when not precomputed.
    row_of: Vec<u32>,
    /// `bits[row * words + j / 64] >> (j % 64) & 1`: the row's cell sees corner j.
    bits: Vec<u64>,
}

impl SightTable {
    /// The table of `grid`'s free cells among `cells` (row-major indices) against every corner.
    fn build(grid: &OccupancyGrid, cells: impl Iterator<Item = usize>) -> Self {
        let words = grid.graph.len().div_ceil(64);
        let mut row_of = vec![u32::MAX; grid.cols * grid.rows];
        let mut bits = Vec::new();
        for cell in cells {
            if !grid.free[cell] || row_of[cell] != u32::MAX {
                continue;
            }
            let (c, r) = (cell % grid.cols, cell / grid.cols);
            row_of[cell] = (bits.len() / words.max(1)) as u32;
            let start = bits.len();
            bits.resize(start + words, 0);
            let row = &mut bits[start..];
            for (j, &corner) in grid.graph.corners.iter().enumerate() {
                if grid.line_of_sight((c, r), corner) {
                    row[j / 64] |= 1 << (j % 64);
                }
            }
        }
        Self {
            words,
            row_of,
            bits,
        }
    }

    /// Corners seen from `cell` (row-major index), in increasing order, if precomputed.
    fn seen_from(&self, cell: usize) -> Option<impl Iterator<Item = usize> + '_> {
        let row = *self.row_of.get(cell)? as usize;
        if row == u32::MAX as usize {
            return None;
        }
        let words = &self.bits[row * self.words..(row + 1) * self.words];
        Some(words.iter().enumerate().flat_map(|(w, &word)| {
            let mut rest = word;
            std::iter::from_fn(move || {
                if rest == 0 {
                    return None;
                }
                let bit = rest.trailing_zeros() as usize;
                rest &= rest - 1;
                Some(w * 64 + bit)
            })
        }))
    }

    /// Cells precomputed.
    fn cells(&self) -> usize {
        self.bits.len() / self.words.max(1)
    }

    /// Bytes held.
    fn bytes(&self) -> usize {
        self.bits.len() * std::mem::size_of::<u64>() + self.row_of.len() * 4
    }
}

/// `to[j] = min(to[j], d + row[j])` for every j: a select per slot, no index, so it compiles to
/// packed adds and minimums (4 wide where the CPU has AVX2, detected once; the same values
/// either way: no fused operation, and the minimum of two numbers does not depend on the width).
fn relax(to: &mut [f64], row: &[f64], d: f64) {
    #[cfg(target_arch = "x86_64")]
    {
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU has AVX2 (checked just above); the function has no other
            // requirement.
            unsafe { relax_avx2(to, row, d) };
            return;
        }
    }
    relax_generic(to, row, d);
}

#[inline(always)]
fn relax_generic(to: &mut [f64], row: &[f64], d: f64) {
    for (slot, &dij) in to.iter_mut().zip(row) {
        let cand = d + dij;
        *slot = if cand < *slot { cand } else { *slot };
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn relax_avx2(to: &mut [f64], row: &[f64], d: f64) {
    relax_generic(to, row, d);
}

/// What [`OccupancyGrid::precompute_endpoint_sight`] built.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SightStats {
    /// Free cells whose sight was precomputed.
    pub cells: usize,
    /// Bytes of the table.
    pub bytes: usize,
}

/// One endpoint of navigation queries (a start or a goal), connected to the corner graph once:
/// which corners its cell sees, and (when first needed) its shortest distance to every corner.
/// Build it once and ask [`OccupancyGrid::path_length_between`] for every leg that starts or
/// ends there.
#[derive(Clone, Debug)]
pub struct NavEndpoint {
    xy: (f64, f64),
    cell: (usize, usize),
    /// Corners this endpoint's cell sees, in increasing index, with the distance from the exact
    /// point (m).
    visible: Vec<(u32, f64)>,
    /// Shortest distance (m) from the point to each corner through a visible corner, computed
    /// the first time a leg from here needs it (a leg to an endpoint that sees few corners
    /// does not: [`OccupancyGrid::path_length_between`]). Which visible corner a path enters by
    /// is found again only when a path is asked for ([`NavEndpoint::entry_towards`]).
    to_corner: std::sync::OnceLock<Vec<f64>>,
}

impl NavEndpoint {
    /// The exact point (m).
    pub fn xy(&self) -> (f64, f64) {
        self.xy
    }

    /// How many corners this endpoint's cell sees.
    pub fn visible_count(&self) -> usize {
        self.visible.len()
    }

    /// Shortest distances to every corner (computed once).
    fn to_corner(&self, graph: &CornerGraph) -> &[f64] {
        self.to_corner.get_or_init(|| {
            let v = graph.len();
            let mut to = vec![f64::INFINITY; v];
            for &(i, d) in &self.visible {
                relax(
                    &mut to,
                    &graph.dist[i as usize * v..(i as usize + 1) * v],
                    d,
                );
            }
            to
        })
    }

    /// The visible corner the shortest path to corner `j` enters by: the first in index order
    /// whose distance through it is the least (the same choice as a scan keeping strict
    /// improvements).
    fn entry_towards(&self, graph: &CornerGraph, j: usize) -> u32 {
        let v = graph.len();
        let mut best = (f64::INFINITY, u32::MAX);
        for &(i, d) in &self.visible {
            let cand = d + graph.dist[i as usize * v + j];
            if cand < best.0 {
                best = (cand, i);
            }
        }
        best.1
    }
}

/// Most corners the far end of a leg may see for the leg to be taken pair by pair (visible
/// corner of one end against visible corner of the other) instead of through the near end's
/// distances to every corner.
const PAIRWISE_MAX_VISIBLE: usize = 64;

impl OccupancyGrid {
    /// Precomputes which corners of the graph each free cell in `boxes` (world `(x_min, x_max,
    /// y_min, y_max)`, grown by [`super::ENDPOINT_SNAP_CELLS`]) sees: one line-of-sight check per
    /// cell and corner, once per map, replacing any earlier table. Every later
    /// [`OccupancyGrid::endpoint`] whose cell is in the table reads its bits instead of checking
    /// each corner: the same endpoints and path lengths, bit for bit; other cells are checked as
    /// before. Worth it for the places where decisions put endpoints (the goal bands along the
    /// table, the station, the start), when many decisions run on one map (the onboard planner).
    pub fn precompute_endpoint_sight(&mut self, boxes: &[(f64, f64, f64, f64)]) -> SightStats {
        let mut cells = Vec::new();
        for &(x0, x1, y0, y1) in boxes {
            if !(x0.is_finite() && x1.is_finite() && y0.is_finite() && y1.is_finite()) {
                continue;
            }
            let grow = super::ENDPOINT_SNAP_CELLS as f64 * super::NAV_CELL_M;
            let (c0, r0) = self.cell_of_clamped(x0.min(x1) - grow, y0.min(y1) - grow);
            let (c1, r1) = self.cell_of_clamped(x0.max(x1) + grow, y0.max(y1) + grow);
            for r in r0..=r1 {
                cells.extend((c0..=c1).map(|c| r * self.cols + c));
            }
        }
        let table = SightTable::build(self, cells.into_iter());
        let stats = SightStats {
            cells: table.cells(),
            bytes: table.bytes(),
        };
        self.sight = Some(table);
        stats
    }

    /// Whether [`OccupancyGrid::precompute_endpoint_sight`] covers the cell of `xy`'s endpoint.
    pub fn has_endpoint_sight(&self, xy: (f64, f64)) -> bool {
        let Some(table) = &self.sight else {
            return false;
        };
        xy.0.is_finite()
            && xy.1.is_finite()
            && self
                .snap(xy.0, xy.1)
                .is_some_and(|(c, r)| table.seen_from(r * self.cols + c).is_some())
    }

    /// Connects `xy` to the corner graph once per map, with its distances to every corner, and
    /// keeps it: every later [`OccupancyGrid::endpoint`] at exactly `xy` is a copy (the loading
    /// station: a leg from it to each goal, every decision). Returns false when `xy` is not near
    /// a free cell. The same endpoint and lengths as without, bit for bit.
    pub fn keep_endpoint(&mut self, xy: (f64, f64)) -> bool {
        let Some(endpoint) = self.endpoint(xy) else {
            return false;
        };
        endpoint.to_corner(&self.graph);
        self.kept_endpoints.retain(|e| e.xy != xy);
        self.kept_endpoints.push(endpoint);
        true
    }

    /// Connects a point to the corner graph, or `None` when the point is not within
    /// [`super::ENDPOINT_SNAP_CELLS`] of a free cell (or not finite).
    pub fn endpoint(&self, xy: (f64, f64)) -> Option<NavEndpoint> {
        if !(xy.0.is_finite() && xy.1.is_finite()) {
            return None;
        }
        if let Some(kept) = self
            .kept_endpoints
            .iter()
            .find(|e| e.xy.0.to_bits() == xy.0.to_bits() && e.xy.1.to_bits() == xy.1.to_bits())
        {
            return Some(kept.clone());
        }
        let cell = self.snap(xy.0, xy.1)?;
        let g = &self.graph;
        let v = g.len();
        // `sqrt` of the sum of squares, not `hypot`: no overflow is possible at room scale, and
        // libm's `hypot` was a tenth of a decision.
        let distance = |i: usize| {
            let (x, y) = self.cell_center(g.corners[i].0, g.corners[i].1);
            let (dx, dy) = (x - xy.0, y - xy.1);
            (dx * dx + dy * dy).sqrt()
        };
        let seen = self
            .sight
            .as_ref()
            .and_then(|table| table.seen_from(cell.1 * self.cols + cell.0));
        let visible: Vec<(u32, f64)> = match seen {
            Some(seen) => seen.map(|i| (i as u32, distance(i))).collect(),
            None => (0..v)
                .filter(|&i| self.line_of_sight(cell, g.corners[i]))
                .map(|i| (i as u32, distance(i)))
                .collect(),
        };
        Some(NavEndpoint {
            xy,
            cell,
            visible,
            to_corner: std::sync::OnceLock::new(),
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
            Route::Corners { leave, .. } => {
                let enter = a.entry_towards(&self.graph, leave as usize);
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
        let g = &self.graph;
        let v = g.len();
        let mut best = (f64::INFINITY, u32::MAX);
        let pairwise = a.to_corner.get().is_none()
            && b.visible.len() <= PAIRWISE_MAX_VISIBLE
            && 4 * b.visible.len() < v;
        if pairwise {
            // `to_corner[j]` for just b's corners: the minimum over the same candidates, so the
            // same values as the full distances would give, bit for bit.
            let mut via = [f64::INFINITY; PAIRWISE_MAX_VISIBLE];
            let via = &mut via[..b.visible.len()];
            for &(i, d) in &a.visible {
                let row = &g.dist[i as usize * v..(i as usize + 1) * v];
                for (slot, &(j, _)) in via.iter_mut().zip(&b.visible) {
                    let cand = d + row[j as usize];
                    *slot = if cand < *slot { cand } else { *slot };
                }
            }
            for (&to_j, &(j, d)) in via.iter().zip(&b.visible) {
                let cand = to_j + d;
                if cand < best.0 {
                    best = (cand, j);
                }
            }
        } else {
            let to = a.to_corner(g);
            for &(j, d) in &b.visible {
                let cand = to[j as usize] + d;
                if cand < best.0 {
                    best = (cand, j);
                }
            }
        }
        if best.0.is_finite() {
            Route::Corners {
                length_m: best.0,
                leave: best.1,
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

    /// The per-map sight table changes nothing: every endpoint sees the same corners at the same
    /// distances, and every path length and path is the same, bit for bit, as with a
    /// line-of-sight check per corner; blocked cells see nothing.
    #[test]
    fn sight_table_gives_the_same_endpoints_and_paths() {
        use rand::{RngExt, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(12);
        for (seed, chairs) in [(1, 15), (2, 20), (5, 25), (9, 0)] {
            let scene = evaluation_scene(seed, chairs, 6);
            let plain = OccupancyGrid::from_scene(&scene, &RobotConfig::default());
            let mut sighted = plain.clone();
            let room = scene.room;
            let start = (scene.robot_start.x_m, scene.robot_start.y_m);
            assert!(!sighted.has_endpoint_sight(start));
            // The whole room on one seed, a band holding half the points on the others.
            let boxes = if seed == 1 {
                vec![(room.x_min_m, room.x_max_m, room.y_min_m, room.y_max_m)]
            } else {
                let mid = 0.5 * (room.y_min_m + room.y_max_m);
                vec![
                    (room.x_min_m, room.x_max_m, room.y_min_m, mid),
                    (start.0, start.0, start.1, start.1),
                ]
            };
            let stats = sighted.precompute_endpoint_sight(&boxes);
            assert!(sighted.has_endpoint_sight(start));
            let free_cells = plain.free_cell_count();
            if seed == 1 {
                assert_eq!(stats.cells, free_cells);
            } else {
                assert!(
                    stats.cells > free_cells / 4 && stats.cells < free_cells,
                    "{stats:?}"
                );
            }
            let table = sighted.sight.as_ref().expect("built");
            for cell in 0..plain.cols * plain.rows {
                if !plain.free[cell] {
                    assert!(table.seen_from(cell).is_none());
                }
            }
            let points: Vec<(f64, f64)> = (0..40)
                .map(|_| {
                    (
                        rng.random_range(room.x_min_m..room.x_max_m),
                        rng.random_range(room.y_min_m..room.y_max_m),
                    )
                })
                .chain([(scene.robot_start.x_m, scene.robot_start.y_m)])
                .collect();
            let a: Vec<_> = points.iter().map(|&p| plain.endpoint(p)).collect();
            let b: Vec<_> = points.iter().map(|&p| sighted.endpoint(p)).collect();
            let mut compared = 0;
            for (ea, eb) in a.iter().zip(&b) {
                match (ea, eb) {
                    (Some(ea), Some(eb)) => {
                        assert_eq!(ea.visible, eb.visible);
                        assert_eq!(ea.to_corner(&plain.graph), eb.to_corner(&sighted.graph));
                    }
                    (None, None) => {}
                    _ => panic!("endpoint connected in one grid only"),
                }
            }
            for i in 0..points.len() {
                for j in 0..points.len() {
                    if let (Some(pa), Some(pb), Some(sa), Some(sb)) = (&a[i], &a[j], &b[i], &b[j]) {
                        let length = plain.path_length_between(pa, pb);
                        assert_eq!(length, sighted.path_length_between(sa, sb));
                        let path = plain.plan_between(pa, pb);
                        assert_eq!(path, sighted.plan_between(sa, sb));
                        compared += 1;
                    }
                }
            }
            assert!(compared > 400, "{compared} legs compared");
        }
    }

    /// A leg taken pair by pair (the far end sees few corners) has the same length and path, bit
    /// for bit, as through the near end's distances to every corner; a kept endpoint answers as
    /// a fresh one.
    #[test]
    fn pairwise_legs_and_kept_endpoints_change_nothing() {
        use rand::{RngExt, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(99);
        let mut pairwise = 0;
        for (seed, chairs) in [(3, 15), (4, 20), (8, 25)] {
            let scene = evaluation_scene(seed, chairs, 6);
            let grid = OccupancyGrid::from_scene(&scene, &RobotConfig::default());
            let station = (scene.loading_station.x_m, scene.loading_station.y_m);
            let mut kept = grid.clone();
            assert!(kept.keep_endpoint(station));
            assert!(!kept.keep_endpoint((f64::NAN, 0.0)));
            let room = scene.room;
            let mut points: Vec<(f64, f64)> = vec![station];
            // Goals along the table (few corners in sight) and points anywhere.
            for t in scene.targets.iter().take(6) {
                points.push((t.x_m + rng.random_range(-0.7..0.7), t.y_m - 0.8));
                points.push((t.x_m + rng.random_range(-0.7..0.7), t.y_m + 0.8));
            }
            for _ in 0..10 {
                points.push((
                    rng.random_range(room.x_min_m..room.x_max_m),
                    rng.random_range(room.y_min_m..room.y_max_m),
                ));
            }
            let v = grid.corner_count();
            for &pa in &points {
                for &pb in &points {
                    let (Some(a), Some(b)) = (grid.endpoint(pa), grid.endpoint(pb)) else {
                        continue;
                    };
                    if b.visible.len() <= PAIRWISE_MAX_VISIBLE && 4 * b.visible.len() < v {
                        pairwise += 1;
                    }
                    let fresh = (grid.path_length_between(&a, &b), grid.plan_between(&a, &b));
                    a.to_corner(&grid.graph);
                    let full = (grid.path_length_between(&a, &b), grid.plan_between(&a, &b));
                    assert_eq!(fresh, full, "{pa:?} -> {pb:?}");
                    let (ka, kb) = (kept.endpoint(pa).unwrap(), kept.endpoint(pb).unwrap());
                    assert_eq!(ka.to_corner.get().is_some(), pa == station);
                    let from_kept = (
                        kept.path_length_between(&ka, &kb),
                        kept.plan_between(&ka, &kb),
                    );
                    assert_eq!(from_kept, full, "kept: {pa:?} -> {pb:?}");
                }
            }
        }
        assert!(pairwise > 100, "{pairwise} pairwise legs");
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
