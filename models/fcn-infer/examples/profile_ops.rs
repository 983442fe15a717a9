//! Per-operator time of the optimised tract plan, to see where a model spends its microseconds.
//!
//! `cargo run --release -p fcn-infer --example profile_ops -- models/psi-fcn.onnx 1 2000 [direct|tract]`
//! (model, batch size, iterations, how the convolutions run: our `DirectConv` operator, the
//! default, or tract's own lowering). Used to choose the architecture (docs/fcn.md).
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failure panics with its message

use std::collections::BTreeMap;
use std::time::Instant;

use tract_onnx::prelude::*;

fn main() -> TractResult<()> {
    let mut args = std::env::args().skip(1);
    let path = args.next().unwrap_or_else(|| "models/psi-fcn.onnx".into());
    let batch: usize = args.next().map(|s| s.parse()).transpose()?.unwrap_or(1);
    let iters: usize = args.next().map(|s| s.parse()).transpose()?.unwrap_or(2000);
    let direct = match args.next().as_deref() {
        None | Some("direct") => true,
        Some("tract") => false,
        Some(other) => {
            return Err(TractError::msg(format!(
                "backend {other}: expected direct or tract"
            )));
        }
    };
    let mut model = tract_onnx::onnx()
        .model_for_path(&path)?
        .with_input_fact(0, u8::fact([batch, 1, 32, 64]).into())?
        .into_typed()?;
    if direct {
        fcn_infer::direct_conv::rewrite_convolutions(&mut model)?;
    }
    let model = model.into_optimized()?;
    let plan = model.into_runnable()?;
    let mut state = plan.spawn()?;
    let input: TValue = Tensor::zero::<u8>(&[batch, 1, 32, 64])?.into();
    let mut per_node: BTreeMap<usize, (String, Vec<f64>)> = BTreeMap::new();
    for i in 0..iters {
        let record = i >= iters / 10;
        state.run_plan_with_eval(tvec!(input.clone()), |ctx, op_state, node, inputs| {
            let t = Instant::now();
            let r = tract_onnx::tract_core::plan::eval(ctx, op_state, node, inputs);
            if record {
                let e = per_node
                    .entry(node.id)
                    .or_insert_with(|| (format!("{} {}", node.name, node.op().name()), vec![]));
                e.1.push(t.elapsed().as_secs_f64() * 1e6);
            }
            r
        })?;
    }
    // The same plan without the per-operator timing, for the total.
    let mut plain: Vec<f64> = (0..iters)
        .map(|_| {
            let t = Instant::now();
            state.run(tvec!(input.clone())).expect("run");
            t.elapsed().as_secs_f64() * 1e6
        })
        .collect();
    plain.sort_by(f64::total_cmp);
    // Per operator: the median over the recorded runs (robust to preemption on a shared
    // machine), and the sum of those medians.
    let mut rows: Vec<(String, f64)> = per_node
        .into_values()
        .map(|(name, mut us)| {
            us.sort_by(f64::total_cmp);
            (name, us[us.len() / 2])
        })
        .collect();
    let total: f64 = rows.iter().map(|r| r.1).sum();
    rows.sort_by(|a, b| b.1.total_cmp(&a.1));
    println!(
        "batch {batch}: {total:.1} us per run in operators (sum of per-operator medians, instrumented), plain run p50 {:.1} us, {} operators",
        plain[plain.len() / 2],
        rows.len()
    );
    for (name, us) in rows {
        println!("{us:8.2} us  {name}");
    }
    Ok(())
}
