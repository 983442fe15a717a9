//! What the closed-loop test files share: the mission every test starts from.

use std::path::{Path, PathBuf};

use hil_world::mission::{self, MissionSpec};

/// The committed model.
pub fn model() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../models/psi-fcn.onnx")
}

/// An evaluation-scene mission with 3 objects in a fresh temporary folder named after `test`,
/// no log, progress lines every 0.1 s, 400 s at most, and the range sensor off: these tests are
/// about kills, faults, logs and loading, and the generated layouts still block some legs of a
/// base that refuses to touch furniture (docs/lidar.md, "Not done"); `tests/lidar.rs` runs the
/// sensor.
pub fn spec(test: &str, seed: u64) -> MissionSpec {
    let dir = std::env::temp_dir().join(mission::unique_run_name(&format!("grop-{test}")));
    MissionSpec {
        max_sim_s: 400.0,
        progress_s: 0.1,
        lidar: false,
        ..MissionSpec::new(
            dir,
            world::generate::evaluation_scene(seed, 15, 3),
            model(),
            seed,
        )
    }
}
