//! Campaigns in shards (`--shard I/N`, `grop merge`): merged shards give what one run writes,
//! and a missing, duplicated or foreign shard is refused without touching what is there.
#![allow(
    clippy::too_many_lines,
    reason = "a test scenario (or the fuzz harness's) reads top to bottom as one story"
)]
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failure panics with its message

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Output;

mod common;
use common::{grop, model, text};

fn ok(o: Output) -> String {
    let t = text(&o);
    assert!(o.status.success(), "{t}");
    t
}

/// Every file under `dir` (relative path -> bytes).
fn files(dir: &Path) -> BTreeMap<PathBuf, Vec<u8>> {
    fn walk(root: &Path, dir: &Path, out: &mut BTreeMap<PathBuf, Vec<u8>>) {
        for e in std::fs::read_dir(dir).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                walk(root, &p, out);
            } else {
                out.insert(
                    p.strip_prefix(root).unwrap().to_path_buf(),
                    std::fs::read(&p).unwrap(),
                );
            }
        }
    }
    let mut out = BTreeMap::new();
    walk(dir, dir, &mut out);
    out
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

#[test]
fn eval_in_three_shards_merges_byte_for_byte_into_one_run() {
    let dir = tempfile::tempdir().unwrap();
    let m = model();
    let cache = dir.path().join("gt.json");
    let eval = |extra: &[&str]| {
        let mut args = vec![
            "eval",
            "--model",
            &m,
            "--scenes-per-chair-count",
            "1",
            "--tasks-per-scene",
            "2",
            "--trials-per-cell",
            "1",
            "--methods",
            "grop+,grop,petlon",
            "--no-sweep",
            "--cache",
            s(&cache),
        ];
        args.extend_from_slice(extra);
        grop(&args)
    };
    let whole = dir.path().join("whole");
    ok(eval(&["--out-dir", s(&whole)]));
    let shards = dir.path().join("shards");
    for i in [2, 0, 1] {
        let shard = format!("{i}/3");
        let out = ok(eval(&["--out-dir", s(&shards), "--shard", &shard]));
        assert!(out.contains(&format!("shard {i}/3: 2 of 6 tasks")), "{out}");
    }
    // A shard's folder holds its results and manifest only.
    let one = files(&shards.join("shard-001-of-003"));
    assert_eq!(
        one.keys()
            .map(|p| p.display().to_string())
            .collect::<Vec<_>>(),
        ["records.tsv", "shard.json"]
    );
    let manifest: serde_json::Value =
        serde_json::from_slice(&one[Path::new("shard.json")]).unwrap();
    assert_eq!(manifest["task_ids"], serde_json::json!([1, 4]));
    assert_eq!(manifest["seed"], 2022);
    assert_eq!(
        manifest["shard"],
        serde_json::json!({"index": 1, "count": 3})
    );

    let merged = dir.path().join("merged");
    ok(grop(&["merge", "--out", s(&merged), s(&shards)]));
    let (a, b) = (files(&whole), files(&merged));
    assert_eq!(
        a.keys().collect::<Vec<_>>(),
        b.keys().collect::<Vec<_>>(),
        "the same files"
    );
    for (name, bytes) in &a {
        assert!(
            bytes == &b[name],
            "{} differs between one run and the merged shards",
            name.display()
        );
    }

    // Merging again into the same folder is refused and leaves it as it was.
    let o = grop(&["merge", "--out", s(&merged), s(&shards)]);
    assert!(
        !o.status.success() && text(&o).contains("not empty"),
        "{}",
        text(&o)
    );
    assert_eq!(files(&merged), b);

    // A missing shard, named.
    let two = [
        s(&shards.join("shard-000-of-003")).to_owned(),
        s(&shards.join("shard-002-of-003")).to_owned(),
    ];
    let target = dir.path().join("m2");
    let o = grop(&["merge", "--out", s(&target), &two[0], &two[1]]);
    let t = text(&o);
    assert!(
        !o.status.success() && t.contains("shard 1/3") && t.contains("missing"),
        "{t}"
    );
    assert!(!target.exists(), "nothing written on failure");
    // The same shard twice.
    let o = grop(&["merge", "--out", s(&target), s(&shards), &two[0]]);
    let t = text(&o);
    assert!(!o.status.success() && t.contains("twice"), "{t}");
    // A shard of another campaign (other seed), named.
    let other = dir.path().join("other");
    ok(eval(&[
        "--out-dir",
        s(&other),
        "--shard",
        "1/3",
        "--seed",
        "7",
    ]));
    let foreign = other.join("shard-001-of-003");
    let o = grop(&["merge", "--out", s(&target), &two[0], s(&foreign), &two[1]]);
    let t = text(&o);
    assert!(
        !o.status.success()
            && t.contains("foreign")
            && t.contains("seed")
            && t.contains(s(&foreign)),
        "{t}"
    );
    // Same seed, other configuration.
    let other = dir.path().join("other-config");
    ok(eval(&[
        "--out-dir",
        s(&other),
        "--shard",
        "1/3",
        "--speed",
        "0.5",
    ]));
    let foreign = other.join("shard-001-of-003");
    let o = grop(&["merge", "--out", s(&target), &two[0], s(&foreign), &two[1]]);
    let t = text(&o);
    assert!(
        !o.status.success() && t.contains("configuration (options.speed)"),
        "{t}"
    );
    assert!(!target.exists(), "nothing written on failure");
    let leftovers: Vec<String> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with('.'))
        .collect();
    assert!(
        leftovers.is_empty(),
        "temporary folders left: {leftovers:?}"
    );
}

#[test]
fn datagen_in_three_shards_merges_into_the_dataset_of_one_run() {
    let dir = tempfile::tempdir().unwrap();
    let datagen = |extra: &[&str]| {
        let mut args = vec![
            "datagen",
            "--envs",
            "1",
            "--targets-per-env",
            "5",
            "--trials-per-cell",
            "1",
            "--seed",
            "3",
        ];
        args.extend_from_slice(extra);
        grop(&args)
    };
    let whole = dir.path().join("whole");
    ok(datagen(&["--out", s(&whole)]));
    let shards = dir.path().join("shards");
    for i in 0..3 {
        ok(datagen(&[
            "--out",
            s(&shards),
            "--shard",
            &format!("{i}/3"),
        ]));
    }
    let merged = dir.path().join("merged");
    ok(grop(&["merge", "--out", s(&merged), s(&shards)]));
    let (a, b) = (files(&whole), files(&merged));
    assert_eq!(a.keys().collect::<Vec<_>>(), b.keys().collect::<Vec<_>>());
    // dataset.json carries the simulation's wall seconds, which differ between any two runs.
    let wall_free = |bytes: &[u8]| {
        let mut v: serde_json::Value = serde_json::from_slice(bytes).unwrap();
        v["summary"]["simulate_s"] = 0.into();
        v["summary"]["trials_per_s"] = 0.into();
        v
    };
    for (name, bytes) in &a {
        if name == Path::new("dataset.json") {
            assert_eq!(wall_free(bytes), wall_free(&b[name]));
        } else {
            assert!(bytes == &b[name], "{} differs", name.display());
        }
    }
    // Foreign: another configuration.
    let other = dir.path().join("other");
    ok(datagen(&[
        "--out",
        s(&other),
        "--shard",
        "1/3",
        "--no-trials-csv",
    ]));
    let target = dir.path().join("m2");
    let o = grop(&[
        "merge",
        "--out",
        s(&target),
        s(&shards.join("shard-000-of-003")),
        s(&other.join("shard-001-of-003")),
        s(&shards.join("shard-002-of-003")),
    ]);
    let t = text(&o);
    assert!(
        !o.status.success() && t.contains("configuration (options.no_trials_csv)"),
        "{t}"
    );
    assert!(!target.exists());
}

#[test]
fn a_bad_shard_value_is_refused_with_its_text() {
    for bad in ["3/3", "a/2", "1"] {
        let o = grop(&["datagen", "--shard", bad]);
        let t = text(&o);
        assert!(!o.status.success() && t.contains(bad), "{t}");
    }
    let o = grop(&["merge", "--out", "/nonexistent/x", "/nonexistent/shards"]);
    assert!(!o.status.success() && text(&o).contains("/nonexistent/shards"));
}

/// The closed-loop tests one at a time: soak counts this machine's iceoryx2 files and
/// listening sockets before and after each mission.
static CLOSED_LOOP: std::sync::Mutex<()> = std::sync::Mutex::new(());

/// tasks.csv without its wall-time column (`wall_s`, the 11th).
fn without_wall(csv: &str) -> Vec<String> {
    csv.lines()
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            [&f[..10], &f[11..]].concat().join(",")
        })
        .collect()
}

#[test]
fn hil_in_two_shards_merges_into_the_per_task_results_of_one_run() {
    let _serial = CLOSED_LOOP.lock().unwrap_or_else(|e| e.into_inner());
    let dir = tempfile::tempdir().unwrap();
    let m = model();
    let hil = |extra: &[&str]| {
        // The base blind (no range sensor): this test is about shards adding up to one run,
        // and without the sensor's rays a mission runs about ten times faster.
        let mut args = vec![
            "hil",
            "--model",
            &m,
            "--tasks",
            "3",
            "--jobs",
            "1",
            "--no-lidar",
        ];
        args.extend_from_slice(extra);
        grop(&args)
    };
    let whole = dir.path().join("whole");
    ok(hil(&["--out-dir", s(&whole)]));
    let shards = dir.path().join("shards");
    for i in 0..2 {
        ok(hil(&[
            "--out-dir",
            s(&shards),
            "--shard",
            &format!("{i}/2"),
            "--no-build",
        ]));
    }
    let merged = dir.path().join("merged");
    ok(grop(&["merge", "--out", s(&merged), s(&shards)]));
    let a = std::fs::read_to_string(whole.join("tasks.csv")).unwrap();
    let b = std::fs::read_to_string(merged.join("tasks.csv")).unwrap();
    assert_eq!(a.lines().count(), 4, "{a}");
    assert_eq!(without_wall(&a), without_wall(&b));
    let paired = |p: &Path| {
        let t = std::fs::read_to_string(p.join("summary.md")).unwrap();
        t.lines()
            .find(|l| l.starts_with("Paired difference"))
            .unwrap()
            .to_owned()
    };
    assert_eq!(paired(&whole), paired(&merged));
    // Every mission's folder came along.
    let tasks: Vec<String> = std::fs::read_dir(&merged)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with("task-"))
        .collect();
    assert_eq!(tasks.len(), 3, "{tasks:?}");
}

#[test]
fn soak_in_two_shards_adds_up_counts_and_judges_memory_per_shard() {
    let _serial = CLOSED_LOOP.lock().unwrap_or_else(|e| e.into_inner());
    let dir = tempfile::tempdir().unwrap();
    let m = model();
    let shards = dir.path().join("shards");
    // The resource checks count this machine's iceoryx2 files and loopback listeners, which
    // other programs running beside the test change too: a shard may fail them. It writes its
    // folder either way, and the merge must carry its failed checks over.
    let mut shard_failures = 0;
    for i in 0..2 {
        let o = grop(&[
            "soak",
            "--model",
            &m,
            "--missions",
            "4",
            "--scenes",
            "2",
            "--warm-up",
            "1",
            // Blind (no range sensor): this test is about shards adding up.
            "--no-lidar",
            "--out-dir",
            s(&shards),
            "--shard",
            &format!("{i}/2"),
        ]);
        let out = text(&o);
        assert!(out.contains(&format!("shard {i}/2")), "{out}");
        let failures =
            std::fs::read_to_string(shards.join(format!("shard-00{i}-of-002/failures.txt")))
                .unwrap()
                .lines()
                .count();
        assert_eq!(o.status.success(), failures == 0, "{out}");
        shard_failures += failures;
    }
    // Mission i ran in shard i mod 2: shard 1 had missions 1 and 3, both scene seed 1 + 1.
    let rows = std::fs::read_to_string(shards.join("shard-001-of-002/rows.tsv")).unwrap();
    let scenes: Vec<&str> = rows
        .lines()
        .skip(1)
        .map(|l| l.split('\t').next().unwrap())
        .collect();
    assert_eq!(scenes, ["2", "2"]);
    let merged = dir.path().join("merged");
    let o = grop(&["merge", "--out", s(&merged), s(&shards)]);
    assert_eq!(o.status.success(), shard_failures == 0, "{}", text(&o));
    let md = std::fs::read_to_string(merged.join("soak.md")).unwrap();
    assert!(
        md.contains("# Soak: 4 closed-loop missions in 2 shards"),
        "{md}"
    );
    // 4 missions run, none failed to run.
    assert!(md.contains("\n| 4 | "), "{md}");
    for shard in ["0/2", "1/2"] {
        assert!(
            md.contains(&format!("| {shard} | grop-world (peak")),
            "{md}"
        );
    }
    if shard_failures == 0 {
        assert!(md.contains("All checks passed."), "{md}");
    } else {
        assert!(
            md.contains(&format!("**{shard_failures} checks failed:**")),
            "{md}"
        );
    }
}
