//! `sim-ur5e`: the simulated UR5e controller as its own process.
//!
//! `sim-ur5e` listens on the real controller's ports on 127.0.0.1; `sim-ur5e --ephemeral
//! --ports-file ports.json` lets the OS pick free ports and writes them as JSON. It runs until
//! killed.

use std::net::IpAddr;
use std::path::PathBuf;

use anyhow::Context;
use clap::Parser;
use sim_ur5e::{RobotInit, SimConfig, Ur5eSim};

/// Simulated UR5e controller (RTDE, dashboard, primary/secondary/real-time, Robotiq gripper).
#[derive(Debug, Parser)]
#[command(version)]
struct Args {
    /// Address to listen on.
    #[arg(long, default_value = "127.0.0.1")]
    bind: IpAddr,
    /// Let the OS choose every port (overrides the port options).
    #[arg(long)]
    ephemeral: bool,
    /// RTDE port.
    #[arg(long, default_value_t = 30004)]
    rtde_port: u16,
    /// Dashboard port.
    #[arg(long, default_value_t = 29999)]
    dashboard_port: u16,
    /// Primary interface port.
    #[arg(long, default_value_t = 30001)]
    primary_port: u16,
    /// Secondary interface port.
    #[arg(long, default_value_t = 30002)]
    secondary_port: u16,
    /// Real-time interface port.
    #[arg(long, default_value_t = 30003)]
    realtime_port: u16,
    /// Robotiq URCap gripper port.
    #[arg(long, default_value_t = 63352)]
    gripper_port: u16,
    /// Write the bound addresses to this file as JSON once listening.
    #[arg(long)]
    ports_file: Option<PathBuf>,
    /// Start powered off (robot mode POWER_OFF) instead of running.
    #[arg(long)]
    powered_off: bool,
    /// Protective stop when the TCP goes below this height in the base frame (m).
    #[arg(long)]
    floor_z_m: Option<f64>,
    /// Width of an object between the gripper fingers (m).
    #[arg(long)]
    gripper_object_m: Option<f64>,
    /// A program file the dashboard `load` accepts (repeatable).
    #[arg(long = "program")]
    programs: Vec<String>,
    /// Initial joints (rad), six comma-separated values.
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
    initial_q: Option<Vec<f64>>,
    /// The External Control URCap's script sender (URCL's, e.g. 127.0.0.1:50002): dashboard
    /// `play` of a loaded program asks it for the External Control program.
    #[arg(long)]
    urcap_script_sender: Option<std::net::SocketAddr>,
}

fn main() -> anyhow::Result<()> {
    env_logger::Builder::from_env(env_logger::Env::default().default_filter_or("info")).init();
    let args = Args::parse();
    let mut init = RobotInit {
        powered: !args.powered_off,
        floor_z_m: args.floor_z_m,
        ..RobotInit::default()
    };
    if let Some(q) = &args.initial_q {
        init.q = <[f64; 6]>::try_from(q.as_slice()).context("--initial-q needs six values")?;
    }
    let mut cfg = SimConfig {
        bind_ip: args.bind,
        rtde_port: args.rtde_port,
        dashboard_port: args.dashboard_port,
        primary_port: args.primary_port,
        secondary_port: args.secondary_port,
        realtime_port: args.realtime_port,
        gripper_port: args.gripper_port,
        programs: args.programs.clone(),
        init,
        gripper_object_width_m: args.gripper_object_m,
        urcap_script_sender: args.urcap_script_sender,
        ..SimConfig::default()
    };
    if args.ephemeral {
        cfg = SimConfig {
            rtde_port: 0,
            dashboard_port: 0,
            primary_port: 0,
            secondary_port: 0,
            realtime_port: 0,
            gripper_port: 0,
            ..cfg
        };
    }
    let sim = Ur5eSim::start(cfg).context("starting the simulated UR5e")?;
    let p = sim.ports();
    let json = serde_json::json!({
        "rtde": p.rtde.port(),
        "dashboard": p.dashboard.port(),
        "primary": p.primary.port(),
        "secondary": p.secondary.port(),
        "realtime": p.realtime.port(),
        "gripper": p.gripper.port(),
        "host": p.rtde.ip().to_string(),
    });
    if let Some(path) = &args.ports_file {
        // Written to a temporary name and renamed, so a reader never sees half a file.
        let tmp = path.with_extension("tmp");
        std::fs::write(&tmp, json.to_string())
            .with_context(|| format!("writing {}", tmp.display()))?;
        std::fs::rename(&tmp, path).with_context(|| format!("renaming to {}", path.display()))?;
    }
    println!("sim-ur5e ready {json}");
    loop {
        std::thread::park();
    }
}
