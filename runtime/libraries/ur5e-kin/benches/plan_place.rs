//! `cargo bench -p ur5e-kin --bench plan_place`: placement latency and throughput on the
//! dataset generator's workload, plus single representative queries.

use core::f64::consts::FRAC_PI_2;
use std::hint::black_box;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use nalgebra::{Isometry3, Point3};
use planar::Pose2;
use ur5e_kin::bench_scene::dinner_table_queries;
use ur5e_kin::{ObstacleBox, PlaceConfig, Ur5e, plan_place};

fn bench(c: &mut Criterion) {
    let cfg = PlaceConfig::default();
    let queries = dinner_table_queries(&cfg, 1, 5, 1);
    let mut group = c.benchmark_group("plan_place");
    group.throughput(Throughput::Elements(queries.len() as u64));
    group.bench_function("candidate_band_960_queries", |b| {
        b.iter(|| {
            let mut ok = 0u32;
            for q in &queries {
                ok += plan_place(&cfg, q.base, q.goal, &q.obstacles).is_ok() as u32;
            }
            black_box(ok)
        })
    });
    group.throughput(Throughput::Elements(1));
    let table = [ObstacleBox::from_min_max(
        Point3::new(-1.5, 5.8, 0.0),
        Point3::new(1.5, 6.2, 1.0),
    )];
    let goal = Point3::new(0.0, 6.0, 1.3);
    for (name, offset) in [("reachable_0.7m", 0.7), ("out_of_reach_1.2m", 1.2)] {
        let base = Pose2 {
            x_m: 0.0,
            y_m: 6.0 - offset,
            yaw_rad: FRAC_PI_2,
        };
        group.bench_function(name, |b| {
            b.iter(|| black_box(plan_place(&cfg, black_box(base), goal, &table)))
        });
    }
    group.finish();

    let arm = Ur5e::default();
    let q = [0.4, -1.2, 1.1, -1.3, 1.0, 0.6];
    let pose: Isometry3<f64> = arm.forward(&q);
    c.bench_function("ur5e/forward", |b| {
        b.iter(|| black_box(arm.forward(black_box(&q))))
    });
    c.bench_function("ur5e/inverse", |b| {
        b.iter(|| black_box(arm.inverse(black_box(&pose))))
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
