//! Task planner, GROP and baselines.
pub mod arm;
pub mod costs;
pub mod feasibility;
pub mod methods;
pub mod problem;
pub mod task;
