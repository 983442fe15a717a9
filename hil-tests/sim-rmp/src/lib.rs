//! Simulated Segway RMP base on the virtual CAN bus.
