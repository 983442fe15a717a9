//! Simulated UR5e controller on loopback TCP.
