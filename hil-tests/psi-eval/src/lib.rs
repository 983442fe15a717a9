//! Quality evaluation of feasibility evaluators (FCN, geometric heuristics, oracle) against simulated ground truth.
