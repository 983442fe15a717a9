//! `grop-world`: the closed-loop HIL world as its own process (see the crate docs). Prints one
//! `grop-world ready ...` line with the names and ports the onboard processes need, runs the
//! mission in simulated time, and writes the report as JSON.
#![allow(
    unsafe_code,
    reason = "libc::signal installs the SIGTERM/SIGINT flag handler"
)]

use std::io::Write;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use anyhow::Context;
use clap::Parser;
use hil_world::{World, WorldConfig};

/// The closed-loop HIL world: simulated clock, RMP base on the virtual CAN bus, UR5e on
/// loopback TCP, objects, collisions, overhead camera, localisation.
#[derive(Parser, Debug)]
#[command(name = "grop-world", version)]
struct Args {
    /// Scene file (the truth; the onboard map file may differ).
    #[arg(long)]
    scene: PathBuf,
    /// Robot file (default: the built-in robot).
    #[arg(long)]
    robot: Option<PathBuf>,
    /// Run name: the clock, the bus and the iceoryx2 namespace are derived from it.
    #[arg(long)]
    run: String,
    /// Seed of the world's noise.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Simulated seconds per wall second (1 = wall-clock pace); lock-step as fast as possible
    /// when absent.
    #[arg(long)]
    pace: Option<f64>,
    /// Camera frame size, WIDTHxHEIGHT (at least 640x480, at most 1280x960).
    #[arg(long, default_value = "640x480")]
    camera: String,
    /// Simulated time limit of the mission, s.
    #[arg(long, default_value_t = 900.0)]
    max_sim_s: f64,
    /// Print progress every this many simulated seconds (0: quiet).
    #[arg(long, default_value_t = 0.0)]
    progress_s: f64,
    /// Participants to wait for, comma-separated.
    #[arg(long, default_value = "grop-planner,grop-executive")]
    expect: String,
    /// Inject one fault: KIND, KIND@driving, KIND@arm or KIND@SECONDS after the mission
    /// starts (docs/reliability.md lists the kinds).
    #[arg(long)]
    fault: Option<hil_world::faults::FaultSpec>,
    /// Where to write the report (JSON).
    #[arg(long)]
    report: Option<PathBuf>,
    /// Do not simulate the range sensor (the executive then drives without its collision
    /// monitor: the behaviour before the lidar, for comparisons).
    #[arg(long)]
    no_lidar: bool,
    /// Move a chair during the mission: AT_S:CHAIR:X:Y:YAW (simulated seconds, the chair's
    /// index in the scene file, where it goes); repeat for more moves.
    #[arg(long = "move-chair", value_name = "AT_S:CHAIR:X:Y:YAW")]
    move_chair: Vec<hil_world::moves::ChairMove>,
}

static STOP: AtomicBool = AtomicBool::new(false);

extern "C" fn on_signal(_: libc::c_int) {
    STOP.store(true, Ordering::Relaxed);
}

fn parse_size(s: &str) -> anyhow::Result<(u32, u32)> {
    let (w, h) = s
        .split_once('x')
        .with_context(|| format!("--camera {s:?}: expected WIDTHxHEIGHT"))?;
    let w: u32 = w.parse().with_context(|| format!("--camera width {w:?}"))?;
    let h: u32 = h
        .parse()
        .with_context(|| format!("--camera height {h:?}"))?;
    anyhow::ensure!(
        (640..=1280).contains(&w) && (480..=960).contains(&h),
        "--camera {s}: must be between 640x480 and 1280x960"
    );
    Ok((w, h))
}

fn main() -> anyhow::Result<()> {
    env_logger::Builder::from_env(env_logger::Env::default().default_filter_or("warn")).init();
    let args = Args::parse();
    // SAFETY: installing a handler that only stores to an atomic.
    unsafe {
        libc::signal(libc::SIGTERM, on_signal as *const () as libc::sighandler_t);
        libc::signal(libc::SIGINT, on_signal as *const () as libc::sighandler_t);
    }
    let scene = world::Scene::load(&args.scene)?;
    let robot = match &args.robot {
        Some(p) => world::RobotConfig::load(p)?,
        None => world::RobotConfig::default(),
    };
    let mut config = WorldConfig::new(&args.run, scene, robot, args.seed);
    config.pace = args.pace.filter(|p| *p > 0.0);
    config.camera_px = parse_size(&args.camera)?;
    config.max_sim_time = Duration::from_secs_f64(args.max_sim_s.max(1.0));
    config.progress_every =
        (args.progress_s > 0.0).then(|| Duration::from_secs_f64(args.progress_s));
    config.expect = args
        .expect
        .split(',')
        .filter(|s| !s.is_empty())
        .map(str::to_owned)
        .collect();
    config.fault = args.fault;
    config.lidar = !args.no_lidar;
    config.chair_moves = args.move_chair;
    let mut world = World::new(config).context("starting the world")?;
    let ports = world.arm_ports();
    let c = world.config();
    println!(
        "grop-world ready clock=sim:{} namespace={} bus={} rtde={} dashboard={} secondary={} gripper={} lidar={}",
        c.clock_name,
        c.namespace,
        c.bus_name,
        ports.rtde,
        ports.dashboard,
        ports.secondary,
        ports.gripper,
        world
            .lidar_port()
            .map_or_else(|| "none".to_owned(), |p| p.to_string())
    );
    std::io::stdout().flush().context("flushing stdout")?;
    let report = world.run(&|| STOP.load(Ordering::Relaxed));
    if let Some(path) = &args.report {
        let text = serde_json::to_string_pretty(&report).context("encoding the report")?;
        std::fs::write(path, text).with_context(|| format!("writing {}", path.display()))?;
    }
    println!(
        "grop-world done end={:?} placed={}/{} sim_s={:.1} wall_s={:.2}",
        report.end,
        report.placed,
        report.objects.len(),
        report.timing.sim_time_s,
        report.timing.wall_time_s
    );
    Ok(())
}
