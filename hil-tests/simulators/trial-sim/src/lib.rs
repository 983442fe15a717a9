//! The simulated world's trial simulator and the feasibility dataset generator (paper
//! section III-B): a trial commands the base to a cell facing the table, adds N(0, sigma^2 I)
//! navigation noise, and succeeds iff the base stands free and the UR5e finds a collision-free
//! placing configuration. Ground-truth heatmaps and `grop datagen` are built on it.
//!
//! ```no_run
//! use trial_sim::{ground_truth_heatmap, datagen};
//! use world::{RobotConfig, Side};
//! let scene = world::generate::training_scenes(0, 1, 1).remove(0);
//! let robot = RobotConfig::default();
//! // Fea^m over the candidate area (paper eq. 1), 5 trials per cell, seeded.
//! let heatmap = ground_truth_heatmap(&scene, &robot, scene.targets[0].as_array(), Side::Near, 5, 42);
//! // The paper's 96,000-trial dataset into out/dataset.
//! let summary = datagen::generate(&datagen::DatagenConfig::default(), &datagen::NoProgress)?;
//! println!("success rate {:.3}", summary.success_rate);
//! # let _ = heatmap;
//! # Ok::<(), datagen::DatagenError>(())
//! ```

pub mod datagen;
pub mod retry;
pub mod shard;
pub mod trial;

pub use trial::{
    ArmModel, CellCounts, HeatmapArea, TrialOutcome, TrialResult, TrialSimulator, Ur5eArm,
    cell_rng, ground_truth_heatmap, ground_truth_heatmap_in, ground_truth_heatmaps, run_trial,
    simulate_cells, task_feasibility,
};
