//! Segway RMP base driver over a CAN bus.
