//! `datagen`: outputs, their consistency with the simulator, determinism across threads.
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failure panics with its message

use std::io::{BufRead, BufReader};

use trial_sim::datagen::{DatagenConfig, NoProgress, SideSelection, generate, simulate};
use trial_sim::ground_truth_heatmap;
use world::view::{CANDIDATE_CELLS, CROP_CELLS, in_candidate_area};

fn small(out_dir: &std::path::Path) -> DatagenConfig {
    DatagenConfig {
        n_envs: 2,
        targets_per_env: 2,
        out_dir: out_dir.to_owned(),
        ..DatagenConfig::default()
    }
}

fn read_array<T: npyz::Deserialize>(
    archive: &mut npyz::npz::NpzArchive<BufReader<std::fs::File>>,
    name: &str,
) -> (Vec<u64>, Vec<T>) {
    let file = archive
        .by_name(name)
        .expect("readable")
        .unwrap_or_else(|| panic!("array {name} present"));
    let shape = file.shape().to_vec();
    (shape, file.into_vec().expect("decodes"))
}

#[test]
fn writes_the_documented_files() {
    let dir = tempfile::tempdir().expect("temp dir");
    let cfg = small(dir.path());
    let summary = generate(&cfg, &NoProgress).expect("generates");
    let n = 4u64;
    assert_eq!(summary.tasks, 4);
    assert_eq!(summary.trials, 4 * 5 * 192);

    let mut npz = npyz::npz::NpzArchive::open(dir.path().join("dataset.npz")).expect("npz opens");
    let (shape, images) = read_array::<u8>(&mut npz, "images");
    assert_eq!(shape, vec![n, 32, 64]);
    let (_, labels) = read_array::<f32>(&mut npz, "labels");
    let (_, mask) = read_array::<u8>(&mut npz, "mask");
    let (_, successes) = read_array::<u16>(&mut npz, "successes");
    let (_, trials) = read_array::<u16>(&mut npz, "trials_per_cell");
    let (tshape, targets) = read_array::<f64>(&mut npz, "targets");
    let (_, scene) = read_array::<i32>(&mut npz, "scene");
    let (_, side) = read_array::<i8>(&mut npz, "side");
    assert_eq!(tshape, vec![n, 3]);
    assert_eq!(trials, vec![5; 4]);
    assert_eq!(scene, vec![0, 0, 1, 1]);
    assert_eq!(side, vec![1; 4]);
    assert!(targets.chunks(3).all(|t| t[1] == 6.0 && t[2] == 1.3));
    for task in 0..4 {
        for cell in 0..CROP_CELLS {
            let i = task * CROP_CELLS + cell;
            let labelled = in_candidate_area(cell / 64, cell % 64);
            assert_eq!(mask[i], u8::from(labelled));
            assert_eq!(labels[i], f32::from(successes[i]) / 5.0);
            if !labelled {
                assert_eq!(successes[i], 0);
            }
        }
    }
    assert!(images.contains(&world::view::TABLE_GRAY));

    let csv = BufReader::new(std::fs::File::open(dir.path().join("trials.csv")).expect("csv"));
    let lines: Vec<String> = csv.lines().map(|l| l.expect("utf-8")).collect();
    assert!(lines[0].starts_with("task,scene,target_x_m,side,row,col,trial"));
    assert_eq!(lines.len() - 1, 4 * 5 * CANDIDATE_CELLS);
    let csv_successes = lines.iter().filter(|l| l.ends_with(",success")).count() as u64;
    assert_eq!(csv_successes, summary.successes);
    assert_eq!(
        successes.iter().map(|&s| u64::from(s)).sum::<u64>(),
        summary.successes
    );

    let json: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(dir.path().join("dataset.json")).expect("json"),
    )
    .expect("parses");
    assert_eq!(json["format_version"], 1);
    assert_eq!(json["generator"]["trials_per_cell"], 5);
    assert_eq!(json["summary"]["trials"], 3840);
    assert_eq!(json["tasks"].as_array().map(Vec::len), Some(4));
    let scene_file = json["tasks"][3]["scene_file"]
        .as_str()
        .expect("scene file named");
    let scene = world::Scene::load(dir.path().join(scene_file)).expect("scene file reloads");
    assert_eq!(scene.targets.len(), 2);
    world::RobotConfig::load(dir.path().join("robot.toml")).expect("robot file reloads");

    let hist: u64 = summary.successes_per_cell_histogram.iter().sum();
    assert_eq!(hist, 4 * 192);
}

#[test]
fn labels_equal_the_ground_truth_heatmap_of_each_task() {
    let cfg = DatagenConfig {
        n_envs: 1,
        targets_per_env: 2,
        sides: SideSelection::Both,
        ..DatagenConfig::default()
    };
    let dataset = simulate(&cfg, &NoProgress, false).expect("simulates");
    assert_eq!(dataset.tasks.len(), 4);
    for task in &dataset.tasks {
        let t = task.task;
        let expected = ground_truth_heatmap(
            &dataset.scenes[t.scene],
            &cfg.robot,
            t.target,
            t.side,
            5,
            t.seed,
        );
        assert_eq!(task.counts.heatmap(), expected, "task {}", t.index);
        assert_eq!(
            task.crop,
            world::view::render_crop(&dataset.scenes[t.scene], t.target[0], t.side)
        );
    }
}

#[test]
fn thread_count_does_not_change_the_data() {
    let cfg = DatagenConfig {
        n_envs: 2,
        targets_per_env: 2,
        ..DatagenConfig::default()
    };
    let run = |threads| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("pool");
        pool.install(|| simulate(&cfg, &NoProgress, true).expect("simulates"))
    };
    let (one, two) = (run(1), run(2));
    for (a, b) in one.tasks.iter().zip(&two.tasks) {
        assert_eq!(a.counts.successes, b.counts.successes);
        assert_eq!(a.records, b.records);
    }
    assert_eq!(one.summary.results, two.summary.results);
}

#[test]
fn bad_settings_are_rejected() {
    let zero_trials = DatagenConfig {
        trials_per_cell: 0,
        ..DatagenConfig::default()
    };
    assert!(simulate(&zero_trials, &NoProgress, false).is_err());
    let mut bad_robot = DatagenConfig::default();
    bad_robot.robot.speed_mps = f64::NAN;
    let err = simulate(&bad_robot, &NoProgress, false).expect_err("NaN speed");
    assert!(err.to_string().contains("speed_mps"), "{err}");
}

#[test]
fn shards_through_their_files_merge_into_the_whole_dataset() {
    use trial_sim::datagen::{merge_shards, read_shard_tasks, simulate_shard, write_shard_tasks};
    use trial_sim::shard::Shard;
    let dir = tempfile::tempdir().expect("tempdir");
    let cfg = DatagenConfig {
        n_envs: 1,
        targets_per_env: 5,
        trials_per_cell: 2,
        ..small(dir.path())
    };
    let whole = simulate(&cfg, &NoProgress, true).expect("simulates");
    let mut parts = Vec::new();
    for index in 0..3 {
        let shard = Shard { index, count: 3 };
        let d = simulate_shard(&cfg, shard, &NoProgress, true).expect("simulates");
        assert_eq!(
            d.tasks.iter().map(|t| t.task.index).collect::<Vec<_>>(),
            shard.positions(5)
        );
        let file = dir.path().join(format!("shard-{index}.bin"));
        write_shard_tasks(&d, &file).expect("writes");
        let (_, tasks) = read_shard_tasks(&cfg, &file).expect("reads back");
        parts.extend(tasks);
    }
    parts.reverse();
    let merged = merge_shards(&cfg, parts.clone(), 0.0).expect("merges");
    assert_eq!(merged.tasks.len(), whole.tasks.len());
    for (a, b) in merged.tasks.iter().zip(&whole.tasks) {
        assert_eq!(a.task, b.task);
        assert_eq!(a.crop, b.crop);
        assert_eq!(a.counts.successes, b.counts.successes);
        assert_eq!(a.counts.trials, b.counts.trials);
        assert_eq!(a.records, b.records);
    }
    let wall_free = |s: &trial_sim::datagen::DatasetSummary| trial_sim::datagen::DatasetSummary {
        simulate_s: 0.0,
        trials_per_s: 0.0,
        ..s.clone()
    };
    assert_eq!(wall_free(&merged.summary), wall_free(&whole.summary));
    // A task twice or one missing is refused.
    let mut twice = parts.clone();
    twice.push(parts[0].clone());
    assert!(merge_shards(&cfg, twice, 0.0).is_err());
    parts.pop();
    assert!(merge_shards(&cfg, parts, 0.0).is_err());
}
