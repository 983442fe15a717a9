//! A dinner-table workload for benchmarks and examples: the placement queries the dataset
//! generator makes (docs/architecture.md: 24 x 8 candidate cells per target, 5 noisy trials
//! each), against a table, ten chairs on the near side and the robot's own body.
//! Not part of the planning API.

use core::f64::consts::{FRAC_PI_2, PI};
use planar::Pose2;

use nalgebra::{Point3, Vector3};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::{ObstacleBox, PlaceConfig};

/// One placement query: base pose, object goal, obstacles (world frame).
pub struct PlaceQuery {
    /// Realised base pose.
    pub base: Pose2,
    /// Object goal.
    pub goal: Point3<f64>,
    /// Table, chairs and the base body.
    pub obstacles: Vec<ObstacleBox>,
}

/// Standard normal draw (Box-Muller), so the workload needs no distribution crate.
fn normal(rng: &mut ChaCha8Rng) -> f64 {
    let u1: f64 = rng.random_range(f64::MIN_POSITIVE..1.0);
    let u2: f64 = rng.random_range(0.0..1.0);
    (-2.0 * u1.ln()).sqrt() * (2.0 * PI * u2).cos()
}

/// `targets` targets x `trials_per_cell` trials on each of the 24 x 8 candidate cells,
/// deterministic for `seed`.
pub fn dinner_table_queries(
    cfg: &PlaceConfig,
    seed: u64,
    targets: usize,
    trials_per_cell: usize,
) -> Vec<PlaceQuery> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut out = Vec::with_capacity(targets * trials_per_cell * 192);
    for _ in 0..targets {
        let target_x: f64 = rng.random_range(-6.0..6.0);
        // Chairs in the authors' near-side band, 0.45 m square, 0.9 m high backrest.
        let mut scene = vec![ObstacleBox::from_min_max(
            Point3::new(target_x - 1.5, 5.8, 0.0),
            Point3::new(target_x + 1.5, 6.2, 1.0),
        )];
        for _ in 0..3 {
            scene.push(ObstacleBox {
                center: Point3::new(
                    target_x + rng.random_range(-1.5..1.5),
                    rng.random_range(4.35..5.35),
                    0.45,
                ),
                half_extents: Vector3::new(0.225, 0.225, 0.45),
                yaw_rad: rng.random_range(-PI..PI),
            });
        }
        for row in 9..=16 {
            for col in 20..=43 {
                let cx = target_x - 2.0 + (col as f64 + 0.5) * 0.0625;
                let cy = 6.0 - (row as f64 + 0.5) * 0.0625;
                for _ in 0..trials_per_cell {
                    let base = Pose2 {
                        x_m: cx + 0.1 * normal(&mut rng),
                        y_m: cy + 0.1 * normal(&mut rng),
                        yaw_rad: FRAC_PI_2,
                    };
                    let mut obstacles = scene.clone();
                    obstacles.push(ObstacleBox {
                        center: Point3::new(base.x_m, base.y_m, 0.5 * cfg.mount.height_m),
                        half_extents: Vector3::new(0.30, 0.275, 0.5 * cfg.mount.height_m),
                        yaw_rad: base.yaw_rad,
                    });
                    out.push(PlaceQuery {
                        base,
                        goal: Point3::new(target_x, 6.0, 1.3),
                        obstacles,
                    });
                }
            }
        }
    }
    out
}
