//! `grop hil --suite NAME` / `--scenes DIR`: every scene file of a folder as one closed-loop
//! mission (the world and the unchanged onboard processes, as `grop demo` runs one), seeded, one
//! row per scene. The hand-made suite (`--suite handmade`, `hil-tests/layouts/`) holds layouts
//! the generator never makes (docs/hil.md).

use std::path::Path;
use std::sync::Mutex;
use std::time::{Duration, Instant};

use anyhow::Context;
use hil_world::mission::{self, MissionSpec};
use hil_world::objects::{ObjectState, Verdict};
use hil_world::report::{MissionEnd, WorldReport};
use hil_world::suite::{self, SuiteScene};
use world::generate::mix_seed;

use crate::cmd_hil::Args;

/// One scene's results.
#[derive(Debug, Clone)]
struct SceneRow {
    name: String,
    objects: usize,
    placed: usize,
    placed_strict: usize,
    misplaced: usize,
    not_attempted: usize,
    contacts: usize,
    end: MissionEnd,
    sim_s: f64,
    wall_s: f64,
}

fn row_of(name: &str, r: &WorldReport, wall_s: f64) -> SceneRow {
    let verdict = |v: Verdict| {
        r.objects
            .iter()
            .filter(|o| matches!(o.state, ObjectState::Released { verdict, .. } if verdict == v))
            .count()
    };
    SceneRow {
        name: name.to_owned(),
        objects: r.objects.len(),
        placed: r.placed_end_state,
        placed_strict: r.placed,
        misplaced: verdict(Verdict::Misplaced),
        not_attempted: r
            .objects
            .iter()
            .filter(|o| o.state == ObjectState::AtStation)
            .count(),
        contacts: r.collisions.len(),
        end: r.end,
        sim_s: r.timing.sim_time_s,
        wall_s,
    }
}

/// `grop hil --suite NAME` (a committed suite's folder) or `--scenes DIR`: [`run`] over it.
/// (`main` sends a `grop hil` with either here, every other one to `cmd_hil::run`.)
pub fn run_command(args: &Args) -> anyhow::Result<()> {
    if let Some(name) = &args.suite {
        let dir = hil_world::suite::suite_dir(name)?;
        return run(args, name, &dir);
    }
    match &args.scenes {
        Some(dir) => run(args, &dir.display().to_string(), dir),
        None => anyhow::bail!("grop hil: a suite run needs --suite or --scenes"),
    }
}

/// Runs the suite in `dir` with the options of `args` (method, seed, model, jobs, out-dir).
pub fn run(args: &Args, label: &str, dir: &Path) -> anyhow::Result<()> {
    anyhow::ensure!(args.jobs > 0, "--jobs must be positive");
    anyhow::ensure!(
        args.shard.is_none() && !args.write_docs,
        "--shard and --write-docs are for the task suite; a scene suite prints its table (docs/hil.md)"
    );
    let scenes = suite::load_dir(dir)?;
    let model = crate::cmd_hil::model_path(&args.model)?;
    let bins = crate::common::mission_binaries(!args.no_build)?;
    std::fs::create_dir_all(&args.out_dir)
        .with_context(|| format!("creating {}", args.out_dir.display()))?;
    let started = Instant::now();
    let rows: Mutex<Vec<(usize, SceneRow)>> = Mutex::new(Vec::new());
    let failures: Mutex<Vec<String>> = Mutex::new(Vec::new());
    let next = Mutex::new(0usize);
    let run_one = |k: usize, s: &SuiteScene| -> anyhow::Result<SceneRow> {
        let spec = MissionSpec {
            method: args.method.clone(),
            paper_smp: args.paper_smp,
            lidar: !args.no_lidar,
            ..MissionSpec::new(
                args.out_dir.join(format!("scene-{}", s.name)),
                s.scene.clone(),
                model.clone(),
                mix_seed(args.seed, k as u64, 0x7375_6974),
            )
        };
        let t0 = Instant::now();
        let report = mission::start(&spec, &bins)
            .and_then(|m| m.finish(Duration::from_secs(900), &mut |_| {}))?;
        crate::cmd_hil::save_picture(args, &spec, &report)?;
        Ok(row_of(&s.name, &report, t0.elapsed().as_secs_f64()))
    };
    std::thread::scope(|scope| {
        for _ in 0..args.jobs.min(scenes.len()) {
            scope.spawn(|| loop {
                let k = {
                    let mut g = next.lock().unwrap_or_else(|e| e.into_inner());
                    let k = *g;
                    *g += 1;
                    k
                };
                let Some(s) = scenes.get(k) else { return };
                match run_one(k, s) {
                    Ok(row) => {
                        eprintln!(
                            "{}: placed {} of {} ({} strictly), {} contacts, {:?} at {:.1} s sim ({:.1} s wall)",
                            row.name, row.placed, row.objects, row.placed_strict, row.contacts, row.end, row.sim_s, row.wall_s
                        );
                        rows.lock().unwrap_or_else(|e| e.into_inner()).push((k, row));
                    }
                    Err(e) => failures
                        .lock()
                        .unwrap_or_else(|e| e.into_inner())
                        .push(format!("{}: {e:#}", s.name)),
                }
            });
        }
    });
    let failures = failures.into_inner().unwrap_or_else(|e| e.into_inner());
    for f in &failures {
        eprintln!("{f}");
    }
    let mut rows = rows.into_inner().unwrap_or_else(|e| e.into_inner());
    rows.sort_by_key(|(k, _)| *k);
    let rows: Vec<SceneRow> = rows.into_iter().map(|(_, r)| r).collect();
    anyhow::ensure!(!rows.is_empty(), "no mission finished");
    let table = table(label, args, &rows, failures.len(), started.elapsed());
    println!("{table}");
    let csv = args.out_dir.join("scenes.csv");
    std::fs::write(&csv, scenes_csv(&rows))
        .with_context(|| format!("writing {}", csv.display()))?;
    let md = args.out_dir.join("suite.md");
    std::fs::write(&md, &table).with_context(|| format!("writing {}", md.display()))?;
    Ok(())
}

fn end_name(e: MissionEnd) -> String {
    serde_json::to_string(&e)
        .map(|s| s.trim_matches('"').to_owned())
        .unwrap_or_default()
}

/// The per-scene table (markdown) with the totals.
fn table(label: &str, args: &Args, rows: &[SceneRow], failed: usize, wall: Duration) -> String {
    use std::fmt::Write as _;
    let mut s = format!(
        "Suite {label}, method {}, seed {} ({} missions, {failed} failed to run, {:.0} s wall with {} side by side)\n\n\
| scene | placed (end state) | placed (strict) | misplaced | not attempted | contacts | end | time (sim) |\n\
|---|---|---|---|---|---|---|---|\n",
        args.method,
        args.seed,
        rows.len(),
        wall.as_secs_f64(),
        args.jobs
    );
    for r in rows {
        let _ = writeln!(
            s,
            "| {} | {} / {} | {} | {} | {} | {} | {} | {:.1} s |",
            r.name,
            r.placed,
            r.objects,
            r.placed_strict,
            r.misplaced,
            r.not_attempted,
            r.contacts,
            end_name(r.end),
            r.sim_s
        );
    }
    let sum = |f: &dyn Fn(&SceneRow) -> usize| rows.iter().map(f).sum::<usize>();
    let _ = writeln!(
        s,
        "| **all** | {} / {} | {} | {} | {} | {} | {} finished | {:.1} s mean |",
        sum(&|r| r.placed),
        sum(&|r| r.objects),
        sum(&|r| r.placed_strict),
        sum(&|r| r.misplaced),
        sum(&|r| r.not_attempted),
        sum(&|r| r.contacts),
        rows.iter()
            .filter(|r| r.end == MissionEnd::Finished)
            .count(),
        rows.iter().map(|r| r.sim_s).sum::<f64>() / rows.len() as f64
    );
    s
}

fn scenes_csv(rows: &[SceneRow]) -> String {
    let mut s = String::from(
        "scene,objects,placed,placed_strict,misplaced,not_attempted,contacts,end,sim_s,wall_s\n",
    );
    for r in rows {
        s.push_str(&format!(
            "{},{},{},{},{},{},{},{},{:.2},{:.2}\n",
            r.name,
            r.objects,
            r.placed,
            r.placed_strict,
            r.misplaced,
            r.not_attempted,
            r.contacts,
            end_name(r.end),
            r.sim_s,
            r.wall_s
        ));
    }
    s
}
