//! One closed-loop mission as processes: the world (`grop-world`) and the unchanged onboard
//! binaries (`grop-planner`, `grop-executive`), started with names and ports that belong to
//! this run only, so that missions run side by side and leftovers of crashed runs do not
//! collide. Used by `grop demo`, `grop hil` and the closed-loop tests.
#![allow(
    unsafe_code,
    reason = "libc::kill sends SIGTERM to the processes a mission started"
)]

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc::{Receiver, channel};
use std::time::{Duration, Instant};

use crate::harness_error::{Context, HarnessError, bail};
use world::{RobotConfig, Scene};

pub use crate::binaries::{Binaries, binaries, binaries_built_with};
use crate::report::WorldReport;

/// What to run.
#[derive(Debug, Clone)]
pub struct MissionSpec {
    /// Folder for the run's files (scene, robot, deployment, report, logs).
    pub dir: PathBuf,
    /// The scene (the world's truth and the onboard map).
    pub scene: Scene,
    /// The robot file.
    pub robot: RobotConfig,
    /// Psi's ONNX file.
    pub model: PathBuf,
    /// Planning method name.
    pub method: String,
    /// The paper's Smp (whole heatmap) instead of free cells only.
    pub paper_smp: bool,
    /// Retry policy of the planner (`none`, the paper's, or `replan`).
    pub retry: String,
    /// Seed (world noise and the planner's draws).
    pub seed: u64,
    /// Pace (`None`: lock-step as fast as possible).
    pub pace: Option<f64>,
    /// Camera size.
    pub camera_px: (u32, u32),
    /// Simulated time limit, s.
    pub max_sim_s: f64,
    /// World progress lines every this many simulated seconds (0: none).
    pub progress_s: f64,
    /// Write the mission log (MCAP) here (`grop-recorder` joins the mission); `None`: no log.
    pub log: Option<PathBuf>,
    /// Serve the live view (Foxglove WebSocket) on this address: the recorder's `--live`; needs
    /// `log`. Port 0: one the OS chooses ([`RunningMission::live_addr`] says which).
    pub live: Option<std::net::SocketAddr>,
    /// A fault for the world to inject (docs/reliability.md).
    pub fault: Option<crate::faults::FaultSpec>,
    /// Simulate the range sensor (default); `false`: the executive drives without its
    /// collision monitor, as before the lidar.
    pub lidar: bool,
    /// Chairs that stand in the world but not in the onboard map (`scene`): moved there after
    /// the map was made. The world (and its camera) has them; only the range sensor tells the
    /// executive.
    pub unmapped_chairs: Vec<world::Chair>,
    /// Chairs the world moves during the mission (indices into the world's scene: the map's
    /// chairs, then `unmapped_chairs`).
    pub chair_moves: Vec<crate::moves::ChairMove>,
}

static RUNS: AtomicU64 = AtomicU64::new(0);

impl MissionSpec {
    /// A mission of `scene` in `dir` with the paper's robot, GROP without retries, the default
    /// camera, 600 s of simulated time at most, the range sensor on, no log, no fault: what a
    /// campaign's missions and most tests start from (change the fields that differ).
    pub fn new(dir: PathBuf, scene: Scene, model: PathBuf, seed: u64) -> Self {
        Self {
            dir,
            scene,
            robot: RobotConfig::default(),
            model,
            method: "grop".into(),
            paper_smp: false,
            retry: "none".into(),
            seed,
            pace: None,
            camera_px: (640, 480),
            max_sim_s: 600.0,
            progress_s: 0.0,
            log: None,
            live: None,
            fault: None,
            lidar: true,
            unmapped_chairs: Vec::new(),
            chair_moves: Vec::new(),
        }
    }
}

/// A run name unique on this machine (pid, counter, time).
pub fn unique_run_name(prefix: &str) -> String {
    let t = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.subsec_nanos())
        .unwrap_or(0);
    format!(
        "{prefix}-{}-{}-{:x}",
        std::process::id(),
        RUNS.fetch_add(1, Ordering::Relaxed),
        t & 0xffff
    )
}

/// The processes of a running mission.
pub struct RunningMission {
    /// The run's name (clock, bus, namespace).
    pub run: String,
    /// The world.
    pub world: Child,
    /// The planner.
    pub planner: Child,
    /// The executive.
    pub executive: Child,
    /// The recorder, when the mission is logged.
    pub recorder: Option<Child>,
    lines: Receiver<String>,
    report_path: PathBuf,
    dir: PathBuf,
    /// Largest resident set seen of the world, the planner and the executive (VmHWM, KiB).
    peak_rss_kib: [u64; 3],
}

/// A process's peak resident set so far (`VmHWM`, KiB), if it still runs.
fn peak_rss_kib(pid: u32) -> Option<u64> {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).ok()?;
    status
        .lines()
        .find_map(|l| l.strip_prefix("VmHWM:"))
        .and_then(|v| v.trim().trim_end_matches("kB").trim().parse().ok())
}

fn kill(child: &mut Child, signal: i32) {
    // SAFETY: sending a signal to our own child by pid.
    unsafe {
        libc::kill(child.id() as libc::pid_t, signal);
    }
}

impl RunningMission {
    /// The address of the live view (the recorder prints it once it listens), waiting up to
    /// `timeout`; an error when the recorder exits first (a bind error names the address) or
    /// the mission has no live view.
    pub fn live_addr(&mut self, timeout: Duration) -> Result<std::net::SocketAddr, HarnessError> {
        let out = self.dir.join("recorder-out.log");
        let err = self.dir.join("recorder.log");
        let end = Instant::now() + timeout;
        loop {
            let text = std::fs::read_to_string(&out).unwrap_or_default();
            if let Some(addr) = text
                .lines()
                .find_map(|l| l.strip_prefix("grop-recorder live ws://"))
            {
                return addr
                    .trim()
                    .parse()
                    .with_context(|| format!("{}: live address {addr:?}", out.display()));
            }
            let exited = match self.recorder.as_mut() {
                Some(r) => !matches!(r.try_wait(), Ok(None)),
                None => bail!("this mission has no recorder, so no live view"),
            };
            if exited {
                bail!(
                    "grop-recorder stopped before its live view listened: {}",
                    log_tail(&err, 5)
                );
            }
            if Instant::now() >= end {
                bail!(
                    "grop-recorder printed no live address within {timeout:?} (see {})",
                    err.display()
                );
            }
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    /// The next line the world printed, waiting up to `timeout`.
    pub fn next_line(&self, timeout: Duration) -> Option<String> {
        self.lines.recv_timeout(timeout).ok()
    }

    /// Waits until the world prints a line for which `pred` holds (returns it), forwarding
    /// every line to `echo`.
    pub fn wait_for_line(
        &self,
        timeout: Duration,
        pred: impl Fn(&str) -> bool,
        echo: &mut dyn FnMut(&str),
    ) -> Option<String> {
        let end = Instant::now() + timeout;
        while let Some(left) = end.checked_duration_since(Instant::now()) {
            match self.lines.recv_timeout(left) {
                Ok(line) => {
                    echo(&line);
                    if pred(&line) {
                        return Some(line);
                    }
                }
                Err(_) => return None,
            }
        }
        None
    }

    /// Kills the planner (SIGKILL: no chance to clean up).
    pub fn kill_planner(&mut self) {
        kill(&mut self.planner, libc::SIGKILL);
        let _ = self.planner.wait();
    }

    /// Kills the executive (SIGKILL).
    pub fn kill_executive(&mut self) {
        kill(&mut self.executive, libc::SIGKILL);
        let _ = self.executive.wait();
    }

    /// Waits for the world to finish (forwarding its lines to `echo`), then stops the onboard
    /// processes and returns the world's report.
    pub fn finish(
        self,
        timeout: Duration,
        echo: &mut dyn FnMut(&str),
    ) -> Result<WorldReport, HarnessError> {
        self.finish_measured(timeout, echo)
            .map(|(report, _)| report)
    }

    /// [`finish`](Self::finish), also returning the peak resident set (KiB) of the world, the
    /// planner and the executive, sampled every 20 ms while the mission ran.
    pub fn finish_measured(
        mut self,
        timeout: Duration,
        echo: &mut dyn FnMut(&str),
    ) -> Result<(WorldReport, [u64; 3]), HarnessError> {
        let end = Instant::now() + timeout;
        let status = loop {
            while let Ok(line) = self.lines.try_recv() {
                echo(&line);
            }
            for (peak, child) in
                self.peak_rss_kib
                    .iter_mut()
                    .zip([&self.world, &self.planner, &self.executive])
            {
                if let Some(kib) = peak_rss_kib(child.id()) {
                    *peak = (*peak).max(kib);
                }
            }
            if let Some(status) = self.world.try_wait().context("waiting for grop-world")? {
                break status;
            }
            // An onboard process that exits with an error (not one we killed) will never join:
            // say why instead of waiting for the world's join timeout.
            let recorder = self.recorder.as_mut().map(|c| ("recorder", c));
            let exited = [
                ("planner", &mut self.planner),
                ("executive", &mut self.executive),
            ]
            .into_iter()
            .chain(recorder)
            .find_map(|(name, child)| match child.try_wait() {
                Ok(Some(status)) if status.code().is_some_and(|c| c != 0) => Some((name, status)),
                _ => None,
            });
            {
                if let Some((name, status)) = exited {
                    {
                        kill(&mut self.world, libc::SIGTERM);
                        let _ = self.world.wait();
                        self.stop_onboard();
                        bail!(
                            "grop-{name} exited ({status}); the end of its log ({}):\n{}",
                            self.dir.join(format!("{name}.log")).display(),
                            log_tail(&self.dir.join(format!("{name}.log")), 8)
                        );
                    }
                }
            }
            if Instant::now() > end {
                kill(&mut self.world, libc::SIGTERM);
                let _ = self.world.wait();
                self.stop_onboard();
                bail!("the mission did not finish within {timeout:?} (wall)");
            }
            std::thread::sleep(Duration::from_millis(20));
        };
        while let Ok(line) = self.lines.recv_timeout(Duration::from_millis(100)) {
            echo(&line);
        }
        self.stop_onboard();
        if !status.success() {
            bail!(
                "grop-world failed ({status}); see the log in {}",
                self.report_path.display()
            );
        }
        let text = std::fs::read_to_string(&self.report_path)
            .with_context(|| format!("reading {}", self.report_path.display()))?;
        let report = serde_json::from_str(&text)
            .with_context(|| format!("parsing {}", self.report_path.display()))?;
        Ok((report, self.peak_rss_kib))
    }

    fn stop_onboard(&mut self) {
        // The recorder ends by itself when the world's clock closes (it finishes the file
        // first); on the wall clock, or if it lingers, SIGTERM does the same.
        if let Some(recorder) = self.recorder.as_mut() {
            let end = Instant::now() + Duration::from_secs(30);
            while matches!(recorder.try_wait(), Ok(None)) && Instant::now() < end {
                if self.world.try_wait().ok().flatten().is_none() {
                    break;
                }
                std::thread::sleep(Duration::from_millis(10));
            }
            if matches!(recorder.try_wait(), Ok(None)) {
                kill(recorder, libc::SIGTERM);
                let end = Instant::now() + Duration::from_secs(30);
                while matches!(recorder.try_wait(), Ok(None)) && Instant::now() < end {
                    std::thread::sleep(Duration::from_millis(10));
                }
            }
            if matches!(recorder.try_wait(), Ok(None)) {
                kill(recorder, libc::SIGKILL);
            }
            let _ = recorder.wait();
        }
        for child in [&mut self.planner, &mut self.executive] {
            if matches!(child.try_wait(), Ok(None)) {
                kill(child, libc::SIGTERM);
            }
        }
        let end = Instant::now() + Duration::from_secs(5);
        for child in [&mut self.planner, &mut self.executive] {
            while matches!(child.try_wait(), Ok(None)) && Instant::now() < end {
                std::thread::sleep(Duration::from_millis(10));
            }
            if matches!(child.try_wait(), Ok(None)) {
                kill(child, libc::SIGKILL);
            }
            let _ = child.wait();
        }
    }
}

impl Drop for RunningMission {
    fn drop(&mut self) {
        let recorder = self.recorder.as_mut();
        for child in [&mut self.world, &mut self.planner, &mut self.executive]
            .into_iter()
            .chain(recorder)
        {
            if matches!(child.try_wait(), Ok(None)) {
                kill(child, libc::SIGKILL);
                let _ = child.wait();
            }
        }
    }
}

/// Starts the world, waits for its ready line, then starts the planner and the executive
/// against it.
#[allow(
    clippy::too_many_lines,
    reason = "starts a mission's processes in order, each failure naming its step"
)]
pub fn start(spec: &MissionSpec, bins: &Binaries) -> Result<RunningMission, HarnessError> {
    std::fs::create_dir_all(&spec.dir)
        .with_context(|| format!("creating {}", spec.dir.display()))?;
    // Absolute: the deployment file's relative paths resolve against its own folder.
    let dir = std::fs::canonicalize(&spec.dir)
        .with_context(|| format!("resolving {}", spec.dir.display()))?;
    let spec = &MissionSpec {
        dir,
        ..spec.clone()
    };
    let run = unique_run_name("m");
    let scene_path = spec.dir.join("scene.toml");
    spec.scene
        .save(&scene_path)
        .with_context(|| format!("writing {}", scene_path.display()))?;
    // The world's truth: the map plus the chairs the map does not know.
    let world_scene_path = if spec.unmapped_chairs.is_empty() {
        scene_path.clone()
    } else {
        let mut truth = spec.scene.clone();
        truth.chairs.extend_from_slice(&spec.unmapped_chairs);
        let path = spec.dir.join("world-scene.toml");
        truth
            .save(&path)
            .with_context(|| format!("writing {}", path.display()))?;
        path
    };
    let robot_path = spec.dir.join("robot.toml");
    spec.robot
        .save(&robot_path)
        .with_context(|| format!("writing {}", robot_path.display()))?;
    let report_path = spec.dir.join("world-report.json");
    let _ = std::fs::remove_file(&report_path);
    let log = |name: &str| -> Result<Stdio, HarnessError> {
        let path = spec.dir.join(format!("{name}.log"));
        Ok(std::fs::File::create(&path)
            .with_context(|| format!("creating {}", path.display()))?
            .into())
    };

    if spec.live.is_some() && spec.log.is_none() {
        bail!(
            "the live view is served by the recorder: it needs the mission log (not --no-record)"
        );
    }
    let mut world_cmd = Command::new(&bins.world);
    world_cmd
        .arg("--scene")
        .arg(&world_scene_path)
        .arg("--robot")
        .arg(&robot_path)
        .args(["--run", &run, "--seed", &spec.seed.to_string()])
        .args([
            "--camera",
            &format!("{}x{}", spec.camera_px.0, spec.camera_px.1),
        ])
        .args(["--max-sim-s", &spec.max_sim_s.to_string()])
        .args(["--progress-s", &spec.progress_s.to_string()])
        .arg("--report")
        .arg(&report_path)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(log("world")?);
    if let Some(p) = spec.pace {
        world_cmd.args(["--pace", &p.to_string()]);
    }
    for m in &spec.chair_moves {
        world_cmd.args(["--move-chair", &m.to_string()]);
    }
    if let Some(f) = spec.fault {
        world_cmd.args(["--fault", &f.to_string()]);
    }
    if !spec.lidar {
        world_cmd.arg("--no-lidar");
    }
    if spec.log.is_some() {
        world_cmd.args(["--expect", "grop-planner,grop-executive,grop-recorder"]);
    }
    let mut world = world_cmd.spawn().context("starting grop-world")?;
    let stdout = world.stdout.take().context("grop-world has no stdout")?;
    let (tx, lines) = channel();
    std::thread::spawn(move || {
        for line in BufReader::new(stdout).lines() {
            let Ok(line) = line else { break };
            if tx.send(line).is_err() {
                break;
            }
        }
    });
    let ready = loop {
        match lines.recv_timeout(Duration::from_secs(30)) {
            Ok(line) if line.starts_with("grop-world ready") => break line,
            Ok(_) => continue,
            Err(_) => {
                let _ = world.kill();
                bail!(
                    "grop-world did not get ready (see {})",
                    spec.dir.join("world.log").display()
                );
            }
        }
    };
    let field = |key: &str| -> Result<String, HarnessError> {
        ready
            .split_whitespace()
            .find_map(|kv| kv.strip_prefix(&format!("{key}=")).map(str::to_owned))
            .with_context(|| format!("grop-world's ready line has no {key}: {ready}"))
    };
    let clock = field("clock")?;
    let namespace = field("namespace")?;
    let bus = field("bus")?;

    let deployment_path = spec.dir.join("deployment.toml");
    let deployment = deployment_for(
        spec,
        &scene_path,
        &robot_path,
        &namespace,
        &clock,
        &bus,
        &field,
    )?;
    std::fs::write(&deployment_path, deployment)
        .with_context(|| format!("writing {}", deployment_path.display()))?;

    let planner = Command::new(&bins.planner)
        .arg("--deployment")
        .arg(&deployment_path)
        .stdin(Stdio::null())
        .stdout(log("planner-out")?)
        .stderr(log("planner")?)
        .env(
            "RUST_LOG",
            std::env::var("RUST_LOG").unwrap_or_else(|_| "info".into()),
        )
        .spawn()
        .context("starting grop-planner")?;
    let executive = Command::new(&bins.executive)
        .arg("--deployment")
        .arg(&deployment_path)
        .stdin(Stdio::null())
        .stdout(log("executive-out")?)
        .stderr(log("executive")?)
        .env(
            "RUST_LOG",
            std::env::var("RUST_LOG").unwrap_or_else(|_| "info".into()),
        )
        .spawn()
        .context("starting grop-executive")?;
    let recorder = match &spec.log {
        Some(path) => Some(
            Command::new(&bins.recorder)
                .arg("--deployment")
                .arg(&deployment_path)
                .arg("--out")
                .arg(path)
                .args(
                    spec.live
                        .iter()
                        .flat_map(|a| ["--live".to_owned(), a.to_string()]),
                )
                .stdin(Stdio::null())
                .stdout(log("recorder-out")?)
                .stderr(log("recorder")?)
                .env(
                    "RUST_LOG",
                    std::env::var("RUST_LOG").unwrap_or_else(|_| "info".into()),
                )
                .spawn()
                .context("starting grop-recorder")?,
        ),
        None => None,
    };
    Ok(RunningMission {
        run,
        world,
        planner,
        executive,
        recorder,
        lines,
        report_path,
        peak_rss_kib: [0; 3],
        dir: spec.dir.clone(),
    })
}

/// The error a process printed at exit (from its last `Error:` line), else the last `n` lines
/// of its log.
fn log_tail(path: &Path, n: usize) -> String {
    let text = std::fs::read_to_string(path).unwrap_or_default();
    let lines: Vec<&str> = text.lines().collect();
    let from = lines
        .iter()
        .rposition(|l| l.starts_with("Error:"))
        .unwrap_or(lines.len().saturating_sub(n));
    lines[from..]
        .iter()
        .take(n)
        .copied()
        .collect::<Vec<_>>()
        .join("\n")
}

/// The deployment file the onboard processes of a HIL mission read (the format of
/// `grop_onboard::deployment`): the scene as the map, the run's clock, bus and namespace, and
/// the simulated UR5e's ports from the world's ready line.
fn deployment_for(
    spec: &MissionSpec,
    scene: &std::path::Path,
    robot: &std::path::Path,
    namespace: &str,
    clock: &str,
    bus: &str,
    field: &dyn Fn(&str) -> Result<String, HarnessError>,
) -> Result<String, HarnessError> {
    let quote = |p: &std::path::Path| format!("{:?}", p.display().to_string());
    Ok(format!(
        "# Written by the HIL mission runner for one closed-loop run.\n\
         namespace = {namespace:?}\n\
         map = {}\n\
         robot = {}\n\
         model = {}\n\
         can = \"vcan:{bus}\"\n\
         clock = {clock:?}\n\
         seed = {}\n\
         lidar = {:?}\n\
         {}\n\
         [inputs]\n\
         fixes = \"world\"\n\
         operator = \"world\"\n\n\
         [arm]\n\
         host = \"127.0.0.1\"\n\
         rtde_port = {}\n\
         dashboard_port = {}\n\
         script_port = {}\n\
         gripper_port = {}\n\n\
         [planner]\n\
         method = {:?}\n\
         paper_smp = {}\n\
         retry = {:?}\n",
        quote(scene),
        quote(robot),
        quote(&spec.model),
        spec.seed,
        match field("lidar")?.as_str() {
            "none" => "none".to_owned(),
            port => format!("udp:127.0.0.1:{port}"),
        },
        // The simulated sensor sends from loopback.
        match field("lidar")?.as_str() {
            "none" => "",
            _ => "lidar_sensor = \"127.0.0.1\"\n",
        },
        field("rtde")?,
        field("dashboard")?,
        field("secondary")?,
        field("gripper")?,
        spec.method,
        spec.paper_smp,
        spec.retry,
    ))
}
