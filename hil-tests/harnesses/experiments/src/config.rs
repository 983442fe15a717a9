//! The evaluation's settings and its errors.

use super::*;

/// Everything that defines an evaluation run. `Default` is the paper's setup.
#[derive(Debug, Clone)]
pub struct EvalConfig {
    /// Seed of scenes, goal draws, tie-breaks and navigation noise.
    pub seed: u64,
    /// Scenes per chair count (paper: 10).
    pub scenes_per_chair_count: usize,
    /// Chair counts (paper: 15, 20, 25).
    pub chair_counts: Vec<usize>,
    /// Tasks per scene (paper: 14, i.e. 420 tasks).
    pub tasks_per_scene: usize,
    /// Objects per task (paper: 3).
    pub objects_per_task: usize,
    /// Methods of the main comparison (Fig. 5).
    pub methods: Vec<MethodKind>,
    /// Speed of the main comparison (m/s).
    pub main_speed_mps: f64,
    /// Speeds of the sweep (Table I: 0.2, 0.4, 0.8 m/s); empty for none.
    pub sweep_speeds_mps: Vec<f64>,
    /// Methods of the sweep (Table I: GROP, PETLON, DVH).
    pub sweep_methods: Vec<MethodKind>,
    /// Planner settings (R, aggregation, goal draws, baseline goal variant); the speed is set per run.
    pub planner: PlannerConfig,
    /// Time to load one object at the station (s).
    pub load_time_s: f64,
    /// Time of one unloading attempt (s).
    pub unload_time_s: f64,
    /// Time charged for a navigation that finds no path or ends in collision (s).
    pub failed_nav_time_s: f64,
    /// Trials per cell of the ground-truth heatmaps that define difficulty.
    pub gt_trials_per_cell: u16,
    /// The robot (speed is overridden per run).
    pub robot: RobotConfig,
}

impl Default for EvalConfig {
    fn default() -> Self {
        let robot = RobotConfig::default();
        Self {
            seed: 2022,
            scenes_per_chair_count: 10,
            chair_counts: vec![15, 20, 25],
            tasks_per_scene: 14,
            objects_per_task: 3,
            methods: MethodKind::ALL.to_vec(),
            main_speed_mps: 0.4,
            sweep_speeds_mps: vec![0.2, 0.4, 0.8],
            sweep_methods: vec![
                MethodKind::GropPlus,
                MethodKind::Grop,
                MethodKind::Petlon,
                MethodKind::Dvh,
            ],
            planner: PlannerConfig::for_robot(&robot),
            // 3 x 3 s + 3 x 5 s = 24 s of manipulation per task: what Table I's times imply
            // (t = D / v + M at the three speeds gives M ~ 24 s for GROP).
            load_time_s: 3.0,
            unload_time_s: 5.0,
            failed_nav_time_s: 60.0,
            gt_trials_per_cell: 5,
            robot,
        }
    }
}

impl EvalConfig {
    /// Checks the values a user can set.
    pub fn check(&self) -> Result<(), EvalError> {
        let bad = |s: &str| Err(EvalError::Config(s.to_string()));
        if self.chair_counts.is_empty()
            || self.scenes_per_chair_count == 0
            || self.tasks_per_scene == 0
        {
            return bad("need at least one chair count, scene and task");
        }
        if self.objects_per_task == 0 || self.objects_per_task > planner::task::MAX_OBJECTS {
            return bad("objects per task must be in 1..=12");
        }
        let speeds =
            std::iter::once(self.main_speed_mps).chain(self.sweep_speeds_mps.iter().copied());
        for s in speeds {
            if !(s.is_finite() && s > 0.0) {
                return bad("speeds must be finite and > 0");
            }
        }
        if self.methods.is_empty() {
            return bad("no methods to evaluate");
        }
        if self.gt_trials_per_cell == 0 {
            return bad("ground truth needs at least one trial per cell");
        }
        Ok(())
    }

    /// The (speed, method) pairs to run: every method at the main speed, the sweep methods at the
    /// other sweep speeds.
    pub fn runs(&self) -> Vec<(f64, MethodKind)> {
        let mut runs: Vec<(f64, MethodKind)> = self
            .methods
            .iter()
            .map(|&m| (self.main_speed_mps, m))
            .collect();
        for &s in &self.sweep_speeds_mps {
            for &m in &self.sweep_methods {
                if !runs.iter().any(|&(rs, rm)| rs == s && rm == m) {
                    runs.push((s, m));
                }
            }
        }
        runs
    }
}

/// Why an evaluation failed.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum EvalError {
    /// A configuration value is out of range.
    #[error("evaluation configuration: {0}")]
    Config(String),
    /// A planner failed on a task.
    #[error("{method} on task {task}: {source}")]
    Plan {
        /// The method.
        method: &'static str,
        /// Task id.
        task: usize,
        /// The planner's error.
        source: PlanError,
    },
    /// The feasibility evaluator failed.
    #[error("feasibility evaluation: {0}")]
    Feasibility(#[from] FeasibilityError),
    /// A file could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The operating system's error.
        source: std::io::Error,
    },
    /// A shard's records file cannot be read back.
    #[error("eval records {path}: {reason}")]
    Records {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        reason: String,
    },
    /// The ground-truth cache file is not what this version writes.
    #[error("ground-truth cache {path}: {reason}")]
    Cache {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        reason: String,
    },
    /// Drawing the figure failed.
    #[error("plot {path}: {reason}")]
    Plot {
        /// The file.
        path: PathBuf,
        /// The backend's error.
        reason: String,
    },
}
