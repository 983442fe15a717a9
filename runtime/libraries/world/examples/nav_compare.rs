//! The corner visibility graph against Lazy Theta* on evaluation scenes: path lengths,
//! connectivity, per-map build time and per-query time. Figures quoted in docs/world.md.
//!
//!     cargo run --release -p world --example nav_compare [seeds]
//!
//! Pairs: robot start, loading station, and a near (y 5.2) and far (y 6.8) point in front of
//! every target of every scene (10 seeds x 15/20/25 chairs by default).

use std::time::{Duration, Instant};

use world::nav::OccupancyGrid;
use world::{RobotConfig, generate::evaluation_scene};

fn main() {
    let seeds: u64 = std::env::args()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(10);
    let robot = RobotConfig::default();
    let (mut pairs, mut both, mut longer, mut shorter, mut mismatches) =
        (0usize, 0usize, 0usize, 0usize, 0usize);
    let (mut min_ratio, mut max_ratio, mut sum_ratio) = (f64::INFINITY, 0.0f64, 0.0f64);
    let (mut t_theta, mut t_vg, mut t_leg) = (Duration::ZERO, Duration::ZERO, Duration::ZERO);
    let (mut builds, mut corners) = (Vec::new(), Vec::new());
    for seed in 0..seeds {
        for chairs in [15usize, 20, 25] {
            let scene = evaluation_scene(seed, chairs, 30);
            let t = Instant::now();
            let grid = OccupancyGrid::from_scene(&scene, &robot);
            builds.push(t.elapsed().as_secs_f64() * 1e3);
            corners.push(grid.corner_count());
            let mut points = vec![
                (scene.robot_start.x_m, scene.robot_start.y_m),
                (scene.loading_station.x_m, scene.loading_station.y_m),
            ];
            for target in &scene.targets {
                points.push((target.x_m, 5.2));
                points.push((target.x_m, 6.8));
            }
            let endpoints: Vec<_> = points.iter().map(|&p| grid.endpoint(p)).collect();
            for i in 0..points.len() {
                for j in i + 1..points.len() {
                    let t0 = Instant::now();
                    let theta = grid.plan_theta_star(points[i], points[j]);
                    let t1 = Instant::now();
                    let vg = grid.plan(points[i], points[j]);
                    let t2 = Instant::now();
                    if let (Some(a), Some(b)) = (&endpoints[i], &endpoints[j]) {
                        std::hint::black_box(grid.path_length_between(a, b));
                    }
                    let t3 = Instant::now();
                    t_theta += t1 - t0;
                    t_vg += t2 - t1;
                    t_leg += t3 - t2;
                    pairs += 1;
                    match (theta, vg) {
                        (Some(a), Some(b)) => {
                            let r = b.length_m / a.length_m;
                            min_ratio = min_ratio.min(r);
                            max_ratio = max_ratio.max(r);
                            sum_ratio += r;
                            both += 1;
                            longer += usize::from(r > 1.0 + 1e-9);
                            shorter += usize::from(r < 1.0 - 1e-9);
                        }
                        (None, None) => {}
                        _ => mismatches += 1,
                    }
                }
            }
        }
    }
    builds.sort_by(f64::total_cmp);
    corners.sort_unstable();
    println!(
        "{} maps: corner cells {}..{} (median {}), build {:.1}..{:.1} ms (median {:.1})",
        builds.len(),
        corners[0],
        corners[corners.len() - 1],
        corners[corners.len() / 2],
        builds[0],
        builds[builds.len() - 1],
        builds[builds.len() / 2]
    );
    println!(
        "{pairs} pairs ({both} with a path); connectivity mismatches {mismatches}; length visibility graph / Theta*: \
         min {min_ratio:.4}, max {max_ratio:.4}, mean {:.4}; shorter in {shorter}, longer in {longer}",
        sum_ratio / both.max(1) as f64
    );
    println!(
        "mean per query: Theta* {:.1} us, visibility graph {:.1} us (two endpoints connected), \
         leg between connected endpoints {:.2} us",
        t_theta.as_secs_f64() * 1e6 / pairs as f64,
        t_vg.as_secs_f64() * 1e6 / pairs as f64,
        t_leg.as_secs_f64() * 1e6 / pairs as f64
    );
}
