//! Joint-space motion planning for the arm: RRT-Connect (Kuffner and LaValle, ICRA 2000) with
//! collision-checked edges, then random shortcutting. Deterministic for a seed.

use planar::Pose2;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::collision::ObstacleBox;
use crate::kinematics::Joints;
pub use crate::place::JointPathSettings;
use crate::place::{ArmScene, PlaceConfig};

/// Why no joint path was found.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, thiserror::Error)]
pub enum JointPathError {
    /// The start configuration is outside the joint limits, not finite, or collides.
    #[error("start configuration is invalid (limits, NaN or collision)")]
    InvalidStart,
    /// The goal configuration is outside the joint limits, not finite, or collides.
    #[error("goal configuration is invalid (limits, NaN or collision)")]
    InvalidGoal,
    /// The sample budget ran out before the trees met.
    #[error("no collision-free path found within {samples} samples")]
    NoPath {
        /// Samples drawn.
        samples: u32,
    },
}

#[derive(Clone, Copy)]
struct Node {
    q: Joints,
    parent: usize,
}

/// Largest absolute joint difference [rad].
fn max_norm(a: &Joints, b: &Joints) -> f64 {
    a.iter().zip(b).fold(0.0, |m, (x, y)| m.max((x - y).abs()))
}

fn lerp(a: &Joints, b: &Joints, t: f64) -> Joints {
    core::array::from_fn(|i| a[i] + (b[i] - a[i]) * t)
}

struct Checker<'a> {
    cfg: &'a PlaceConfig,
    scene: ArmScene<'a>,
}

impl Checker<'_> {
    fn valid(&self, q: &Joints) -> bool {
        q.iter().all(|v| v.is_finite())
            && self.cfg.arm.limits.contains(q)
            && !self.scene.collides(self.cfg, q)
    }

    /// Straight joint-space edge, checked at `edge_resolution_rad` (the end point included,
    /// the start point assumed valid).
    fn edge_free(&self, a: &Joints, b: &Joints) -> bool {
        let steps = (max_norm(a, b) / self.cfg.path.edge_resolution_rad)
            .ceil()
            .max(1.0) as usize;
        (1..=steps).all(|k| {
            !self
                .scene
                .collides(self.cfg, &lerp(a, b, k as f64 / steps as f64))
        })
    }
}

enum Extend {
    Reached(usize),
    Advanced(usize),
    Trapped,
}

fn nearest(tree: &[Node], q: &Joints) -> usize {
    let mut best = (f64::INFINITY, 0);
    for (i, n) in tree.iter().enumerate() {
        let d: f64 = n.q.iter().zip(q).map(|(a, b)| (a - b) * (a - b)).sum();
        if d < best.0 {
            best = (d, i);
        }
    }
    best.1
}

fn extend(tree: &mut Vec<Node>, q: &Joints, check: &Checker<'_>) -> Extend {
    let near = nearest(tree, q);
    let from = tree[near].q;
    let dist = max_norm(&from, q);
    let (target, reached) = if dist <= check.cfg.path.step_rad {
        (*q, true)
    } else {
        (lerp(&from, q, check.cfg.path.step_rad / dist), false)
    };
    if !check.edge_free(&from, &target) {
        return Extend::Trapped;
    }
    tree.push(Node {
        q: target,
        parent: near,
    });
    if reached {
        Extend::Reached(tree.len() - 1)
    } else {
        Extend::Advanced(tree.len() - 1)
    }
}

fn connect(tree: &mut Vec<Node>, q: &Joints, check: &Checker<'_>) -> Option<usize> {
    loop {
        match extend(tree, q, check) {
            Extend::Reached(i) => return Some(i),
            Extend::Advanced(_) => {}
            Extend::Trapped => return None,
        }
    }
}

fn branch(tree: &[Node], mut i: usize) -> Vec<Joints> {
    let mut out = vec![tree[i].q];
    while i != 0 {
        i = tree[i].parent;
        out.push(tree[i].q);
    }
    out
}

/// A collision-free joint path from `start` to `goal` for the arm on the base at `base`,
/// among `obstacles` (world frame): RRT-Connect, then shortcutting. The first element is
/// `start`, the last `goal`; consecutive waypoints are joined by straight joint-space segments
/// that were checked every `cfg.path.edge_resolution_rad`. The same seed gives the same path.
pub fn plan_joint_path(
    cfg: &PlaceConfig,
    base: Pose2,
    start: &Joints,
    goal: &Joints,
    obstacles: &[ObstacleBox],
    seed: u64,
) -> Result<Vec<Joints>, JointPathError> {
    let check = Checker {
        cfg,
        scene: ArmScene::new(cfg, base, obstacles),
    };
    if !check.valid(start) {
        return Err(JointPathError::InvalidStart);
    }
    if !check.valid(goal) {
        return Err(JointPathError::InvalidGoal);
    }
    if !(cfg.path.step_rad > 0.0 && cfg.path.edge_resolution_rad > 0.0) {
        return Err(JointPathError::NoPath { samples: 0 });
    }
    if check.edge_free(start, goal) {
        return Ok(vec![*start, *goal]);
    }
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let limits = &cfg.arm.limits;
    let mut tree_a = vec![Node {
        q: *start,
        parent: 0,
    }];
    let mut tree_b = vec![Node {
        q: *goal,
        parent: 0,
    }];
    // `a_is_start` tracks which tree grows from the start as the trees swap roles.
    let mut a_is_start = true;
    for sample in 1..=cfg.path.max_samples {
        let q_rand: Joints = core::array::from_fn(|j| {
            let (lo, hi) = (limits.lower_rad[j], limits.upper_rad[j]);
            if hi > lo {
                rng.random_range(lo..hi)
            } else {
                lo
            }
        });
        let new = match extend(&mut tree_a, &q_rand, &check) {
            Extend::Reached(i) | Extend::Advanced(i) => Some(i),
            Extend::Trapped => None,
        };
        if let Some(i) = new {
            let q_new = tree_a[i].q;
            if let Some(j) = connect(&mut tree_b, &q_new, &check) {
                let (from_start, to_goal) = if a_is_start {
                    (branch(&tree_a, i), branch(&tree_b, j))
                } else {
                    (branch(&tree_b, j), branch(&tree_a, i))
                };
                // from_start runs meeting point -> start; to_goal runs meeting point -> goal.
                let mut path: Vec<Joints> = from_start.into_iter().rev().collect();
                path.extend(to_goal.into_iter().skip(1));
                shortcut(&mut path, &check, &mut rng);
                log::debug!(
                    "joint path: {} waypoints after {sample} samples",
                    path.len()
                );
                return Ok(path);
            }
        }
        core::mem::swap(&mut tree_a, &mut tree_b);
        a_is_start = !a_is_start;
    }
    Err(JointPathError::NoPath {
        samples: cfg.path.max_samples,
    })
}

/// Random shortcutting: join two random waypoints by a straight edge when it is free.
fn shortcut(path: &mut Vec<Joints>, check: &Checker<'_>, rng: &mut ChaCha8Rng) {
    for _ in 0..check.cfg.path.shortcut_attempts {
        if path.len() <= 2 {
            return;
        }
        let i = rng.random_range(0..path.len() - 2);
        let j = rng.random_range(i + 2..path.len());
        if check.edge_free(&path[i], &path[j]) {
            path.drain(i + 1..j);
        }
    }
}
