//! RTDE receive jitter at 500 Hz with the `ur5e` client against the simulator running as its
//! own process (a documented harness, not criterion: the result is a distribution of
//! inter-arrival times, not the duration of a function).
//!
//! `cargo bench -p sim-ur5e --bench rtde_jitter [-- --seconds 10]`
//!
//! Reports, over N received packages: p50 / p99 / max of |inter-arrival - 2 ms| measured on
//! this side with the monotonic clock, packages skipped by newest-wins, and the same deviation
//! of the controller's own timestamps (its 500 Hz loop on absolute deadlines).
#![allow(
    clippy::too_many_lines,
    reason = "a benchmark's setup, loop and report in one place"
)]
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failure panics with its message

use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use ur5e::rtde::{DataPackage, RtdeClient, RtdeTimeouts};

fn percentile(sorted: &[f64], p: f64) -> f64 {
    let i = ((sorted.len() as f64 - 1.0) * p).round() as usize;
    sorted[i.min(sorted.len() - 1)]
}

fn main() {
    let mut seconds = 10.0;
    let args: Vec<String> = std::env::args().collect();
    if let Some(i) = args.iter().position(|a| a == "--seconds") {
        seconds = args
            .get(i + 1)
            .and_then(|s| s.parse().ok())
            .unwrap_or(seconds);
    }
    let dir = std::env::temp_dir().join(format!("rtde-jitter-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let ports_file = dir.join("ports.json");
    let mut child = Command::new(env!("CARGO_BIN_EXE_sim-ur5e"))
        .args(["--ephemeral", "--ports-file"])
        .arg(&ports_file)
        .env("RUST_LOG", "warn")
        .stdout(Stdio::null())
        .spawn()
        .expect("sim-ur5e starts");
    let t0 = Instant::now();
    while !ports_file.exists() {
        assert!(
            t0.elapsed() < Duration::from_secs(10),
            "sim-ur5e did not start"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    let text = std::fs::read_to_string(&ports_file).expect("ports file");
    let port: u16 = text
        .split("\"rtde\":")
        .nth(1)
        .and_then(|s| s.split([',', '}']).next())
        .and_then(|s| s.trim().parse().ok())
        .expect("rtde port in ports file");

    let mut c = RtdeClient::connect(("127.0.0.1", port), RtdeTimeouts::default()).expect("connect");
    let recipe = c
        .setup_outputs(
            &[
                "timestamp",
                "actual_q",
                "actual_qd",
                "actual_TCP_pose",
                "robot_mode",
                "safety_status_bits",
                "runtime_state",
            ],
            500.0,
        )
        .expect("recipe")
        .clone();
    c.start().expect("start");
    let mut pkg = DataPackage::for_recipe(&recipe);
    // Warm-up.
    for _ in 0..250 {
        c.receive_latest(&mut pkg, Duration::from_secs(1))
            .expect("receive");
    }
    let n = (seconds * 500.0) as usize;
    let mut arrivals = Vec::with_capacity(n);
    let mut stamps = Vec::with_capacity(n);
    let mut skipped = 0u64;
    for _ in 0..n {
        c.receive_latest(&mut pkg, Duration::from_secs(1))
            .expect("receive");
        arrivals.push(pkg.received_at);
        stamps.push(pkg.values[0].as_f64().unwrap_or(f64::NAN));
        skipped += u64::from(pkg.skipped);
    }
    let _ = child.kill();
    let _ = child.wait();
    let _ = std::fs::remove_dir_all(&dir);

    let period_us = 2000.0;
    let mut dev: Vec<f64> = arrivals
        .windows(2)
        .map(|w| ((w[1] - w[0]).as_secs_f64() * 1e6 - period_us).abs())
        .collect();
    dev.sort_by(f64::total_cmp);
    let mut ctl: Vec<f64> = stamps
        .windows(2)
        .map(|w| ((w[1] - w[0]) * 1e6 - period_us).abs())
        .collect();
    ctl.sort_by(f64::total_cmp);
    println!(
        "RTDE receive jitter, 500 Hz, {} packages ({seconds} s), sim-ur5e as a separate process",
        n
    );
    println!(
        "  arrival deviation |dt - 2 ms|: p50 {:.1} us, p90 {:.1} us, p95 {:.1} us, p99 {:.1} us, max {:.1} us",
        percentile(&dev, 0.5),
        percentile(&dev, 0.9),
        percentile(&dev, 0.95),
        percentile(&dev, 0.99),
        dev.last().copied().unwrap_or(f64::NAN)
    );
    // Delay of each package behind the controller's schedule: arrival (client clock) minus
    // controller time, minus the smallest such offset (both clocks run at nominal rate).
    let offsets: Vec<f64> = arrivals
        .iter()
        .zip(&stamps)
        .map(|(a, t)| (*a - arrivals[0]).as_secs_f64() - (t - stamps[0]))
        .collect();
    let min = offsets.iter().copied().fold(f64::INFINITY, f64::min);
    let mut late: Vec<f64> = offsets.iter().map(|o| (o - min) * 1e6).collect();
    late.sort_by(f64::total_cmp);
    println!(
        "  delay behind the controller's 2 ms schedule: p50 {:.1} us, p99 {:.1} us, max {:.1} us",
        percentile(&late, 0.5),
        percentile(&late, 0.99),
        late.last().copied().unwrap_or(f64::NAN)
    );
    println!(
        "  controller timestamp steps deviating from 2 ms: p50 {:.1} us, p99 {:.1} us (non-zero = skipped packages)",
        percentile(&ctl, 0.5),
        percentile(&ctl, 0.99)
    );
    println!(
        "  packages dropped by newest-wins: {skipped} ({:.3} %)",
        100.0 * skipped as f64 / n as f64
    );
}
