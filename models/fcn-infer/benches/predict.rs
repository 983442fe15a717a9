//! Criterion benchmark of the committed model: one crop and a batch of six (both sides of three
//! targets) on the calling thread. `cargo bench -p fcn-infer`. The p50/p99 table against
//! onnxruntime comes from `models/bench/run_bench.py` (docs/fcn.md).
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failure panics with its message

use std::path::Path;

use criterion::{Criterion, criterion_group, criterion_main};
use fcn_infer::{CROP_CELLS, FcnModel, MAX_BATCH};

fn bench(c: &mut Criterion) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../psi-fcn.onnx");
    let mut model = FcnModel::load(&path).expect("models/psi-fcn.onnx loads");
    let crops = fcn_infer::pattern_crops(MAX_BATCH);
    let mut one = [0f32; CROP_CELLS];
    let mut six = vec![[0f32; CROP_CELLS]; MAX_BATCH];
    c.bench_function("psi_fcn_one_crop", |b| {
        b.iter(|| model.predict(&crops[0], &mut one).expect("predict"))
    });
    c.bench_function("psi_fcn_batch_of_6", |b| {
        b.iter(|| model.predict_batch(&crops, &mut six).expect("predict"))
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
