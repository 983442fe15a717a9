//! Simulated localisation: global fixes whose error makes the base's realised stop follow the
//! robot file's navigation noise, and table-relative fixes at the table.
//!
//! The paper models the realised base position as the commanded goal plus N(0, sigma^2 I). A
//! closed loop reaches that only if the localiser is wrong by that much when the base stops: the
//! follower drives until its *belief* is at the goal, so the truth ends where the belief error
//! puts it. So the localiser's error is a bias drawn from N(0, sigma^2 I) each time the base
//! starts a leg (moving after standing still), constant during the leg (a localiser settles
//! into one wrong local optimum per place), plus a small white jitter per fix. Yaw gets a small
//! bias too. At the table a table-edge detector measures the pose relative to the table with
//! millimetre-to-centimetre error, independent of the leg's bias: that fix is what the arm uses.

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

/// Settings of the simulated localisers.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct FixModel {
    /// Per-leg bias of global fixes, per axis, m (the robot file's `nav_noise_sigma_m`).
    pub leg_bias_sigma_m: f64,
    /// Per-leg heading bias, rad.
    pub leg_yaw_sigma_rad: f64,
    /// White jitter of each global fix, per axis, m.
    pub jitter_sigma_m: f64,
    /// Table-relative fix error, per axis, m.
    pub table_sigma_m: f64,
    /// Table-relative heading error, rad.
    pub table_yaw_sigma_rad: f64,
    /// Table-relative fixes are produced within this distance of the table edge, m.
    pub table_range_m: f64,
    /// Standing still at least this long (s) before moving again starts a new leg.
    pub still_before_leg_s: f64,
}

impl FixModel {
    /// The model for a robot file's navigation noise sigma.
    pub fn for_sigma(sigma_m: f64) -> Self {
        Self {
            leg_bias_sigma_m: sigma_m,
            leg_yaw_sigma_rad: 0.01,
            jitter_sigma_m: 0.005,
            table_sigma_m: 0.005,
            table_yaw_sigma_rad: 0.005,
            table_range_m: 1.6,
            still_before_leg_s: 0.5,
        }
    }
}

/// The fix generator.
#[derive(Debug, Clone)]
pub struct FixSimulator {
    model: FixModel,
    rng: ChaCha8Rng,
    bias: [f64; 3],
    still_s: f64,
    moving: bool,
    legs: u32,
}

fn normal(rng: &mut ChaCha8Rng) -> f64 {
    StandardNormal.sample(rng)
}

impl FixSimulator {
    /// A generator seeded with `seed`; the first leg's bias is drawn at once (the localiser
    /// is wrong from the start).
    pub fn new(model: FixModel, seed: u64) -> Self {
        let mut s = Self {
            model,
            rng: ChaCha8Rng::seed_from_u64(seed),
            bias: [0.0; 3],
            still_s: 0.0,
            moving: false,
            legs: 0,
        };
        s.draw_bias();
        s
    }

    fn draw_bias(&mut self) {
        let m = self.model;
        self.bias = [
            m.leg_bias_sigma_m * normal(&mut self.rng),
            m.leg_bias_sigma_m * normal(&mut self.rng),
            m.leg_yaw_sigma_rad * normal(&mut self.rng),
        ];
        self.legs += 1;
    }

    /// Legs started so far.
    pub fn legs(&self) -> u32 {
        self.legs
    }

    /// The current bias (x, y, yaw).
    pub fn bias(&self) -> [f64; 3] {
        self.bias
    }

    /// Follows the true motion: `speed` is the true planar speed magnitude (m/s, plus yaw rate
    /// scaled to the footprint), `dt_s` the step. A start after standing still draws a new bias.
    pub fn observe_motion(&mut self, speed: f64, dt_s: f64) {
        let moving = speed > 0.01;
        if moving && !self.moving && self.still_s >= self.model.still_before_leg_s {
            self.draw_bias();
        }
        if moving {
            self.still_s = 0.0;
        } else {
            self.still_s += dt_s;
        }
        self.moving = moving;
    }

    /// A global fix of the true pose.
    pub fn global_fix(&mut self, truth: [f64; 3]) -> [f64; 3] {
        let j = self.model.jitter_sigma_m;
        let jx = j * normal(&mut self.rng);
        let jy = j * normal(&mut self.rng);
        [
            truth[0] + self.bias[0] + jx,
            truth[1] + self.bias[1] + jy,
            truth[2] + self.bias[2],
        ]
    }

    /// A table-relative fix of the true pose, if the base stands still near the table
    /// (`distance_to_table_m` from its footprint centre to the nearest table edge).
    pub fn table_fix(&mut self, truth: [f64; 3], distance_to_table_m: f64) -> Option<[f64; 3]> {
        if self.moving || distance_to_table_m > self.model.table_range_m {
            return None;
        }
        let m = self.model;
        Some([
            truth[0] + m.table_sigma_m * normal(&mut self.rng),
            truth[1] + m.table_sigma_m * normal(&mut self.rng),
            truth[2] + m.table_yaw_sigma_rad * normal(&mut self.rng),
        ])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_new_leg_draws_a_new_bias_only_after_standing_still() {
        let mut f = FixSimulator::new(FixModel::for_sigma(0.1), 7);
        let first = f.bias();
        f.observe_motion(0.3, 0.02); // moving from the start: same leg
        assert_eq!(f.bias(), first);
        for _ in 0..10 {
            f.observe_motion(0.0, 0.02); // 0.2 s: too short
        }
        f.observe_motion(0.3, 0.02);
        assert_eq!(f.bias(), first);
        for _ in 0..30 {
            f.observe_motion(0.0, 0.02); // 0.6 s
        }
        f.observe_motion(0.3, 0.02);
        assert_ne!(f.bias(), first);
        assert_eq!(f.legs(), 2);
    }

    #[test]
    fn leg_biases_follow_the_navigation_noise() {
        let sigma = 0.1;
        let mut f = FixSimulator::new(FixModel::for_sigma(sigma), 1);
        let mut xs = Vec::new();
        for _ in 0..4000 {
            for _ in 0..30 {
                f.observe_motion(0.0, 0.02);
            }
            f.observe_motion(0.3, 0.02);
            xs.push(f.bias()[0]);
        }
        let mean = xs.iter().sum::<f64>() / xs.len() as f64;
        let sd = (xs.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / xs.len() as f64).sqrt();
        assert!(mean.abs() < 0.01, "{mean}");
        assert!((sd - sigma).abs() < 0.01, "{sd}");
    }
}
