//! The paper's experiments (section V): GROP and the four baselines plan 3-object table-setting
//! tasks in the 30 evaluation scenes, and each plan is executed in the trial simulator with
//! navigation noise. Measures per-object and all-three success, execution time, difficulty thirds
//! by ground-truth servable area, and the robot-speed sweep of Table I.
//!
//! ```no_run
//! use experiments::{EvalConfig, Workload, ground_truth, evaluate_heatmaps, run, Summary};
//! let cfg = EvalConfig::default();
//! let workload = Workload::build(&cfg);
//! // Ground truth (for difficulty), cached on disk because it is the slow part.
//! let truth = ground_truth(&cfg, &workload, Some(std::path::Path::new("target/gt.json")))?;
//! // Psi for the planners: here the simulator oracle (an independent estimate).
//! let mut oracle = psi_eval::heuristics::OracleEvaluator::new(5, 99);
//! let psi = evaluate_heatmaps(&workload, &mut oracle)?;
//! let records = run(&cfg, &workload, &psi, &truth)?;
//! let summary = Summary::from_records(&cfg, &records);
//! println!("{}", summary.markdown(&cfg));
//! # Ok::<(), experiments::EvalError>(())
//! ```
//!
//! Execution protocol (paper and authors' code): drive to the station and load everything, then
//! for each unloading step drive (A* path at the robot's speed) to the commanded goal, where the
//! base ends at goal + N(0, sigma^2 I); the object is placed iff the realised base is collision-free
//! and the arm can place it. A navigation that finds no path or ends in collision fails and counts
//! [`EvalConfig::failed_nav_time_s`] (60 s). No replanning after a failure, except GROP+'s
//! retries ([`planner::grop_plus::retry_goal`]): each retry is one more attempt of the trial
//! simulator ([`trial_sim::retry`]), with the same noise model and its own travel and unloading
//! time.

mod config;
mod execution;
pub mod full_setting;
mod heatmaps;
pub mod plot;
mod records;
mod report;
mod stats;
mod workload;

pub use config::*;
pub use execution::*;
pub use heatmaps::*;
pub use records::*;
pub use stats::*;
pub use workload::*;

use std::path::{Path, PathBuf};

use planner::costs::GridTravelTime;
use planner::feasibility::{FeasibilityError, FeasibilityEvaluator};
use planner::grop_plus::retry_goal;
use planner::methods::{
    MethodKind, PlanError, PlannedTask, Planner, PlannerConfig, TaskMotionPlanner,
};
use planner::problem::{CANDIDATE_CELLS, TaskProblem, candidate_cells, evaluate_crops};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use trial_sim::retry::{Attempt, AttemptCosts, unload_with_retries};
pub use trial_sim::shard::Shard;
use trial_sim::{TrialResult, TrialSimulator, ground_truth_heatmap};
use world::generate::{evaluation_suite, mix_seed};
use world::nav::OccupancyGrid;
use world::view::{CELL_SIZE_M, render_crop};
use world::{Heatmap, RobotConfig, Scene, Side};

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn thirds_by_area() {
        let areas = [5.0, 1.0, 3.0, 2.0, 6.0, 4.0];
        let g = difficulty_groups(&areas);
        assert_eq!(g[1], Difficulty::Hard);
        assert_eq!(g[3], Difficulty::Hard);
        assert_eq!(g[2], Difficulty::Normal);
        assert_eq!(g[5], Difficulty::Normal);
        assert_eq!(g[0], Difficulty::Easy);
        assert_eq!(g[4], Difficulty::Easy);
    }

    #[test]
    fn stats_aggregate() {
        let r = |placed, time_s| TaskRecord {
            task: 0,
            scene: 0,
            n_chairs: 15,
            speed_mps: 0.4,
            method: "GROP",
            difficulty: Difficulty::Easy,
            servable_area_m2: 1.0,
            objects: 3,
            placed,
            time_s,
            distance_m: 0.0,
            predicted_f: 0.0,
            predicted_cost_s: 0.0,
            motion_planner_calls: 19,
            retries: 0,
            steps: String::new(),
        };
        let s = Stats::of(&[r(3, 10.0), r(0, 30.0)]);
        assert_eq!(s.tasks, 2);
        assert_eq!(s.completion, 0.5);
        assert_eq!(s.all_placed, 0.5);
        assert_eq!(s.mean_time_s, 20.0);
        assert_eq!(s.std_time_s, 10.0);
        assert_eq!(Stats::of(&[]), Stats::default());
    }

    #[test]
    fn paired_difference_matches_tasks() {
        let r = |task, method, placed| TaskRecord {
            task,
            scene: 0,
            n_chairs: 15,
            speed_mps: 0.4,
            method,
            difficulty: Difficulty::Easy,
            servable_area_m2: 1.0,
            objects: 3,
            placed,
            time_s: 1.0,
            distance_m: 0.0,
            predicted_f: 0.0,
            predicted_cost_s: 0.0,
            motion_planner_calls: 0,
            retries: 0,
            steps: String::new(),
        };
        let a = [
            r(0, "GROP", 3),
            r(1, "GROP", 2),
            r(2, "GROP", 3),
            r(7, "GROP", 0),
        ];
        // Listed in another order; task 7 has no partner and is left out.
        let b = [r(2, "DVH", 0), r(0, "DVH", 3), r(1, "DVH", 2)];
        let d = PairedDiff::of(&a.iter().collect::<Vec<_>>(), &b.iter().collect::<Vec<_>>());
        assert_eq!(d.tasks, 3);
        // Differences 0, 0, 1: mean 1/3, sample sd sqrt(1/3), se sqrt(1/9).
        assert!((d.mean - 1.0 / 3.0).abs() < 1e-12);
        assert!((d.std_error - (1.0f64 / 9.0).sqrt()).abs() < 1e-12);
        assert!(PairedDiff::of(&[], &[]).std_error.is_nan());
    }

    #[test]
    fn runs_cover_main_and_sweep_once() {
        let cfg = EvalConfig::default();
        let runs = cfg.runs();
        // Six methods at 0.4 m/s; GROP+, GROP, PETLON and DVH also at 0.2 and 0.8 m/s.
        assert_eq!(runs.len(), 6 + 2 * 4);
        assert!(runs.contains(&(0.2, MethodKind::Dvh)));
        assert!(runs.contains(&(0.8, MethodKind::GropPlus)));
        assert!(!runs.contains(&(0.2, MethodKind::Satisficing)));
    }

    #[test]
    fn bad_config_is_reported() {
        let cfg = EvalConfig {
            main_speed_mps: 0.0,
            ..EvalConfig::default()
        };
        assert!(matches!(cfg.check(), Err(EvalError::Config(_))));
        let cfg = EvalConfig {
            methods: vec![],
            ..EvalConfig::default()
        };
        assert!(matches!(cfg.check(), Err(EvalError::Config(_))));
    }
}
