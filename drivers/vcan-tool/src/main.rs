//! `vcan`: candump / cansend for the iceoryx2 virtual CAN bus, plus the conformance echo peer.
//!
//! ```text
//! vcan dump hil                 # print every frame on bus "hil"
//! vcan send hil 500#0000000100000000 00000413#
//! vcan echo hil                 # conformance echo peer (tests spawn it)
//! ```

use std::time::{Duration, Instant};

use anyhow::Context;
use can_bus::{CanBus, CanFrame, VirtualBusConfig, VirtualCanBus, conformance};
use clap::{Parser, Subcommand};

#[derive(Parser)]
#[command(version, about = "Tools for the grop virtual CAN bus (iceoryx2)")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

/// Which bus to join; the sizes must match every other node's.
#[derive(clap::Args)]
struct BusArgs {
    /// Virtual bus name.
    bus: String,
    /// Most nodes on the bus (must match the other nodes).
    #[arg(long, default_value_t = VirtualBusConfig::default().max_nodes)]
    max_nodes: usize,
    /// Frames buffered per sender (must match the other nodes).
    #[arg(long, default_value_t = VirtualBusConfig::default().rx_queue_depth)]
    queue_depth: usize,
}

impl BusArgs {
    fn join(&self, role: &str) -> anyhow::Result<VirtualCanBus> {
        let config = VirtualBusConfig {
            max_nodes: self.max_nodes,
            rx_queue_depth: self.queue_depth,
            ..VirtualBusConfig::default()
        };
        let node_name = format!("vcan-{role}-{}", std::process::id());
        Ok(VirtualCanBus::join_with_config(
            &self.bus, &node_name, &config,
        )?)
    }
}

#[derive(Subcommand)]
enum Command {
    /// Print every frame on the bus, candump style, until interrupted.
    Dump {
        #[command(flatten)]
        bus: BusArgs,
        /// Stop after this many frames.
        #[arg(long)]
        count: Option<u64>,
    },
    /// Send frames given in cansend notation (`123#DEADBEEF`, `1F334455#00`).
    Send {
        #[command(flatten)]
        bus: BusArgs,
        /// Frames, in order.
        #[arg(required = true)]
        frames: Vec<String>,
    },
    /// Run the conformance echo peer until it is told to stop.
    Echo {
        #[command(flatten)]
        bus: BusArgs,
        /// Give up when nothing arrives for this long.
        #[arg(long, default_value_t = 10_000)]
        idle_timeout_ms: u64,
    },
}

fn main() -> anyhow::Result<()> {
    let cli = Cli::parse();
    // iceoryx2 warns about running without a config file; only errors matter to a user here.
    iceoryx2::prelude::set_log_level_from_env_or(iceoryx2::prelude::LogLevel::Error);
    match cli.command {
        Command::Dump { bus, count } => {
            let mut node = bus.join("dump")?;
            let start = Instant::now();
            let mut printed = 0u64;
            while count.is_none_or(|count| printed < count) {
                if let Some(frame) = node.recv_timeout(Duration::from_secs(1))? {
                    let t = start.elapsed().as_secs_f64();
                    println!("({t:12.6}) {}  {frame}", bus.bus);
                    printed += 1;
                }
            }
            if node.lost_frame_count() > 0 {
                eprintln!("lost {} frames (reader too slow)", node.lost_frame_count());
            }
        }
        Command::Send { bus, frames } => {
            let frames = frames
                .iter()
                .map(|text| {
                    text.parse::<CanFrame>()
                        .with_context(|| format!("frame {text:?}"))
                })
                .collect::<anyhow::Result<Vec<_>>>()?;
            let mut node = bus.join("send")?;
            for frame in &frames {
                node.send(frame)?;
            }
        }
        Command::Echo {
            bus,
            idle_timeout_ms,
        } => {
            let mut node = bus.join("echo")?;
            let stats = conformance::echo_peer(&mut node, Duration::from_millis(idle_timeout_ms))?;
            eprintln!(
                "echo peer done: {} echoed, {} burst frames",
                stats.echoed, stats.burst_frames
            );
        }
    }
    Ok(())
}
