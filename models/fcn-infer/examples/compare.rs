//! Round-robin latency of several model files through `FcnModel`, so that the noise of a shared
//! machine hits every candidate alike (used to compare equivalent graph forms, docs/fcn.md).
//!
//! `cargo run --release -p fcn-infer --example compare -- 20 200 a.onnx b.onnx ...`
//! (rounds, calls per round and model, files); prints p50 of one crop and of a batch of 6 per file.

use std::path::PathBuf;
use std::time::Instant;

use fcn_infer::{CROP_CELLS, FcnModel, MAX_BATCH};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let rounds: usize = args.next().map(|s| s.parse()).transpose()?.unwrap_or(20);
    let per: usize = args.next().map(|s| s.parse()).transpose()?.unwrap_or(200);
    let paths: Vec<PathBuf> = args.map(PathBuf::from).collect();
    let mut models = paths
        .iter()
        .map(|p| FcnModel::load(p))
        .collect::<Result<Vec<_>, _>>()?;
    let crops = fcn_infer::pattern_crops(MAX_BATCH);
    let mut one = [0f32; CROP_CELLS];
    let mut six = vec![[0f32; CROP_CELLS]; MAX_BATCH];
    let mut t1 = vec![Vec::new(); models.len()];
    let mut t6 = vec![Vec::new(); models.len()];
    for r in 0..rounds {
        for (i, m) in models.iter_mut().enumerate() {
            for _ in 0..per {
                let t = Instant::now();
                m.predict(&crops[0], &mut one)?;
                if r > 0 {
                    t1[i].push(t.elapsed().as_secs_f64() * 1e6);
                }
            }
            for _ in 0..per / 4 {
                let t = Instant::now();
                m.predict_batch(&crops, &mut six)?;
                if r > 0 {
                    t6[i].push(t.elapsed().as_secs_f64() * 1e6);
                }
            }
        }
    }
    let p50 = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    for (i, p) in paths.iter().enumerate() {
        println!(
            "{:>8.1} {:>8.1}  {}",
            p50(&mut t1[i]),
            p50(&mut t6[i]),
            p.display()
        );
    }
    Ok(())
}
