//! Trials per second: single trials, one task's ground-truth heatmap (960 trials) and a small
//! dataset run. Run with `cargo bench -p trial-sim --bench trials`.

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use trial_sim::datagen::{DatagenConfig, NoProgress, simulate};
use trial_sim::{TrialSimulator, ground_truth_heatmap};
use world::view::{Side, cell_center_world};
use world::{RobotConfig, generate::training_scenes};

fn bench_trials(c: &mut Criterion) {
    let scene = training_scenes(0, 1, 1).remove(0);
    let robot = RobotConfig::default();
    let target = scene.targets[0].as_array();
    let mut group = c.benchmark_group("trial");
    group.throughput(Throughput::Elements(1));
    for (name, row) in [("reachable_row_10", 10usize), ("far_row_16", 16)] {
        let commanded = cell_center_world(target[0], Side::Near, row, 31);
        let mut sim = TrialSimulator::new(&scene, &robot);
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        group.bench_function(name, |b| {
            b.iter(|| sim.run(target, Side::Near, commanded, &mut rng))
        });
    }
    group.finish();

    let mut group = c.benchmark_group("heatmap");
    group.throughput(Throughput::Elements(5 * 192));
    group.bench_function("ground_truth_5_trials_per_cell", |b| {
        b.iter(|| ground_truth_heatmap(&scene, &robot, target, Side::Near, 5, 3))
    });
    group.finish();

    let mut group = c.benchmark_group("datagen");
    group.sample_size(10);
    let cfg = DatagenConfig {
        n_envs: 2,
        targets_per_env: 5,
        ..DatagenConfig::default()
    };
    group.throughput(Throughput::Elements(10 * 5 * 192));
    group.bench_function("simulate_10_tasks_parallel", |b| {
        b.iter(|| simulate(&cfg, &NoProgress, false).map(|d| d.summary.successes))
    });
    group.finish();
}

criterion_group!(benches, bench_trials);
criterion_main!(benches);
