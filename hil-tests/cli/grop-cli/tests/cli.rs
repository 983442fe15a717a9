//! End-to-end runs of the `grop` binary: every job on small settings, and clear errors on bad
//! input (no panic, non-zero exit, the bad thing named).
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failure panics with its message

use std::path::PathBuf;
use std::process::{Command, Output};

mod common;
use common::{grop, model, text};

#[test]
fn demo_runs_the_closed_loop_and_reports_decision_steps_and_latency() {
    let dir = tempfile::tempdir().unwrap();
    let png = dir.path().join("demo.png");
    let run = dir.path().join("run");
    let log = dir.path().join("demo.mcap");
    let o = grop(&[
        "demo",
        "--model",
        &model(),
        "--out",
        png.to_str().unwrap(),
        "--run-dir",
        run.to_str().unwrap(),
        "--record",
        log.to_str().unwrap(),
    ]);
    let out = text(&o);
    assert!(o.status.success(), "{out}");
    for expected in [
        "decision: plan 1",
        "unload obj0",
        "steps:",
        "mission Finished",
        "latency per stage:",
        "perception + planning (wall)",
        "mission log",
    ] {
        assert!(out.contains(expected), "no {expected:?} in:\n{out}");
    }
    // A mission that finished with no fault has nothing to explain.
    assert!(!out.contains("why the mission ended"), "{out}");
    assert!(
        std::fs::metadata(&log).is_ok_and(|m| m.len() > 0),
        "no log at {log:?}"
    );
    let img = image_header(&png);
    assert_eq!(&img[..8], b"\x89PNG\r\n\x1a\n");
    // The run's files: what the processes read and what the world found.
    for f in [
        "scene.toml",
        "deployment.toml",
        "world-report.json",
        "executive.log",
    ] {
        assert!(run.join(f).is_file(), "{f} missing");
    }
    // The committed Foxglove layout's panels, drawn from that log (from another folder: the
    // layout is found in the checkout); a layout that is not there is named.
    let layout_png = dir.path().join("layout.png");
    let o = Command::new(env!("CARGO_BIN_EXE_grop"))
        .current_dir(dir.path())
        .args(["layout-picture", log.to_str().unwrap(), "--out"])
        .arg(&layout_png)
        .args(["--width", "900", "--height", "600"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", text(&o));
    let bytes = std::fs::read(&layout_png).unwrap();
    assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n");
    // The IHDR chunk's width.
    assert_eq!(u32::from_be_bytes(bytes[16..20].try_into().unwrap()), 900);
    let o = grop(&[
        "layout-picture",
        log.to_str().unwrap(),
        "--layout",
        "no-such.json",
    ]);
    assert!(!o.status.success());
    assert!(text(&o).contains("no-such.json"), "{}", text(&o));
}

#[test]
fn demo_says_why_a_faulted_mission_ended_and_what_to_do_next() {
    let dir = tempfile::tempdir().unwrap();
    let png = dir.path().join("demo.png");
    let run = dir.path().join("run");
    let o = grop(&[
        "demo",
        "--model",
        &model(),
        "--fault",
        "kill-switch",
        "--no-record",
        "--out",
        png.to_str().unwrap(),
        "--run-dir",
        run.to_str().unwrap(),
    ]);
    let out = text(&o);
    assert!(o.status.success(), "{out}");
    for expected in [
        "mission Aborted",
        "why the mission ended (aborted):",
        "fault injected: kill-switch@driving at ",
        "noticed by the RMP driver",
        "MissionAborted: BaseFault",
        "reaction: first zero base command at ",
        "base stood still at ",
        "next: release the base's kill switch",
    ] {
        assert!(out.contains(expected), "no {expected:?} in:\n{out}");
    }
}

#[test]
fn demo_in_process_plans_explains_executes_and_draws() {
    let dir = tempfile::tempdir().unwrap();
    let png = dir.path().join("demo.png");
    let o = grop(&[
        "demo",
        "--in-process",
        "--model",
        &model(),
        "--out",
        png.to_str().unwrap(),
    ]);
    let out = text(&o);
    assert!(o.status.success(), "{out}");
    // GROP+ is the default method.
    assert!(out.contains("GROP+: F(p) ="), "{out}");
    assert!(out.contains("of 288 plans"), "{out}");
    assert!(out.contains("placed "), "{out}");
    let img = image_header(&png);
    assert_eq!(&img[..8], b"\x89PNG\r\n\x1a\n");
}

#[test]
fn demo_in_process_is_deterministic_for_a_seed() {
    let dir = tempfile::tempdir().unwrap();
    let run = |name: &str| {
        let png = dir.path().join(name);
        let o = grop(&[
            "demo",
            "--in-process",
            "--model",
            &model(),
            "--seed",
            "5",
            "--method",
            "petlon",
            "--out",
            png.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{}", text(&o));
        // Everything but the measured decision time.
        let stdout = String::from_utf8_lossy(&o.stdout).to_string();
        let kept: Vec<&str> = stdout
            .lines()
            .filter(|l| !l.starts_with("decision in") && !l.starts_with("wrote"))
            .collect();
        (kept.join("\n"), std::fs::read(&png).unwrap())
    };
    assert_eq!(run("a.png"), run("b.png"));
}

#[test]
fn demo_names_a_bad_method_and_a_missing_model() {
    let o = grop(&["demo", "--method", "magic", "--model", &model()]);
    assert!(!o.status.success());
    assert!(
        text(&o).contains("unknown --method \"magic\""),
        "{}",
        text(&o)
    );

    let o = grop(&["demo", "--model", "/nonexistent/psi.onnx", "--no-build"]);
    assert!(!o.status.success());
    let out = text(&o);
    assert!(out.contains("/nonexistent/psi.onnx"), "{out}");
    assert!(!out.contains("panicked"), "{out}");

    // A model file that is not a model: the planner process says so and the demo stops.
    let dir = tempfile::tempdir().unwrap();
    let bad = dir.path().join("garbage.onnx");
    std::fs::write(&bad, b"not a network").unwrap();
    let run = dir.path().join("run");
    let o = grop(&[
        "demo",
        "--model",
        bad.to_str().unwrap(),
        "--run-dir",
        run.to_str().unwrap(),
        "--no-record",
    ]);
    assert!(!o.status.success());
    let out = text(&o);
    assert!(out.contains("grop-planner exited"), "{out}");
    assert!(out.contains("garbage.onnx"), "{out}");
    assert!(!out.contains("panicked"), "{out}");
}

#[test]
fn demo_live_names_a_taken_address_and_needs_the_recorder() {
    let taken = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let addr = taken.local_addr().unwrap().to_string();
    let dir = tempfile::tempdir().unwrap();
    let run = dir.path().join("run");
    let o = grop(&["demo", "--live", &addr, "--run-dir", run.to_str().unwrap()]);
    assert!(!o.status.success());
    let out = text(&o);
    assert!(
        out.contains(&format!("--live {addr}: cannot listen")),
        "{out}"
    );
    assert!(!out.contains("panicked"), "{out}");

    let o = grop(&[
        "demo",
        "--live",
        "--no-record",
        "--run-dir",
        run.to_str().unwrap(),
    ]);
    assert!(!o.status.success());
    assert!(text(&o).contains("drop --no-record"), "{}", text(&o));

    let o = grop(&["demo", "--live", "--in-process"]);
    assert!(!o.status.success());
    assert!(
        text(&o).contains("--live needs the closed loop"),
        "{}",
        text(&o)
    );
}

#[test]
fn eval_writes_tables_and_names_a_bad_success_bonus() {
    let dir = tempfile::tempdir().unwrap();
    let model_path = model();
    let out_dir = dir.path().join("exp");
    let cache = dir.path().join("gt.json");
    // A small evaluation into the temporary folder, with `extra` settings.
    let eval = |extra: &[&str]| {
        let mut args = vec![
            "eval",
            "--model",
            &model_path,
            "--scenes-per-chair-count",
            "1",
            "--no-sweep",
            "--out-dir",
            out_dir.to_str().unwrap(),
            "--cache",
            cache.to_str().unwrap(),
        ];
        args.extend_from_slice(extra);
        let o = grop(&args);
        (o.status.success(), text(&o))
    };
    let summary = || std::fs::read_to_string(out_dir.join("summary.md")).unwrap();

    let (ok, out) = eval(&["--tasks-per-scene", "2", "--success-bonus", "100"]);
    assert!(ok, "{out}");
    let s = summary();
    assert!(s.contains("6 tasks") && s.contains("R 100"), "{s}");
    assert!(s.contains("GROP minus each method"), "{s}");
    assert!(s.contains("GROP+ (retries 1, goal draws 20"), "{s}");
    let csv = std::fs::read_to_string(out_dir.join("eval_tasks.csv")).unwrap();
    // Header + 6 tasks x 6 methods (GROP+ and GROP first).
    assert_eq!(csv.lines().count(), 1 + 6 * 6);
    assert!(out_dir.join("fig5.svg").exists());

    // A geometric heuristic as Psi, GROP alone, the paper's Smp.
    let (ok, out) = eval(&[
        "--tasks-per-scene",
        "1",
        "--evaluator",
        "binary",
        "--methods",
        "grop",
        "--paper-smp",
    ]);
    assert!(ok, "{out}");
    let s = summary();
    assert!(
        s.contains("evaluator Binary") && s.contains("paper Smp"),
        "{s}"
    );

    let (ok, out) = eval(&["--success-bonus=-1"]);
    assert!(!ok);
    assert!(out.contains("success_bonus_r"), "{out}");
    let (ok, out) = eval(&["--plus-retries", "9"]);
    assert!(!ok);
    assert!(out.contains("GROP+ retries must be at most 8"), "{out}");
}

#[test]
fn render_writes_picture_crops_and_scene() {
    let dir = tempfile::tempdir().unwrap();
    let png = dir.path().join("r.png");
    let o = grop(&[
        "render",
        "--trials-per-cell",
        "2",
        "--out",
        png.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", text(&o));
    assert!(png.exists());
    assert!(dir.path().join("r.crops.png").exists());
    // The scene written beside the picture renders again from the file.
    let scene = dir.path().join("r.scene.toml");
    let again = dir.path().join("again.png");
    let o = grop(&[
        "render",
        "--scene",
        scene.to_str().unwrap(),
        "--trials-per-cell",
        "2",
        "--out",
        again.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", text(&o));
    assert_eq!(std::fs::read(&png).unwrap(), std::fs::read(&again).unwrap());
}

#[test]
fn render_names_the_file_and_field_of_a_bad_scene() {
    let dir = tempfile::tempdir().unwrap();
    let bad = dir.path().join("bad.toml");
    std::fs::write(&bad, "format_version = 1\nname = \"x\"\nbogus_field = 3\n").unwrap();
    let o = grop(&["render", "--scene", bad.to_str().unwrap()]);
    assert!(!o.status.success());
    let out = text(&o);
    assert!(out.contains("bad.toml"), "{out}");
    assert!(!out.contains("panicked"), "{out}");
}

#[test]
fn datagen_writes_the_documented_files() {
    let dir = tempfile::tempdir().unwrap();
    let out_dir = dir.path().join("ds");
    let o = grop(&[
        "datagen",
        "--envs",
        "1",
        "--targets-per-env",
        "2",
        "--out",
        out_dir.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", text(&o));
    for f in ["dataset.npz", "dataset.json", "trials.csv"] {
        assert!(out_dir.join(f).exists(), "{f} missing");
    }
    let json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out_dir.join("dataset.json")).unwrap()).unwrap();
    // 2 tasks x 5 trials x 24 x 8 cells.
    assert_eq!(json["summary"]["trials"], 1920);
}

/// `grop` run in `cwd` (relative defaults such as `out/` and `docs/` land there).
fn grop_in(cwd: &std::path::Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_grop"))
        .current_dir(cwd)
        .args(args)
        .args(["--log", "warn"])
        .output()
        .expect("the grop binary runs")
}

#[test]
fn bench_writes_under_out_and_regenerates_the_doc_only_with_write_docs() {
    let dir = tempfile::tempdir().unwrap();
    // No --model: the committed model is found from a folder outside the checkout, as the
    // closed-loop demo finds it.
    let bench = ["bench", "--iterations", "10"];
    let o = grop_in(dir.path(), &bench);
    assert!(o.status.success(), "{}", text(&o));
    assert!(dir.path().join("out/planner-bench.md").is_file());
    assert!(
        !dir.path().join("docs").exists(),
        "docs/ written without --write-docs"
    );
    let o = grop_in(dir.path(), &[&bench[..], &["--write-docs"]].concat());
    assert!(o.status.success(), "{}", text(&o));
    let doc = std::fs::read_to_string(dir.path().join("docs/planner-bench.md")).unwrap();
    assert!(doc.contains("bench --write-docs"), "{doc}");
    // The decision both between the other cases and back to back, and the verdict on both.
    assert!(doc.contains("| grop-3 |"), "{doc}");
    assert!(doc.contains("| grop-3/back-to-back |"), "{doc}");
    assert!(doc.contains("Back to back (`grop-3/back-to-back`"), "{doc}");
    assert!(doc.contains("| grop-3/whole-heatmaps |"), "{doc}");
    assert!(
        doc.contains("with whole heatmaps (`grop-3/whole-heatmaps`"),
        "{doc}"
    );
}

#[test]
fn eval_writes_under_out_and_regenerates_the_docs_only_with_write_docs() {
    let dir = tempfile::tempdir().unwrap();
    let model = model();
    let eval = [
        "eval",
        "--model",
        &model,
        "--evaluator",
        "binary",
        "--methods",
        "grop",
        "--scenes-per-chair-count",
        "1",
        "--tasks-per-scene",
        "1",
        "--no-sweep",
        "--cache",
        "gt.json",
    ];
    let o = grop_in(dir.path(), &eval);
    assert!(o.status.success(), "{}", text(&o));
    for f in ["summary.md", "eval_tasks.csv", "fig5.svg"] {
        assert!(dir.path().join("out/experiments").join(f).is_file(), "{f}");
    }
    assert!(
        !dir.path().join("docs").exists(),
        "docs/ written without --write-docs"
    );
    // Bare: the main results' folder; with a value: a variant's.
    let o = grop_in(dir.path(), &[&eval[..], &["--write-docs"]].concat());
    assert!(o.status.success(), "{}", text(&o));
    let o = grop_in(
        dir.path(),
        &[&eval[..], &["--write-docs", "docs/experiments/oracle"]].concat(),
    );
    assert!(o.status.success(), "{}", text(&o));
    for f in ["summary.md", "eval_tasks.csv", "fig5.svg"] {
        assert!(dir.path().join("docs/experiments").join(f).is_file(), "{f}");
        assert!(
            dir.path().join("docs/experiments/oracle").join(f).is_file(),
            "{f}"
        );
    }
}

/// Every file under `dir` (relative path -> bytes).
fn snapshot(dir: &std::path::Path) -> std::collections::BTreeMap<PathBuf, Vec<u8>> {
    let mut files = std::collections::BTreeMap::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for entry in std::fs::read_dir(&d).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                stack.push(path);
            } else {
                let bytes = std::fs::read(&path).unwrap();
                files.insert(path.strip_prefix(dir).unwrap().to_path_buf(), bytes);
            }
        }
    }
    files
}

#[test]
fn an_interrupted_datagen_leaves_the_previous_dataset_whole() {
    let dir = tempfile::tempdir().unwrap();
    let out_dir = dir.path().join("ds");
    let out = out_dir.to_str().unwrap();
    let small = [
        "datagen",
        "--envs",
        "1",
        "--targets-per-env",
        "2",
        "--out",
        out,
    ];
    let o = grop(&[&small[..], &["--seed", "1"]].concat());
    assert!(o.status.success(), "{}", text(&o));
    let before = snapshot(&out_dir);
    // Another seed, killed while it writes its files: the file-size limit (8 KiB) lets the
    // scene and robot files through and stops the process (SIGXFSZ) inside dataset.npz.
    let o = Command::new("bash")
        .arg("-c")
        .arg("ulimit -f 8; exec \"$0\" \"$@\"")
        .arg(env!("CARGO_BIN_EXE_grop"))
        .args(small)
        .args(["--seed", "2", "--log", "warn"])
        .output()
        .unwrap();
    assert!(
        !o.status.success(),
        "the limited run must fail: {}",
        text(&o)
    );
    let after = snapshot(&out_dir);
    assert_eq!(
        before.keys().collect::<Vec<_>>(),
        after.keys().collect::<Vec<_>>()
    );
    for (file, bytes) in &before {
        assert!(after[file] == *bytes, "{} changed", file.display());
    }
    // The next complete run replaces the dataset as a whole and clears what the killed one
    // left behind.
    let o = grop(&[&small[..], &["--seed", "2"]].concat());
    assert!(o.status.success(), "{}", text(&o));
    let json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out_dir.join("dataset.json")).unwrap()).unwrap();
    assert_eq!(json["generator"]["seed"], 2);
    let names: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(names, ["ds"], "temporary folders left behind");
}

#[test]
fn datagen_refuses_to_replace_a_folder_that_is_not_a_dataset() {
    let dir = tempfile::tempdir().unwrap();
    let precious = dir.path().join("notes.txt");
    std::fs::write(&precious, "keep me").unwrap();
    let o = grop(&[
        "datagen",
        "--envs",
        "1",
        "--targets-per-env",
        "1",
        "--out",
        dir.path().to_str().unwrap(),
    ]);
    let out = text(&o);
    assert!(!o.status.success(), "{out}");
    assert!(out.contains("dataset.json"), "{out}");
    assert_eq!(std::fs::read_to_string(&precious).unwrap(), "keep me");
}

fn image_header(path: &std::path::Path) -> Vec<u8> {
    std::fs::read(path).unwrap().into_iter().take(8).collect()
}

#[test]
fn hil_runs_a_folder_of_scene_files_one_mission_each_and_names_a_bad_folder() {
    let dir = tempfile::tempdir().unwrap();
    let scenes = dir.path().join("scenes");
    std::fs::create_dir_all(&scenes).unwrap();
    let layouts = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../layouts");
    std::fs::copy(
        layouts.join("08-start-off-to-the-side.toml"),
        scenes.join("side.toml"),
    )
    .unwrap();
    let out_dir = dir.path().join("out");
    let o = grop(&[
        "hil",
        "--model",
        &model(),
        "--scenes",
        scenes.to_str().unwrap(),
        "--out-dir",
        out_dir.to_str().unwrap(),
        "--jobs",
        "1",
        "--pictures",
    ]);
    let out = text(&o);
    assert!(o.status.success(), "{out}");
    assert!(out.contains("| scene | placed (end state)"), "{out}");
    // --pictures: the mission drawn in its folder.
    let img = image_header(&out_dir.join("scene-side/mission.png"));
    assert_eq!(&img[..8], b"\x89PNG\r\n\x1a\n");
    let row = out
        .lines()
        .find(|l| l.starts_with("| side |"))
        .unwrap_or_else(|| panic!("no row for the scene in:\n{out}"));
    assert!(row.contains("/ 3"), "{row}");
    let csv = std::fs::read_to_string(out_dir.join("scenes.csv")).unwrap();
    assert!(csv.lines().nth(1).unwrap().starts_with("side,3,"), "{csv}");
    assert!(out_dir.join("scene-side").is_dir());

    // An empty folder, a bad scene file and an unknown suite are named.
    let empty = dir.path().join("empty");
    std::fs::create_dir_all(&empty).unwrap();
    let o = grop(&["hil", "--scenes", empty.to_str().unwrap(), "--no-build"]);
    assert!(!o.status.success());
    assert!(text(&o).contains("no scene files"), "{}", text(&o));
    std::fs::write(scenes.join("bad.toml"), "format_version = 1\nname = 3\n").unwrap();
    let o = grop(&["hil", "--scenes", scenes.to_str().unwrap(), "--no-build"]);
    assert!(!o.status.success());
    assert!(text(&o).contains("bad.toml"), "{}", text(&o));
    let o = grop(&["hil", "--suite", "nope", "--no-build"]);
    assert!(!o.status.success());
    assert!(text(&o).contains("unknown suite \"nope\""), "{}", text(&o));
}

#[test]
fn enable_gives_the_operators_enable_and_names_what_it_refuses() {
    let o = grop(&["enable", "--deployment", "/nonexistent/deployment.toml"]);
    assert!(!o.status.success());
    assert!(
        text(&o).contains("/nonexistent/deployment.toml"),
        "{}",
        text(&o)
    );
    // A HIL deployment runs on the simulated clock: the world is the operator there.
    let hil = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../harnesses/fuzz-replay/data/hil-deployment.toml");
    let o = grop(&["enable", "--deployment", hil.to_str().unwrap()]);
    assert!(!o.status.success());
    assert!(
        text(&o).contains("world plays the operator"),
        "{}",
        text(&o)
    );
    // On the wall clock: one enable on <ns>/operator/enable, stamped now.
    let dir = tempfile::tempdir().unwrap();
    let namespace = format!("grop-cli-enable-{}", std::process::id());
    let deployment = dir.path().join("deployment.toml");
    let text_in = std::fs::read_to_string(&hil)
        .unwrap()
        .replace("grop-m-4242-1\"", &format!("{namespace}\""))
        .replace("sim:grop-m-4242-1-clock", "wall");
    std::fs::write(&deployment, text_in).unwrap();
    let node = grop_ipc::IpcNode::new(&namespace, "cli-test").unwrap();
    let enables = node.subscriber::<grop_ipc::OperatorEnableMsg>().unwrap();
    // Read while it holds the enable (a sample lives as long as its publisher).
    let child = Command::new(env!("CARGO_BIN_EXE_grop"))
        .args(["enable", "--deployment", deployment.to_str().unwrap()])
        .args(["--hold-s", "2", "--log", "warn"])
        .stdout(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let mut got = None;
    let until = std::time::Instant::now() + std::time::Duration::from_secs(10);
    while got.is_none() && std::time::Instant::now() < until {
        got = enables.try_recv().unwrap().map(|m| *m);
        std::thread::sleep(std::time::Duration::from_millis(10));
    }
    let o = child.wait_with_output().unwrap();
    assert!(o.status.success(), "{}", text(&o));
    assert!(text(&o).contains("operator/enable"), "{}", text(&o));
    let got = got.expect("the enable arrived");
    assert_eq!(got.seq, 1);
    assert!(got.stamp_ns > 0);
}
