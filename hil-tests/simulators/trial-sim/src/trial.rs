//! One trial of the paper's data collection (section III-B): command the base to a cell centre
//! facing the table, add navigation noise, check the base's footprint against the scene, then
//! ask the arm for a collision-free placing configuration.

use nalgebra::Point3;
use planar::Pose2;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use ur5e_kin::{ObstacleBox, PlaceConfig, PlaceFailure};
use world::generate::mix_seed;
use world::view::{CROP_COLS, CROP_ROWS, Heatmap, Side, cell_center_world, in_candidate_area};
use world::{RobotConfig, Scene, base_collides};

/// How a trial ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TrialResult {
    /// The base stood free and the arm placed the object.
    Success,
    /// The realised base footprint touched a table, a chair or a wall.
    BaseCollision,
    /// No arm configuration puts the object at its goal with the tool pointing down.
    ArmOutOfReach,
    /// Configurations exist but none within the UR5e's joint limits.
    ArmJointLimits,
    /// Every placing configuration within limits hits the scene or the robot itself.
    ArmCollision,
}

impl TrialResult {
    /// All results, in the order of the summary's counters.
    pub const ALL: [TrialResult; 5] = [
        TrialResult::Success,
        TrialResult::BaseCollision,
        TrialResult::ArmOutOfReach,
        TrialResult::ArmJointLimits,
        TrialResult::ArmCollision,
    ];

    /// snake_case name, as in `trials.csv`.
    pub fn name(self) -> &'static str {
        match self {
            TrialResult::Success => "success",
            TrialResult::BaseCollision => "base_collision",
            TrialResult::ArmOutOfReach => "arm_out_of_reach",
            TrialResult::ArmJointLimits => "arm_joint_limits",
            TrialResult::ArmCollision => "arm_collision",
        }
    }

    /// Position in [`TrialResult::ALL`].
    pub fn index(self) -> usize {
        self as usize
    }
}

impl From<PlaceFailure> for TrialResult {
    fn from(failure: PlaceFailure) -> Self {
        match failure {
            PlaceFailure::OutOfReach => TrialResult::ArmOutOfReach,
            PlaceFailure::JointLimits => TrialResult::ArmJointLimits,
            PlaceFailure::Collision => TrialResult::ArmCollision,
        }
    }
}

/// What happened in one trial.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TrialOutcome {
    /// Where the base really stood (goal + N(0, sigma^2 I), facing the table).
    pub realised: Pose2,
    /// How it ended.
    pub result: TrialResult,
}

/// The arm's side of a trial: can the object be placed at `goal` from `base`? The simulator's
/// default is [`Ur5eArm`]; tests and what-if studies plug in others.
pub trait ArmModel: Sync {
    /// `Ok(())` when a collision-free placing configuration exists.
    fn place(
        &self,
        place: &PlaceConfig,
        base: Pose2,
        goal: Point3<f64>,
        obstacles: &[ObstacleBox],
    ) -> Result<(), PlaceFailure>;
}

/// The UR5e of ur5e-kin: closed-form IK, joint limits, collision with boxes.
#[derive(Clone, Copy, Debug, Default)]
pub struct Ur5eArm;

impl ArmModel for Ur5eArm {
    fn place(
        &self,
        place: &PlaceConfig,
        base: Pose2,
        goal: Point3<f64>,
        obstacles: &[ObstacleBox],
    ) -> Result<(), PlaceFailure> {
        ur5e_kin::plan_place(place, base, goal, obstacles).map(|_| ())
    }
}

/// Runs trials in one scene, reusing its scratch buffers (no allocation per trial once warm).
pub struct TrialSimulator<'a, A: ArmModel = Ur5eArm> {
    scene: &'a Scene,
    robot: &'a RobotConfig,
    arm: A,
    obstacles: Vec<ObstacleBox>,
}

impl<'a> TrialSimulator<'a, Ur5eArm> {
    /// A simulator with the UR5e arm.
    pub fn new(scene: &'a Scene, robot: &'a RobotConfig) -> Self {
        Self::with_arm(scene, robot, Ur5eArm)
    }
}

impl<'a, A: ArmModel> TrialSimulator<'a, A> {
    /// A simulator with another arm model.
    pub fn with_arm(scene: &'a Scene, robot: &'a RobotConfig, arm: A) -> Self {
        Self {
            scene,
            robot,
            arm,
            obstacles: Vec::with_capacity(16),
        }
    }

    /// One trial: base commanded to `commanded_xy` facing the table from `side`, object goal
    /// `target` (world, m). The realised position is commanded + N(0, sigma^2 I); yaw is exact.
    pub fn run<R: Rng + ?Sized>(
        &mut self,
        target: [f64; 3],
        side: Side,
        commanded_xy: (f64, f64),
        rng: &mut R,
    ) -> TrialOutcome {
        let sigma = self.robot.nav_noise_sigma_m;
        let dx: f64 = StandardNormal.sample(rng);
        let dy: f64 = StandardNormal.sample(rng);
        let realised = Pose2 {
            x_m: commanded_xy.0 + sigma * dx,
            y_m: commanded_xy.1 + sigma * dy,
            yaw_rad: side.facing_yaw_rad(),
        };
        let result = self.evaluate(target, realised);
        TrialOutcome { realised, result }
    }

    /// The deterministic part of a trial: does the base collide at `base`, and can the arm place
    /// the object from there?
    pub fn evaluate(&mut self, target: [f64; 3], base: Pose2) -> TrialResult {
        if base_collides(self.scene, self.robot, base) {
            return TrialResult::BaseCollision;
        }
        self.scene
            .obstacle_boxes_into(self.robot, base, &mut self.obstacles);
        let goal = Point3::new(target[0], target[1], target[2]);
        match self
            .arm
            .place(&self.robot.place, base, goal, &self.obstacles)
        {
            Ok(()) => TrialResult::Success,
            Err(failure) => failure.into(),
        }
    }
}

/// One trial with the UR5e (see [`TrialSimulator::run`]; use the simulator directly in loops).
pub fn run_trial<R: Rng + ?Sized>(
    scene: &Scene,
    robot: &RobotConfig,
    target: [f64; 3],
    side: Side,
    commanded_xy: (f64, f64),
    rng: &mut R,
) -> TrialOutcome {
    TrialSimulator::new(scene, robot).run(target, side, commanded_xy, rng)
}

/// Which crop cells get trials.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum HeatmapArea {
    /// The paper's 24 x 8 candidate cells (the dataset's labels); other cells stay 0.
    Candidate,
    /// All 32 x 64 cells (for pictures).
    WholeCrop,
}

impl HeatmapArea {
    /// Whether (row, col) is simulated.
    pub fn contains(self, row: usize, col: usize) -> bool {
        match self {
            HeatmapArea::Candidate => in_candidate_area(row, col),
            HeatmapArea::WholeCrop => row < CROP_ROWS && col < CROP_COLS,
        }
    }
}

/// The random stream of cell (row, col) of a task: seeded from the task's seed and the cell
/// alone, so results do not depend on the order cells or tasks are simulated in.
pub fn cell_rng(task_seed: u64, row: usize, col: usize) -> ChaCha8Rng {
    ChaCha8Rng::seed_from_u64(mix_seed(task_seed, row as u64, col as u64))
}

/// Per-cell trial counts of one task.
#[derive(Clone, Debug)]
pub struct CellCounts {
    /// Successful trials per cell, row-major 32 x 64.
    pub successes: Vec<u16>,
    /// Trials run per cell (0 outside the simulated area).
    pub trials: Vec<u16>,
}

impl CellCounts {
    /// Success fraction per cell (0 where no trials ran).
    pub fn heatmap(&self) -> Heatmap {
        let mut heatmap = Heatmap::zeros();
        for ((v, &s), &n) in heatmap
            .values_mut()
            .iter_mut()
            .zip(&self.successes)
            .zip(&self.trials)
        {
            *v = if n > 0 {
                f32::from(s) / f32::from(n)
            } else {
                0.0
            };
        }
        heatmap
    }
}

/// Simulates `trials_per_cell` trials at every cell of `area`, calling `record(row, col,
/// trial_index, commanded_xy, outcome)` for each trial. Deterministic for `task_seed`.
#[allow(clippy::too_many_arguments)]
pub fn simulate_cells<A: ArmModel>(
    sim: &mut TrialSimulator<'_, A>,
    target: [f64; 3],
    side: Side,
    area: HeatmapArea,
    trials_per_cell: u16,
    task_seed: u64,
    mut record: impl FnMut(usize, usize, u16, (f64, f64), &TrialOutcome),
) -> CellCounts {
    let mut counts = CellCounts {
        successes: vec![0; CROP_ROWS * CROP_COLS],
        trials: vec![0; CROP_ROWS * CROP_COLS],
    };
    for row in 0..CROP_ROWS {
        for col in 0..CROP_COLS {
            if !area.contains(row, col) {
                continue;
            }
            let commanded = cell_center_world(target[0], side, row, col);
            let mut rng = cell_rng(task_seed, row, col);
            let mut successes = 0u16;
            for trial in 0..trials_per_cell {
                let outcome = sim.run(target, side, commanded, &mut rng);
                if outcome.result == TrialResult::Success {
                    successes += 1;
                }
                record(row, col, trial, commanded, &outcome);
            }
            counts.successes[row * CROP_COLS + col] = successes;
            counts.trials[row * CROP_COLS + col] = trials_per_cell;
        }
    }
    counts
}

/// The ground-truth heatmap of a target and side over the paper's candidate area: success
/// fraction of `trials_per_cell` trials per cell, 0 outside the area. Deterministic for `seed`;
/// cells are independent streams, so callers may parallelise over targets freely.
pub fn ground_truth_heatmap(
    scene: &Scene,
    robot: &RobotConfig,
    target: [f64; 3],
    side: Side,
    trials_per_cell: u16,
    seed: u64,
) -> Heatmap {
    ground_truth_heatmap_in(
        scene,
        robot,
        target,
        side,
        HeatmapArea::Candidate,
        trials_per_cell,
        seed,
    )
}

/// As [`ground_truth_heatmap`] over a chosen area.
pub fn ground_truth_heatmap_in(
    scene: &Scene,
    robot: &RobotConfig,
    target: [f64; 3],
    side: Side,
    area: HeatmapArea,
    trials_per_cell: u16,
    seed: u64,
) -> Heatmap {
    let mut sim = TrialSimulator::new(scene, robot);
    simulate_cells(
        &mut sim,
        target,
        side,
        area,
        trials_per_cell,
        seed,
        |_, _, _, _, _| {},
    )
    .heatmap()
}

/// Ground-truth heatmaps of several (target, side) pairs of one scene, in parallel (rayon).
/// Pair `i` uses the seed `mix_seed(seed, i, 0)`, so the result does not depend on threads.
pub fn ground_truth_heatmaps(
    scene: &Scene,
    robot: &RobotConfig,
    pairs: &[([f64; 3], Side)],
    area: HeatmapArea,
    trials_per_cell: u16,
    seed: u64,
) -> Vec<Heatmap> {
    use rayon::prelude::*;
    pairs
        .par_iter()
        .enumerate()
        .map(|(i, &(target, side))| {
            ground_truth_heatmap_in(
                scene,
                robot,
                target,
                side,
                area,
                trials_per_cell,
                mix_seed(seed, i as u64, 0),
            )
        })
        .collect()
}

/// Task-level feasibility of one heatmap over `area` (paper eq. 4 in closed form): the
/// expectation of Fea^m at a cell drawn by Smp (probability proportional to its value),
/// F = sum(v^2) / sum(v); 0 when every cell is 0.
pub fn task_feasibility(heatmap: &Heatmap, area: HeatmapArea) -> f64 {
    let mut sum = 0.0f64;
    let mut sum_sq = 0.0f64;
    for row in 0..CROP_ROWS {
        for col in 0..CROP_COLS {
            if area.contains(row, col) {
                let v = f64::from(heatmap.get(row, col).max(0.0));
                sum += v;
                sum_sq += v * v;
            }
        }
    }
    if sum > 0.0 { sum_sq / sum } else { 0.0 }
}
