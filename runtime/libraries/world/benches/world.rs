//! Costs of the world's hot calls: crop rendering (once per target and side), grid building
//! (once per scene) and planning (a few dozen per task). `cargo bench -p world --bench world`.

use criterion::{Criterion, criterion_group, criterion_main};
use world::nav::OccupancyGrid;
use world::view::{Side, render_crop};
use world::{RobotConfig, generate::evaluation_scene};

fn bench_world(c: &mut Criterion) {
    let scene = evaluation_scene(0, 25, 3);
    let robot = RobotConfig::default();
    let target_x = scene.targets[0].x_m;
    c.bench_function("render_crop", |b| {
        b.iter(|| render_crop(&scene, target_x, Side::Far))
    });
    c.bench_function("occupancy_grid_from_scene", |b| {
        b.iter(|| OccupancyGrid::from_scene(&scene, &robot))
    });
    let grid = OccupancyGrid::from_scene(&scene, &robot);
    let start = (scene.robot_start.x_m, scene.robot_start.y_m);
    // Around an end of the 13.5 m table to the far side (a free goal; 13 corners).
    c.bench_function("plan_start_to_far_side", |b| {
        b.iter(|| grid.plan(start, (0.0, 8.0)))
    });
    c.bench_function("plan_start_to_near_side", |b| {
        b.iter(|| grid.plan(start, (target_x, 5.2)))
    });
}

criterion_group!(benches, bench_world);
criterion_main!(benches);
