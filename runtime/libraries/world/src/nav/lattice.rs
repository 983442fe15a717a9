//! Heading-true base paths: the footprint checked at the heading the base really has.
//!
//! The occupancy grid ([`super::OccupancyGrid`]) calls a cell free when the footprint fits there
//! at *some* heading, which is right for the paper's travel times but not for driving: the base
//! crosses each stretch facing along it and turns in place at the corners (the follower turns
//! in place when the next stretch lies more than about a radian off), so a path through cells
//! free only at another heading, or with a corner where the turn sweeps into a chair, is not a
//! path the base can drive.
//!
//! [`Clearance`] says whether the footprint (grown by a margin) at a pose, along a straight
//! stretch at its heading, or turning in place, is clear of the walls, the furniture and points
//! the range sensor sees that the map does not. [`Clearance::polyline_clear`] checks a path as
//! the base will drive it. [`Lattice`] plans one where the any-heading grid's path fails: A* over
//! (cell, direction of travel) with 16 directions (moves of one cell, a diagonal, or a knight's
//! move), turns in place between neighbouring directions, each state and turn checked at its
//! real heading, the cost the time the base takes (travel at the cruise speed, turns at the yaw
//! rate limit); the lattice path is then shortened by straight stretches checked exactly.
//! Near the path's two ends the footprint is checked without the margin: the base stands where
//! it stands, and a goal next to furniture was chosen by its own checks.

use std::collections::BinaryHeap;

use super::{NAV_CELL_M, NavPath, OpenEntry};
use crate::geometry::OrientedRect;
use crate::robot::RobotConfig;
use crate::scene::{Room, Scene};

/// Directions of travel: one cell, a diagonal, or a knight's move, counterclockwise from +x.
const MOVES: [(i64, i64); DIRECTIONS] = [
    (1, 0),
    (2, 1),
    (1, 1),
    (1, 2),
    (0, 1),
    (-1, 2),
    (-1, 1),
    (-2, 1),
    (-1, 0),
    (-2, -1),
    (-1, -1),
    (-1, -2),
    (0, -1),
    (1, -2),
    (1, -1),
    (2, -1),
];

/// Directions of travel in the lattice.
pub const DIRECTIONS: usize = 16;

/// Near the path's ends (m from the start or the goal) the footprint is checked without the
/// margin.
pub const ENDPOINT_RELAX_M: f64 = 0.35;

/// A start where the bare footprint overlaps something on the map is left unchecked this far
/// (m): the base is there, whatever the map says.
const START_EXEMPT_M: f64 = 0.15;

/// Straight stretches are checked every this many metres.
const LINE_STEP_M: f64 = 0.05;

/// Turns in place are checked every this many radians (10 degrees).
const TURN_STEP_RAD: f64 = 0.1745;

/// Added to each turn in place (s): the base stops and starts again.
const TURN_PENALTY_S: f64 = 0.2;

/// Most lattice states expanded before the search gives up.
const MAX_EXPANSIONS: usize = 400_000;

fn direction_heading(d: usize) -> f64 {
    let (x, y) = MOVES[d % DIRECTIONS];
    (y as f64).atan2(x as f64)
}

/// Heading half-way between direction `d` and `d + 1`.
fn mid_heading(d: usize) -> f64 {
    let a = direction_heading(d);
    let b = direction_heading(d + 1);
    a + 0.5 * planar::wrap_angle(b - a)
}

/// What the base must stay clear of: the room's walls, the furniture's footprints and points
/// (returns the map does not explain), with the footprint grown by a margin on every side.
#[derive(Clone, Debug)]
pub struct Clearance {
    room: Room,
    rects: Vec<OrientedRect>,
    points: Vec<(f64, f64)>,
    length_m: f64,
    width_m: f64,
    margin_m: f64,
}

impl Clearance {
    /// The scene's walls and furniture for `robot`'s footprint grown by `margin_m`.
    pub fn of_scene(scene: &Scene, robot: &RobotConfig, margin_m: f64) -> Self {
        Self {
            room: scene.room,
            rects: scene.furniture_footprints(),
            points: Vec::new(),
            length_m: robot.footprint.length_m + 2.0 * margin_m,
            width_m: robot.footprint.width_m + 2.0 * margin_m,
            margin_m,
        }
    }

    /// The same with `points` (world frame, m) as obstacles too.
    pub fn with_points(&self, points: &[(f64, f64)]) -> Self {
        let mut out = self.clone();
        out.points.extend_from_slice(points);
        out
    }

    /// The margin around the footprint (m).
    pub fn margin_m(&self) -> f64 {
        self.margin_m
    }

    /// Point obstacles held.
    pub fn points(&self) -> &[(f64, f64)] {
        &self.points
    }

    /// The grown footprint at a pose.
    fn footprint(&self, x_m: f64, y_m: f64, yaw_rad: f64) -> OrientedRect {
        OrientedRect::new(x_m, y_m, self.length_m, self.width_m, yaw_rad)
    }

    /// Whether the grown footprint at (`x_m`, `y_m`, `yaw_rad`) is clear.
    pub fn pose_free(&self, x_m: f64, y_m: f64, yaw_rad: f64) -> bool {
        let fp = self.footprint(x_m, y_m, yaw_rad);
        let reach = fp.circumradius_m();
        self.room.contains_rect(&fp)
            && !self.rects.iter().any(|r| {
                let near = reach + r.circumradius_m();
                (r.center_x_m - x_m).powi(2) + (r.center_y_m - y_m).powi(2) <= near * near
                    && r.overlaps(&fp)
            })
            && !self.points.iter().any(|&(px, py)| {
                (px - x_m).powi(2) + (py - y_m).powi(2) <= reach * reach
                    && fp.contains_point(px, py)
            })
    }

    /// Whether the footprint is clear all along the straight stretch from `a` to `b`, facing
    /// along it.
    pub fn line_free(&self, a: (f64, f64), b: (f64, f64)) -> bool {
        self.line_free_with(a, b, &|x, y, yaw| self.pose_free(x, y, yaw))
    }

    fn line_free_with(
        &self,
        a: (f64, f64),
        b: (f64, f64),
        free: &dyn Fn(f64, f64, f64) -> bool,
    ) -> bool {
        let (dx, dy) = (b.0 - a.0, b.1 - a.1);
        let d = dx.hypot(dy);
        if d < 1e-9 {
            return true;
        }
        let yaw = dy.atan2(dx);
        let steps = (d / LINE_STEP_M).ceil() as usize;
        (0..=steps).all(|k| {
            let t = k as f64 / steps as f64;
            free(a.0 + t * dx, a.1 + t * dy, yaw)
        })
    }

    /// Whether turning in place at (`x_m`, `y_m`) from `from_yaw` to `to_yaw`, the shorter way
    /// round, is clear.
    pub fn turn_free(&self, x_m: f64, y_m: f64, from_yaw: f64, to_yaw: f64) -> bool {
        self.turn_free_with(x_m, y_m, from_yaw, to_yaw, &|x, y, yaw| {
            self.pose_free(x, y, yaw)
        })
    }

    fn turn_free_with(
        &self,
        x_m: f64,
        y_m: f64,
        from_yaw: f64,
        to_yaw: f64,
        free: &dyn Fn(f64, f64, f64) -> bool,
    ) -> bool {
        let turn = planar::wrap_angle(to_yaw - from_yaw);
        let steps = (turn.abs() / TURN_STEP_RAD).ceil().max(1.0) as usize;
        (0..=steps).all(|k| free(x_m, y_m, from_yaw + turn * k as f64 / steps as f64))
    }

    /// Whether the base can drive `points` starting at heading `start_yaw`: every straight
    /// stretch clear facing along it, every turn in place at a corner (and at the start, to the
    /// first stretch) clear. Within [`ENDPOINT_RELAX_M`] of the first and the last point the
    /// footprint is checked with `relaxed` (no margin) instead.
    pub fn polyline_clear(
        &self,
        relaxed: &Clearance,
        start_yaw: f64,
        points: &[(f64, f64)],
    ) -> bool {
        let (Some(&first), Some(&last)) = (points.first(), points.last()) else {
            return true;
        };
        self.polyline_clear_between(relaxed, start_yaw, points, first, last)
    }

    /// [`Clearance::polyline_clear`] for a piece of a longer path whose ends are `first` and
    /// `last` (where the margin is relaxed).
    fn polyline_clear_between(
        &self,
        relaxed: &Clearance,
        start_yaw: f64,
        points: &[(f64, f64)],
        first: (f64, f64),
        last: (f64, f64),
    ) -> bool {
        // Where the map says the base already overlaps something (an estimate a little into a
        // chair), it may still leave: the first few centimetres are not checked.
        let stuck = !relaxed.pose_free(first.0, first.1, start_yaw);
        let free = |x: f64, y: f64, yaw: f64| {
            let from_first = (first.0 - x).hypot(first.1 - y);
            if stuck && from_first <= START_EXEMPT_M {
                return true;
            }
            let near = |p: (f64, f64)| (p.0 - x).hypot(p.1 - y) <= ENDPOINT_RELAX_M;
            if from_first <= ENDPOINT_RELAX_M || near(last) {
                relaxed.pose_free(x, y, yaw)
            } else {
                self.pose_free(x, y, yaw)
            }
        };
        let mut heading = start_yaw;
        for w in points.windows(2) {
            let (a, b) = (w[0], w[1]);
            if (b.0 - a.0).hypot(b.1 - a.1) < 1e-9 {
                continue;
            }
            let next = (b.1 - a.1).atan2(b.0 - a.0);
            if !self.turn_free_with(a.0, a.1, heading, next, &free)
                || !self.line_free_with(a, b, &free)
            {
                return false;
            }
            heading = next;
        }
        true
    }
}

/// The footprint's clearance per cell and heading over the room: bit `d` (0..8) set when the
/// footprint fits facing direction `d` (or its opposite), bit `8 + d` when it fits half-way
/// between directions `d` and `d + 1` (a turn in place between them).
#[derive(Clone, Debug)]
struct HeadingMasks {
    masks: Vec<u16>,
}

impl HeadingMasks {
    /// Every cell's mask, each heading tested only against what lies within reach.
    fn build(grid: &LatticeGrid, c: &Clearance, walls: bool) -> Self {
        let mut masks = vec![u16::MAX; grid.cols * grid.rows];
        let headings = Self::headings();
        let reach = 0.5 * c.length_m.hypot(c.width_m);
        let mut clear_where =
            |x0: f64, x1: f64, y0: f64, y1: f64, hits: &dyn Fn(&OrientedRect) -> bool| {
                let (c0, r0) = grid.cell_clamped(x0 - reach, y0 - reach);
                let (c1, r1) = grid.cell_clamped(x1 + reach, y1 + reach);
                for r in r0..=r1 {
                    for col in c0..=c1 {
                        let i = r * grid.cols + col;
                        let (x, y) = grid.center(col, r);
                        for (bit, &yaw) in headings.iter().enumerate() {
                            if masks[i] & (1 << bit) != 0 && hits(&c.footprint(x, y, yaw)) {
                                masks[i] &= !(1 << bit);
                            }
                        }
                    }
                }
            };
        if walls {
            let room = c.room;
            let outside = |fp: &OrientedRect| !room.contains_rect(fp);
            clear_where(
                room.x_min_m,
                room.x_min_m,
                room.y_min_m,
                room.y_max_m,
                &outside,
            );
            clear_where(
                room.x_max_m,
                room.x_max_m,
                room.y_min_m,
                room.y_max_m,
                &outside,
            );
            clear_where(
                room.x_min_m,
                room.x_max_m,
                room.y_min_m,
                room.y_min_m,
                &outside,
            );
            clear_where(
                room.x_min_m,
                room.x_max_m,
                room.y_max_m,
                room.y_max_m,
                &outside,
            );
        }
        for rect in &c.rects {
            let (x0, x1, y0, y1) = rect.bounds();
            clear_where(x0, x1, y0, y1, &|fp: &OrientedRect| fp.overlaps(rect));
        }
        for &(px, py) in &c.points {
            clear_where(px, px, py, py, &|fp: &OrientedRect| {
                fp.contains_point(px, py)
            });
        }
        Self { masks }
    }

    /// The 16 headings of the mask bits.
    fn headings() -> [f64; 16] {
        std::array::from_fn(|bit| {
            if bit < 8 {
                direction_heading(bit)
            } else {
                mid_heading(bit - 8)
            }
        })
    }
}

/// The lattice's cells: the room in [`NAV_CELL_M`] cells.
#[derive(Clone, Copy, Debug)]
struct LatticeGrid {
    x_min_m: f64,
    y_min_m: f64,
    cols: usize,
    rows: usize,
}

impl LatticeGrid {
    fn of_room(room: &Room) -> Self {
        Self {
            x_min_m: room.x_min_m,
            y_min_m: room.y_min_m,
            cols: ((room.x_max_m - room.x_min_m) / NAV_CELL_M).ceil().max(1.0) as usize,
            rows: ((room.y_max_m - room.y_min_m) / NAV_CELL_M).ceil().max(1.0) as usize,
        }
    }

    fn center(&self, col: usize, row: usize) -> (f64, f64) {
        (
            self.x_min_m + (col as f64 + 0.5) * NAV_CELL_M,
            self.y_min_m + (row as f64 + 0.5) * NAV_CELL_M,
        )
    }

    fn cell_clamped(&self, x_m: f64, y_m: f64) -> (usize, usize) {
        let c = ((x_m - self.x_min_m) / NAV_CELL_M).floor();
        let r = ((y_m - self.y_min_m) / NAV_CELL_M).floor();
        (
            c.clamp(0.0, (self.cols - 1) as f64) as usize,
            r.clamp(0.0, (self.rows - 1) as f64) as usize,
        )
    }

    fn cell(&self, x_m: f64, y_m: f64) -> Option<(usize, usize)> {
        let c = ((x_m - self.x_min_m) / NAV_CELL_M).floor();
        let r = ((y_m - self.y_min_m) / NAV_CELL_M).floor();
        (c.is_finite()
            && r.is_finite()
            && c >= 0.0
            && r >= 0.0
            && (c as usize) < self.cols
            && (r as usize) < self.rows)
            .then_some((c as usize, r as usize))
    }
}

/// Heading-true planning over (cell, direction of travel) for one margin: the masks with the
/// margin, and without it for the ends.
#[derive(Clone, Debug)]
pub struct Lattice {
    grid: LatticeGrid,
    strict: Clearance,
    relaxed: Clearance,
    strict_masks: HeadingMasks,
    relaxed_masks: HeadingMasks,
    speed_mps: f64,
    yaw_rate_radps: f64,
}

impl Lattice {
    /// The lattice for `scene` and `robot` with the footprint grown by `margin_m` (none near
    /// the ends).
    pub fn new(scene: &Scene, robot: &RobotConfig, margin_m: f64) -> Self {
        let grid = LatticeGrid::of_room(&scene.room);
        let strict = Clearance::of_scene(scene, robot, margin_m);
        let relaxed = Clearance::of_scene(scene, robot, 0.0);
        Self {
            strict_masks: HeadingMasks::build(&grid, &strict, true),
            relaxed_masks: HeadingMasks::build(&grid, &relaxed, true),
            grid,
            strict,
            relaxed,
            speed_mps: robot.speed_mps.max(0.05),
            yaw_rate_radps: robot.yaw_rate_radps.max(0.1),
        }
    }

    /// The same lattice with `points` (world frame) as obstacles too (returns the range sensor
    /// sees that the map does not explain).
    pub fn with_points(&self, points: &[(f64, f64)]) -> Self {
        if points.is_empty() {
            return self.clone();
        }
        let strict = self.strict.with_points(points);
        let relaxed = self.relaxed.with_points(points);
        let only_points = |c: &Clearance| Clearance {
            rects: Vec::new(),
            ..c.clone()
        };
        let mut strict_masks = self.strict_masks.clone();
        let mut relaxed_masks = self.relaxed_masks.clone();
        for (masks, c) in [
            (&mut strict_masks, only_points(&strict)),
            (&mut relaxed_masks, only_points(&relaxed)),
        ] {
            let extra = HeadingMasks::build(&self.grid, &c, false);
            for (m, e) in masks.masks.iter_mut().zip(extra.masks) {
                *m &= e;
            }
        }
        Self {
            grid: self.grid,
            strict,
            relaxed,
            strict_masks,
            relaxed_masks,
            speed_mps: self.speed_mps,
            yaw_rate_radps: self.yaw_rate_radps,
        }
    }

    /// The clearance with the margin.
    pub fn clearance(&self) -> &Clearance {
        &self.strict
    }

    /// The clearance without it (the ends).
    pub fn relaxed(&self) -> &Clearance {
        &self.relaxed
    }

    /// Whether `points`, driven from heading `start_yaw`, are clear at their real headings
    /// (the margin away from the ends): [`Clearance::polyline_clear`].
    pub fn drivable(&self, start_yaw: f64, points: &[(f64, f64)]) -> bool {
        self.strict.polyline_clear(&self.relaxed, start_yaw, points)
    }

    /// A heading-true path from `from` (the base facing `from_yaw`) to `to`, or `None`.
    pub fn plan(&self, from: (f64, f64), from_yaw: f64, to: (f64, f64)) -> Option<NavPath> {
        let raw = self.search(from, from_yaw, to)?;
        let points = self.shorten(from_yaw, &raw)?;
        Some(NavPath::through(points))
    }

    fn mask(&self, col: usize, row: usize, near_end: bool) -> u16 {
        let i = row * self.grid.cols + col;
        if near_end {
            self.relaxed_masks.masks[i]
        } else {
            self.strict_masks.masks[i]
        }
    }

    /// A* over (cell, direction): the corners of the cheapest route, `from` first, `to` last.
    #[allow(
        clippy::too_many_lines,
        reason = "one A* search: the start, the expansion by moves and turns, the path read back"
    )]
    fn search(&self, from: (f64, f64), from_yaw: f64, to: (f64, f64)) -> Option<Vec<(f64, f64)>> {
        let g = self.grid;
        let (sc, sr) = g.cell(from.0, from.1)?;
        let (gc, gr) = g.cell(to.0, to.1)?;
        let near_end = |c: usize, r: usize| {
            let (x, y) = g.center(c, r);
            (x - from.0).hypot(y - from.1) <= ENDPOINT_RELAX_M
                || (x - to.0).hypot(y - to.1) <= ENDPOINT_RELAX_M
        };
        // The start cell: the base is there; if the map says even the bare footprint does not
        // fit (an estimate a little into a chair), it may still turn and leave.
        let start_mask = match self.mask(sc, sr, true) {
            0 => u16::MAX,
            m => m,
        };
        let mask_at = |c: usize, r: usize| {
            if (c, r) == (sc, sr) {
                start_mask
            } else {
                self.mask(c, r, near_end(c, r))
            }
        };
        if mask_at(gc, gr) & 0x00ff == 0 {
            return None;
        }
        let d0 = (0..DIRECTIONS)
            .min_by(|&a, &b| {
                let ea = planar::wrap_angle(direction_heading(a) - from_yaw).abs();
                let eb = planar::wrap_angle(direction_heading(b) - from_yaw).abs();
                ea.total_cmp(&eb)
            })
            .unwrap_or(0);
        let states = g.cols * g.rows * DIRECTIONS;
        let index = |c: usize, r: usize, d: usize| (r * g.cols + c) * DIRECTIONS + d;
        let mut cost = vec![f64::INFINITY; states];
        let mut parent = vec![usize::MAX; states];
        let mut heap = BinaryHeap::new();
        let h = |c: usize, r: usize| {
            let (x, y) = g.center(c, r);
            (x - to.0).hypot(y - to.1) / self.speed_mps
        };
        let start = index(sc, sr, d0);
        cost[start] = 0.0;
        heap.push(OpenEntry {
            f: h(sc, sr),
            g: 0.0,
            index: start,
        });
        let mut expansions = 0usize;
        let mut reached = None;
        while let Some(OpenEntry { index: s, .. }) = heap.pop() {
            let d = s % DIRECTIONS;
            let cell = s / DIRECTIONS;
            let (c, r) = (cell % g.cols, cell / g.cols);
            if (c, r) == (gc, gr) {
                reached = Some(s);
                break;
            }
            expansions += 1;
            if expansions > MAX_EXPANSIONS {
                return None;
            }
            let here = mask_at(c, r);
            // Turns in place to the neighbouring directions.
            for (nd, mid_bit) in [
                ((d + 1) % DIRECTIONS, 8 + d % 8),
                (
                    (d + DIRECTIONS - 1) % DIRECTIONS,
                    8 + (d + DIRECTIONS - 1) % 8,
                ),
            ] {
                if here & (1 << (nd % 8)) == 0 || here & (1 << mid_bit) == 0 {
                    continue;
                }
                let turn = planar::wrap_angle(direction_heading(nd) - direction_heading(d)).abs();
                let cand = cost[s] + turn / self.yaw_rate_radps + TURN_PENALTY_S;
                relax(
                    &mut cost,
                    &mut parent,
                    &mut heap,
                    s,
                    index(c, r, nd),
                    cand,
                    h(c, r),
                );
            }
            // A move along the direction faced.
            let (mx, my) = MOVES[d];
            let (nc, nr) = (c as i64 + mx, r as i64 + my);
            if nc < 0 || nr < 0 || nc as usize >= g.cols || nr as usize >= g.rows {
                continue;
            }
            let (nc, nr) = (nc as usize, nr as usize);
            let bit = 1 << (d % 8);
            if mask_at(nc, nr) & bit == 0 {
                continue;
            }
            // A knight's move passes between two cells half-way: both must fit.
            if mx.abs() + my.abs() == 3 {
                let (c0, r0) = (c as i64, r as i64);
                // (2, 1): half-way lies between (c+1, r) and (c+1, r+1); (1, 2) likewise.
                let (a, b) = if mx.abs() == 2 {
                    ((c0 + mx / 2, r0), (c0 + mx / 2, r0 + my))
                } else {
                    ((c0, r0 + my / 2), (c0 + mx, r0 + my / 2))
                };
                let fits = |(x, y): (i64, i64)| mask_at(x as usize, y as usize) & bit != 0;
                if !fits(a) || !fits(b) {
                    continue;
                }
            }
            let step_m = ((mx * mx + my * my) as f64).sqrt() * NAV_CELL_M;
            let cand = cost[s] + step_m / self.speed_mps;
            relax(
                &mut cost,
                &mut parent,
                &mut heap,
                s,
                index(nc, nr, d),
                cand,
                h(nc, nr),
            );
        }
        let mut s = reached?;
        let mut cells = Vec::new();
        loop {
            let cell = s / DIRECTIONS;
            let p = g.center(cell % g.cols, cell / g.cols);
            if cells.last() != Some(&p) {
                cells.push(p);
            }
            match parent[s] {
                usize::MAX => break,
                p => s = p,
            }
        }
        cells.reverse();
        // The real ends instead of their cells' centres.
        if let Some(first) = cells.first_mut() {
            *first = from;
        }
        if cells.len() > 1 {
            let n = cells.len();
            cells[n - 1] = to;
        } else {
            cells.push(to);
        }
        Some(cells)
    }

    /// Shortens the lattice route by straight stretches, each (and each turn in place at its
    /// start) checked exactly at its real heading; `None` if a stretch of the route itself
    /// does not pass the exact check.
    fn shorten(&self, from_yaw: f64, route: &[(f64, f64)]) -> Option<Vec<(f64, f64)>> {
        let n = route.len();
        let mut out = vec![route[0]];
        let mut heading = from_yaw;
        let mut i = 0;
        while i + 1 < n {
            let j = (i + 1..n).rev().find(|&j| {
                let (a, b) = (route[i], route[j]);
                let piece = [a, b];
                self.strict.polyline_clear_between(
                    &self.relaxed,
                    heading,
                    &piece,
                    route[0],
                    route[n - 1],
                )
            })?;
            let (a, b) = (route[i], route[j]);
            if (b.0 - a.0).hypot(b.1 - a.1) > 1e-9 {
                heading = (b.1 - a.1).atan2(b.0 - a.0);
            }
            out.push(b);
            i = j;
        }
        Some(out)
    }
}

/// A* relaxation: reaching `next` from `from` at cost `cand` (s), with the heuristic `h_next`
/// left to go.
fn relax(
    cost: &mut [f64],
    parent: &mut [usize],
    heap: &mut BinaryHeap<OpenEntry>,
    from: usize,
    next: usize,
    cand: f64,
    h_next: f64,
) {
    if cand < cost[next] {
        cost[next] = cand;
        parent[next] = from;
        heap.push(OpenEntry {
            f: cand + h_next,
            g: cand,
            index: next,
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scene_with_chairs(chairs: &[(f64, f64, f64)]) -> Scene {
        let mut scene = Scene::empty_paper_room();
        for &(x, y, yaw) in chairs {
            scene.chairs.push(crate::scene::Chair {
                x_m: x,
                y_m: y,
                yaw_rad: yaw,
                depth_m: 0.45,
                width_m: 0.45,
                height_m: 0.9,
            });
        }
        scene
    }

    #[test]
    fn a_straight_stretch_is_checked_at_its_heading() {
        let robot = RobotConfig::default();
        // Two chairs 0.61 m apart (edge to edge): the base (0.55 m wide, 0.60 m long, 0.59 and
        // 0.64 m with the margin) passes between them facing along the gap, not across it, and
        // not at 45 degrees (0.87 m).
        let scene = scene_with_chairs(&[(0.0, 2.0, 0.0), (1.06, 2.0, 0.0)]);
        let c = Clearance::of_scene(&scene, &robot, 0.02);
        assert!(c.line_free((0.53, 1.0), (0.53, 3.0)));
        assert!(!c.pose_free(0.53, 2.0, 0.0));
        assert!(!c.pose_free(0.53, 2.0, std::f64::consts::FRAC_PI_4));
        // Turning in place between them is not free.
        assert!(!c.turn_free(0.53, 2.0, std::f64::consts::FRAC_PI_2, 0.0));
    }

    #[test]
    fn a_corner_between_chairs_is_planned_around_at_the_real_heading() {
        let robot = RobotConfig::default();
        // A gap the base can only drive straight through: the path must not turn in it.
        let scene = scene_with_chairs(&[(0.0, 2.0, 0.0), (1.06, 2.0, 0.0)]);
        let lattice = Lattice::new(&scene, &robot, 0.02);
        let from = (0.53, 1.0);
        let to = (2.5, 3.2);
        let path = lattice.plan(from, 0.0, to).expect("a path");
        assert!(lattice.drivable(0.0, &path.points), "{path:?}");
        // The path's corners are not inside the gap.
        for p in &path.points[1..path.points.len() - 1] {
            assert!(
                !(p.1 > 1.6 && p.1 < 2.4 && p.0 > 0.1 && p.0 < 1.0),
                "a corner in the gap: {path:?}"
            );
        }
        // A path that turns in the gap is refused by the check.
        assert!(!lattice.drivable(0.0, &[from, (0.53, 2.0), to]));
        // A start the map puts into the loading table's edge still gets a way out.
        let stuck = (0.53, 0.8);
        assert!(!lattice.relaxed().pose_free(stuck.0, stuck.1, 0.0));
        let out = lattice.plan(stuck, 0.0, to).expect("a way out");
        assert!(lattice.drivable(0.0, &out.points), "{out:?}");
    }

    #[test]
    fn points_the_map_does_not_have_are_planned_around() {
        let robot = RobotConfig::default();
        let scene = Scene::empty_paper_room();
        let lattice = Lattice::new(&scene, &robot, 0.1);
        let (from, to) = ((0.0, 1.0), (0.0, 5.0));
        let straight = lattice
            .plan(from, std::f64::consts::FRAC_PI_2, to)
            .expect("a path");
        assert!((straight.length_m - 4.0).abs() < 1e-6, "{straight:?}");
        // A wall of points across the straight way (a chair the map does not know).
        let points: Vec<(f64, f64)> = (0..10)
            .map(|k| (-0.25 + 0.05 * f64::from(k), 3.0))
            .collect();
        let seen = lattice.with_points(&points);
        assert!(!seen.drivable(std::f64::consts::FRAC_PI_2, &straight.points));
        let around = seen
            .plan(from, std::f64::consts::FRAC_PI_2, to)
            .expect("a way round");
        assert!(
            seen.drivable(std::f64::consts::FRAC_PI_2, &around.points),
            "{around:?}"
        );
        assert!(around.length_m > 4.0, "{around:?}");
    }

    #[test]
    fn no_path_when_the_goal_is_walled_in() {
        let robot = RobotConfig::default();
        let scene = Scene::empty_paper_room();
        let lattice = Lattice::new(&scene, &robot, 0.05);
        let ring: Vec<(f64, f64)> = (0..120)
            .map(|k| {
                let a = f64::from(k) * std::f64::consts::TAU / 120.0;
                (1.0 * a.cos(), 4.0 + 1.0 * a.sin())
            })
            .collect();
        let seen = lattice.with_points(&ring);
        assert!(seen.plan((0.0, 1.0), 0.0, (0.0, 4.0)).is_none());
    }
}
