//! Seeded scene generators: the paper's training environments and its evaluation scenes.
//!
//! Same seed, same scenes, on every platform (ChaCha8). Chairs are placed by rejection
//! sampling as in the authors' code: x ~ U[-7, 7], near band y ~ U[4.35, 5.35], far band
//! y ~ U[6.65, 7.65], yaw ~ U[-pi, pi], centres at least 0.8 m apart. Targets x ~ U[-6, 6] on the
//! table's centre line at 1.3 m.

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::scene::{Chair, Scene, UnloadTarget};

/// Generator settings; [`ChairBands::default`] is the authors'.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ChairBands {
    /// Chair centre x range (m).
    pub x_range_m: (f64, f64),
    /// Near-side chair centre y range (m).
    pub near_y_range_m: (f64, f64),
    /// Far-side chair centre y range (m).
    pub far_y_range_m: (f64, f64),
    /// Minimum distance between chair centres (m).
    pub min_spacing_m: f64,
    /// Target x range (m).
    pub target_x_range_m: (f64, f64),
}

impl Default for ChairBands {
    fn default() -> Self {
        Self {
            x_range_m: (-7.0, 7.0),
            near_y_range_m: (4.35, 5.35),
            far_y_range_m: (6.65, 7.65),
            min_spacing_m: 0.8,
            target_x_range_m: (-6.0, 6.0),
        }
    }
}

/// Chairs in a training environment (all on the near side).
pub const TRAINING_CHAIRS: usize = 10;
/// The paper's training environments.
pub const TRAINING_ENVS: usize = 10;
/// The paper's targets per training environment.
pub const TRAINING_TARGETS_PER_ENV: usize = 10;
/// Evaluation targets per scene (the paper: 420 tasks over 30 scenes).
pub const EVALUATION_TARGETS: usize = 14;

/// Rejection sampling gives up after this many draws per chair (only reachable with absurd
/// chair counts for the band).
const MAX_DRAWS_PER_CHAIR: usize = 10_000;

/// `n_envs` training environments (10 near-side chairs each) with `targets_per_env` targets.
/// The paper: `training_scenes(seed, 10, 10)`.
pub fn training_scenes(seed: u64, n_envs: usize, targets_per_env: usize) -> Vec<Scene> {
    (0..n_envs)
        .map(|env| {
            let mut rng = ChaCha8Rng::seed_from_u64(mix_seed(seed, 0x7261_696e, env as u64));
            let bands = ChairBands::default();
            let mut scene = Scene::empty_paper_room();
            scene.name = format!("training-{seed}-{env}");
            place_chairs(&mut rng, &bands, TRAINING_CHAIRS, 0, &mut scene.chairs);
            scene.targets = draw_targets(&mut rng, &bands, targets_per_env);
            scene
        })
        .collect()
}

/// One evaluation scene with `n_chairs` chairs over both sides (floor(n/2) near, the rest far:
/// 15 = 7 + 8, 20 = 10 + 10, 25 = 12 + 13) and `n_targets` targets.
pub fn evaluation_scene(seed: u64, n_chairs: usize, n_targets: usize) -> Scene {
    let mut rng = ChaCha8Rng::seed_from_u64(mix_seed(seed, 0x6576_616c, n_chairs as u64));
    let bands = ChairBands::default();
    let mut scene = Scene::empty_paper_room();
    scene.name = format!("evaluation-{seed}-{n_chairs}");
    let near = n_chairs / 2;
    place_chairs(&mut rng, &bands, near, n_chairs - near, &mut scene.chairs);
    scene.targets = draw_targets(&mut rng, &bands, n_targets);
    scene
}

/// The paper's 30 evaluation scenes: 10 each with 15, 20 and 25 chairs, `n_targets` targets each.
pub fn evaluation_suite(seed: u64, n_targets: usize) -> Vec<Scene> {
    [15usize, 20, 25]
        .iter()
        .flat_map(|&chairs| {
            (0..10u64)
                .map(move |i| evaluation_scene(mix_seed(seed, chairs as u64, i), chairs, n_targets))
        })
        .collect()
}

fn place_chairs(
    rng: &mut ChaCha8Rng,
    bands: &ChairBands,
    near: usize,
    far: usize,
    chairs: &mut Vec<Chair>,
) {
    let spacing2 = bands.min_spacing_m * bands.min_spacing_m;
    for (count, y_range) in [(near, bands.near_y_range_m), (far, bands.far_y_range_m)] {
        for _ in 0..count {
            for _ in 0..MAX_DRAWS_PER_CHAIR {
                let x = rng.random_range(bands.x_range_m.0..bands.x_range_m.1);
                let y = rng.random_range(y_range.0..y_range.1);
                let yaw = rng.random_range(-std::f64::consts::PI..std::f64::consts::PI);
                let clear = chairs
                    .iter()
                    .all(|c| (c.x_m - x).powi(2) + (c.y_m - y).powi(2) >= spacing2);
                if clear {
                    chairs.push(Chair::new(x, y, yaw));
                    break;
                }
            }
        }
    }
}

fn draw_targets(rng: &mut ChaCha8Rng, bands: &ChairBands, n: usize) -> Vec<UnloadTarget> {
    (0..n)
        .map(|_| {
            UnloadTarget::on_center_line(
                rng.random_range(bands.target_x_range_m.0..bands.target_x_range_m.1),
            )
        })
        .collect()
}

/// Mixes a seed with two stream numbers (SplitMix64 finaliser): independent, reproducible
/// sub-seeds for environments, tasks, cells and trials.
pub fn mix_seed(seed: u64, a: u64, b: u64) -> u64 {
    fn splitmix(mut z: u64) -> u64 {
        z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    splitmix(splitmix(splitmix(seed) ^ a) ^ b)
}
