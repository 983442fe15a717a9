//! Per-call latency percentiles and single-core throughput of `plan_place` on the dataset
//! generator's workload (100 targets x 192 candidate cells x 5 noisy trials = 96,000 calls),
//! and the outcome mix.
//!
//! `cargo run --release -p ur5e-kin --example place_latency`

use std::time::Instant;

use ur5e_kin::bench_scene::dinner_table_queries;
use ur5e_kin::{PlaceConfig, PlaceFailure, plan_place};

fn main() {
    let cfg = PlaceConfig::default();
    let queries = dinner_table_queries(&cfg, 2022, 100, 5);
    let mut latencies_ns = Vec::with_capacity(queries.len());
    let mut counts = [0usize; 4];
    let start = Instant::now();
    for q in &queries {
        let t = Instant::now();
        let result = plan_place(&cfg, q.base, q.goal, &q.obstacles);
        latencies_ns.push(t.elapsed().as_nanos() as u64);
        counts[match result {
            Ok(_) => 0,
            Err(PlaceFailure::OutOfReach) => 1,
            Err(PlaceFailure::JointLimits) => 2,
            Err(PlaceFailure::Collision) => 3,
        }] += 1;
    }
    let total_s = start.elapsed().as_secs_f64();
    latencies_ns.sort_unstable();
    let pct = |p: f64| latencies_ns[((latencies_ns.len() - 1) as f64 * p) as usize] as f64 / 1e3;
    let n = queries.len();
    println!(
        "{n} plan_place calls in {total_s:.3} s on one core: {:.0} calls/s",
        n as f64 / total_s
    );
    println!(
        "latency us: p50 {:.2}  p90 {:.2}  p99 {:.2}  max {:.2}",
        pct(0.5),
        pct(0.9),
        pct(0.99),
        pct(1.0)
    );
    let share = |c: usize| 100.0 * c as f64 / n as f64;
    println!(
        "outcomes: placed {:.1}%  out of reach {:.1}%  joint limits {:.1}%  collision {:.1}%",
        share(counts[0]),
        share(counts[1]),
        share(counts[2]),
        share(counts[3])
    );
}
