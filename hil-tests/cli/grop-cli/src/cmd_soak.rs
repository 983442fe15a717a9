//! `grop soak`: many closed-loop missions back to back (world + onboard processes, simulated
//! time, no mission logs), watching for what a long run on the robot would show: a crash or a
//! hang, memory that grows from mission to mission, shared memory (iceoryx2) or sockets left
//! behind. Writes out/soak.md (`--write-docs`: docs/soak.md); exits non-zero if any check fails.
//!
//! Memory: each mission's processes are fresh, so their peak resident set (VmHWM, sampled every
//! 20 ms) must stay flat across missions (the same work, the same memory), and the soak
//! runner's own resident set (it starts, supervises and parses every mission) must stay within
//! 5 % of its value after warm-up. Resources: after every mission the iceoryx2 files
//! (/dev/shm/iox2_*, /tmp/iceoryx2/**), this process's open file descriptors and the listening
//! loopback TCP sockets must be back to where they were before the first.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use anyhow::Context;
use hil_world::mission::{self, MissionSpec};
use hil_world::report::MissionEnd;
use serde::{Deserialize, Serialize};
use trial_sim::shard::{Shard, ShardManifest};

/// Arguments of `grop soak`.
#[derive(clap::Args, Debug, Serialize, Deserialize)]
pub struct Args {
    /// Missions to run.
    #[arg(long, default_value_t = 1000)]
    pub missions: usize,
    /// First seed: mission i runs scene `seed + i mod scenes` (its scene, noise and draws), so
    /// each scene comes back every `--scenes` missions and its memory can be compared with its
    /// own earlier runs (missions are deterministic in simulated time).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Distinct scenes in rotation.
    #[arg(long, default_value_t = 10)]
    pub scenes: usize,
    /// Missions whose figures are the warm-up (not held to the 5 % bound).
    #[arg(long, default_value_t = 10)]
    pub warm_up: usize,
    /// Allowed growth of the runner's resident set and of the missions' peak resident sets
    /// over their post-warm-up baseline, percent.
    #[arg(long, default_value_t = 5.0)]
    pub rss_tolerance_pct: f64,
    /// Planning method of the onboard planner.
    #[arg(long, default_value = "grop")]
    pub method: String,
    /// The feasibility network Psi (ONNX).
    #[arg(long, default_value = "models/psi-fcn.onnx")]
    pub model: PathBuf,
    /// Folder for the runs (each mission's files are deleted after it passed). With
    /// `--shard`: the campaign folder that gets the shard's folder `shard-III-of-NNN`.
    #[arg(long, default_value = "out/soak")]
    #[serde(default)]
    pub out_dir: PathBuf,
    /// Also write the summary to docs/soak.md.
    #[arg(long)]
    #[serde(default)]
    pub write_docs: bool,
    /// Do not run `cargo build` for the world and the onboard binaries first (they must stand
    /// beside this program; what array jobs do, docs/campaigns.md).
    #[arg(long)]
    #[serde(default)]
    pub no_build: bool,
    /// Do not simulate the range sensor: the executive drives without its collision monitor
    /// (a mission runs several times faster; what the campaign tests use).
    #[arg(long)]
    #[serde(default)]
    pub no_lidar: bool,
    /// Run only shard I of N (0-based) of the missions: mission i when i mod N == I (its scene
    /// and seed stay those of mission i). The shard judges memory over its own missions, after
    /// its own warm-up (`--warm-up` of its missions), and writes its rows, its soak.md and its
    /// manifest into `<out-dir>/shard-III-of-NNN`; `grop merge` adds the counts up.
    #[arg(long, value_name = "I/N")]
    #[serde(default)]
    pub shard: Option<Shard>,
}

/// What the machine holds that a mission could leak.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Resources {
    iceoryx2_files: usize,
    open_fds: usize,
    loopback_listeners: usize,
}

fn count_entries(dir: &Path, filter: &dyn Fn(&str) -> bool) -> usize {
    let Ok(rd) = std::fs::read_dir(dir) else {
        return 0;
    };
    rd.filter_map(Result::ok)
        .map(|e| {
            let name = e.file_name().to_string_lossy().into_owned();
            match e.file_type() {
                Ok(t) if t.is_dir() => count_entries(&e.path(), &|_| true),
                _ => usize::from(filter(&name)),
            }
        })
        .sum()
}

fn resources() -> Resources {
    let iceoryx2_files = count_entries(Path::new("/dev/shm"), &|n| n.starts_with("iox2_"))
        + count_entries(Path::new("/tmp/iceoryx2"), &|_| true);
    let open_fds = count_entries(Path::new("/proc/self/fd"), &|_| true);
    // /proc/net/tcp: local address 0100007F:port (127.0.0.1), state 0A = LISTEN.
    let loopback_listeners = std::fs::read_to_string("/proc/net/tcp")
        .map(|t| {
            t.lines()
                .skip(1)
                .filter(|l| {
                    let f: Vec<&str> = l.split_whitespace().collect();
                    f.len() > 3 && f[1].starts_with("0100007F:") && f[3] == "0A"
                })
                .count()
        })
        .unwrap_or(0);
    Resources {
        iceoryx2_files,
        open_fds,
        loopback_listeners,
    }
}

fn own_rss_kib() -> u64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find_map(|l| l.strip_prefix("VmRSS:"))
                .and_then(|v| v.trim().trim_end_matches("kB").trim().parse().ok())
        })
        .unwrap_or(0)
}

/// One mission's figures.
#[derive(Debug, Clone)]
struct Row {
    scene: u64,
    end: MissionEnd,
    placed: usize,
    sim_s: f64,
    wall_s: f64,
    peaks_kib: [u64; 3],
    runner_kib: u64,
    after: Resources,
}

/// A process's memory verdict: name, baseline, largest, last (KiB), worst ratio, within bound.
type Flat = (String, u64, u64, u64, f64, bool);

/// Median of a list (sorted copy).
fn median(v: &[u64]) -> u64 {
    let mut s = v.to_vec();
    s.sort_unstable();
    s.get(s.len() / 2).copied().unwrap_or(0)
}

/// Runs `grop soak`.
#[allow(
    clippy::too_many_lines,
    reason = "a command's steps in order: arguments, the campaign, the report"
)]
pub fn run(args: Args) -> anyhow::Result<()> {
    anyhow::ensure!(args.missions > 0, "--missions must be at least 1");
    anyhow::ensure!(args.scenes > 0, "--scenes must be at least 1");
    let shard = args.shard.unwrap_or(Shard::WHOLE);
    let missions = shard.positions(args.missions);
    anyhow::ensure!(
        args.warm_up < missions.len(),
        "--warm-up {} leaves no mission to judge ({} missions{})",
        args.warm_up,
        missions.len(),
        args.shard
            .map(|s| format!(" in shard {s} of --missions {}", args.missions))
            .unwrap_or_default()
    );
    let model = crate::common::committed_file_abs(&args.model, "the feasibility network")?;
    let bins = crate::common::mission_binaries(!args.no_build)?;
    let (shard_dir, out_dir) = crate::common::output_folder(&args.out_dir, args.shard)?;
    let machine = latency::machine::MachineInfo::now();
    let started = Instant::now();
    let before = resources();
    let mut rows: Vec<Row> = Vec::with_capacity(args.missions);
    let mut failures: Vec<String> = Vec::new();
    for (done, &i) in missions.iter().enumerate() {
        let seed = args.seed + (i % args.scenes) as u64;
        let dir = out_dir.join(format!("mission-{i}-scene-{seed}"));
        let spec = MissionSpec {
            method: args.method.clone(),
            lidar: !args.no_lidar,
            ..MissionSpec::new(
                dir.clone(),
                world::generate::evaluation_scene(seed, 5 + (seed % 16) as usize, 3),
                model.clone(),
                seed,
            )
        };
        let t0 = Instant::now();
        let outcome = mission::start(&spec, &bins)
            .and_then(|m| m.finish_measured(Duration::from_secs(600), &mut |_| {}));
        let (report, peaks_kib) = match outcome {
            Ok(r) => r,
            Err(e) => {
                failures.push(format!("mission {seed}: {e:#}"));
                println!("mission {seed}: FAILED: {e:#}");
                continue;
            }
        };
        let after = resources();
        let row = Row {
            scene: seed,
            end: report.end,
            placed: report.placed_end_state,
            sim_s: report.timing.sim_time_s,
            wall_s: t0.elapsed().as_secs_f64(),
            peaks_kib,
            runner_kib: own_rss_kib(),
            after,
        };
        if matches!(row.end, MissionEnd::TimedOut | MissionEnd::NeverStarted) {
            failures.push(format!("mission {seed}: ended {:?}", row.end));
        }
        if after != before {
            // Give the kernel and iceoryx2's cleanup a moment, then look again.
            std::thread::sleep(Duration::from_millis(200));
        }
        let after = resources();
        if after.iceoryx2_files > before.iceoryx2_files
            || after.open_fds > before.open_fds
            || after.loopback_listeners > before.loopback_listeners
        {
            failures.push(format!(
                "mission {seed}: resources left behind: {after:?} (before the soak {before:?})"
            ));
        } else {
            let _ = std::fs::remove_dir_all(&dir);
        }
        if (done + 1) % 10 == 0 || done + 1 == missions.len() {
            println!(
                "soak: {}/{} missions, {:.0} s wall; runner {} KiB; last peaks world/planner/executive {:?} KiB; {} failures",
                done + 1,
                missions.len(),
                started.elapsed().as_secs_f64(),
                row.runner_kib,
                row.peaks_kib,
                failures.len()
            );
        }
        rows.push(Row { after, ..row });
    }

    // Flatness after warm-up: each process's peak against the same scene's first peak after
    // warm-up (the same mission, so the same memory unless something accumulates); the
    // runner's own resident set against its value after warm-up.
    let judged: Vec<&Row> = rows.iter().skip(args.warm_up).collect();
    let tol = 1.0 + args.rss_tolerance_pct / 100.0;
    let mut flat = Vec::new();
    let names = [
        "grop-world",
        "grop-planner",
        "grop-executive",
        "soak runner",
    ];
    for (k, name) in names.iter().enumerate() {
        let value = |r: &Row| if k < 3 { r.peaks_kib[k] } else { r.runner_kib };
        let mut first: std::collections::BTreeMap<u64, u64> = std::collections::BTreeMap::new();
        let (mut worst, mut base_of_worst, mut max_seen) = (1.0_f64, 0u64, 0u64);
        for r in &judged {
            let v = value(r);
            if v == 0 {
                continue;
            }
            let key = if k < 3 { r.scene } else { 0 };
            let base = *first.entry(key).or_insert(v);
            max_seen = max_seen.max(v);
            let ratio = v as f64 / base as f64;
            if ratio >= worst {
                worst = ratio;
                base_of_worst = base;
            }
        }
        if first.is_empty() {
            continue;
        }
        let base = if base_of_worst > 0 {
            base_of_worst
        } else {
            *first.values().next().unwrap_or(&0)
        };
        let last = judged.last().map_or(0, |r| value(r));
        let ok = worst <= tol;
        if !ok {
            failures.push(format!(
                "{name}: resident set grew {:+.2} % over the same scene's run after warm-up (> {:.1} %)",
                (worst - 1.0) * 100.0,
                args.rss_tolerance_pct
            ));
        }
        flat.push((name.to_string(), base, max_seen, last, worst, ok));
    }

    let summary = summary(
        &machine,
        &args,
        &rows,
        &flat,
        before,
        &failures,
        started.elapsed(),
    );
    let out = out_dir.join("soak.md");
    std::fs::write(&out, &summary).with_context(|| format!("writing {}", out.display()))?;
    println!("{summary}");
    if let (Some(dir), Some(shard)) = (shard_dir, args.shard) {
        write_shard_files(dir.path(), &rows, &flat, &failures)?;
        let mut config = serde_json::to_value(&args).context("recording the options")?;
        if let Some(o) = config.as_object_mut() {
            for k in ["out_dir", "write_docs", "no_build", "shard"] {
                o.remove(k);
            }
            o.insert(
                "model_sha256".into(),
                trial_sim::shard::file_sha256(&model).into(),
            );
        }
        let manifest =
            crate::shards::manifest("soak", shard, args.seed, config, args.missions, started);
        let dest = dir.commit(&manifest).context("writing the shard folder")?;
        println!("written: {}", dest.display());
        anyhow::ensure!(
            failures.is_empty(),
            "{} soak checks failed (see {})",
            failures.len(),
            dest.join("soak.md").display()
        );
        return Ok(());
    }
    println!("written: {}", out.display());
    if args.write_docs {
        let docs = crate::common::committed_file(std::path::Path::new("docs")).join("soak.md");
        std::fs::write(&docs, &summary).with_context(|| format!("writing {}", docs.display()))?;
        println!("written: {}", docs.display());
    }
    anyhow::ensure!(
        failures.is_empty(),
        "{} soak checks failed (see {})",
        failures.len(),
        out.display()
    );
    Ok(())
}

fn summary(
    machine: &latency::machine::MachineInfo,
    args: &Args,
    rows: &[Row],
    flat: &[Flat],
    before: Resources,
    failures: &[String],
    wall: Duration,
) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "# Soak: {} closed-loop missions{}\n",
        args.missions,
        args.shard
            .map(|sh| format!(", shard {sh}"))
            .unwrap_or_default()
    );
    let _ = writeln!(
        s,
        "Generated by `cargo run --release -p grop-cli -- soak --missions {} --seed {} --scenes {}{}` on {} ({} CPUs, load average {} at the start), {}, {:.0} s wall. Each mission: `grop-world` and the onboard `grop-planner` / `grop-executive` as processes, simulated time, no mission log, an evaluation scene of 5-20 chairs and 3 objects, method `{}`.\n",
        args.missions,
        args.seed,
        args.scenes,
        if args.write_docs { " --write-docs" } else { "" },
        machine.cpu_model,
        machine.cpus,
        machine
            .loadavg_1min
            .map_or_else(|| "unknown".into(), |l| format!("{l:.1}")),
        machine.date_utc,
        wall.as_secs_f64(),
        args.method
    );
    let planned = args
        .shard
        .map_or(args.missions, |sh| sh.positions(args.missions).len());
    counts_table(&mut s, rows, planned);
    let _ = writeln!(
        s,
        "Resident set after the first {} missions (warm-up): every mission's peak is held against the same scene's first peak after warm-up ({} scenes in rotation; the same mission uses the same memory unless something accumulates), and the runner's resident set against its value after warm-up; the bound is {:.1} %. The largest column is over all scenes; growth is the worst ratio to the same scene's baseline (the baseline column is that scene's).\n",
        args.warm_up, args.scenes, args.rss_tolerance_pct
    );
    let _ = writeln!(
        s,
        "| process | baseline (KiB) | largest (KiB) | last (KiB) | worst growth | within bound |\n|---|---|---|---|---|---|"
    );
    memory_rows(&mut s, flat, "");
    let last = rows.last().map(|r| r.after);
    let _ = writeln!(
        s,
        "\nResources before the first mission: {} iceoryx2 files, {} open file descriptors, {} listening loopback TCP sockets; after the last: {}.\n",
        before.iceoryx2_files,
        before.open_fds,
        before.loopback_listeners,
        match last {
            Some(r) => format!(
                "{} / {} / {}",
                r.iceoryx2_files, r.open_fds, r.loopback_listeners
            ),
            None => "no mission ran".into(),
        }
    );
    failure_list(&mut s, failures);
    s
}

/// The mission counts' table.
fn counts_table(s: &mut String, rows: &[Row], planned: usize) {
    let count = |e: MissionEnd| rows.iter().filter(|r| r.end == e).count();
    let _ = writeln!(
        s,
        "| missions run | finished | aborted | timed out | failed to run | objects placed | simulated time | wall per mission (median) |\n|---|---|---|---|---|---|---|---|"
    );
    let mut walls: Vec<u64> = rows.iter().map(|r| (r.wall_s * 1000.0) as u64).collect();
    walls.sort_unstable();
    let _ = writeln!(
        s,
        "| {} | {} | {} | {} | {} | {} / {} | {:.0} s | {:.2} s |\n",
        rows.len(),
        count(MissionEnd::Finished),
        count(MissionEnd::Aborted),
        count(MissionEnd::TimedOut),
        planned.saturating_sub(rows.len()),
        rows.iter().map(|r| r.placed).sum::<usize>(),
        3 * rows.len(),
        rows.iter().map(|r| r.sim_s).sum::<f64>(),
        median(&walls) as f64 / 1000.0
    );
}

fn failure_list(s: &mut String, failures: &[String]) {
    if failures.is_empty() {
        let _ = writeln!(s, "All checks passed.");
    } else {
        let _ = writeln!(s, "**{} checks failed:**\n", failures.len());
        for f in failures.iter().take(50) {
            let _ = writeln!(s, "- {f}");
        }
    }
}

/// The memory table's rows (`prefix`: a first cell, as `| shard 1/4 `, or nothing).
fn memory_rows(s: &mut String, flat: &[Flat], prefix: &str) {
    for (name, base, max, last, worst, ok) in flat {
        let _ = writeln!(
            s,
            "{prefix}| {name} ({}) | {base} | {max} | {last} | {:+.2} % | {} |",
            if name == "soak runner" {
                "VmRSS after each mission"
            } else {
                "peak per mission, VmHWM"
            },
            (worst - 1.0) * 100.0,
            if *ok { "yes" } else { "**no**" }
        );
    }
}

const ROWS_FILE: &str = "rows.tsv";
const MEMORY_FILE: &str = "memory.tsv";
const FAILURES_FILE: &str = "failures.txt";

/// A shard's figures: its missions' rows, its memory verdicts and its failed checks.
fn write_shard_files(
    dir: &Path,
    rows: &[Row],
    flat: &[Flat],
    failures: &[String],
) -> anyhow::Result<()> {
    let mut r = String::from("scene\tend\tplaced\tsim_s\twall_s\n");
    for row in rows {
        let _ = writeln!(
            r,
            "{}\t{}\t{}\t{:?}\t{:?}",
            row.scene,
            serde_json::to_string(&row.end)?.trim_matches('"'),
            row.placed,
            row.sim_s,
            row.wall_s
        );
    }
    let mut m = String::from("process\tbaseline_kib\tlargest_kib\tlast_kib\tworst_ratio\tok\n");
    for (name, base, max, last, worst, ok) in flat {
        let _ = writeln!(m, "{name}\t{base}\t{max}\t{last}\t{worst:?}\t{ok}");
    }
    let f: String = failures.iter().map(|x| format!("{x}\n")).collect();
    for (name, text) in [(ROWS_FILE, r), (MEMORY_FILE, m), (FAILURES_FILE, f)] {
        std::fs::write(dir.join(name), text)
            .with_context(|| format!("writing {}", dir.join(name).display()))?;
    }
    Ok(())
}

/// Reads a shard's files back: rows (without resources), memory verdicts, failures.
fn read_shard_files(dir: &Path) -> anyhow::Result<(Vec<Row>, Vec<Flat>, Vec<String>)> {
    let read = |name: &str| {
        std::fs::read_to_string(dir.join(name))
            .with_context(|| format!("reading {}", dir.join(name).display()))
    };
    fn num<T: std::str::FromStr>(s: &str, what: &str) -> anyhow::Result<T> {
        s.parse()
            .map_err(|_| anyhow::anyhow!("{what} {s:?} is not a number"))
    }
    let none = Resources {
        iceoryx2_files: 0,
        open_fds: 0,
        loopback_listeners: 0,
    };
    let mut rows = Vec::new();
    for (i, line) in read(ROWS_FILE)?.lines().enumerate().skip(1) {
        let f: Vec<&str> = line.split('\t').collect();
        let row = (|| -> anyhow::Result<Row> {
            anyhow::ensure!(f.len() == 5, "{} fields, expected 5", f.len());
            Ok(Row {
                scene: num(f[0], "scene")?,
                end: serde_json::from_str(&format!("\"{}\"", f[1]))
                    .with_context(|| format!("mission end {:?}", f[1]))?,
                placed: num(f[2], "placed")?,
                sim_s: num(f[3], "sim_s")?,
                wall_s: num(f[4], "wall_s")?,
                peaks_kib: [0; 3],
                runner_kib: 0,
                after: none,
            })
        })()
        .with_context(|| format!("{} line {}", dir.join(ROWS_FILE).display(), i + 1))?;
        rows.push(row);
    }
    let mut flat = Vec::new();
    for (i, line) in read(MEMORY_FILE)?.lines().enumerate().skip(1) {
        let f: Vec<&str> = line.split('\t').collect();
        let v = (|| -> anyhow::Result<Flat> {
            anyhow::ensure!(f.len() == 6, "{} fields, expected 6", f.len());
            Ok((
                f[0].to_owned(),
                num(f[1], "baseline")?,
                num(f[2], "largest")?,
                num(f[3], "last")?,
                num(f[4], "worst ratio")?,
                num(f[5], "ok")?,
            ))
        })()
        .with_context(|| format!("{} line {}", dir.join(MEMORY_FILE).display(), i + 1))?;
        flat.push(v);
    }
    let failures = read(FAILURES_FILE)?
        .lines()
        .filter(|l| !l.is_empty())
        .map(str::to_owned)
        .collect();
    Ok((rows, flat, failures))
}

/// `grop merge` of soak shards: the missions' counts added up, memory judged per shard (each
/// shard is its own process with its own warm-up and baselines), every failed check listed.
/// Writes soak.md; fails (after writing) when any shard's check failed.
pub fn merge(set: &[(PathBuf, ShardManifest)], out: &Path) -> anyhow::Result<()> {
    let first = &set[0].1;
    let c = &first.config;
    let staged = trial_sim::shard::MergeDir::create(out)?;
    let mut rows = Vec::new();
    let mut failures = Vec::new();
    let mut s = String::new();
    let _ = writeln!(
        s,
        "# Soak: {} closed-loop missions in {} shards\n",
        first.total_tasks,
        set.len()
    );
    let _ = writeln!(
        s,
        "Merged by `grop merge` from the shards of `grop soak --missions {} --seed {} --scenes {} --shard I/{}` (commit {}); mission i ran in shard i mod {}. Longest shard {:.0} s wall, all shards together {:.0} s.\n",
        first.total_tasks,
        first.seed,
        c["scenes"],
        set.len(),
        first.commit,
        set.len(),
        set.iter().map(|(_, m)| m.wall_s).fold(0.0, f64::max),
        set.iter().map(|(_, m)| m.wall_s).sum::<f64>()
    );
    let mut memory = String::new();
    for (dir, m) in set {
        let (r, flat, f) = read_shard_files(dir)?;
        memory_rows(&mut memory, &flat, &format!("| {} ", m.shard));
        failures.extend(f.into_iter().map(|x| format!("shard {}: {x}", m.shard)));
        rows.extend(r);
    }
    counts_table(&mut s, &rows, first.total_tasks);
    let _ = writeln!(
        s,
        "Memory is judged per shard: each shard's processes and runner are its own, with their own warm-up ({} missions) and baselines; the bound is {} %.\n",
        c["warm_up"], c["rss_tolerance_pct"]
    );
    let _ = writeln!(
        s,
        "| shard | process | baseline (KiB) | largest (KiB) | last (KiB) | worst growth | within bound |\n|---|---|---|---|---|---|---|"
    );
    s.push_str(&memory);
    s.push('\n');
    failure_list(&mut s, &failures);
    std::fs::write(staged.path().join("soak.md"), &s).context("writing soak.md")?;
    let dest = staged.commit()?;
    println!("{s}");
    println!("merged {} soak shards into {}", set.len(), dest.display());
    anyhow::ensure!(
        failures.is_empty(),
        "{} soak checks failed (see {})",
        failures.len(),
        dest.join("soak.md").display()
    );
    Ok(())
}
