//! Prints the optimised tract plan of a model (ops and their details), for architecture work.
//!
//! `cargo run --release -p fcn-infer --example dump_plan -- models/psi-fcn.onnx 1`
use tract_onnx::prelude::*;

fn main() -> TractResult<()> {
    let mut args = std::env::args().skip(1);
    let path = args.next().unwrap_or_else(|| "models/psi-fcn.onnx".into());
    let batch: usize = args.next().map(|s| s.parse()).transpose()?.unwrap_or(1);
    let model = tract_onnx::onnx()
        .model_for_path(&path)?
        .with_input_fact(0, u8::fact([batch, 1, 32, 64]).into())?
        .into_optimized()?;
    for node in model.eval_order()? {
        let node = model.node(node);
        let facts: Vec<String> = node
            .outputs
            .iter()
            .map(|o| format!("{:?}", o.fact))
            .collect();
        println!("{} {} -> {}", node.name, node.op().name(), facts.join(", "));
        for line in node.op().info()? {
            println!("      {line}");
        }
    }
    Ok(())
}
