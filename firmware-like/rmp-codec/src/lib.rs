//! Segway RMP CAN protocol codec (no_std, no heap).
