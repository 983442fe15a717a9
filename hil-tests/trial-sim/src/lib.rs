//! Trial simulator, dataset generator and experiments.
