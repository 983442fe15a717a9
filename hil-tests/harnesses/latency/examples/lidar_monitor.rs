//! The range sensor's path to the base alone (the section `grop latency` reports;
//! docs/lidar.md, "Latency"): a revolution over loopback UDP to the obstacles, the monitor's
//! check of one command, and a stop decision to its CAN frame.
//!
//! `cargo run --release -p latency --example lidar_monitor -- [SAMPLES]` (default 200).

fn main() -> anyhow::Result<()> {
    let samples: usize = std::env::args()
        .nth(1)
        .map(|a| a.parse())
        .transpose()?
        .unwrap_or(200);
    let r = latency::lidar::measure(&latency::lidar::LidarConfig {
        revolutions: samples,
        stops: samples,
    })?;
    print!("{}", latency::lidar::markdown(&r));
    Ok(())
}
