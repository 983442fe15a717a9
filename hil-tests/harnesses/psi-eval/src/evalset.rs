//! Evaluation sets: freshly generated evaluation scenes (both sides, 15/20/25 chairs, never used
//! for training), their crops, and ground-truth heatmaps from many simulator trials per cell.

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use planner::feasibility::{FeasibilityError, FeasibilityEvaluator, FeasibilityQuery};
use planner::problem::UnloadLocation;
use world::view::render_crop;
use world::{Heatmap, RobotConfig, Scene, Side};

use crate::metrics::{MetricsAccumulator, QualityReport};

/// What to generate.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct EvalSpec {
    /// Seed of the scenes and of the ground-truth trials.
    pub seed: u64,
    /// Number of evaluation scenes; scene i gets `chairs[i % chairs.len()]` chairs.
    pub scenes: usize,
    /// Targets per scene; each is evaluated from both sides.
    pub targets_per_scene: usize,
    /// Ground-truth trials per candidate cell (the issue asks for at least 25).
    pub trials_per_cell: u16,
    /// Chair counts cycled over the scenes (the paper's evaluation uses 15, 20 and 25).
    pub chairs: Vec<usize>,
}

impl Default for EvalSpec {
    fn default() -> Self {
        Self {
            seed: 9_000,
            scenes: 6,
            targets_per_scene: 5,
            trials_per_cell: 25,
            chairs: vec![15, 20, 25],
        }
    }
}

/// Why an evaluation set could not be built.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum EvalSetError {
    /// A count in the spec is zero.
    #[error("evaluation spec field `{0}` must be at least 1")]
    Empty(&'static str),
}

/// One (target, side) with what an evaluator sees and the truth.
#[derive(Clone, Debug)]
pub struct EvalTask {
    /// Index into [`EvalSet::scenes`].
    pub scene: usize,
    /// Object goal (x, y, z) in the world frame [m].
    pub target: [f64; 3],
    /// Side of the table the base stands on.
    pub side: Side,
    /// The overhead crop (`world::view::render_crop`).
    pub crop: [u8; 2048],
    /// Success fraction of `trials_per_cell` trials per candidate cell.
    pub truth: Heatmap,
    /// 1 on the candidate cells where the base, commanded there facing the table, is
    /// collision-free; 0 elsewhere.
    pub free: Heatmap,
}

/// Scenes, robot and tasks of one evaluation.
#[derive(Clone, Debug)]
pub struct EvalSet {
    /// How it was made.
    pub spec: EvalSpec,
    /// The robot the truth was simulated with.
    pub robot: RobotConfig,
    /// The generated scenes.
    pub scenes: Vec<Scene>,
    /// Every (target, side) of every scene.
    pub tasks: Vec<EvalTask>,
}

/// Generates the scenes and simulates the ground truth (parallel over tasks, deterministic).
pub fn build_eval_set(robot: &RobotConfig, spec: &EvalSpec) -> Result<EvalSet, EvalSetError> {
    if spec.scenes == 0 {
        return Err(EvalSetError::Empty("scenes"));
    }
    if spec.targets_per_scene == 0 {
        return Err(EvalSetError::Empty("targets_per_scene"));
    }
    if spec.trials_per_cell == 0 {
        return Err(EvalSetError::Empty("trials_per_cell"));
    }
    if spec.chairs.is_empty() {
        return Err(EvalSetError::Empty("chairs"));
    }
    let scenes: Vec<Scene> = (0..spec.scenes)
        .map(|i| {
            let chairs = spec.chairs[i % spec.chairs.len()];
            world::generate::evaluation_scene(
                world::generate::mix_seed(spec.seed, 0x7073_6900, i as u64),
                chairs,
                spec.targets_per_scene,
            )
        })
        .collect();
    let jobs: Vec<(usize, [f64; 3], Side)> = scenes
        .iter()
        .enumerate()
        .flat_map(|(i, s)| {
            s.targets
                .iter()
                .flat_map(move |t| Side::BOTH.map(|side| (i, t.as_array(), side)))
        })
        .collect();
    let tasks = jobs
        .par_iter()
        .enumerate()
        .map(|(k, &(scene, target, side))| {
            let s = &scenes[scene];
            let seed = world::generate::mix_seed(spec.seed, 0x7472_7574, k as u64);
            EvalTask {
                scene,
                target,
                side,
                crop: render_crop(s, target[0], side),
                free: free_cells(s, robot, target, side),
                truth: trial_sim::ground_truth_heatmap(
                    s,
                    robot,
                    target,
                    side,
                    spec.trials_per_cell,
                    seed,
                ),
            }
        })
        .collect();
    Ok(EvalSet {
        spec: spec.clone(),
        robot: robot.clone(),
        scenes,
        tasks,
    })
}

/// 1 on the candidate cells of (target, side) where the base, commanded to the cell centre facing
/// the table, collides with nothing; 0 elsewhere.
pub fn free_cells(scene: &Scene, robot: &RobotConfig, target: [f64; 3], side: Side) -> Heatmap {
    // The planner's own marking, so the metric sees exactly the cells GROP draws from.
    let mut location = UnloadLocation::from_heatmap(0, side, target, &Heatmap::zeros());
    location.mark_free_cells(scene, robot);
    let mut free = Heatmap::zeros();
    for cell in location.cells.iter().filter(|c| c.free) {
        free.set(cell.row, cell.col, 1.0);
    }
    free
}

/// Largest number of queries per evaluator call: both sides of three targets, as the planner asks.
pub const QUERIES_PER_CALL: usize = 6;

/// Runs `evaluator` on every task of `set` and compares with the truth.
pub fn evaluate(
    evaluator: &mut dyn FeasibilityEvaluator,
    set: &EvalSet,
) -> Result<QualityReport, FeasibilityError> {
    let mut acc = MetricsAccumulator::default();
    let mut out = vec![Heatmap::zeros(); QUERIES_PER_CALL];
    for chunk in set.tasks.chunks(QUERIES_PER_CALL) {
        let queries: Vec<FeasibilityQuery<'_>> = chunk
            .iter()
            .map(|t| FeasibilityQuery {
                scene: &set.scenes[t.scene],
                robot: &set.robot,
                target: t.target,
                side: t.side,
                crop: &t.crop,
            })
            .collect();
        let out = &mut out[..chunk.len()];
        evaluator.evaluate(&queries, out)?;
        for (t, h) in chunk.iter().zip(out.iter()) {
            acc.add(h, &t.truth, Some(&t.free));
        }
    }
    Ok(acc.report(evaluator.name()))
}
