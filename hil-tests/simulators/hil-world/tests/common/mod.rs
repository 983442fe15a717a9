//! What the closed-loop test files share: the mission every test starts from.

use std::path::{Path, PathBuf};

use hil_world::mission::{self, MissionSpec};
use hil_world::report::{DeathRecord, WorldReport};

/// The committed model.
pub fn model() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../models/psi-fcn.onnx")
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

/// The planner's death as the clock saw it and when `PeerLost` came (s), after checking that the executive reported it
/// lost (`PeerLost`) within 0.65 s: heartbeats every 100 ms, declared dead after 500 ms,
/// checked at 50 Hz. `why` says what the test is about in the failure message.
#[allow(
    dead_code,
    reason = "shared by closed_loop.rs and forger.rs; the other binaries including common do not kill the planner"
)]
pub fn planner_death_noticed<'r>(report: &'r WorldReport, why: &str) -> (&'r DeathRecord, f64) {
    let death = report
        .deaths
        .iter()
        .find(|d| d.name == "grop-planner")
        .expect("the clock noticed the planner die");
    let lost = report
        .events
        .iter()
        .find(|e| e.kind == "PeerLost")
        .unwrap_or_else(|| panic!("the executive did not report the planner lost ({why})"));
    assert!(
        lost.t_s - death.t_s <= 0.65,
        "{} vs {} ({why})",
        lost.t_s,
        death.t_s
    );
    (death, lost.t_s)
}
