//! The motion-level feasibility evaluator `Psi` (paper eq. 3, `h^y = Psi(IM^y)`) as a trait, so
//! that GROP runs the same with the FCN, a geometric heuristic or the simulator oracle.
//!
//! Contract (shared with `psi-eval` and `fcn-infer`): one [`FeasibilityQuery`] per (target, side)
//! with the crop as `world::view::render_crop` returns it; the evaluator writes one
//! [`Heatmap`] per query, in the same layout as the crop (near-crop convention, far side already
//! rotated), values in `[0, 1]`.

use fcn_infer::{Crop, FcnModel, HeatmapCells, InferError, MAX_BATCH};
use world::{Heatmap, RobotConfig, Scene, Side};

/// One (target, side) whose heatmap is wanted.
#[derive(Clone, Copy, Debug)]
pub struct FeasibilityQuery<'a> {
    /// The world (an oracle simulates in it; the FCN only looks at `crop`).
    pub scene: &'a Scene,
    /// The robot (footprint, arm mount, noise).
    pub robot: &'a RobotConfig,
    /// The object's goal position (x, y, z) in the world frame (m).
    pub target: [f64; 3],
    /// Which side of the table the base stands on.
    pub side: Side,
    /// The overhead crop of that (target, side), exactly as `world::view::render_crop` returns it.
    pub crop: &'a [u8; 2048],
}

/// Why an evaluator could not produce heatmaps.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum FeasibilityError {
    /// `out` does not have one heatmap per query.
    #[error("{queries} feasibility queries but {outputs} output heatmaps")]
    OutputCount {
        /// Queries given.
        queries: usize,
        /// Output heatmaps given.
        outputs: usize,
    },
    /// The FCN failed on a batch of crops.
    #[error("FCN inference failed: {0}")]
    Inference(#[from] InferError),
    /// Any other evaluator-specific failure (an oracle's simulator, a heuristic's input check),
    /// with the evaluator's name and what went wrong.
    #[error("feasibility evaluator {evaluator} failed: {reason}")]
    Evaluator {
        /// [`FeasibilityEvaluator::name`] of the failing evaluator.
        evaluator: String,
        /// What went wrong.
        reason: String,
    },
}

/// `Psi`: predicts the motion-level feasibility heatmap of each query.
pub trait FeasibilityEvaluator {
    /// Short name for logs and tables (`fcn`, `oracle`, `clearance`, ...).
    fn name(&self) -> &str;

    /// Writes `out[i] = Psi(queries[i])`. `out.len()` must equal `queries.len()`, else
    /// [`FeasibilityError::OutputCount`].
    fn evaluate(
        &mut self,
        queries: &[FeasibilityQuery<'_>],
        out: &mut [Heatmap],
    ) -> Result<(), FeasibilityError>;
}

impl<E: FeasibilityEvaluator + ?Sized> FeasibilityEvaluator for Box<E> {
    fn name(&self) -> &str {
        (**self).name()
    }
    fn evaluate(
        &mut self,
        queries: &[FeasibilityQuery<'_>],
        out: &mut [Heatmap],
    ) -> Result<(), FeasibilityError> {
        (**self).evaluate(queries, out)
    }
}

/// The trained FCN (`fcn-infer`) as a feasibility evaluator: batches the crops by
/// [`MAX_BATCH`] (six: both sides of three targets in one call) and copies the outputs into
/// heatmaps. Buffers are kept between calls, so a steady planner does not allocate here.
pub struct FcnEvaluator {
    model: FcnModel,
    crops: Vec<Crop>,
    cells: Vec<HeatmapCells>,
    /// Rows and columns computed; `None`: whole heatmaps.
    window: Option<(std::ops::Range<usize>, std::ops::Range<usize>)>,
}

impl FcnEvaluator {
    /// Wraps a loaded model.
    pub fn new(model: FcnModel) -> Self {
        Self {
            model,
            crops: Vec::with_capacity(MAX_BATCH),
            cells: vec![[0.0; 2048]; MAX_BATCH],
            window: None,
        }
    }

    /// This evaluator, writing only the planner's candidate cells of each heatmap
    /// (`world::view::CANDIDATE_ROWS` x `CANDIDATE_COLS`, 192 of 2,048) and 0 elsewhere: all a
    /// decision reads ([`crate::problem::UnloadLocation::from_heatmap`]). When the model's
    /// decoder runs over windows ([`FcnModel::decodes_windows`]) that takes a fifth to a quarter
    /// less of Psi's time (docs/fcn.md); the cells are the whole heatmaps' cells, bit for bit.
    /// Not for pictures or logs of whole heatmaps.
    pub fn candidate_cells_only(mut self) -> Self {
        let (rows, cols) = (world::view::CANDIDATE_ROWS, world::view::CANDIDATE_COLS);
        self.window = Some((
            *rows.start()..*rows.end() + 1,
            *cols.start()..*cols.end() + 1,
        ));
        self
    }

    /// Loads the model file (e.g. `models/psi-fcn.onnx`) and wraps it.
    pub fn load(path: &std::path::Path) -> Result<Self, fcn_infer::ModelLoadError> {
        Ok(Self::new(FcnModel::load(path)?))
    }

    /// The wrapped model.
    pub fn model(&self) -> &FcnModel {
        &self.model
    }
}

impl FeasibilityEvaluator for FcnEvaluator {
    fn name(&self) -> &str {
        "fcn"
    }

    fn evaluate(
        &mut self,
        queries: &[FeasibilityQuery<'_>],
        out: &mut [Heatmap],
    ) -> Result<(), FeasibilityError> {
        check_output_count(queries, out)?;
        for (qs, outs) in queries.chunks(MAX_BATCH).zip(out.chunks_mut(MAX_BATCH)) {
            self.crops.clear();
            self.crops.extend(qs.iter().map(|q| *q.crop));
            let cells = &mut self.cells[..qs.len()];
            match &self.window {
                Some((rows, cols)) => self.model.predict_batch_window(
                    &self.crops,
                    cells,
                    rows.clone(),
                    cols.clone(),
                )?,
                None => self.model.predict_batch(&self.crops, cells)?,
            }
            for (h, c) in outs.iter_mut().zip(cells.iter()) {
                h.values_mut().copy_from_slice(c);
            }
        }
        Ok(())
    }
}

/// The check every evaluator starts with: one output per query.
pub fn check_output_count(
    queries: &[FeasibilityQuery<'_>],
    out: &[Heatmap],
) -> Result<(), FeasibilityError> {
    if queries.len() != out.len() {
        return Err(FeasibilityError::OutputCount {
            queries: queries.len(),
            outputs: out.len(),
        });
    }
    Ok(())
}
