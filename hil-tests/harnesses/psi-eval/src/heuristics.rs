//! Geometric comparators for Psi and the simulator oracle, all behind
//! [`planner::feasibility::FeasibilityEvaluator`].
//!
//! - [`BinaryAnnulusEvaluator`]: a cell is 1 when the arm base, with the base at the cell centre
//!   facing the table, lies within the arm's reach annulus of the target and the base footprint
//!   touches no furniture; else 0.
//! - [`BlurredAnnulusEvaluator`]: the same indicator averaged over the navigation noise
//!   N(0, sigma^2 I) around the cell centre (a 9 x 9 quadrature grid over +-3 sigma): what the
//!   binary map would be if it knew the robot misses its goal.
//! - [`OracleEvaluator`]: Monte-Carlo trials in the simulator itself (an upper bound; it sees the
//!   scene, not the image).
//!
//! The heuristics fill the paper's candidate area (the cells Smp draws from) and leave 0 elsewhere.

use planar::Pose2;
use planner::feasibility::{
    FeasibilityError, FeasibilityEvaluator, FeasibilityQuery, check_output_count,
};
use rayon::prelude::*;
use trial_sim::ArmModel;
use world::view::{CROP_COLS, candidate_cells, cell_center_world};
use world::{Heatmap, PlaceConfig, RobotConfig, Scene, Side, base_collides};

/// Horizontal distances from the arm base axis to the object goal at which the arm can place it
/// (no obstacles), found by probing the arm's own kinematics (`trial_sim::Ur5eArm`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReachAnnulus {
    /// Smallest horizontal distance with a placing solution [m].
    pub min_m: f64,
    /// Largest horizontal distance with a placing solution [m].
    pub max_m: f64,
}

/// Radial step of the probe [m].
const PROBE_STEP_M: f64 = 0.005;
/// Farthest probed distance [m]; a UR5e reaches about 0.85 m.
const PROBE_MAX_M: f64 = 1.6;

impl ReachAnnulus {
    /// Probes `place` along rays from a goal at `goal_z_m` (target height), with the base facing
    /// the goal's table (yaw +pi/2) and the arm base at distance r in directions within +-60
    /// degrees of straight ahead. `None` when no distance works (the arm cannot place at all).
    pub fn probe(place: &PlaceConfig, goal_z_m: f64) -> Option<ReachAnnulus> {
        let arm = trial_sim::Ur5eArm;
        let goal = nalgebra::Point3::new(0.0, 6.0, goal_z_m);
        let yaw = Side::Near.facing_yaw_rad();
        let (mx, my) = mount_offset_world(place, yaw);
        let mut found: Option<ReachAnnulus> = None;
        for k in -4i32..=4 {
            let dir = std::f64::consts::FRAC_PI_2 + f64::from(k) * (std::f64::consts::PI / 12.0);
            let steps = (PROBE_MAX_M / PROBE_STEP_M) as usize;
            for i in 0..=steps {
                let r = i as f64 * PROBE_STEP_M;
                // Arm base at goal - r * (cos dir, sin dir): in front of the table for dir ~ +y.
                let (ax, ay) = (goal.x - r * dir.cos(), goal.y - r * dir.sin());
                let base = Pose2 {
                    x_m: ax - mx,
                    y_m: ay - my,
                    yaw_rad: yaw,
                };
                if arm.place(place, base, goal, &[]).is_ok() {
                    let a = found.get_or_insert(ReachAnnulus { min_m: r, max_m: r });
                    a.min_m = a.min_m.min(r);
                    a.max_m = a.max_m.max(r);
                }
            }
        }
        found
    }

    /// Whether the arm base of a base at `base` is within the annulus around `target`.
    pub fn contains(&self, place: &PlaceConfig, base: Pose2, target: [f64; 3]) -> bool {
        let (mx, my) = mount_offset_world(place, base.yaw_rad);
        let d = (base.x_m + mx - target[0]).hypot(base.y_m + my - target[1]);
        (self.min_m..=self.max_m).contains(&d)
    }
}

/// Arm base position relative to the base centre, in the world frame, for base yaw `yaw_rad`.
fn mount_offset_world(place: &PlaceConfig, yaw_rad: f64) -> (f64, f64) {
    let (s, c) = yaw_rad.sin_cos();
    let m = &place.mount;
    (
        c * m.forward_m - s * m.lateral_m,
        s * m.forward_m + c * m.lateral_m,
    )
}

/// The annulus for the last robot seen (recomputed when a query brings another arm setup).
#[derive(Default)]
struct AnnulusCache {
    key: Option<(PlaceConfig, u64)>,
    annulus: Option<ReachAnnulus>,
}

impl AnnulusCache {
    fn get(&mut self, place: &PlaceConfig, goal_z_m: f64) -> Option<ReachAnnulus> {
        let key = (place.clone(), goal_z_m.to_bits());
        if self.key.as_ref() != Some(&key) {
            self.annulus = ReachAnnulus::probe(place, goal_z_m);
            log::debug!(
                "reach annulus for goal height {goal_z_m} m: {:?}",
                self.annulus
            );
            self.key = Some(key);
        }
        self.annulus
    }
}

/// Indicator of the binary heuristic at one realised base pose.
fn annulus_and_free(
    scene: &Scene,
    robot: &RobotConfig,
    annulus: &ReachAnnulus,
    base: Pose2,
    target: [f64; 3],
) -> bool {
    annulus.contains(&robot.place, base, target) && !base_collides(scene, robot, base)
}

/// Reach annulus minus furniture, 0 or 1 per candidate cell.
#[derive(Default)]
pub struct BinaryAnnulusEvaluator {
    cache: AnnulusCache,
}

impl BinaryAnnulusEvaluator {
    /// A new evaluator (the annulus is probed on the first query).
    pub fn new() -> Self {
        Self::default()
    }
}

impl FeasibilityEvaluator for BinaryAnnulusEvaluator {
    fn name(&self) -> &str {
        "binary-annulus"
    }

    fn evaluate(
        &mut self,
        queries: &[FeasibilityQuery<'_>],
        out: &mut [Heatmap],
    ) -> Result<(), FeasibilityError> {
        check_output_count(queries, out)?;
        for (q, heat) in queries.iter().zip(out.iter_mut()) {
            *heat = Heatmap::zeros();
            let Some(annulus) = self.cache.get(&q.robot.place, q.target[2]) else {
                continue;
            };
            let yaw = q.side.facing_yaw_rad();
            for (r, c) in candidate_cells() {
                let (x, y) = cell_center_world(q.target[0], q.side, r, c);
                let base = Pose2 {
                    x_m: x,
                    y_m: y,
                    yaw_rad: yaw,
                };
                if annulus_and_free(q.scene, q.robot, &annulus, base, q.target) {
                    heat.values_mut()[r * CROP_COLS + c] = 1.0;
                }
            }
        }
        Ok(())
    }
}

/// Half-width of the noise quadrature grid in sigmas.
const BLUR_SPAN_SIGMA: f64 = 3.0;
/// Points per axis of the noise quadrature grid.
const BLUR_POINTS: usize = 9;

/// The binary heuristic averaged over the navigation noise N(0, sigma^2 I) of the robot.
#[derive(Default)]
pub struct BlurredAnnulusEvaluator {
    cache: AnnulusCache,
}

impl BlurredAnnulusEvaluator {
    /// A new evaluator (the annulus is probed on the first query).
    pub fn new() -> Self {
        Self::default()
    }
}

/// Offsets (in sigmas) and normalised Gaussian weights of the quadrature grid.
fn blur_stencil() -> Vec<(f64, f64, f64)> {
    let step = 2.0 * BLUR_SPAN_SIGMA / (BLUR_POINTS - 1) as f64;
    let mut pts = Vec::with_capacity(BLUR_POINTS * BLUR_POINTS);
    for i in 0..BLUR_POINTS {
        for j in 0..BLUR_POINTS {
            let (u, v) = (
                -BLUR_SPAN_SIGMA + i as f64 * step,
                -BLUR_SPAN_SIGMA + j as f64 * step,
            );
            pts.push((u, v, (-0.5 * (u * u + v * v)).exp()));
        }
    }
    let total: f64 = pts.iter().map(|p| p.2).sum();
    pts.iter_mut().for_each(|p| p.2 /= total);
    pts
}

impl FeasibilityEvaluator for BlurredAnnulusEvaluator {
    fn name(&self) -> &str {
        "blurred-annulus"
    }

    fn evaluate(
        &mut self,
        queries: &[FeasibilityQuery<'_>],
        out: &mut [Heatmap],
    ) -> Result<(), FeasibilityError> {
        check_output_count(queries, out)?;
        let stencil = blur_stencil();
        for (q, heat) in queries.iter().zip(out.iter_mut()) {
            *heat = Heatmap::zeros();
            let Some(annulus) = self.cache.get(&q.robot.place, q.target[2]) else {
                continue;
            };
            let yaw = q.side.facing_yaw_rad();
            let sigma = q.robot.nav_noise_sigma_m;
            for (r, c) in candidate_cells() {
                let (x, y) = cell_center_world(q.target[0], q.side, r, c);
                let value: f64 = stencil
                    .iter()
                    .filter(|(u, v, _)| {
                        let base = Pose2 {
                            x_m: x + sigma * u,
                            y_m: y + sigma * v,
                            yaw_rad: yaw,
                        };
                        annulus_and_free(q.scene, q.robot, &annulus, base, q.target)
                    })
                    .map(|p| p.2)
                    .sum();
                heat.values_mut()[r * CROP_COLS + c] = value.clamp(0.0, 1.0) as f32;
            }
        }
        Ok(())
    }
}

/// The simulator as Psi: `trials_per_cell` noisy trials per candidate cell
/// (`trial_sim::ground_truth_heatmap`), seeded per (seed, target, side) so that it is
/// deterministic and independent of a ground truth computed with another seed.
pub struct OracleEvaluator {
    trials_per_cell: u16,
    seed: u64,
}

impl OracleEvaluator {
    /// An oracle running `trials_per_cell` trials per cell.
    pub fn new(trials_per_cell: u16, seed: u64) -> Self {
        Self {
            trials_per_cell,
            seed,
        }
    }
}

impl FeasibilityEvaluator for OracleEvaluator {
    fn name(&self) -> &str {
        "oracle"
    }

    fn evaluate(
        &mut self,
        queries: &[FeasibilityQuery<'_>],
        out: &mut [Heatmap],
    ) -> Result<(), FeasibilityError> {
        check_output_count(queries, out)?;
        if self.trials_per_cell == 0 {
            return Err(FeasibilityError::Evaluator {
                evaluator: self.name().to_owned(),
                reason: "trials_per_cell must be at least 1".into(),
            });
        }
        // Each query has its own seed, so the parallel result does not depend on thread count.
        let results: Vec<Heatmap> = queries
            .par_iter()
            .map(|q| {
                let seed = world::generate::mix_seed(
                    self.seed,
                    q.target[0].to_bits(),
                    u64::from(q.side.sign() as u8),
                );
                trial_sim::ground_truth_heatmap(
                    q.scene,
                    q.robot,
                    q.target,
                    q.side,
                    self.trials_per_cell,
                    seed,
                )
            })
            .collect();
        for (heat, result) in out.iter_mut().zip(results) {
            *heat = result;
        }
        Ok(())
    }
}
