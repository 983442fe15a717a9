//! Latency through the virtual CAN bus (and the in-process MemoryBus for comparison).
//!
//! - `one_way/*`: a sender thread stamps the send time into the frame; the receiving node sleeps
//!   in `recv_timeout` on another thread (the wake-up path a driver uses) and measures arrival.
//!   One frame in flight at a time.
//! - `round_trip/virtual_bus_two_processes`: send a frame, wait for the echo from `vcan echo`
//!   in another process (a command-to-reply cycle through the bus).
//!
//! criterion reports means and medians; p50/p99/max of every measured frame are printed at the
//! end, as a bus latency table wants them. Run: `cargo bench -p vcan-tool` (here beside the `vcan`
//! binary, which the two-process round trip spawns).
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failure panics with its message

use std::process::{Command, Stdio};
use std::sync::mpsc;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use can_bus::{CanBus, CanFrame, CanId, MemoryBus, VirtualCanBus, conformance};
use criterion::{Criterion, criterion_group, criterion_main};

type Samples = Arc<Mutex<Vec<Duration>>>;

fn report(name: &str, samples: &Samples) {
    let Ok(mut samples) = samples.lock() else {
        return;
    };
    if samples.is_empty() {
        return;
    }
    samples.sort_unstable();
    let at = |q: f64| samples[((samples.len() - 1) as f64 * q).round() as usize];
    println!(
        "{name}: n={} p50={:.1?} p99={:.1?} max={:.1?}",
        samples.len(),
        at(0.5),
        at(0.99),
        samples[samples.len() - 1]
    );
}

/// One-way latency between two nodes made by `join`, receiver blocked on another thread.
fn one_way<B: CanBus + Send + 'static>(
    c: &mut Criterion,
    name: &str,
    mut sender: B,
    mut receiver: B,
) -> Samples {
    let samples: Samples = Arc::default();
    let epoch = Instant::now();
    let (latency_tx, latency_rx) = mpsc::channel::<Option<Duration>>();
    let (stop_tx, stop_rx) = mpsc::channel::<()>();
    let receiver_thread = std::thread::spawn(move || {
        while stop_rx.try_recv().is_err() {
            match receiver.recv_timeout(Duration::from_millis(100)) {
                Ok(Some(frame)) => {
                    let arrived = epoch.elapsed();
                    let mut stamp = [0u8; 8];
                    stamp.copy_from_slice(frame.data());
                    let sent = Duration::from_nanos(u64::from_le_bytes(stamp));
                    if latency_tx.send(Some(arrived.saturating_sub(sent))).is_err() {
                        return;
                    }
                }
                Ok(None) => {}
                Err(_) => {
                    let _ = latency_tx.send(None);
                    return;
                }
            }
        }
    });
    let recorded = Arc::clone(&samples);
    c.bench_function(&format!("one_way/{name}"), |b| {
        b.iter_custom(|iters| {
            let mut total = Duration::ZERO;
            for _ in 0..iters {
                let stamp = u64::try_from(epoch.elapsed().as_nanos()).unwrap_or(u64::MAX);
                let frame = CanFrame::new(CanId::Standard(0x502), &stamp.to_le_bytes())
                    .expect("valid frame");
                sender.send(&frame).expect("send");
                let latency = latency_rx
                    .recv_timeout(Duration::from_secs(5))
                    .ok()
                    .flatten()
                    .expect("frame arrives");
                total += latency;
                recorded.lock().expect("samples").push(latency);
            }
            total
        });
    });
    let _ = stop_tx.send(());
    let _ = receiver_thread.join();
    samples
}

fn round_trip_two_processes(c: &mut Criterion, bus: &str) -> Option<Samples> {
    let samples: Samples = Arc::default();
    let mut local = VirtualCanBus::join(bus, "bench-local").ok()?;
    let mut peer = Command::new(env!("CARGO_BIN_EXE_vcan"))
        .args(["echo", bus, "--idle-timeout-ms", "20000"])
        .stdout(Stdio::null())
        .spawn()
        .ok()?;
    let ready = local.recv_timeout(Duration::from_secs(5)).ok().flatten();
    if ready.map(|f| f.id()) != Some(conformance::PEER_READY_ID) {
        let _ = peer.kill();
        return None;
    }
    let recorded = Arc::clone(&samples);
    let frame = CanFrame::new(CanId::Standard(0x500), &[0, 0, 0, 1, 0, 0, 0, 0]).ok()?;
    c.bench_function("round_trip/virtual_bus_two_processes", |b| {
        b.iter_custom(|iters| {
            let mut total = Duration::ZERO;
            for _ in 0..iters {
                let start = Instant::now();
                local.send(&frame).expect("send");
                let echo = local.recv_timeout(Duration::from_secs(5)).expect("receive");
                assert_eq!(echo, Some(frame), "echo peer answered");
                let elapsed = start.elapsed();
                total += elapsed;
                recorded.lock().expect("samples").push(elapsed);
            }
            total
        });
    });
    let stop = CanFrame::new(conformance::PEER_STOP_ID, &[]).ok()?;
    let _ = local.send(&stop);
    let _ = peer.wait();
    Some(samples)
}

fn latency(c: &mut Criterion) {
    let bus_name = format!("bench-{}", std::process::id());
    let virtual_bus = one_way(
        c,
        "virtual_bus_two_threads",
        join(&bus_name, "a"),
        join(&bus_name, "b"),
    );
    let memory = MemoryBus::new();
    let memory_bus = one_way(c, "memory_bus_two_threads", memory.join(), memory.join());
    let round_trip = round_trip_two_processes(c, &format!("bench-rt-{}", std::process::id()));
    report("one_way/virtual_bus_two_threads", &virtual_bus);
    report("one_way/memory_bus_two_threads", &memory_bus);
    match round_trip {
        Some(samples) => report("round_trip/virtual_bus_two_processes", &samples),
        None => println!("round_trip/virtual_bus_two_processes: echo peer did not start, skipped"),
    }
}

fn join(bus: &str, node: &str) -> VirtualCanBus {
    VirtualCanBus::join(bus, node).expect("join the virtual bus")
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(50).measurement_time(Duration::from_secs(3));
    targets = latency
}
criterion_main!(benches);
