//! `sim-rmp`: the simulated Segway RMP base as its own process on the iceoryx2 virtual CAN bus.
//!
//! ```text
//! sim-rmp --bus hil [--node sim-rmp] [--profile segway2014|older440] [--yaw-sign 1|-1]
//! ```
//!
//! Prints `sim-rmp ready` on stdout once it has joined the bus. Reads control lines on stdin
//! (fault injection for HIL tests): `silent on|off`, `fault <name> on|off` (names: kill,
//! disable, shutdown, velocity-control, decel-switch), `status` (prints pose and state),
//! `quit`. Exits on `quit` or when stdin closes (so a crashed test harness never leaves it
//! running), or after `--exit-after-s`.

use std::io::{BufRead, Write};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use anyhow::{Context, bail};
use can_bus::VirtualCanBus;
use clap::Parser;
use rmp_codec::v3::FirmwareProfile;
use sim_rmp::{SimConfig, SimRmp, SimRmpNode, fault_by_name};

#[derive(Parser, Debug)]
#[command(about = "Simulated Segway RMP v3 base on the iceoryx2 virtual CAN bus")]
struct Args {
    /// Virtual bus to join.
    #[arg(long)]
    bus: String,
    /// Node name on the bus.
    #[arg(long, default_value = "sim-rmp")]
    node: String,
    /// Firmware command numbering: segway2014 or older440.
    #[arg(long, default_value = "segway2014")]
    profile: String,
    /// +1: positive yaw is counter-clockwise; -1: clockwise.
    #[arg(long, default_value_t = 1.0, allow_hyphen_values = true)]
    yaw_sign: f64,
    /// Exit after this many seconds (0 = never).
    #[arg(long, default_value_t = 0.0)]
    exit_after_s: f64,
}

enum Control {
    Line(String),
    Eof,
}

fn main() -> anyhow::Result<()> {
    env_logger::Builder::from_env(env_logger::Env::default().default_filter_or("info")).init();
    let args = Args::parse();
    let profile = match args.profile.as_str() {
        "segway2014" => FirmwareProfile::SegwayInc2014,
        "older440" => FirmwareProfile::Older440,
        other => bail!("unknown --profile {other:?} (segway2014 or older440)"),
    };
    if args.yaw_sign != 1.0 && args.yaw_sign != -1.0 {
        bail!("--yaw-sign must be 1 or -1, got {}", args.yaw_sign);
    }
    let bus = VirtualCanBus::join(&args.bus, &args.node)
        .with_context(|| format!("joining virtual CAN bus {:?} as {:?}", args.bus, args.node))?;
    let sim = SimRmp::new(SimConfig {
        profile,
        yaw_sign: args.yaw_sign,
        ..SimConfig::default()
    });
    let mut node = SimRmpNode::new(bus, sim);

    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        for line in std::io::stdin().lock().lines() {
            match line {
                Ok(l) => {
                    if tx.send(Control::Line(l)).is_err() {
                        return;
                    }
                }
                Err(_) => break,
            }
        }
        let _ = tx.send(Control::Eof);
    });

    let origin = Instant::now();
    let clock = move || origin.elapsed();
    println!("sim-rmp ready bus={} node={}", args.bus, args.node);
    std::io::stdout().flush().context("flushing stdout")?;
    log::info!(
        "sim-rmp on bus {:?} as {:?}, profile {profile:?}",
        args.bus,
        args.node
    );

    loop {
        while let Ok(control) = rx.try_recv() {
            match control {
                Control::Eof => {
                    log::info!("stdin closed: exiting");
                    return Ok(());
                }
                Control::Line(line) => {
                    if !apply_control(&mut node, line.trim())? {
                        return Ok(());
                    }
                }
            }
        }
        if args.exit_after_s > 0.0 && clock().as_secs_f64() > args.exit_after_s {
            log::info!("--exit-after-s reached: exiting");
            return Ok(());
        }
        if let Err(e) = node.poll_blocking(Duration::from_millis(1), clock) {
            // A malformed frame from another node is its problem; keep serving.
            log::warn!("{e}");
        }
    }
}

/// Applies one control line; returns false on `quit`.
fn apply_control<B>(node: &mut SimRmpNode<B>, line: &str) -> anyhow::Result<bool>
where
    B: can_bus::CanBus,
{
    let words: Vec<&str> = line.split_whitespace().collect();
    let on = |w: &str| match w {
        "on" => Ok(true),
        "off" => Ok(false),
        other => Err(anyhow::anyhow!("expected on|off, got {other:?}")),
    };
    let result = match words.as_slice() {
        [] => Ok(()),
        ["quit"] => return Ok(false),
        ["silent", state] => on(state).map(|s| node.sim_mut().set_silent(s)),
        ["power-cycle"] => {
            node.sim_mut().power_cycle();
            Ok(())
        }
        ["fault", name, state] => match fault_by_name(name) {
            Some(fault) => on(state).map(|s| node.sim_mut().set_fault(fault, s)),
            None => Err(anyhow::anyhow!("unknown fault {name:?}")),
        },
        ["status"] => {
            let sim = node.sim();
            let p = sim.pose();
            let (v, w) = sim.velocity();
            println!(
                "status state={:?} x_m={:.4} y_m={:.4} yaw_rad={:.4} speed_mps={:.4} yaw_rate_radps={:.4} commands={} replies={}",
                sim.state(),
                p.x_m,
                p.y_m,
                p.yaw_rad,
                v,
                w,
                sim.stats().motion_commands,
                sim.stats().replies
            );
            std::io::stdout().flush().context("flushing stdout")?;
            Ok(())
        }
        _ => Err(anyhow::anyhow!("unknown control line {line:?}")),
    };
    if let Err(e) = result {
        log::warn!("{e}");
    }
    Ok(true)
}
