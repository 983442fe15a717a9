//! The onboard binaries link no simulator: nothing under hil-tests/ (the simulated devices, the
//! trial simulator, the world, the experiments, the CLI) is in grop-onboard's normal dependency
//! tree. Asked of cargo itself (`cargo tree`, offline, from the lock file).

use std::process::Command;

const SIMULATION_CRATES: [&str; 8] = [
    "sim-rmp",
    "sim-ur5e",
    "trial-sim",
    "hil-world",
    "experiments",
    "psi-eval",
    "grop-cli",
    "criterion",
];

#[test]
fn onboard_binaries_link_no_simulator() {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let manifest = concat!(env!("CARGO_MANIFEST_DIR"), "/Cargo.toml");
    let out = Command::new(cargo)
        .args([
            "tree",
            "--offline",
            "--manifest-path",
            manifest,
            "-p",
            "grop-onboard",
            "-e",
            "normal",
            "--prefix",
            "none",
            "--format",
            "{p}",
        ])
        .output()
        .expect("running cargo tree");
    assert!(
        out.status.success(),
        "cargo tree failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let tree = String::from_utf8_lossy(&out.stdout);
    let names: Vec<&str> = tree
        .lines()
        .filter_map(|l| l.split_whitespace().next())
        .collect();
    assert!(names.contains(&"grop-onboard"), "{tree}");
    assert!(
        names.contains(&"rmp-base") && names.contains(&"ur5e"),
        "{tree}"
    );
    for sim in SIMULATION_CRATES {
        assert!(
            !names.contains(&sim),
            "grop-onboard depends on {sim}:\n{tree}"
        );
    }
    // And nothing from hil-tests/ by path.
    assert!(!tree.contains("/hil-tests/"), "{tree}");
}
