//! Command-to-feedback round trip through the iceoryx2 virtual CAN bus: this process sends one
//! 0x500 motion frame, the `sim-rmp` process (its own process, as in HIL) answers with a
//! feedback set, and the time until the set's last frame (and its first) arrives is measured.
//!
//! Criterion reports the mean and its confidence interval; p50 / p99 come from a separate pass
//! of `PERCENTILE_SAMPLES` round trips printed at the end. Run with
//! `cargo bench -p sim-rmp --bench can_round_trip`.
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failure panics with its message

use std::io::{BufRead, BufReader};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use can_bus::{CanBus, VirtualCanBus};
use criterion::{Criterion, criterion_group, criterion_main};
use rmp_base::{DRIVER_FEEDBACK_ITEMS, from_can, to_can};
use rmp_codec::feedback::{FeedbackBitmaps, FeedbackLayout};
use rmp_codec::v3::{ConfigCommand, FirmwareProfile, MotionCommand};

const PERCENTILE_SAMPLES: usize = 2000;

struct Sim(Child);

impl Drop for Sim {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

fn spawn_sim(bus: &str) -> Sim {
    let mut child = Command::new(env!("CARGO_BIN_EXE_sim-rmp"))
        .args(["--bus", bus, "--exit-after-s", "600"])
        .env("RUST_LOG", "warn")
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .spawn()
        .expect("sim-rmp starts");
    let stdout = child.stdout.take().expect("piped");
    let mut line = String::new();
    BufReader::new(stdout)
        .read_line(&mut line)
        .expect("ready line");
    assert!(line.starts_with("sim-rmp ready"), "{line}");
    Sim(child)
}

/// One round trip; returns (first frame, complete set) latencies.
fn round_trip(bus: &mut VirtualCanBus, frames_per_set: usize) -> (Duration, Duration) {
    let frame = to_can(&MotionCommand::ZERO.encode());
    let start = Instant::now();
    bus.send(&frame).expect("send");
    let mut first = None;
    let last_id = 0x502 + frames_per_set as u16 - 1;
    loop {
        let got = bus
            .recv_timeout(Duration::from_secs(1))
            .expect("recv")
            .and_then(|f| from_can(&f))
            .expect("the simulator answers within 1 s");
        first.get_or_insert_with(|| start.elapsed());
        if got.id() == last_id {
            return (first.unwrap_or_default(), start.elapsed());
        }
    }
}

fn configure(bus: &mut VirtualCanBus, bitmaps: FeedbackBitmaps) {
    for (index, bitmap) in bitmaps.words().into_iter().enumerate() {
        let cmd = ConfigCommand::SetFeedbackBitmap {
            index: index as u8,
            bitmap,
        }
        .encode(FirmwareProfile::SegwayInc2014)
        .expect("valid");
        bus.send(&to_can(&cmd)).expect("send");
    }
    // Drain the replies.
    while bus
        .recv_timeout(Duration::from_millis(200))
        .expect("recv")
        .is_some()
    {}
}

fn percentiles(mut v: Vec<Duration>) -> (Duration, Duration, Duration) {
    v.sort();
    let at = |q: f64| v[((v.len() - 1) as f64 * q).round() as usize];
    (at(0.5), at(0.99), v[v.len() - 1])
}

fn bench(c: &mut Criterion) {
    let bus_name = format!("rmp-bench-{}", std::process::id());
    let _sim = spawn_sim(&bus_name);
    let mut bus = VirtualCanBus::join(&bus_name, "bench").expect("join");
    let driver_set = FeedbackBitmaps::from_items(&DRIVER_FEEDBACK_ITEMS);
    let mut report = Vec::new();
    for (label, bitmaps) in [
        ("default_96_items_48_frames", FeedbackBitmaps::DEFAULT),
        ("driver_16_items_8_frames", driver_set),
    ] {
        configure(&mut bus, bitmaps);
        let frames = FeedbackLayout::User(bitmaps).frame_count();
        c.bench_function(&format!("can_round_trip/{label}"), |b| {
            b.iter_custom(|iters| {
                (0..iters)
                    .map(|_| round_trip(&mut bus, frames).1)
                    .sum::<Duration>()
            })
        });
        let samples: Vec<_> = (0..PERCENTILE_SAMPLES)
            .map(|_| round_trip(&mut bus, frames))
            .collect();
        let first = percentiles(samples.iter().map(|s| s.0).collect());
        let full = percentiles(samples.iter().map(|s| s.1).collect());
        report.push(format!(
            "{label}: first frame p50 {:?} p99 {:?} max {:?}; complete set p50 {:?} p99 {:?} max {:?} ({PERCENTILE_SAMPLES} round trips)",
            first.0, first.1, first.2, full.0, full.1, full.2
        ));
    }
    println!("\nCAN command-to-feedback round trip through the virtual bus (sim-rmp process):");
    for line in report {
        println!("  {line}");
    }
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(30).measurement_time(Duration::from_secs(5));
    targets = bench
}
criterion_main!(benches);
