//! What the closed-loop test files share: the mission every test starts from.

use std::path::{Path, PathBuf};

use hil_world::mission::{self, MissionSpec};
use world::RobotConfig;

/// The committed model.
pub fn model() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../models/psi-fcn.onnx")
}

/// An evaluation-scene mission with 3 objects in a fresh temporary folder named after `test`,
/// no log.
pub fn spec(test: &str, seed: u64) -> MissionSpec {
    let dir = std::env::temp_dir().join(mission::unique_run_name(&format!("grop-{test}")));
    MissionSpec {
        dir,
        scene: world::generate::evaluation_scene(seed, 15, 3),
        robot: RobotConfig::default(),
        model: model(),
        method: "grop".into(),
        paper_smp: false,
        retry: "none".into(),
        seed,
        pace: None,
        camera_px: (640, 480),
        max_sim_s: 400.0,
        progress_s: 0.1,
        log: None,
        fault: None,
        lidar: true,
        unmapped_chairs: Vec::new(),
    }
}
