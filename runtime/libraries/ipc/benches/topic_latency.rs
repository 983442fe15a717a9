//! One-way latency through the runtime's services: the publisher stamps the message, a
//! subscriber asleep in `recv_timeout` on another thread measures arrival. One message in
//! flight. criterion reports means; p50/p99/max over every message are printed at the end.
//! Run: `cargo bench -p grop-ipc`.
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failure panics with its message

use std::sync::mpsc;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use criterion::{Criterion, criterion_group, criterion_main};
use grop_ipc::{BaseStateMsg, CameraFrameHeader, CameraFrameMsg, IpcNode, PixelFormat, Topic};

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

/// `fill(message, stamp_ns)` writes a message carrying its send time.
fn one_way<T: Topic>(
    c: &mut Criterion,
    name: &str,
    namespace: &str,
    fill: fn(&mut T, u64),
) -> Samples {
    let samples: Samples = Arc::default();
    let epoch = Instant::now();
    let pub_node = IpcNode::new(namespace, "bench-pub").expect("node");
    let publisher = pub_node.publisher::<T>().expect("publisher");
    let (ready_tx, ready_rx) = mpsc::channel::<()>();
    let (latency_tx, latency_rx) = mpsc::channel::<Duration>();
    let (stop_tx, stop_rx) = mpsc::channel::<()>();
    let sub_namespace = namespace.to_owned();
    let receiver = std::thread::spawn(move || {
        let node = IpcNode::new(&sub_namespace, "bench-sub").expect("node");
        let subscriber = node.subscriber::<T>().expect("subscriber");
        let _ = ready_tx.send(());
        while stop_rx.try_recv().is_err() {
            if let Ok(Some(message)) = subscriber.recv_timeout(Duration::from_millis(100)) {
                let arrived = epoch.elapsed();
                let sent = Duration::from_nanos(message.stamp_ns());
                if latency_tx.send(arrived.saturating_sub(sent)).is_err() {
                    return;
                }
            }
        }
    });
    ready_rx.recv().expect("subscriber ready");
    let recorded = Arc::clone(&samples);
    c.bench_function(&format!("one_way/{name}"), |b| {
        b.iter_custom(|iters| {
            let mut total = Duration::ZERO;
            for _ in 0..iters {
                let stamp = u64::try_from(epoch.elapsed().as_nanos()).unwrap_or(u64::MAX);
                publisher
                    .publish_with(|message| fill(message, stamp))
                    .expect("publish");
                let latency = latency_rx
                    .recv_timeout(Duration::from_secs(5))
                    .expect("message arrives");
                total += latency;
                recorded.lock().expect("samples").push(latency);
            }
            total
        });
    });
    let _ = stop_tx.send(());
    let _ = receiver.join();
    samples
}

fn fill_state(state: &mut BaseStateMsg, stamp_ns: u64) {
    state.stamp_ns = stamp_ns;
    state.speed_mps = 0.4;
}

fn fill_crop_frame(frame: &mut CameraFrameMsg, stamp_ns: u64) {
    fill_frame(frame, stamp_ns, 64, 64, PixelFormat::Mono8);
}

fn fill_room_frame(frame: &mut CameraFrameMsg, stamp_ns: u64) {
    fill_frame(frame, stamp_ns, 640, 480, PixelFormat::Rgb8);
}

/// Writes the image in place, as a camera driver would (no intermediate buffer).
fn fill_frame(
    frame: &mut CameraFrameMsg,
    stamp_ns: u64,
    width_px: u32,
    height_px: u32,
    format: PixelFormat,
) {
    let mut header = CameraFrameHeader {
        frame_id: stamp_ns,
        stamp_ns,
        width_px,
        height_px,
        pixel_format: 0,
        row_stride_bytes: width_px * format.bytes_per_px() as u32,
        metres_per_px: 0.03125,
        left_x_m: 0.0,
        top_y_m: 0.0,
    };
    header.set_pixel_format(format);
    let image = frame.image_mut(header).expect("a valid header");
    for (index, byte) in image.iter_mut().enumerate() {
        *byte = index as u8;
    }
}

fn latency(c: &mut Criterion) {
    let ns = |what: &str| format!("bench-{}-{what}", std::process::id());
    let state = one_way(c, "base_state", &ns("state"), fill_state);
    let crop = one_way(c, "camera_64x64_mono8", &ns("crop"), fill_crop_frame);
    let room = one_way(c, "camera_640x480_rgb8", &ns("room"), fill_room_frame);
    report("one_way/base_state", &state);
    report("one_way/camera_64x64_mono8", &crop);
    report("one_way/camera_640x480_rgb8 (incl. writing 900 KiB)", &room);
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(30).measurement_time(Duration::from_secs(3));
    targets = latency
}
criterion_main!(benches);
