//! A task as the planners see it: the start, the loading station and, per (object, side), the
//! heatmap `h = Psi(IM)` over the candidate area with each cell's world position and whether a
//! base standing there (facing the table) is obstacle-free.
//!
//! [`TaskProblem::from_world`] builds it from a scene: it renders the six crops (three objects),
//! runs the feasibility evaluator once on all of them and keeps the candidate cells. Tests build
//! problems by hand (no world rendering, no FCN).

use world::collision::BaseCollisionChecker;
use world::view::{CANDIDATE_COLS, CANDIDATE_ROWS, cell_center_world, render_crop};
use world::{Heatmap, RobotConfig, Scene, Side};

use crate::feasibility::{FeasibilityError, FeasibilityEvaluator, FeasibilityQuery};
use crate::task::{ObjectId, location_index};

/// Most objects a [`TaskProblem`] holds: 12 place settings of 3 items (issue 13). The
/// single-trip planners ([`crate::methods::Planner`]) plan at most
/// [`crate::task::MAX_OBJECTS`] of them; the multi-trip planner ([`crate::multi_trip`]) all.
pub const MAX_PROBLEM_OBJECTS: usize = 36;

/// Cells in the candidate area (the paper's 24 x 8 px).
pub const CANDIDATE_CELLS: usize = 192;
/// Columns of the candidate area.
const CANDIDATE_WIDTH: usize = 24;

/// One cell of a location's candidate area.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CandidateCell {
    /// Crop row (9..=16).
    pub row: usize,
    /// Crop column (20..=43).
    pub col: usize,
    /// World position of the cell centre (m).
    pub xy: (f64, f64),
    /// A base commanded exactly here, facing the table, collides with nothing.
    pub free: bool,
}

/// One symbolic unloading location `l'` = (object, side) with what the planners need of it.
#[derive(Debug, Clone)]
pub struct UnloadLocation {
    /// The object whose target this is.
    pub object: ObjectId,
    /// The side of the table.
    pub side: Side,
    /// The object's goal (x, y, z) in the world (m).
    pub target: [f64; 3],
    /// `h` over the candidate area, in [`UnloadLocation::cells`] order (row-major over rows
    /// 9..=16, cols 20..=43).
    pub heat: [f32; CANDIDATE_CELLS],
    /// The candidate cells.
    pub cells: [CandidateCell; CANDIDATE_CELLS],
}

impl UnloadLocation {
    /// A location whose candidate cells follow the world's crop geometry around `target`, all
    /// marked free, with heatmap values taken from `heatmap`.
    pub fn from_heatmap(object: ObjectId, side: Side, target: [f64; 3], heatmap: &Heatmap) -> Self {
        let mut heat = [0.0; CANDIDATE_CELLS];
        let mut cells = [CandidateCell {
            row: 0,
            col: 0,
            xy: (0.0, 0.0),
            free: true,
        }; CANDIDATE_CELLS];
        for (i, (row, col)) in candidate_cells().enumerate() {
            heat[i] = heatmap.get(row, col);
            cells[i] = CandidateCell {
                row,
                col,
                xy: cell_center_world(target[0], side, row, col),
                free: true,
            };
        }
        Self {
            object,
            side,
            target,
            heat,
            cells,
        }
    }

    /// Marks each cell free or not by checking the base footprint, facing the table, against the
    /// scene.
    pub fn mark_free_cells(&mut self, scene: &Scene, robot: &RobotConfig) {
        let yaw_rad = self.side.facing_yaw_rad();
        let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
        for c in &self.cells {
            (x0, x1) = (x0.min(c.xy.0), x1.max(c.xy.0));
            (y0, y1) = (y0.min(c.xy.1), y1.max(c.xy.1));
        }
        // Obstacle footprints once per location, then only overlap tests per cell: the same
        // answer as `base_collides` on the whole scene for every cell.
        let checker = BaseCollisionChecker::new(scene, robot, yaw_rad, (x0, x1, y0, y1));
        for c in self.cells.iter_mut() {
            c.free = !checker.collides(c.xy.0, c.xy.1);
        }
    }
}

/// The candidate cells (row, col) in the order used by [`UnloadLocation`].
pub fn candidate_cells() -> impl Iterator<Item = (usize, usize)> {
    CANDIDATE_ROWS.flat_map(|r| CANDIDATE_COLS.map(move |c| (r, c)))
}

/// Index of crop cell (row, col) in [`UnloadLocation::cells`], if it is a candidate cell.
pub fn candidate_index(row: usize, col: usize) -> Option<usize> {
    if CANDIDATE_ROWS.contains(&row) && CANDIDATE_COLS.contains(&col) {
        Some((row - CANDIDATE_ROWS.start()) * CANDIDATE_WIDTH + (col - CANDIDATE_COLS.start()))
    } else {
        None
    }
}

/// Where a decision on `scene` can put navigation endpoints, as world boxes `(x_min, x_max,
/// y_min, y_max)`: the goal bands (the centres of every candidate cell on either side, for
/// targets anywhere along the banquet table), the start and the loading station. The boxes for
/// [`world::nav::OccupancyGrid::precompute_endpoint_sight`]; a goal outside them (a target beyond
/// the table's ends) is still answered, by line-of-sight checks.
pub fn endpoint_regions(scene: &Scene) -> Vec<(f64, f64, f64, f64)> {
    let (x0, x1, _, _) = scene.banquet_table.footprint().bounds();
    let mut boxes = Vec::with_capacity(4);
    for side in [Side::Near, Side::Far] {
        let (mut bx0, mut bx1, mut by0, mut by1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
        for x in [x0, x1] {
            for row in [*CANDIDATE_ROWS.start(), *CANDIDATE_ROWS.end()] {
                for col in [*CANDIDATE_COLS.start(), *CANDIDATE_COLS.end()] {
                    let (cx, cy) = cell_center_world(x, side, row, col);
                    (bx0, bx1) = (bx0.min(cx), bx1.max(cx));
                    (by0, by1) = (by0.min(cy), by1.max(cy));
                }
            }
        }
        boxes.push((bx0, bx1, by0, by1));
    }
    for (x, y) in [
        (scene.robot_start.x_m, scene.robot_start.y_m),
        (scene.loading_station.x_m, scene.loading_station.y_m),
    ] {
        boxes.push((x, x, y, y));
    }
    boxes
}

/// Everything a planner needs for one task.
#[derive(Debug, Clone)]
pub struct TaskProblem {
    /// Where the robot starts (m).
    pub start_xy: (f64, f64),
    /// Where it loads (m).
    pub station_xy: (f64, f64),
    /// `2n` locations, at [`location_index`]`(object, side)`.
    pub locations: Vec<UnloadLocation>,
}

/// Why a task problem could not be built.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ProblemError {
    /// No targets.
    #[error("the task has no unloading targets")]
    NoTargets,
    /// More targets than the planner handles.
    #[error("{0} unloading targets; at most {MAX_PROBLEM_OBJECTS} are supported")]
    TooManyTargets(usize),
    /// A target coordinate is NaN or infinite.
    #[error("unloading target {index} has a non-finite coordinate")]
    BadTarget {
        /// Index of the target in the task.
        index: usize,
    },
    /// The locations do not come as (near, far) pairs per object in `location_index` order.
    #[error("locations are not (near, far) pairs in object order")]
    LocationOrder,
    /// The feasibility evaluator failed.
    #[error("feasibility evaluation: {0}")]
    Feasibility(#[from] FeasibilityError),
}

impl TaskProblem {
    /// Number of objects.
    pub fn n_objects(&self) -> usize {
        self.locations.len() / 2
    }

    /// The location of (object, side).
    pub fn location(&self, object: ObjectId, side: Side) -> &UnloadLocation {
        &self.locations[location_index(object, side)]
    }

    /// Checks the shape: at least one object, at most [`MAX_PROBLEM_OBJECTS`], locations in order.
    pub fn check(&self) -> Result<(), ProblemError> {
        if self.locations.is_empty() {
            return Err(ProblemError::NoTargets);
        }
        if self.locations.len() % 2 != 0 {
            return Err(ProblemError::LocationOrder);
        }
        if self.n_objects() > MAX_PROBLEM_OBJECTS {
            return Err(ProblemError::TooManyTargets(self.n_objects()));
        }
        for (i, l) in self.locations.iter().enumerate() {
            if location_index(l.object, l.side) != i {
                return Err(ProblemError::LocationOrder);
            }
        }
        Ok(())
    }

    /// Builds the problem for `targets` in `scene`: renders each (target, side) crop, evaluates
    /// `Psi` on all of them in one call (Algorithm 1, lines 8-9), and marks the obstacle-free cells.
    pub fn from_world(
        scene: &Scene,
        robot: &RobotConfig,
        targets: &[[f64; 3]],
        evaluator: &mut dyn FeasibilityEvaluator,
    ) -> Result<Self, ProblemError> {
        let crops = Self::render_crops(scene, targets)?;
        Self::from_crops(scene, robot, targets, &crops, evaluator)
    }

    /// Builds the problem from the crops of every (target, side) in [`location_index`] order
    /// (rendered, or cut from a camera frame): Psi on all of them in one call
    /// ([`evaluate_crops`]), then [`from_heatmaps`](Self::from_heatmaps).
    pub fn from_crops(
        scene: &Scene,
        robot: &RobotConfig,
        targets: &[[f64; 3]],
        crops: &[[u8; 2048]],
        evaluator: &mut dyn FeasibilityEvaluator,
    ) -> Result<Self, ProblemError> {
        let mut heatmaps = vec![Heatmap::zeros(); crops.len()];
        evaluate_crops(scene, robot, targets, crops, evaluator, &mut heatmaps)?;
        Ok(Self::from_heatmaps(scene, robot, targets, &heatmaps))
    }

    /// The crops of every (target, side), in [`location_index`] order. Checks the targets.
    pub fn render_crops(
        scene: &Scene,
        targets: &[[f64; 3]],
    ) -> Result<Vec<[u8; 2048]>, ProblemError> {
        check_targets(targets)?;
        Ok((0..2 * targets.len())
            .map(|i| render_crop(scene, targets[i / 2][0], side_of_location(i)))
            .collect())
    }

    /// Builds the problem from heatmaps already computed, one per (target, side) in
    /// [`location_index`] order (e.g. ground truth from the simulator).
    pub fn from_heatmaps(
        scene: &Scene,
        robot: &RobotConfig,
        targets: &[[f64; 3]],
        heatmaps: &[Heatmap],
    ) -> Self {
        let locations = (0..2 * targets.len())
            .map(|i| {
                let mut l = UnloadLocation::from_heatmap(
                    i / 2,
                    side_of_location(i),
                    targets[i / 2],
                    &heatmaps[i],
                );
                l.mark_free_cells(scene, robot);
                l
            })
            .collect();
        Self {
            start_xy: (scene.robot_start.x_m, scene.robot_start.y_m),
            station_xy: (scene.loading_station.x_m, scene.loading_station.y_m),
            locations,
        }
    }
}

/// Psi's heatmaps of `crops`, one crop per (target, side) in [`location_index`] order (target
/// `i / 2` of `targets`, side [`side_of_location`]`(i)`), evaluated in one call into `heatmaps`
/// (Algorithm 1, lines 8-9). The one place crops become feasibility queries.
pub fn evaluate_crops(
    scene: &Scene,
    robot: &RobotConfig,
    targets: &[[f64; 3]],
    crops: &[[u8; 2048]],
    evaluator: &mut dyn FeasibilityEvaluator,
    heatmaps: &mut [Heatmap],
) -> Result<(), FeasibilityError> {
    let queries: Vec<FeasibilityQuery<'_>> = crops
        .iter()
        .enumerate()
        .map(|(i, crop)| FeasibilityQuery {
            scene,
            robot,
            target: targets[i / 2],
            side: side_of_location(i),
            crop,
        })
        .collect();
    evaluator.evaluate(&queries, heatmaps)
}

fn check_targets(targets: &[[f64; 3]]) -> Result<(), ProblemError> {
    if targets.is_empty() {
        return Err(ProblemError::NoTargets);
    }
    if targets.len() > MAX_PROBLEM_OBJECTS {
        return Err(ProblemError::TooManyTargets(targets.len()));
    }
    if let Some(index) = targets
        .iter()
        .position(|t| t.iter().any(|v| !v.is_finite()))
    {
        return Err(ProblemError::BadTarget { index });
    }
    Ok(())
}

/// Side of location index `i` (even = near, odd = far).
pub fn side_of_location(i: usize) -> Side {
    if i % 2 == 0 { Side::Near } else { Side::Far }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn candidate_indexing_round_trips() {
        for (i, (r, c)) in candidate_cells().enumerate() {
            assert_eq!(candidate_index(r, c), Some(i));
        }
        assert_eq!(candidate_cells().count(), CANDIDATE_CELLS);
        assert_eq!(candidate_index(8, 30), None);
        assert_eq!(candidate_index(10, 44), None);
    }

    #[test]
    fn location_from_heatmap_keeps_candidate_values() {
        let mut h = Heatmap::zeros();
        h.set(9, 20, 0.25);
        h.set(16, 43, 0.75);
        h.set(0, 0, 1.0); // outside the candidate area: ignored
        let l = UnloadLocation::from_heatmap(1, Side::Far, [2.0, 6.0, 1.3], &h);
        assert_eq!(l.heat[0], 0.25);
        assert_eq!(l.heat[CANDIDATE_CELLS - 1], 0.75);
        assert_eq!(l.heat.iter().sum::<f32>(), 1.0);
        // Far side cells lie beyond the table centre line.
        assert!(l.cells.iter().all(|c| c.xy.1 > 6.5 && c.xy.1 < 7.1));
    }
}
