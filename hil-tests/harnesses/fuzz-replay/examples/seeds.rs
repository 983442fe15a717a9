//! Writes the seed inputs of every fuzz target to `<dir>/<target>/seed-<k>` (docs/fuzzing.md):
//! `cargo run -p fuzz-replay --example seeds -- fuzz/seeds`.

fn main() -> std::io::Result<()> {
    let dir = std::env::args()
        .nth(1)
        .unwrap_or_else(|| "fuzz/seeds".to_owned());
    for (target, seeds) in fuzz_replay::seeds::seeds() {
        let folder = std::path::Path::new(&dir).join(target);
        std::fs::create_dir_all(&folder)?;
        for (k, bytes) in seeds.iter().enumerate() {
            std::fs::write(folder.join(format!("seed-{k:02}")), bytes)?;
        }
        println!("{target}: {} seeds", seeds.len());
    }
    Ok(())
}
