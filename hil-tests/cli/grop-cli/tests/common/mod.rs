//! What the `grop` binary's end-to-end tests share.
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failure panics with its message

use std::path::PathBuf;
use std::process::{Command, Output};
use std::sync::OnceLock;

/// Subcommands that start the world and the onboard processes and, without `--no-build`, run
/// `cargo build` for them first with grop-cli's own feature set. Under `cargo test` that set
/// differs from the test build's (dev-dependencies), so each would compile about 40 crates
/// again: the tests build the binaries once with the test build's set and pass `--no-build`.
const STARTS_MISSIONS: [&str; 3] = ["demo", "hil", "soak"];

/// Runs `grop` with `args` (and `--log warn`), the mission binaries built first where needed.
pub fn grop(args: &[&str]) -> Output {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_grop"));
    cmd.args(args).args(["--log", "warn"]);
    if args.first().is_some_and(|a| STARTS_MISSIONS.contains(a)) && !args.contains(&"--no-build") {
        mission_binaries_built();
        cmd.arg("--no-build");
    }
    cmd.output().expect("the grop binary runs")
}

/// Builds the world and onboard binaries once per test binary.
fn mission_binaries_built() {
    static BUILT: OnceLock<()> = OnceLock::new();
    BUILT.get_or_init(|| {
        hil_world::mission::binaries(true).expect("the world and onboard binaries build");
    });
}

/// The committed model.
pub fn model() -> String {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../../models/psi-fcn.onnx")
        .display()
        .to_string()
}

/// stdout and stderr together.
pub fn text(o: &Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}
