//! Plan published to the first motion frame on CAN, alone (the row `grop latency` reports):
//! `cargo run --release -p latency --example plan_motion -- [SAMPLES]`.

fn main() -> anyhow::Result<()> {
    let samples = std::env::args()
        .nth(1)
        .map(|s| s.parse::<usize>())
        .transpose()?
        .unwrap_or(20);
    let namespace = format!("grop-plan-motion-example-{}", std::process::id());
    let s = latency::plan_motion::plan_to_motion(samples, &namespace)?;
    println!(
        "plan published -> first motion frame on CAN: {} samples, p50 {:.1} ms, p99 {:.1} ms, max {:.1} ms",
        s.count,
        s.p50_ns as f64 / 1e6,
        s.p99_ns as f64 / 1e6,
        s.max_ns as f64 / 1e6
    );
    Ok(())
}
