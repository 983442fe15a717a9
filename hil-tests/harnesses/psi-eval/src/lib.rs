//! How good is a feasibility evaluator Psi (paper eq. 2-4)? This crate holds the comparators the
//! trained FCN is measured against and the measurement itself:
//!
//! - [`heuristics`]: reach annulus minus furniture (binary), the same blurred by the navigation
//!   noise, and the simulator oracle, all behind `planner::feasibility::FeasibilityEvaluator`
//!   (the FCN is `planner::feasibility::FcnEvaluator`);
//! - [`evalset`]: freshly generated evaluation scenes with ground truth from many trials per cell;
//! - [`metrics`]: MAE, Brier, ECE, |F_hat - F| (eq. 4) and the expected success of Smp's goal.
//!
//! ```no_run
//! use psi_eval::{evalset::{build_eval_set, evaluate, EvalSpec}, heuristics::BinaryAnnulusEvaluator};
//! use planner::feasibility::FcnEvaluator;
//! let robot = world::RobotConfig::default();
//! let set = build_eval_set(&robot, &EvalSpec::default())?;
//! let mut fcn = FcnEvaluator::load(std::path::Path::new("models/psi-fcn.onnx"))?;
//! let fcn_report = evaluate(&mut fcn, &set)?;
//! let binary_report = evaluate(&mut BinaryAnnulusEvaluator::new(), &set)?;
//! println!("{}\n{}\n{}", psi_eval::metrics::QualityReport::markdown_header(),
//!          fcn_report.markdown_row(), binary_report.markdown_row());
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! `grop model-eval` runs this from the command line; docs/fcn.md has the numbers.

pub mod evalset;
pub mod heuristics;
pub mod metrics;
pub mod thresholds;
