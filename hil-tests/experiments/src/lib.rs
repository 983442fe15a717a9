//! The paper's experiments: GROP and baselines executed in the trial simulator.
