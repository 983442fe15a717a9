//! `grop-executive --deployment FILE [--namespace NS] [--clock SPEC]`: the executive as a
//! process: connects the UR5e (RTDE, URScript, dashboard, gripper) and the RMP base's CAN bus
//! named in the deployment, joins the runtime clock, and runs the cyclic executive (2 ms arm
//! cycle, 50 Hz base loop) until SIGTERM or SIGINT, when it commands the base to zero and stops
//! the arm before exiting. If it is killed instead, the base's own 0.5 s loss-of-command timeout
//! and the UR controller's RTDE watchdog stop both.

use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::time::Duration;

use anyhow::Context;
use can_bus::{CanBus, SocketCanBus, VirtualCanBus};
use clap::Parser;
use grop_onboard::deployment::{CanSpec, LidarSource};
use grop_onboard::executive::arm_io::RecordingArm;
use grop_onboard::executive::range::Vlp16Sensor;
use grop_onboard::executive::ur5e_arm::{ArmIoSettings, ArmMotionSettings, Ur5eDevice};
use grop_onboard::executive::{Executive, ExecutiveConfig, MissionState};

/// Rank of the executive on a simulated clock: after the planner at each instant.
const EXECUTIVE_CLOCK_RANK: u32 = 20;

#[derive(Parser, Debug)]
#[command(
    name = "grop-executive",
    about = "grop executive: base and arm loops",
    version
)]
struct Args {
    #[command(flatten)]
    deployment: grop_onboard::process::DeploymentArgs,
    /// Exit when the mission has finished or aborted (default: hold the base at zero until
    /// stopped, as on the robot).
    #[arg(long)]
    exit_when_done: bool,
}

#[allow(
    clippy::too_many_lines,
    reason = "the process's wiring in order: deployment, devices, clock, executive, sensor, run, report"
)]
fn main() -> anyhow::Result<()> {
    env_logger::Builder::from_env(env_logger::Env::default().default_filter_or("info")).init();
    let args = Args::parse();
    let deployment = args.deployment.load()?;
    let stop = grop_onboard::process::stop_flag()?;
    args.deployment.apply_rt("grop-executive");
    let scene = world::Scene::load(&deployment.map)
        .with_context(|| format!("the map {}", deployment.map.display()))?;
    let robot = deployment.load_robot().context("the robot file")?;
    let objects = scene.targets.len();

    // Devices first (the HIL world runs at wall-clock pace until we join its clock).
    let bus: Box<dyn CanBus> = match &deployment.can {
        CanSpec::Virtual { bus } => Box::new(
            VirtualCanBus::join(bus, "grop-executive")
                .with_context(|| format!("joining virtual CAN bus {bus}"))?,
        ),
        CanSpec::SocketCan { ifname } => Box::new(
            SocketCanBus::open(ifname).with_context(|| format!("opening SocketCAN {ifname}"))?,
        ),
    };
    let a = &deployment.arm;
    let host: std::net::IpAddr = a
        .host
        .parse()
        .with_context(|| format!("arm.host {:?} is not an IP address", a.host))?;
    let arm_config = ur5e::ArmConfig {
        host,
        rtde_port: a.rtde_port,
        dashboard_port: a.dashboard_port,
        script_port: a.script_port,
        gripper_port: Some(a.gripper_port),
        tcp_offset: Some(ur5e::TcpPose::from_array([
            0.0,
            0.0,
            robot.place.tcp_offset_m,
            0.0,
            0.0,
            0.0,
        ])),
        ..ur5e::ArmConfig::default()
    };
    let arm = ur5e::Ur5eArm::connect(arm_config)
        .with_context(|| format!("connecting the UR5e at {}", a.host))?;
    let node = grop_ipc::IpcNode::new(&deployment.namespace, "grop-executive")
        .context("joining the iceoryx2 namespace")?;
    let clock: Arc<dyn grop_clock::Clock> = Arc::from(
        grop_clock::open(&deployment.clock, "grop-executive", EXECUTIVE_CLOCK_RANK)
            .with_context(|| format!("opening clock {}", deployment.clock))?,
    );
    // The arm's sockets on their own threads (the base loop never waits on them); every arm
    // call and its answer goes out on `arm/io` (the mission log's RTDE record).
    let motion = ArmMotionSettings::default();
    let io = ArmIoSettings::for_clock(
        clock.is_simulated(),
        arm.config().stale_after,
        &motion,
        arm.config().io_timeout,
    );
    let arm = Ur5eDevice::new(arm, motion, io).context("starting the arm's I/O threads")?;
    let arm = RecordingArm::new(arm, &node).context("opening arm/io")?;
    let config = ExecutiveConfig {
        inputs: deployment.inputs.clone(),
        ..ExecutiveConfig::for_robot(&robot)
    };
    let mut executive = Executive::new(
        config,
        Arc::clone(&clock),
        bus,
        arm,
        &node,
        scene.clone(),
        objects,
    )
    .context("starting the executive")?;
    match &deployment.lidar {
        LidarSource::Udp(addr) => {
            let mut sensor = Vlp16Sensor::bind(addr, &robot.lidar, robot.footprint.body_height_m)?;
            match deployment.lidar_sensor {
                Some(ip) => sensor.only_from(ip),
                None => log::warn!(
                    "grop-executive: no lidar_sensor in the deployment: range packets from any sender are read"
                ),
            }
            executive.set_range_sensor(Box::new(sensor), &scene);
            log::info!("grop-executive: collision monitor on the VLP-16 at udp:{addr}");
        }
        LidarSource::None => {
            log::warn!(
                "grop-executive: no range sensor (lidar = none): the collision monitor is off"
            )
        }
    }
    log::info!(
        "grop-executive: namespace `{}`, clock {}, CAN {}, arm {}:{}",
        deployment.namespace,
        deployment.clock,
        deployment.can,
        a.host,
        a.rtde_port
    );
    let state = executive.run(&|| !stop.load(Ordering::Relaxed), args.exit_when_done);
    let stats = executive.stats();
    log::info!("grop-executive: minor cycle {}", executive.loop_summary());
    if let Some(range) = executive.range_status(clock.now()) {
        log::info!("grop-executive: range sensor {range}");
    }
    log::info!(
        "grop-executive: {state:?}; {} cycles, {} overruns, {} unloads ok, {} failed, {} inputs refused",
        stats.cycles,
        stats.overruns,
        stats.unloads_ok,
        stats.unloads_failed,
        stats.inputs_refused
    );
    // Give the zero command a moment on a real bus before the process goes.
    if matches!(state, MissionState::Aborted(_)) && deployment.clock == "wall" {
        std::thread::sleep(Duration::from_millis(100));
    }
    Ok(())
}
