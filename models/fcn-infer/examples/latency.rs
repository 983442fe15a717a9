//! Latency harness: p50 / p99 of one crop and of a batch of 6 with tract on the calling thread.
//!
//! `cargo run --release -p fcn-infer --example latency -- models/psi-fcn.onnx 2000 [direct|tract]`
//! prints one JSON object (microseconds); the third argument picks how the convolutions run
//! (`direct`, our operator, the default; `tract`, tract's own lowering); `models/bench/run_bench.py` runs it beside the
//! onnxruntime harness and writes the side-by-side table into docs/fcn.md.
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failure panics with its message

use std::path::PathBuf;
use std::time::Instant;

use fcn_infer::{CROP_CELLS, ConvBackend, FcnModel, MAX_BATCH};

fn percentile(sorted: &[f64], q: f64) -> f64 {
    let idx = ((sorted.len() as f64 - 1.0) * q).round() as usize;
    sorted[idx.min(sorted.len() - 1)]
}

fn measure(iters: usize, mut f: impl FnMut()) -> (f64, f64, f64) {
    for _ in 0..iters / 10 + 10 {
        f();
    }
    let mut us: Vec<f64> = (0..iters)
        .map(|_| {
            let t = Instant::now();
            f();
            t.elapsed().as_secs_f64() * 1e6
        })
        .collect();
    us.sort_by(f64::total_cmp);
    let mean = us.iter().sum::<f64>() / us.len() as f64;
    (percentile(&us, 0.5), percentile(&us, 0.99), mean)
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let path = PathBuf::from(args.next().unwrap_or_else(|| "models/psi-fcn.onnx".into()));
    let iters: usize = args.next().map(|s| s.parse()).transpose()?.unwrap_or(2000);
    let backend = match args.next().as_deref() {
        None | Some("direct") => ConvBackend::Direct,
        Some("tract") => ConvBackend::Tract,
        Some(other) => return Err(format!("backend {other}: expected direct or tract").into()),
    };
    let t = Instant::now();
    let mut model = FcnModel::load_with(&path, backend)?;
    let load_ms = t.elapsed().as_secs_f64() * 1e3;
    let crops = fcn_infer::pattern_crops(MAX_BATCH);
    let mut one = [0f32; CROP_CELLS];
    let mut six = vec![[0f32; CROP_CELLS]; MAX_BATCH];
    let (p50_1, p99_1, mean_1) = measure(iters, || {
        model.predict(&crops[0], &mut one).expect("predict")
    });
    let (p50_6, p99_6, mean_6) = measure(iters / 2, || {
        model
            .predict_batch(&crops, &mut six)
            .expect("predict_batch")
    });
    // The planner's candidate cells only (world::view::CANDIDATE_ROWS x CANDIDATE_COLS).
    let (p50_w, p99_w, mean_w) = measure(iters / 2, || {
        model
            .predict_batch_window(&crops, &mut six, 9..17, 20..44)
            .expect("predict_batch_window")
    });
    println!(
        "{{\"runtime\": \"tract\", \"convolutions\": \"{backend:?}\", \"threads\": 1, \"iterations\": {iters}, \"load_ms\": {load_ms:.1}, \
         \"batch1\": {{\"p50_us\": {p50_1:.2}, \"p99_us\": {p99_1:.2}, \"mean_us\": {mean_1:.2}}}, \
         \"batch6\": {{\"p50_us\": {p50_6:.2}, \"p99_us\": {p99_6:.2}, \"mean_us\": {mean_6:.2}}}, \
         \"batch6_candidates\": {{\"p50_us\": {p50_w:.2}, \"p99_us\": {p99_w:.2}, \"mean_us\": {mean_w:.2}}}, \
         \"decoder_over_windows\": {}}}",
        model.decodes_windows()
    );
    Ok(())
}
