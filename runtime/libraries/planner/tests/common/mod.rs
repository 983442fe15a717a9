//! Test doubles shared by the integration tests: random task problems and a travel-time oracle
//! with obstacles (detours and missing paths), no world rendering, no FCN.
#![allow(dead_code)]

use planner::costs::TravelTime;
use planner::problem::{TaskProblem, UnloadLocation, candidate_cells};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use world::{Heatmap, Side};

/// Symmetric travel oracle: straight line at `speed_mps` times a detour factor in [1, 2) that
/// depends on the unordered pair of (rounded) endpoints; a fraction `no_path` of legs have no path.
pub struct DetourOracle {
    pub speed_mps: f64,
    pub salt: u64,
    pub no_path: f64,
    pub calls: usize,
}

fn key(p: (f64, f64)) -> u64 {
    ((p.0 * 1000.0).round() as i64 as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15)
        ^ ((p.1 * 1000.0).round() as i64 as u64).wrapping_mul(0xC2B2_AE3D_27D4_EB4F)
}

impl TravelTime for DetourOracle {
    fn travel_time_s(&mut self, from: (f64, f64), to: (f64, f64)) -> Option<f64> {
        self.calls += 1;
        let (a, b) = (key(from), key(to));
        let h = world::generate::mix_seed(self.salt, a.min(b), a.max(b));
        let u = (h >> 11) as f64 / (1u64 << 53) as f64;
        if u < self.no_path {
            return None;
        }
        let d = (to.0 - from.0).hypot(to.1 - from.1);
        Some(d / self.speed_mps * (1.0 + u))
    }
}

/// A random problem with `n` objects: targets along the table, heatmaps with blobs of
/// feasibility (some locations all zero), some cells blocked.
pub fn random_problem(n: usize, seed: u64) -> TaskProblem {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut locations = Vec::with_capacity(2 * n);
    for o in 0..n {
        let x = rng.random_range(-6.0..6.0);
        for side in Side::BOTH {
            let mut h = Heatmap::zeros();
            let kind = rng.random_range(0..4);
            let (cr, cc) = (rng.random_range(9.0..17.0), rng.random_range(20.0..44.0));
            let peak: f32 = rng.random_range(0.1..1.0);
            for (r, c) in candidate_cells() {
                let v = match kind {
                    0 => 0.0,
                    1 => peak,
                    _ => {
                        let d2 = (r as f64 - cr).powi(2) / 4.0 + (c as f64 - cc).powi(2) / 36.0;
                        (peak as f64 * (-d2).exp()) as f32
                    }
                };
                h.set(r, c, v);
            }
            let mut l = UnloadLocation::from_heatmap(o, side, [x, 6.0, 1.3], &h);
            let blocked = rng.random_range(0.0..1.0);
            for cell in l.cells.iter_mut() {
                cell.free = rng.random_range(0.0..1.0) >= blocked;
            }
            locations.push(l);
        }
    }
    TaskProblem {
        start_xy: (0.0, 2.0),
        station_xy: (0.0, 1.05),
        locations,
    }
}
