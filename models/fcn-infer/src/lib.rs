//! The feasibility evaluator Psi of the GROP paper (eq. 2-3, h = Psi(IM)) as ONNX inference on
//! tract: a fully convolutional network turns a 64 x 32 overhead crop in front of an unloading
//! target into a heatmap of the probability that the robot, sent to each cell, can unload there.
//!
//! The model is loaded once, one plan per batch size (1 to [`MAX_BATCH`], both sides of three
//! targets) optimised by tract, and then run without any allocation of ours: the input tensors
//! are allocated at load time and refilled in place, results are copied into the caller's
//! buffers. The network's convolutions run as our own tract operator,
//! [`direct_conv::DirectConv`], swapped into the graph after loading (the file and its weights
//! are unchanged; tract's own lowering, Pad + im2col + small matrix products, measured ~2x slower
//! on this network, docs/fcn.md); [`ConvBackend::Tract`] keeps tract's, for reference.
//!
//! When the network ends in Psi's pointwise FCN-8s decoder (found by its structure, then checked
//! against the whole network on fixed crops at load time), tract runs the encoder and the
//! decoder runs as our own code over the cells asked for: [`FcnModel::predict_batch_window`]
//! computes only a window of each heatmap (the planner's 192 candidate cells take about a
//! quarter less of Psi's time than whole heatmaps), with the same values, bit for bit, as whole
//! heatmaps. Models with another decoder run whole and have the window cut from the output.
//!
//! The uint8
//! -> float normalisation is part of the ONNX graph, so callers pass the crop exactly as
//! `world::view::render_crop` returns it.
//!
//! ```no_run
//! use fcn_infer::{FcnModel, CROP_CELLS};
//! # fn main() -> Result<(), Box<dyn std::error::Error>> {
//! let mut model = FcnModel::load(std::path::Path::new("models/psi-fcn.onnx"))?;
//! let crop = [200u8; CROP_CELLS]; // from world::view::render_crop(&scene, target_x, side)
//! let mut heatmap = [0.0f32; CROP_CELLS];
//! model.predict(&crop, &mut heatmap)?;
//! # Ok(()) }
//! ```
//!
//! Far side: the network only knows near-side crops. The far half of an overhead view is rotated
//! 180 degrees before inference and the prediction rotated back; [`overhead`] does both on the
//! 64 x 64 camera image, so a heatmap cell can be placed in the world frame (docs/architecture.md).

use std::ops::Range;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use tract_onnx::prelude::*;
use tract_onnx::tract_hir::infer::Factoid;

mod decoder;
pub mod direct_conv;
pub mod overhead;
mod record;

pub use record::{MAX_MODEL_BYTES, MAX_RECORD_BYTES, record_path, sha256_hex};

/// Rows of a crop and of a heatmap (0.0625 m each; row 0 touches the table's centre line).
pub const CROP_ROWS: usize = 32;
/// Columns of a crop and of a heatmap (0.0625 m each, 4 m in all, centred on the target).
pub const CROP_COLS: usize = 64;
/// Cells of a crop / heatmap, row-major `[row][col]`.
pub const CROP_CELLS: usize = CROP_ROWS * CROP_COLS;
/// Largest batch one call runs: both sides of three targets.
pub const MAX_BATCH: usize = 6;

/// How the network's convolutions run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ConvBackend {
    /// Our [`direct_conv::DirectConv`] operator, swapped into the graph after loading (the
    /// default: the same weights and, within float rounding, the same outputs, 2-3x faster).
    #[default]
    Direct,
    /// tract's own lowering (Pad + im2col + packed matrix products): the reference.
    Tract,
}

/// `count` deterministic gray-pattern crops (not scenes): the fixed inputs of the latency
/// harnesses and benchmarks, so every timing tool feeds the model the same bytes.
pub fn pattern_crops(count: usize) -> Vec<[u8; CROP_CELLS]> {
    (0..count)
        .map(|k| std::array::from_fn(|i| ((i * 13 + k * 101) % 256) as u8))
        .collect()
}

/// Grayscale crop as rendered by `world::view::render_crop`.
pub type Crop = [u8; CROP_CELLS];
/// Heatmap cells in `[0, 1]`, same layout as the crop.
pub type HeatmapCells = [f32; CROP_CELLS];

/// Why a model file could not be loaded.
#[derive(Debug, thiserror::Error)]
pub enum ModelLoadError {
    /// No file at the path.
    #[error("FCN model file {path} does not exist")]
    NotFound {
        /// The path that was tried.
        path: PathBuf,
    },
    /// The file exists but could not be read.
    #[error("cannot read FCN model file {path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The operating system's error.
        source: std::io::Error,
    },
    /// The file is larger than [`MAX_MODEL_BYTES`] (checked before it is read).
    #[error("FCN model file {path} is {size} bytes, more than the {limit}-byte limit")]
    TooLarge {
        /// The file.
        path: PathBuf,
        /// Its size (or the bytes read before the read was cut).
        size: u64,
        /// The limit.
        limit: u64,
    },
    /// The model's bytes do not have the sha256 its record names: another or a damaged model.
    #[error(
        "FCN model file {path} does not match its record {record}: sha256 expected {expected}, actual {actual}"
    )]
    ChecksumMismatch {
        /// The model file.
        path: PathBuf,
        /// The record that names the checksum.
        record: PathBuf,
        /// The record's sha256.
        expected: String,
        /// The file's sha256.
        actual: String,
    },
    /// The record beside the model cannot be read, is not JSON or names no sha256.
    #[error("FCN model record {record} is unusable: {reason}")]
    BadRecord {
        /// The record file.
        record: PathBuf,
        /// What is wrong with it.
        reason: String,
    },
    /// The bytes are not an ONNX model tract can parse.
    #[error("FCN model file {path} is not a valid ONNX model: {reason}")]
    Corrupt {
        /// The file.
        path: PathBuf,
        /// tract's parse error.
        reason: String,
    },
    /// The model's inputs or outputs are not one uint8 crop in, one float32 heatmap out, both
    /// `[N, 1, 32, 64]`.
    #[error(
        "FCN model {path} has the wrong interface: {detail} (expected uint8 crop [N,1,32,64] -> float32 heatmap [N,1,32,64])"
    )]
    WrongInterface {
        /// The file.
        path: PathBuf,
        /// What was found instead.
        detail: String,
    },
    /// tract could not type, optimise or plan the model for a fixed batch size.
    #[error("cannot prepare FCN model {path} for batch {batch}: {reason}")]
    Prepare {
        /// The file.
        path: PathBuf,
        /// Batch size being prepared.
        batch: usize,
        /// tract's error chain.
        reason: String,
    },
}

/// Why an inference call failed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum InferError {
    /// Batch size outside `1..=MAX_BATCH`.
    #[error("batch of {0} crops; 1..={MAX_BATCH} are supported per call")]
    BatchSize(usize),
    /// Not as many output buffers as crops.
    #[error("{crops} crops but {outputs} output heatmaps")]
    OutputCount {
        /// Crops given.
        crops: usize,
        /// Output buffers given.
        outputs: usize,
    },
    /// A heatmap window that is empty or reaches outside the 32 x 64 crop.
    #[error("heatmap window rows {rows:?} x columns {cols:?} is empty or outside the 32 x 64 crop")]
    Window {
        /// The rows asked for.
        rows: Range<usize>,
        /// The columns asked for.
        cols: Range<usize>,
    },
    /// tract failed while running the plan.
    #[error("tract inference failed: {0}")]
    Runtime(String),
    /// The network produced a value that is not a probability (NaN or outside [0, 1]).
    #[error("model produced a non-probability {value} at crop {crop}, cell {cell}")]
    NotAProbability {
        /// Index of the crop in the batch.
        crop: usize,
        /// Cell index (row * 64 + col).
        cell: usize,
        /// The value.
        value: f32,
    },
}

/// The loaded, optimised FCN: one fixed-shape plan, its session state and the input tensor we
/// refill in place.
pub struct FcnModel {
    path: PathBuf,
    /// One plan per batch size: `plans[b - 1]` runs `b` crops.
    plans: Vec<Plan>,
    /// Psi's decoder, when it was recognised (and checked against the whole network): the plans
    /// then run the encoder only, their outputs are its three stages, and this computes the
    /// heatmap cells asked for ([`FcnModel::predict_batch_window`]).
    decoder: Option<decoder::Decoder>,
}

/// A fixed-batch plan, its session state and the input tensor we refill in place.
struct Plan {
    state: TypedSimpleState,
    input: Arc<Tensor>,
}

impl std::fmt::Debug for FcnModel {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("FcnModel")
            .field("path", &self.path)
            .finish_non_exhaustive()
    }
}

impl FcnModel {
    /// Loads an ONNX file, checks its interface and prepares the optimised plans.
    ///
    /// Before parsing: a file over [`MAX_MODEL_BYTES`] is refused without being read
    /// ([`ModelLoadError::TooLarge`]), and when the model's record (`<model>.json`, see
    /// [`record_path`]) sits beside it, the file's sha256 must be the record's `"sha256"`
    /// ([`ModelLoadError::ChecksumMismatch`], [`ModelLoadError::BadRecord`]). A model without
    /// a record loads unverified, with a warning.
    pub fn load(path: &Path) -> Result<FcnModel, ModelLoadError> {
        Self::load_with(path, ConvBackend::default())
    }

    /// [`FcnModel::load`] with the convolutions run by `backend`.
    pub fn load_with(path: &Path, backend: ConvBackend) -> Result<FcnModel, ModelLoadError> {
        let bytes = record::read_bounded(path, MAX_MODEL_BYTES)?;
        record::verify(path, &bytes)?;
        Self::from_bytes_with(&bytes, path, backend)
    }

    /// Like [`FcnModel::load`] from bytes already in memory; `origin` names them in errors.
    ///
    /// Malformed bytes are an error, never a panic: tract's ONNX import indexes and unwraps on
    /// the graph it reads (a graph output that names no node panicked in `parse_graph`, found by
    /// fuzzing, `docs/fuzzing.md`), so a panic while reading, checking or preparing the model is
    /// caught and reported as [`ModelLoadError::Corrupt`].
    pub fn from_bytes(bytes: &[u8], origin: &Path) -> Result<FcnModel, ModelLoadError> {
        Self::from_bytes_with(bytes, origin, ConvBackend::default())
    }

    /// [`FcnModel::from_bytes`] with the convolutions run by `backend`.
    pub fn from_bytes_with(
        bytes: &[u8],
        origin: &Path,
        backend: ConvBackend,
    ) -> Result<FcnModel, ModelLoadError> {
        // Nothing outlives a panic: the partly built model is dropped while unwinding.
        let load =
            std::panic::AssertUnwindSafe(|| Self::from_bytes_unguarded(bytes, origin, backend));
        std::panic::catch_unwind(load).unwrap_or_else(|panic| {
            let message = panic
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| panic.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "unknown panic".into());
            Err(ModelLoadError::Corrupt {
                path: origin.to_path_buf(),
                reason: format!("the ONNX importer failed on it: {message}"),
            })
        })
    }

    fn from_bytes_unguarded(
        bytes: &[u8],
        origin: &Path,
        backend: ConvBackend,
    ) -> Result<FcnModel, ModelLoadError> {
        let path = origin.to_path_buf();
        let model = tract_onnx::onnx()
            .model_for_read(&mut &bytes[..])
            .map_err(|e| ModelLoadError::Corrupt {
                path: path.clone(),
                reason: format!("{e:#}"),
            })?;
        check_declared_interface(&model, &path)?;
        // With our convolutions, one plan per batch size: a batch runs as one (the elementwise
        // and axis ops then run once per call). tract's own plans for batch > 1 of this network
        // fall back to eager im2col and unfused adds, slower than single runs (docs/fcn.md), so
        // with them the one-crop plan runs per crop, as before.
        let batches = match backend {
            ConvBackend::Direct => MAX_BATCH,
            ConvBackend::Tract => 1,
        };
        let full = |path: &Path| {
            (1..=batches)
                .map(|batch| prepare(&model, batch, path, backend))
                .collect::<Result<Vec<_>, _>>()
        };
        let mut fcn = match backend {
            ConvBackend::Direct => match prepare_split(&model, &path) {
                Some((plans, decoder)) => FcnModel {
                    path: path.clone(),
                    plans,
                    decoder: Some(decoder),
                },
                None => FcnModel {
                    plans: full(&path)?,
                    path: path.clone(),
                    decoder: None,
                },
            },
            ConvBackend::Tract => FcnModel {
                plans: full(&path)?,
                path: path.clone(),
                decoder: None,
            },
        };
        if fcn.decoder.is_some() {
            // The decoder found by its structure must compute what the whole network does: on
            // a few fixed crops, against the network's own plan, before it is used.
            let mut reference = FcnModel {
                path: path.clone(),
                plans: vec![prepare(&model, 1, &path, backend)?],
                decoder: None,
            };
            match fcn.agrees_with(&mut reference) {
                Ok(()) => {}
                Err(why) => {
                    log::warn!(
                        "FCN model {}: its decoder does not run on its own ({why}); heatmaps come from the whole network",
                        path.display()
                    );
                    fcn.plans = full(&path)?;
                    fcn.decoder = None;
                }
            }
        }
        log::info!(
            "loaded FCN model {} ({backend:?} convolutions{})",
            path.display(),
            if fcn.decoder.is_some() {
                ", decoder over windows"
            } else {
                ""
            }
        );
        Ok(fcn)
    }

    /// Whether heatmap cells outside a window cost nothing: the model's decoder was recognised
    /// and runs on its own over the cells asked for ([`FcnModel::predict_batch_window`]).
    /// Otherwise the whole network runs and the window is cut from its output.
    pub fn decodes_windows(&self) -> bool {
        self.decoder.is_some()
    }

    /// Compares every cell of a few fixed crops with `reference` (the whole network's plan):
    /// within [`DECODER_TOLERANCE`], else why not.
    fn agrees_with(&mut self, reference: &mut FcnModel) -> Result<(), String> {
        let crops = pattern_crops(3);
        let mut ours = vec![[0.0f32; CROP_CELLS]; crops.len()];
        self.predict_batch(&crops, &mut ours)
            .map_err(|e| e.to_string())?;
        for (k, (crop, ours)) in crops.iter().zip(&ours).enumerate() {
            let mut want = [0.0f32; CROP_CELLS];
            reference
                .predict(crop, &mut want)
                .map_err(|e| e.to_string())?;
            if let Some((cell, (a, b))) = ours
                .iter()
                .zip(want.iter())
                .enumerate()
                .find(|(_, (a, b))| (*a - *b).abs().is_nan() || (*a - *b).abs() > DECODER_TOLERANCE)
            {
                return Err(format!(
                    "crop {k}, cell {cell}: {a} against the network's {b}"
                ));
            }
        }
        Ok(())
    }

    /// The file the model came from.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Psi for one crop: `out[row * 64 + col]` is the success probability of that cell.
    pub fn predict(&mut self, crop: &Crop, out: &mut HeatmapCells) -> Result<(), InferError> {
        self.predict_batch(std::slice::from_ref(crop), std::slice::from_mut(out))
    }

    /// Psi for up to [`MAX_BATCH`] crops in one call (e.g. both sides of three targets), run as
    /// one batch.
    pub fn predict_batch(
        &mut self,
        crops: &[Crop],
        out: &mut [HeatmapCells],
    ) -> Result<(), InferError> {
        self.predict_batch_window(crops, out, 0..CROP_ROWS, 0..CROP_COLS)
    }

    /// [`FcnModel::predict_batch`] for the cells of `rows` x `cols` only (for example the
    /// planner's candidate cells, `world::view::CANDIDATE_ROWS` x `CANDIDATE_COLS`): those cells
    /// get the values a whole heatmap would have, every other cell is set to 0. With a
    /// recognised decoder ([`FcnModel::decodes_windows`]) the decoder runs only over the window;
    /// the encoder always runs whole.
    pub fn predict_batch_window(
        &mut self,
        crops: &[Crop],
        out: &mut [HeatmapCells],
        rows: Range<usize>,
        cols: Range<usize>,
    ) -> Result<(), InferError> {
        if rows.is_empty() || cols.is_empty() || rows.end > CROP_ROWS || cols.end > CROP_COLS {
            return Err(InferError::Window { rows, cols });
        }
        if crops.is_empty() || crops.len() > MAX_BATCH {
            return Err(InferError::BatchSize(crops.len()));
        }
        if out.len() != crops.len() {
            return Err(InferError::OutputCount {
                crops: crops.len(),
                outputs: out.len(),
            });
        }
        let window = (rows, cols);
        if crops.len() <= self.plans.len() {
            return self.run_plan(crops, out, 0, &window);
        }
        // Only the one-crop plan (tract's own convolutions): one run per crop.
        for (i, (crop, heat)) in crops.iter().zip(out.iter_mut()).enumerate() {
            self.run_plan(
                std::slice::from_ref(crop),
                std::slice::from_mut(heat),
                i,
                &window,
            )?;
        }
        Ok(())
    }

    /// Runs the plan for `crops.len()` crops; `first` is the first crop's index in the caller's
    /// batch (for errors).
    fn run_plan(
        &mut self,
        crops: &[Crop],
        out: &mut [HeatmapCells],
        first: usize,
        (rows, cols): &(Range<usize>, Range<usize>),
    ) -> Result<(), InferError> {
        let batch = crops.len();
        let plan = &mut self.plans[batch - 1];
        // The input tensor is ours alone between calls (tract drops its handle at the end of a
        // run), so it is refilled in place; a fresh one is only made if that ever stops holding.
        if Arc::get_mut(&mut plan.input).is_none() {
            plan.input =
                Arc::new(Tensor::zero::<u8>(&[batch, 1, CROP_ROWS, CROP_COLS]).map_err(runtime)?);
        }
        let input = Arc::get_mut(&mut plan.input)
            .ok_or_else(|| InferError::Runtime("input tensor shared".into()))?;
        let mut view = input.try_as_plain_ram_mut().map_err(runtime)?;
        let cells = view.as_slice_mut::<u8>().map_err(runtime)?;
        for (dst, crop) in cells.chunks_exact_mut(CROP_CELLS).zip(crops) {
            dst.copy_from_slice(crop);
        }
        let outputs = plan
            .state
            .run(tvec!(TValue::from_const(plan.input.clone())))
            .map_err(runtime)?;
        let whole = rows.len() == CROP_ROWS && cols.len() == CROP_COLS;
        if let Some(decoder) = &mut self.decoder {
            let [c1, c2, c3] = decoder.stage_channels();
            let mut stages: [&[f32]; 3] = [&[]; 3];
            for (k, (stage, len)) in stages
                .iter_mut()
                .zip([
                    c1 * CROP_CELLS / 4,
                    c2 * CROP_CELLS / 16,
                    c3 * CROP_CELLS / 64,
                ])
                .enumerate()
            {
                *stage = output_values(&outputs, k, batch * len, "encoder stage")?;
            }
            for (n, heat) in out.iter_mut().enumerate() {
                let f = stages.map(|v| {
                    let len = v.len() / batch;
                    &v[n * len..(n + 1) * len]
                });
                if !whole {
                    heat.fill(0.0);
                }
                decoder
                    .decode(f, rows.clone(), cols.clone(), heat)
                    .map_err(runtime)?;
            }
        } else {
            let heat = output_values(&outputs, 0, batch * CROP_CELLS, "output")?;
            for (dst, src) in out.iter_mut().zip(heat.chunks_exact(CROP_CELLS)) {
                if whole {
                    dst.copy_from_slice(src);
                } else {
                    dst.fill(0.0);
                    for r in rows.clone() {
                        let at = r * CROP_COLS;
                        dst[at + cols.start..at + cols.end]
                            .copy_from_slice(&src[at + cols.start..at + cols.end]);
                    }
                }
            }
        }
        for (n, heat) in out.iter().enumerate().take(batch) {
            for r in rows.clone() {
                let at = r * CROP_COLS;
                if let Some((c, &value)) = heat[at + cols.start..at + cols.end]
                    .iter()
                    .enumerate()
                    .find(|(_, v)| !(0.0..=1.0).contains(*v))
                {
                    return Err(InferError::NotAProbability {
                        crop: first + n,
                        cell: at + cols.start + c,
                        value,
                    });
                }
            }
        }
        Ok(())
    }
}

/// Largest difference allowed between the decoder run on its own and the whole network, per
/// cell, at load time (both are float32 sums of the same terms in another order; measured
/// differences are around 1e-7).
const DECODER_TOLERANCE: f32 = 1e-5;

/// Output `k` of a plan's run as `len` floats; `what` names it in errors.
fn output_values<'a>(
    outputs: &'a [TValue],
    k: usize,
    len: usize,
    what: &str,
) -> Result<&'a [f32], InferError> {
    let values = outputs
        .get(k)
        .ok_or_else(|| InferError::Runtime(format!("the plan returned no {what} {k}")))?
        .try_as_plain_ram()
        .map_err(runtime)?
        .as_slice::<f32>()
        .map_err(runtime)?;
    if values.len() != len {
        return Err(InferError::Runtime(format!(
            "{what} {k} has {} values, expected {len}",
            values.len()
        )));
    }
    Ok(values)
}

fn runtime(e: impl std::fmt::Display) -> InferError {
    InferError::Runtime(format!("{e:#}"))
}

/// Checks what the file itself declares: exactly one input (uint8 where a type is given, rank 4
/// `[N,1,32,64]` where a shape is given) and one output.
fn check_declared_interface(model: &InferenceModel, path: &Path) -> Result<(), ModelLoadError> {
    let wrong = |detail: String| ModelLoadError::WrongInterface {
        path: path.to_path_buf(),
        detail,
    };
    let n_in = model
        .input_outlets()
        .map_err(|e| wrong(format!("{e:#}")))?
        .len();
    let n_out = model
        .output_outlets()
        .map_err(|e| wrong(format!("{e:#}")))?
        .len();
    if n_in != 1 || n_out != 1 {
        return Err(wrong(format!("{n_in} inputs and {n_out} outputs")));
    }
    let fact = model.input_fact(0).map_err(|e| wrong(format!("{e:#}")))?;
    if let Some(dt) = fact.datum_type.concretize()
        && dt != u8::datum_type()
    {
        return Err(wrong(format!("input of type {dt:?}")));
    }
    if let Some(rank) = fact.shape.rank().concretize() {
        if rank != 4 {
            return Err(wrong(format!("input of rank {rank}")));
        }
        let expected = [
            None,
            Some(1),
            Some(CROP_ROWS as i64),
            Some(CROP_COLS as i64),
        ];
        for (axis, (dim, want)) in fact.shape.dims().zip(expected).enumerate() {
            if let (Some(d), Some(w)) = (dim.concretize().and_then(|d| d.to_i64().ok()), want)
                && d != w
            {
                return Err(wrong(format!("input axis {axis} of size {d}")));
            }
        }
    }
    Ok(())
}

/// The model typed with its input fixed to `[batch, 1, 32, 64]` u8.
fn typed_for(
    model: &InferenceModel,
    batch: usize,
    path: &Path,
) -> Result<TypedModel, ModelLoadError> {
    model
        .clone()
        .with_input_fact(0, u8::fact([batch, 1, CROP_ROWS, CROP_COLS]).into())
        .and_then(|m| m.into_typed())
        .map_err(|e| ModelLoadError::Prepare {
            path: path.to_path_buf(),
            batch,
            reason: format!("{e:#}"),
        })
}

/// Fixes the input to `[batch, 1, 32, 64]` u8, optimises, checks the output and plans.
fn prepare(
    model: &InferenceModel,
    batch: usize,
    path: &Path,
    backend: ConvBackend,
) -> Result<Plan, ModelLoadError> {
    plan_typed(typed_for(model, batch, path)?, batch, path, backend, None)
}

/// One plan per batch size that runs the encoder only, and the decoder that turns its stages
/// into heatmap cells, when the model's decoder is recognised ([`decoder::Decoder`]). `None`
/// (the caller then plans the whole network) when it is not, or when the split plan cannot be
/// made: that is logged, never an error, since the whole network may still load.
fn prepare_split(model: &InferenceModel, path: &Path) -> Option<(Vec<Plan>, decoder::Decoder)> {
    let mut plans = Vec::with_capacity(MAX_BATCH);
    let mut found = None;
    for batch in 1..=MAX_BATCH {
        let split = typed_for(model, batch, path).and_then(|typed| {
            let recognised =
                decoder::Decoder::recognise(&typed).map_err(|e| ModelLoadError::Prepare {
                    path: path.to_path_buf(),
                    batch,
                    reason: format!("{e:#}"),
                })?;
            let Some((decoder, stages)) = recognised else {
                return Ok(None);
            };
            let shapes = stages_shapes(batch, decoder.stage_channels());
            let plan = plan_typed(
                typed,
                batch,
                path,
                ConvBackend::Direct,
                Some((stages, shapes)),
            )?;
            Ok(Some((plan, decoder)))
        });
        match split {
            Ok(Some((plan, decoder))) => {
                plans.push(plan);
                found.get_or_insert(decoder);
            }
            Ok(None) => return None,
            Err(e) => {
                log::warn!("FCN model {}: decoder not split off: {e}", path.display());
                return None;
            }
        }
    }
    found.map(|decoder| (plans, decoder))
}

/// The shapes of the three encoder stages (strides 2, 4, 8) for a batch.
fn stages_shapes(batch: usize, channels: [usize; 3]) -> [[usize; 4]; 3] {
    let [c1, c2, c3] = channels;
    [
        [batch, c1, CROP_ROWS / 2, CROP_COLS / 2],
        [batch, c2, CROP_ROWS / 4, CROP_COLS / 4],
        [batch, c3, CROP_ROWS / 8, CROP_COLS / 8],
    ]
}

/// Optimises a typed model, checks its outputs and plans it. With `stages`, those outlets
/// become the plan's outputs (the encoder's stages, of the shapes given) instead of the heatmap.
fn plan_typed(
    mut typed: TypedModel,
    batch: usize,
    path: &Path,
    backend: ConvBackend,
    stages: Option<([OutletId; 3], [[usize; 4]; 3])>,
) -> Result<Plan, ModelLoadError> {
    let prep = |e: TractError| ModelLoadError::Prepare {
        path: path.to_path_buf(),
        batch,
        reason: format!("{e:#}"),
    };
    let shape = [batch, 1, CROP_ROWS, CROP_COLS];
    if let Some((outlets, _)) = &stages {
        typed.select_output_outlets(outlets).map_err(prep)?;
    }
    if backend == ConvBackend::Direct {
        let summary = direct_conv::rewrite_convolutions(&mut typed).map_err(prep)?;
        log::debug!("batch {batch}: {summary:?}");
    }
    let typed = typed.into_optimized().map_err(prep)?;
    let wanted: Vec<[usize; 4]> = match &stages {
        Some((_, shapes)) => shapes.to_vec(),
        None => vec![shape],
    };
    let outputs = typed.output_outlets().map_err(prep)?.len();
    for (k, want) in wanted.iter().enumerate() {
        let fact = typed.output_fact(k).map_err(prep)?;
        let want: TVec<TDim> = want.iter().map(|&d| d.to_dim()).collect();
        if outputs != wanted.len()
            || fact.datum_type != f32::datum_type()
            || fact.shape.to_tvec() != want
        {
            return Err(ModelLoadError::WrongInterface {
                path: path.to_path_buf(),
                detail: format!(
                    "output {k} of {outputs}: {:?} {:?} for batch {batch}",
                    fact.datum_type, fact.shape
                ),
            });
        }
    }
    let runnable = typed.into_runnable().map_err(prep)?;
    let state = runnable.spawn().map_err(prep)?;
    let input = Arc::new(Tensor::zero::<u8>(&shape).map_err(prep)?);
    Ok(Plan { state, input })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The load-time check refuses a decoder that does not compute what the network does: one
    /// output-bias value changed is found, and named by its cell.
    #[test]
    fn the_load_time_check_finds_a_decoder_that_differs_from_the_network() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../psi-fcn.onnx");
        let mut fcn = FcnModel::load(&path).expect("load");
        let bytes = std::fs::read(&path).expect("read");
        let model = tract_onnx::onnx()
            .model_for_read(&mut &bytes[..])
            .expect("parse");
        let mut reference = FcnModel {
            path: path.clone(),
            plans: vec![prepare(&model, 1, &path, ConvBackend::Direct).expect("plan")],
            decoder: None,
        };
        assert_eq!(fcn.agrees_with(&mut reference), Ok(()));
        fcn.decoder
            .as_mut()
            .expect("the committed model's decoder is recognised")
            .nudge_out_bias(12 * CROP_COLS + 30, 40.0);
        let why = fcn.agrees_with(&mut reference).unwrap_err();
        assert!(
            why.contains(&format!("cell {}", 12 * CROP_COLS + 30)),
            "{why}"
        );
    }
}
