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
use world::RobotConfig;

/// Arguments of `grop soak`.
#[derive(clap::Args, Debug)]
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
    /// Folder for the runs (each mission's files are deleted after it passed).
    #[arg(long, default_value = "out/soak")]
    pub out_dir: PathBuf,
    /// Also write the summary to docs/soak.md.
    #[arg(long)]
    pub write_docs: bool,
    /// Do not run `cargo build` for the world and the onboard binaries first.
    #[arg(long)]
    pub no_build: bool,
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

/// Median of a list (sorted copy).
fn median(v: &[u64]) -> u64 {
    let mut s = v.to_vec();
    s.sort_unstable();
    s.get(s.len() / 2).copied().unwrap_or(0)
}

/// Runs `grop soak`.
pub fn run(args: Args) -> anyhow::Result<()> {
    anyhow::ensure!(args.missions > 0, "--missions must be at least 1");
    anyhow::ensure!(args.scenes > 0, "--scenes must be at least 1");
    anyhow::ensure!(
        args.warm_up < args.missions,
        "--warm-up {} leaves no mission to judge (--missions {})",
        args.warm_up,
        args.missions
    );
    let model = crate::common::workspace_path(&args.model.to_string_lossy());
    let model = std::fs::canonicalize(&model)
        .with_context(|| format!("the feasibility network {}", args.model.display()))?;
    let bins = mission::binaries(!args.no_build)?;
    std::fs::create_dir_all(&args.out_dir)
        .with_context(|| format!("creating {}", args.out_dir.display()))?;
    let machine = latency::machine::MachineInfo::now();
    let started = Instant::now();
    let before = resources();
    let mut rows: Vec<Row> = Vec::with_capacity(args.missions);
    let mut failures: Vec<String> = Vec::new();
    for i in 0..args.missions {
        let seed = args.seed + (i % args.scenes) as u64;
        let dir = args.out_dir.join(format!("mission-{i}-scene-{seed}"));
        let spec = MissionSpec {
            dir: dir.clone(),
            scene: world::generate::evaluation_scene(seed, 5 + (seed % 16) as usize, 3),
            robot: RobotConfig::default(),
            model: model.clone(),
            method: args.method.clone(),
            paper_smp: false,
            retry: "none".into(),
            seed,
            pace: None,
            camera_px: (640, 480),
            max_sim_s: 600.0,
            progress_s: 0.0,
            log: None,
            fault: None,
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
        if (i + 1) % 10 == 0 || i + 1 == args.missions {
            println!(
                "soak: {}/{} missions, {:.0} s wall; runner {} KiB; last peaks world/planner/executive {:?} KiB; {} failures",
                i + 1,
                args.missions,
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
    let out = args.out_dir.join("soak.md");
    std::fs::write(&out, &summary).with_context(|| format!("writing {}", out.display()))?;
    println!("{summary}");
    println!("written: {}", out.display());
    if args.write_docs {
        let docs = crate::common::workspace_path("docs").join("soak.md");
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
    flat: &[(String, u64, u64, u64, f64, bool)],
    before: Resources,
    failures: &[String],
    wall: Duration,
) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "# Soak: {} closed-loop missions\n", args.missions);
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
        args.missions - rows.len(),
        rows.iter().map(|r| r.placed).sum::<usize>(),
        3 * rows.len(),
        rows.iter().map(|r| r.sim_s).sum::<f64>(),
        median(&walls) as f64 / 1000.0
    );
    let _ = writeln!(
        s,
        "Resident set after the first {} missions (warm-up): every mission's peak is held against the same scene's first peak after warm-up ({} scenes in rotation; the same mission uses the same memory unless something accumulates), and the runner's resident set against its value after warm-up; the bound is {:.1} %. The largest column is over all scenes; growth is the worst ratio to the same scene's baseline (the baseline column is that scene's).\n",
        args.warm_up, args.scenes, args.rss_tolerance_pct
    );
    let _ = writeln!(
        s,
        "| process | baseline (KiB) | largest (KiB) | last (KiB) | worst growth | within bound |\n|---|---|---|---|---|---|"
    );
    for (name, base, max, last, worst, ok) in flat {
        let _ = writeln!(
            s,
            "| {name} ({}) | {base} | {max} | {last} | {:+.2} % | {} |",
            if name == "soak runner" {
                "VmRSS after each mission"
            } else {
                "peak per mission, VmHWM"
            },
            (worst - 1.0) * 100.0,
            if *ok { "yes" } else { "**no**" }
        );
    }
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
    if failures.is_empty() {
        let _ = writeln!(s, "All checks passed.");
    } else {
        let _ = writeln!(s, "**{} checks failed:**\n", failures.len());
        for f in failures.iter().take(50) {
            let _ = writeln!(s, "- {f}");
        }
    }
    s
}
