//! `grop datagen`: the feasibility dataset of paper section III-B. For every task (scene,
//! target, side) it renders the crop the FCN sees, runs `trials_per_cell` trials at each of the
//! 24 x 8 candidate cells and stores the success fraction as the label. The default is the
//! paper's 10 environments x 10 targets x 5 trials x 192 cells = 96,000 trials.
//!
//! Output folder (format in docs/dataset.md and docs/architecture.md): `dataset.npz`,
//! `dataset.json`, `trials.csv`, `robot.toml`, `scenes/scene_NNN.toml`.

use std::collections::BTreeMap;
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::time::Instant;

use npyz::WriterBuilder;
use rayon::prelude::*;
use serde::Serialize;
use world::generate::{mix_seed, training_scenes};
use world::view::{
    CANDIDATE_COLS, CANDIDATE_ROWS, CELL_SIZE_M, CROP_CELLS, CROP_COLS, CROP_ROWS, Side,
    in_candidate_area, render_crop,
};
use world::{RobotConfig, Scene, SceneError};

use crate::shard::Shard;
use crate::trial::{CellCounts, HeatmapArea, TrialResult, TrialSimulator, simulate_cells};

/// Version of the output folder's format (`dataset.json` field `format_version`).
pub const DATASET_FORMAT_VERSION: u32 = 1;

/// Which sides of the table get tasks.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum SideSelection {
    /// Near side only: the paper's dataset (training chairs stand on the near side).
    Near,
    /// Near and far: doubles the tasks; far crops are rotated like near ones.
    Both,
}

impl SideSelection {
    /// The sides, near first.
    pub fn sides(self) -> &'static [Side] {
        match self {
            SideSelection::Near => &[Side::Near],
            SideSelection::Both => &Side::BOTH,
        }
    }
}

/// Settings of one dataset run. [`DatagenConfig::default`] is the paper's dataset.
#[derive(Clone, Debug)]
pub struct DatagenConfig {
    /// Seed of the scene generator and of every trial.
    pub seed: u64,
    /// Training environments (paper: 10).
    pub n_envs: usize,
    /// Targets per environment (paper: 10).
    pub targets_per_env: usize,
    /// Trials per candidate cell (paper: 5).
    pub trials_per_cell: u16,
    /// Sides that get tasks.
    pub sides: SideSelection,
    /// The robot.
    pub robot: RobotConfig,
    /// Where the robot came from (recorded in `dataset.json`; `None` = built-in default).
    pub robot_file: Option<PathBuf>,
    /// Output folder (created if missing; files in it are overwritten).
    pub out_dir: PathBuf,
    /// Whether to write `trials.csv` (one row per trial).
    pub write_trials_csv: bool,
}

impl Default for DatagenConfig {
    fn default() -> Self {
        Self {
            seed: 0,
            n_envs: 10,
            targets_per_env: 10,
            trials_per_cell: 5,
            sides: SideSelection::Near,
            robot: RobotConfig::default(),
            robot_file: None,
            out_dir: PathBuf::from("out/dataset"),
            write_trials_csv: true,
        }
    }
}

/// Receives progress while tasks run (from several threads).
pub trait Progress: Sync {
    /// Called once with the number of tasks.
    fn begin(&self, _tasks: u64) {}
    /// Called after each task.
    fn task_done(&self) {}
    /// Called once when all tasks are simulated.
    fn end(&self) {}
}

/// No progress reporting.
#[derive(Clone, Copy, Debug, Default)]
pub struct NoProgress;
impl Progress for NoProgress {}

impl Progress for indicatif::ProgressBar {
    fn begin(&self, tasks: u64) {
        self.set_length(tasks);
    }
    fn task_done(&self) {
        self.inc(1);
    }
    fn end(&self) {
        self.finish();
    }
}

/// Failure of a dataset run.
#[derive(Debug, thiserror::Error)]
pub enum DatagenError {
    /// A setting is out of range.
    #[error("datagen settings: {0}")]
    InvalidConfig(String),
    /// The robot configuration does not validate.
    #[error("datagen settings: robot: {0}")]
    InvalidRobot(world::InvalidField),
    /// A file or folder could not be written.
    #[error("cannot write {path}: {source}")]
    Write {
        /// The file or folder.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// A scene file could not be written.
    #[error(transparent)]
    Scene(#[from] SceneError),
    /// The robot file could not be written.
    #[error(transparent)]
    Robot(#[from] world::RobotError),
}

/// One task: a target of a scene seen from one side.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Task {
    /// Row of the task in the arrays.
    pub index: usize,
    /// Index of the scene (`scenes/scene_NNN.toml`).
    pub scene: usize,
    /// Index of the target within its scene.
    pub target_index: usize,
    /// The object's goal (world, m).
    pub target: [f64; 3],
    /// Side the base works from.
    pub side: Side,
    /// Seed of the task's trials (cells draw independent streams from it).
    pub seed: u64,
}

/// One trial, as in `trials.csv`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TrialRecord {
    /// Task row.
    pub task: u32,
    /// Crop row of the commanded cell.
    pub row: u8,
    /// Crop column of the commanded cell.
    pub col: u8,
    /// Trial number within the cell.
    pub trial: u16,
    /// Commanded base position (world, m).
    pub commanded_xy: (f64, f64),
    /// Realised base position (world, m).
    pub realised_xy: (f64, f64),
    /// How it ended.
    pub result: TrialResult,
}

/// The simulated data of one task.
#[derive(Clone, Debug)]
pub struct TaskData {
    /// The task.
    pub task: Task,
    /// The crop the FCN sees.
    pub crop: [u8; CROP_CELLS],
    /// Trials and successes per cell.
    pub counts: CellCounts,
    /// Every trial (empty when records are not kept).
    pub records: Vec<TrialRecord>,
}

/// Statistics of a dataset (also in `dataset.json`).
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct DatasetSummary {
    /// Tasks (array rows).
    pub tasks: usize,
    /// Trials run.
    pub trials: u64,
    /// Successful trials.
    pub successes: u64,
    /// successes / trials (the authors' data: about 0.31).
    pub success_rate: f64,
    /// Trials per result (`success`, `base_collision`, `arm_out_of_reach`, ...).
    pub results: BTreeMap<String, u64>,
    /// `successes_per_cell_histogram[k]` = labelled cells with exactly k successful trials.
    pub successes_per_cell_histogram: Vec<u64>,
    /// Mean over tasks of the task's best label (max success fraction over its cells).
    pub mean_best_cell: f64,
    /// Tasks whose every cell has label 0.
    pub tasks_without_feasible_cell: usize,
    /// Success rate per candidate row, nearest the table first, with the row centre's distance
    /// from the table's centre line (m).
    pub success_rate_by_row: Vec<RowRate>,
    /// Wall-clock time of the simulation (s); not part of the determinism contract.
    pub simulate_s: f64,
    /// Trials per second of the simulation.
    pub trials_per_s: f64,
}

/// Success rate of one candidate row.
#[derive(Clone, Copy, Debug, Serialize, PartialEq)]
pub struct RowRate {
    /// Crop row.
    pub row: usize,
    /// Distance of the row's centre from the table's centre line (m).
    pub distance_m: f64,
    /// Successes / trials in the row.
    pub success_rate: f64,
}

/// A simulated dataset held in memory.
#[derive(Clone, Debug)]
pub struct Dataset {
    /// The training scenes.
    pub scenes: Vec<Scene>,
    /// Per-task data, in task order.
    pub tasks: Vec<TaskData>,
    /// Statistics.
    pub summary: DatasetSummary,
}

impl DatagenConfig {
    /// Checks the settings.
    pub fn validate(&self) -> Result<(), DatagenError> {
        if self.n_envs == 0 || self.targets_per_env == 0 {
            return Err(DatagenError::InvalidConfig(
                "need at least one environment and one target".into(),
            ));
        }
        if self.trials_per_cell == 0 {
            return Err(DatagenError::InvalidConfig(
                "trials_per_cell must be at least 1".into(),
            ));
        }
        let tasks = self
            .n_envs
            .saturating_mul(self.targets_per_env)
            .saturating_mul(self.sides.sides().len());
        if tasks > i32::MAX as usize {
            return Err(DatagenError::InvalidConfig(format!(
                "{tasks} tasks do not fit the int32 scene column"
            )));
        }
        self.robot.validate().map_err(DatagenError::InvalidRobot)
    }

    /// The scenes and tasks of this run, in array order (scene, target, side).
    pub fn tasks(&self) -> (Vec<Scene>, Vec<Task>) {
        let scenes = training_scenes(self.seed, self.n_envs, self.targets_per_env);
        let mut tasks = Vec::new();
        for (scene_index, scene) in scenes.iter().enumerate() {
            for (target_index, target) in scene.targets.iter().enumerate() {
                for &side in self.sides.sides() {
                    let index = tasks.len();
                    tasks.push(Task {
                        index,
                        scene: scene_index,
                        target_index,
                        target: target.as_array(),
                        side,
                        seed: mix_seed(self.seed, 0x7461_736b, index as u64),
                    });
                }
            }
        }
        (scenes, tasks)
    }
}

/// Simulates the dataset in memory (parallel over tasks with rayon). Deterministic for the
/// settings: thread count and scheduling do not change a single trial.
pub fn simulate(
    cfg: &DatagenConfig,
    progress: &dyn Progress,
    keep_records: bool,
) -> Result<Dataset, DatagenError> {
    simulate_shard(cfg, Shard::WHOLE, progress, keep_records)
}

/// [`simulate`] for one shard of the tasks: task `k` (array row) belongs to shard `k mod N`.
/// The tasks' data are exactly those of the whole run's rows; the summary is the shard's.
pub fn simulate_shard(
    cfg: &DatagenConfig,
    shard: Shard,
    progress: &dyn Progress,
    keep_records: bool,
) -> Result<Dataset, DatagenError> {
    cfg.validate()?;
    let (scenes, mut tasks) = cfg.tasks();
    tasks.retain(|t| shard.contains(t.index));
    progress.begin(tasks.len() as u64);
    let started = Instant::now();
    let data: Vec<TaskData> = tasks
        .par_iter()
        .map(|task| {
            let scene = &scenes[task.scene];
            let mut sim = TrialSimulator::new(scene, &cfg.robot);
            let mut records = Vec::new();
            if keep_records {
                records.reserve(CANDIDATE_CELLS_USIZE * usize::from(cfg.trials_per_cell));
            }
            let counts = simulate_cells(
                &mut sim,
                task.target,
                task.side,
                HeatmapArea::Candidate,
                cfg.trials_per_cell,
                task.seed,
                |row, col, trial, commanded_xy, outcome| {
                    if keep_records {
                        records.push(TrialRecord {
                            task: task.index as u32,
                            row: row as u8,
                            col: col as u8,
                            trial,
                            commanded_xy,
                            realised_xy: (outcome.realised.x_m, outcome.realised.y_m),
                            result: outcome.result,
                        });
                    }
                },
            );
            let crop = render_crop(scene, task.target[0], task.side);
            progress.task_done();
            TaskData {
                task: *task,
                crop,
                counts,
                records,
            }
        })
        .collect();
    let simulate_s = started.elapsed().as_secs_f64();
    progress.end();
    let summary = summarise(&data, cfg.trials_per_cell, simulate_s);
    Ok(Dataset {
        scenes,
        tasks: data,
        summary,
    })
}

const CANDIDATE_CELLS_USIZE: usize = world::view::CANDIDATE_CELLS;

/// Simulates the dataset and writes the output folder; returns its statistics.
pub fn generate(
    cfg: &DatagenConfig,
    progress: &dyn Progress,
) -> Result<DatasetSummary, DatagenError> {
    let dataset = simulate(cfg, progress, cfg.write_trials_csv)?;
    write_dataset(&dataset, cfg)?;
    Ok(dataset.summary)
}

fn summarise(data: &[TaskData], trials_per_cell: u16, simulate_s: f64) -> DatasetSummary {
    let mut results = [0u64; TrialResult::ALL.len()];
    let mut histogram = vec![0u64; usize::from(trials_per_cell) + 1];
    let mut row_trials = [0u64; CROP_ROWS];
    let mut row_successes = [0u64; CROP_ROWS];
    let mut best_sum = 0.0;
    let mut without_feasible = 0;
    let mut trials = 0u64;
    let mut successes = 0u64;
    for task in data {
        for record in &task.records {
            results[record.result.index()] += 1;
        }
        let mut best = 0.0f64;
        for row in 0..CROP_ROWS {
            for col in 0..CROP_COLS {
                let i = row * CROP_COLS + col;
                let (s, n) = (
                    u64::from(task.counts.successes[i]),
                    u64::from(task.counts.trials[i]),
                );
                if n == 0 {
                    continue;
                }
                trials += n;
                successes += s;
                row_trials[row] += n;
                row_successes[row] += s;
                if let Some(bin) = histogram.get_mut(s as usize) {
                    *bin += 1;
                }
                best = best.max(s as f64 / n as f64);
            }
        }
        best_sum += best;
        if best == 0.0 {
            without_feasible += 1;
        }
    }
    let mut result_map = BTreeMap::new();
    if data.iter().any(|t| !t.records.is_empty()) {
        for r in TrialResult::ALL {
            result_map.insert(r.name().to_owned(), results[r.index()]);
        }
    }
    let ratio = |a: u64, b: u64| if b == 0 { 0.0 } else { a as f64 / b as f64 };
    DatasetSummary {
        tasks: data.len(),
        trials,
        successes,
        success_rate: ratio(successes, trials),
        results: result_map,
        successes_per_cell_histogram: histogram,
        mean_best_cell: if data.is_empty() {
            0.0
        } else {
            best_sum / data.len() as f64
        },
        tasks_without_feasible_cell: without_feasible,
        success_rate_by_row: CANDIDATE_ROWS
            .map(|row| RowRate {
                row,
                distance_m: (row as f64 + 0.5) * CELL_SIZE_M,
                success_rate: ratio(row_successes[row], row_trials[row]),
            })
            .collect(),
        simulate_s,
        trials_per_s: if simulate_s > 0.0 {
            trials as f64 / simulate_s
        } else {
            0.0
        },
    }
}

fn io_err(path: &Path) -> impl FnOnce(std::io::Error) -> DatagenError + '_ {
    move |source| DatagenError::Write {
        path: path.to_owned(),
        source,
    }
}

/// Writes a simulated dataset into `cfg.out_dir`.
pub fn write_dataset(dataset: &Dataset, cfg: &DatagenConfig) -> Result<(), DatagenError> {
    let out = &cfg.out_dir;
    let scenes_dir = out.join("scenes");
    std::fs::create_dir_all(&scenes_dir).map_err(io_err(&scenes_dir))?;
    let scene_files: Vec<String> = (0..dataset.scenes.len())
        .map(|i| format!("scenes/scene_{i:03}.toml"))
        .collect();
    for (scene, file) in dataset.scenes.iter().zip(&scene_files) {
        scene.save(out.join(file))?;
    }
    cfg.robot.save(out.join("robot.toml"))?;
    write_npz(dataset, &out.join("dataset.npz"))?;
    if cfg.write_trials_csv {
        write_trials_csv(dataset, &out.join("trials.csv"))?;
    }
    write_manifest(dataset, cfg, &scene_files, &out.join("dataset.json"))
}

fn write_npz(dataset: &Dataset, path: &Path) -> Result<(), DatagenError> {
    let n = dataset.tasks.len() as u64;
    let crop_shape = [n, CROP_ROWS as u64, CROP_COLS as u64];
    let tasks = &dataset.tasks;
    let write = || -> std::io::Result<()> {
        let mut npz = npyz::npz::NpzWriter::create(path)?;
        let crops = tasks.iter().flat_map(|t| t.crop.iter().copied());
        put_array(&mut npz, "images", &crop_shape, crops)?;
        let labels = tasks
            .iter()
            .flat_map(|t| t.counts.heatmap().values().to_vec());
        put_array(&mut npz, "labels", &crop_shape, labels)?;
        let mask = tasks
            .iter()
            .flat_map(|t| t.counts.trials.iter().map(|&n| u8::from(n > 0)));
        put_array(&mut npz, "mask", &crop_shape, mask)?;
        let successes = tasks
            .iter()
            .flat_map(|t| t.counts.successes.iter().copied());
        put_array(&mut npz, "successes", &crop_shape, successes)?;
        let trials = tasks
            .iter()
            .map(|t| t.counts.trials.iter().copied().max().unwrap_or(0u16));
        put_array(&mut npz, "trials_per_cell", &[n], trials)?;
        let targets = tasks.iter().flat_map(|t| t.task.target);
        put_array(&mut npz, "targets", &[n, 3], targets)?;
        // validate() bounds the task count by i32::MAX, and scenes <= tasks.
        let scenes = tasks
            .iter()
            .map(|t| i32::try_from(t.task.scene).unwrap_or(i32::MAX));
        put_array(&mut npz, "scene", &[n], scenes)?;
        let sides = tasks.iter().map(|t| t.task.side.sign());
        put_array(&mut npz, "side", &[n], sides)?;
        Ok(())
    };
    write().map_err(io_err(path))
}

/// Writes one named array of `shape` (row-major values) into the npz.
fn put_array<T, W>(
    npz: &mut npyz::npz::NpzWriter<W>,
    name: &str,
    shape: &[u64],
    values: impl IntoIterator<Item = T>,
) -> std::io::Result<()>
where
    T: npyz::AutoSerialize,
    W: std::io::Write + std::io::Seek,
{
    // A fixed entry time (the zip format's epoch, 1980-01-01) instead of the time of writing:
    // the same dataset gives the same bytes, whichever run or merge of shards wrote it.
    let options =
        npyz::zip::write::FileOptions::default().last_modified_time(npyz::zip::DateTime::default());
    let mut w = npz
        .array::<T>(name, options)?
        .default_dtype()
        .shape(shape)
        .begin_nd()?;
    w.extend(values)?;
    w.finish()
}

fn write_trials_csv(dataset: &Dataset, path: &Path) -> Result<(), DatagenError> {
    let write = || -> std::io::Result<()> {
        let mut w = BufWriter::with_capacity(1 << 20, File::create(path)?);
        writeln!(
            w,
            "task,scene,target_x_m,side,row,col,trial,commanded_x_m,commanded_y_m,realised_x_m,realised_y_m,result"
        )?;
        for task in &dataset.tasks {
            let t = &task.task;
            for r in &task.records {
                writeln!(
                    w,
                    "{},{},{:.4},{},{},{},{},{:.5},{:.5},{:.5},{:.5},{}",
                    r.task,
                    t.scene,
                    t.target[0],
                    t.side.name(),
                    r.row,
                    r.col,
                    r.trial,
                    r.commanded_xy.0,
                    r.commanded_xy.1,
                    r.realised_xy.0,
                    r.realised_xy.1,
                    r.result.name()
                )?;
            }
        }
        w.flush()
    };
    write().map_err(io_err(path))
}

#[derive(Serialize)]
struct Manifest<'a> {
    format_version: u32,
    generator: GeneratorInfo<'a>,
    geometry: GeometryInfo,
    arrays: BTreeMap<&'static str, &'static str>,
    summary: &'a DatasetSummary,
    tasks: Vec<TaskInfo<'a>>,
}

#[derive(Serialize)]
struct GeneratorInfo<'a> {
    program: &'static str,
    version: &'static str,
    seed: u64,
    n_envs: usize,
    targets_per_env: usize,
    trials_per_cell: u16,
    sides: SideSelection,
    robot_file: Option<String>,
    robot: &'a RobotConfig,
}

#[derive(Serialize)]
struct GeometryInfo {
    crop_rows: usize,
    crop_cols: usize,
    cell_size_m: f64,
    candidate_rows: [usize; 2],
    candidate_cols: [usize; 2],
    table_center_y_m: f64,
}

#[derive(Serialize)]
struct TaskInfo<'a> {
    index: usize,
    scene: usize,
    scene_file: &'a str,
    target_index: usize,
    target: [f64; 3],
    side: Side,
    seed: u64,
}

fn write_manifest(
    dataset: &Dataset,
    cfg: &DatagenConfig,
    scene_files: &[String],
    path: &Path,
) -> Result<(), DatagenError> {
    let arrays = BTreeMap::from([
        (
            "images",
            "uint8 [N, 32, 64]: grayscale crop (near crop; far crops rotated 180 degrees)",
        ),
        (
            "labels",
            "float32 [N, 32, 64]: success fraction per cell, 0 outside the candidate area",
        ),
        ("mask", "uint8 [N, 32, 64]: 1 on labelled (candidate) cells"),
        (
            "successes",
            "uint16 [N, 32, 64]: successful trials per cell",
        ),
        (
            "trials_per_cell",
            "uint16 [N]: trials run at each labelled cell",
        ),
        (
            "targets",
            "float64 [N, 3]: object goal (x, y, z) in the world frame, m",
        ),
        ("scene", "int32 [N]: index of scenes/scene_NNN.toml"),
        ("side", "int8 [N]: +1 near side, -1 far side"),
    ]);
    let manifest = Manifest {
        format_version: DATASET_FORMAT_VERSION,
        generator: GeneratorInfo {
            program: "grop datagen",
            version: env!("CARGO_PKG_VERSION"),
            seed: cfg.seed,
            n_envs: cfg.n_envs,
            targets_per_env: cfg.targets_per_env,
            trials_per_cell: cfg.trials_per_cell,
            sides: cfg.sides,
            robot_file: cfg.robot_file.as_ref().map(|p| p.display().to_string()),
            robot: &cfg.robot,
        },
        geometry: GeometryInfo {
            crop_rows: CROP_ROWS,
            crop_cols: CROP_COLS,
            cell_size_m: CELL_SIZE_M,
            candidate_rows: [*CANDIDATE_ROWS.start(), *CANDIDATE_ROWS.end()],
            candidate_cols: [*CANDIDATE_COLS.start(), *CANDIDATE_COLS.end()],
            table_center_y_m: world::scene::TABLE_CENTER_Y_M,
        },
        arrays,
        summary: &dataset.summary,
        tasks: dataset
            .tasks
            .iter()
            .map(|t| TaskInfo {
                index: t.task.index,
                scene: t.task.scene,
                scene_file: &scene_files[t.task.scene],
                target_index: t.task.target_index,
                target: t.task.target,
                side: t.task.side,
                seed: t.task.seed,
            })
            .collect(),
    };
    let write = || -> std::io::Result<()> {
        let mut w = BufWriter::new(File::create(path)?);
        serde_json::to_writer_pretty(&mut w, &manifest).map_err(std::io::Error::other)?;
        writeln!(w)?;
        w.flush()
    };
    write().map_err(io_err(path))
}

/// Whether (row, col) carries a label (re-exported for readers of the arrays).
pub fn is_labelled(row: usize, col: usize) -> bool {
    in_candidate_area(row, col)
}

/// Sets the number of worker threads of the global pool used by [`simulate`]; must run
/// before the first parallel work.
pub fn set_worker_threads(threads: usize) -> Result<(), String> {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads.max(1))
        .build_global()
        .map_err(|e| e.to_string())
}

/// The file of a datagen shard holding its tasks' data (see [`write_shard_tasks`]).
pub const SHARD_TASKS_FILE: &str = "tasks.bin";
const SHARD_MAGIC: &[u8; 8] = b"GROPDGS1";

/// Writes a shard's simulated tasks, exactly (little-endian binary: magic `GROPDGS1`, the
/// simulation's wall seconds as f64 bits, the task count, then per task its row index, crop,
/// successes and trials per cell and its trial records with f64 bits).
pub fn write_shard_tasks(dataset: &Dataset, path: &Path) -> Result<(), DatagenError> {
    let write = || -> std::io::Result<()> {
        let mut w = BufWriter::with_capacity(1 << 20, File::create(path)?);
        w.write_all(SHARD_MAGIC)?;
        w.write_all(&dataset.summary.simulate_s.to_bits().to_le_bytes())?;
        w.write_all(&(dataset.tasks.len() as u64).to_le_bytes())?;
        for t in &dataset.tasks {
            w.write_all(&(t.task.index as u64).to_le_bytes())?;
            w.write_all(&t.crop)?;
            for v in t.counts.successes.iter().chain(&t.counts.trials) {
                w.write_all(&v.to_le_bytes())?;
            }
            w.write_all(&(t.records.len() as u64).to_le_bytes())?;
            for r in &t.records {
                w.write_all(&r.task.to_le_bytes())?;
                w.write_all(&[r.row, r.col])?;
                w.write_all(&r.trial.to_le_bytes())?;
                for x in [
                    r.commanded_xy.0,
                    r.commanded_xy.1,
                    r.realised_xy.0,
                    r.realised_xy.1,
                ] {
                    w.write_all(&x.to_bits().to_le_bytes())?;
                }
                w.write_all(&[r.result.index() as u8])?;
            }
        }
        w.flush()
    };
    write().map_err(io_err(path))
}

/// A shard file that cannot be read back.
#[derive(Debug, thiserror::Error)]
#[error("datagen shard file {path}: {reason}")]
pub struct ShardFileError {
    /// The file.
    pub path: PathBuf,
    /// What is wrong.
    pub reason: String,
}

/// Reads what [`write_shard_tasks`] wrote: the simulation's wall seconds and the tasks' data
/// (the [`Task`] fields other than the row index are filled in from `cfg`, which must be the
/// configuration the shard ran with).
pub fn read_shard_tasks(
    cfg: &DatagenConfig,
    path: &Path,
) -> Result<(f64, Vec<TaskData>), ShardFileError> {
    let err = |reason: String| ShardFileError {
        path: path.to_path_buf(),
        reason,
    };
    let bytes = std::fs::read(path).map_err(|e| err(e.to_string()))?;
    let mut r = Reader {
        bytes: &bytes,
        at: 0,
    };
    let truncated = |what: &str| err(format!("truncated ({what})"));
    if r.take(8).ok_or_else(|| truncated("magic"))? != SHARD_MAGIC {
        return Err(err("not a datagen shard file (bad magic)".into()));
    }
    let simulate_s = f64::from_bits(r.u64().ok_or_else(|| truncated("header"))?);
    let n = r.u64().ok_or_else(|| truncated("header"))? as usize;
    let (_, all_tasks) = cfg.tasks();
    let mut out = Vec::with_capacity(n.min(all_tasks.len()));
    for _ in 0..n {
        let index = r.u64().ok_or_else(|| truncated("task"))? as usize;
        let task = *all_tasks.get(index).ok_or_else(|| {
            err(format!(
                "task row {index}, the configuration has {} tasks",
                all_tasks.len()
            ))
        })?;
        let crop: [u8; CROP_CELLS] = r
            .take(CROP_CELLS)
            .and_then(|c| c.try_into().ok())
            .ok_or_else(|| truncated("crop"))?;
        let mut cells = Vec::with_capacity(2 * CROP_CELLS);
        for _ in 0..2 * CROP_CELLS {
            cells.push(r.u16().ok_or_else(|| truncated("cells"))?);
        }
        let trials = cells.split_off(CROP_CELLS);
        let m = r.u64().ok_or_else(|| truncated("records"))? as usize;
        let mut records = Vec::with_capacity(m.min(1 << 20));
        for _ in 0..m {
            let rec = (|| {
                let task = r.u32()?;
                let rc = r.take(2)?;
                let (row, col) = (rc[0], rc[1]);
                let trial = r.u16()?;
                let mut x = [0.0; 4];
                for v in &mut x {
                    *v = f64::from_bits(r.u64()?);
                }
                let result = *TrialResult::ALL.get(usize::from(r.take(1)?[0]))?;
                Some(TrialRecord {
                    task,
                    row,
                    col,
                    trial,
                    commanded_xy: (x[0], x[1]),
                    realised_xy: (x[2], x[3]),
                    result,
                })
            })()
            .ok_or_else(|| truncated("trial record"))?;
            records.push(rec);
        }
        out.push(TaskData {
            task,
            crop,
            counts: CellCounts {
                successes: cells,
                trials,
            },
            records,
        });
    }
    if r.at != bytes.len() {
        return Err(err(format!(
            "{} bytes after the last task",
            bytes.len() - r.at
        )));
    }
    Ok((simulate_s, out))
}

struct Reader<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl<'a> Reader<'a> {
    fn take(&mut self, n: usize) -> Option<&'a [u8]> {
        let s = self.bytes.get(self.at..self.at.checked_add(n)?)?;
        self.at += n;
        Some(s)
    }
    fn u64(&mut self) -> Option<u64> {
        Some(u64::from_le_bytes(self.take(8)?.try_into().ok()?))
    }
    fn u32(&mut self) -> Option<u32> {
        Some(u32::from_le_bytes(self.take(4)?.try_into().ok()?))
    }
    fn u16(&mut self) -> Option<u16> {
        Some(u16::from_le_bytes(self.take(2)?.try_into().ok()?))
    }
}

/// The whole dataset from its shards' tasks (any order): every row of `cfg`'s task list
/// exactly once. `simulate_s` (wall seconds, outside the determinism contract) goes into the
/// summary as given.
pub fn merge_shards(
    cfg: &DatagenConfig,
    tasks: Vec<TaskData>,
    simulate_s: f64,
) -> Result<Dataset, DatagenError> {
    cfg.validate()?;
    let (scenes, all) = cfg.tasks();
    let mut slots: Vec<Option<TaskData>> = vec![None; all.len()];
    for t in tasks {
        let i = t.task.index;
        let n = slots.len();
        let slot = slots.get_mut(i).ok_or_else(|| {
            DatagenError::InvalidConfig(format!("task row {i} beyond the {n} tasks"))
        })?;
        if slot.is_some() {
            return Err(DatagenError::InvalidConfig(format!(
                "task row {i} is in two shards"
            )));
        }
        *slot = Some(t);
    }
    let data = slots
        .into_iter()
        .enumerate()
        .map(|(i, t)| {
            t.ok_or_else(|| DatagenError::InvalidConfig(format!("task row {i} is in no shard")))
        })
        .collect::<Result<Vec<_>, _>>()?;
    let summary = summarise(&data, cfg.trials_per_cell, simulate_s);
    Ok(Dataset {
        scenes,
        tasks: data,
        summary,
    })
}
