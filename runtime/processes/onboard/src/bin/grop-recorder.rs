//! `grop-recorder --deployment FILE --out LOG.mcap`: the mission recorder. Subscribes to every
//! topic of the deployment's namespace and listens on its CAN bus, and writes everything into
//! one MCAP file (JSON messages with JSON Schemas, zstd chunks; see docs/logs.md). It never
//! publishes and never sends on the bus, so it cannot hold up a control loop: on the wall clock
//! a full write queue drops (and counts) messages; on a simulated clock it joins the clock last
//! in rank, takes each instant's messages at that instant, and a full queue waits (simulated
//! time stops, nothing is lost). SIGTERM or SIGINT, or the end of a simulation, finish the
//! file; if it is killed, everything but the last second stays readable. `--live ADDR` also
//! serves the mission live to the Foxglove app (docs/logs.md, "Live view").

use std::path::PathBuf;
use std::sync::atomic::Ordering;
use std::time::Duration;

use anyhow::Context;
use can_bus::{CanBus, SocketCanBus, VirtualCanBus};
use clap::Parser;
use grop_onboard::deployment::CanSpec;
use grop_onboard::mission_log::live::{LiveConfig, LiveServer};
use grop_onboard::mission_log::{
    LogWriter, MISSION_METADATA, Overflow, RECORDER_METADATA, Recorder, RecorderConfig, Views,
    WriterConfig,
};

/// Rank on a simulated clock: after every other process at each instant.
const RECORDER_CLOCK_RANK: u32 = 90;

#[derive(Parser, Debug)]
#[command(
    name = "grop-recorder",
    about = "grop mission recorder (MCAP)",
    version
)]
struct Args {
    #[command(flatten)]
    deployment: grop_onboard::process::DeploymentArgs,
    /// The log file to write (replaced if it exists).
    #[arg(long, value_name = "FILE")]
    out: PathBuf,
    /// Keep at most one camera frame per this many seconds (plus every frame a plan used).
    #[arg(long, default_value_t = 1.0)]
    camera_period_s: f64,
    /// Cycle of the recorder, ms (the executive's arm cycle).
    #[arg(long, default_value_t = 2)]
    period_ms: u64,
    /// Most MiB of messages waiting for the disk.
    #[arg(long, default_value_t = 64)]
    queue_mib: usize,
    /// Serve a live view of the mission on this address (Foxglove WebSocket protocol; open
    /// ws://ADDR in the Foxglove app). Port 0: one the OS chooses (printed as
    /// `grop-recorder live ws://ADDR`). Off by default.
    #[arg(long, value_name = "ADDR")]
    live: Option<std::net::SocketAddr>,
    /// Most MiB of messages waiting for the live view (a full queue drops, never waits).
    #[arg(long, default_value_t = 16)]
    live_queue_mib: usize,
}

/// The log's metadata records: the mission (what a replay needs) and the recorder's settings.
fn metadata(
    args: &Args,
    deployment: &grop_onboard::deployment::Deployment,
) -> std::collections::BTreeMap<String, std::collections::BTreeMap<String, String>> {
    let mut m = std::collections::BTreeMap::new();
    m.insert(
        MISSION_METADATA.to_owned(),
        grop_onboard::mission_log::mission_metadata(deployment),
    );
    m.insert(
        RECORDER_METADATA.to_owned(),
        [
            (
                "camera_period_s".to_owned(),
                args.camera_period_s.to_string(),
            ),
            ("period_ms".to_owned(), args.period_ms.to_string()),
        ]
        .into_iter()
        .collect(),
    );
    m
}

/// The live view, when `--live` asks for it (its address printed on stdout).
fn start_live(args: &Args, simulated: bool) -> anyhow::Result<Option<LiveServer>> {
    let Some(addr) = args.live else {
        return Ok(None);
    };
    let server = LiveServer::start(LiveConfig {
        queue_bytes: args.live_queue_mib.max(1) << 20,
        publish_time: simulated,
        ..LiveConfig::new(addr)
    })?;
    // Stdout is line-buffered: a test (or a person) reads the bound address at once.
    println!("grop-recorder live ws://{}", server.local_addr());
    log::info!(
        "grop-recorder: live view on ws://{} (Foxglove: Open connection)",
        server.local_addr()
    );
    Ok(Some(server))
}

fn main() -> anyhow::Result<()> {
    env_logger::Builder::from_env(env_logger::Env::default().default_filter_or("info")).init();
    let args = Args::parse();
    anyhow::ensure!(
        args.camera_period_s.is_finite() && args.camera_period_s >= 0.0,
        "--camera-period-s {} must be a non-negative number",
        args.camera_period_s
    );
    anyhow::ensure!(
        (1..=1000).contains(&args.period_ms),
        "--period-ms {} must be within 1..=1000",
        args.period_ms
    );
    let deployment = args.deployment.load()?;
    let stop = grop_onboard::process::stop_flag()?;
    args.deployment.apply_rt("grop-recorder");
    let simulated = deployment.clock != "wall";
    let bus: Box<dyn CanBus + Send> = match &deployment.can {
        CanSpec::Virtual { bus } => Box::new(
            VirtualCanBus::join(bus, "grop-recorder")
                .with_context(|| format!("joining virtual CAN bus {bus}"))?,
        ),
        CanSpec::SocketCan { ifname } => Box::new(
            SocketCanBus::open(ifname).with_context(|| format!("opening SocketCAN {ifname}"))?,
        ),
    };
    let writer = LogWriter::create(
        &args.out,
        metadata(&args, &deployment),
        WriterConfig {
            queue_bytes: args.queue_mib.max(1) << 20,
            overflow: if simulated {
                Overflow::Block
            } else {
                Overflow::Drop
            },
            ..WriterConfig::default()
        },
    )?;
    let node = grop_ipc::IpcNode::new(&deployment.namespace, "grop-recorder")
        .context("joining the iceoryx2 namespace")?;
    let mut recorder = Recorder::new(
        &node,
        Some(bus),
        writer,
        RecorderConfig {
            camera_period_ns: (args.camera_period_s * 1e9) as u64,
        },
    )?;
    // The channels in Foxglove's well-known schemas need the map and the robot file.
    match (deployment.load_scene(), deployment.load_robot()) {
        (Ok(scene), Ok(robot)) => recorder = recorder.with_views(Views::new(scene, &robot)),
        (Err(e), _) => log::warn!("grop-recorder: no Foxglove views (the map: {e})"),
        (_, Err(e)) => log::warn!("grop-recorder: no Foxglove views (the robot file: {e})"),
    }
    let live = start_live(&args, simulated)?;
    if let Some(server) = &live {
        recorder = recorder.with_live(server.feed());
    }
    let clock = grop_clock::open(&deployment.clock, "grop-recorder", RECORDER_CLOCK_RANK)
        .with_context(|| format!("opening clock {}", deployment.clock))?;
    log::info!(
        "grop-recorder: namespace `{}`, clock {}, CAN {}, writing {}",
        deployment.namespace,
        deployment.clock,
        deployment.can,
        args.out.display()
    );
    let period = Duration::from_millis(args.period_ms);
    let ns = |d: Duration| u64::try_from(d.as_nanos()).unwrap_or(u64::MAX);
    clock.wait_turn();
    let mut deadline = clock.now();
    let mut taken = 0u64;
    while !stop.load(Ordering::Relaxed) && !clock.is_lost() {
        taken += recorder.drain(ns(clock.now())) as u64;
        deadline += period;
        clock.sleep_until(deadline);
    }
    let errors = recorder.receive_errors();
    let last = (!clock.is_lost()).then(|| ns(clock.now()));
    let summary = recorder.finish(last)?;
    let live = live.map(LiveServer::finish);
    let written: u64 = summary.written.values().sum();
    let dropped: u64 = summary.dropped.values().sum();
    let live_line = live.map(|l| format!(" {l}")).unwrap_or_default();
    log::info!(
        "grop-recorder: {} written ({taken} taken), {dropped} dropped, {errors} receive errors, {:.1} MB{live_line}",
        written,
        summary.file_bytes as f64 / 1e6
    );
    println!(
        "grop-recorder done messages={written} dropped={dropped} receive_errors={errors} bytes={} file={}{live_line}",
        summary.file_bytes,
        args.out.display()
    );
    Ok(())
}
