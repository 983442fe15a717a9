//! Task planner, GROP and baselines.
