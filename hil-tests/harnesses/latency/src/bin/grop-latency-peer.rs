//! `grop-latency-peer`: the second process of the latency suite (`grop latency`). Started by
//! the suite, never by hand; each mode prints `ready` when set up and exits when stdin closes.
//!
//! ```text
//! grop-latency-peer camera --service S --namespace NS --uds PATH --tcp-port P [--gap-us 300]
//! grop-latency-peer loop --hz 50 --cycles 500 [--rt on] [--work-us 50]
//! grop-latency-peer spin --cpu 1
//! grop-latency-peer rmp-sim --bus NAME
//! grop-latency-peer alloc --cycles 1000 [--warmup 200]
//! ```

use std::path::PathBuf;
use std::time::Duration;

use clap::{Parser, Subcommand};
use grop_clock::rt::RtSettings;
use latency::alloc_count::CountingAlloc;

/// Counts allocations inside `latency::alloc_count::counted` scopes (the `alloc` mode); a
/// thread-local flag check otherwise.
#[global_allocator]
static GLOBAL: CountingAlloc = CountingAlloc;

#[derive(Parser, Debug)]
#[command(about = "The second process of `grop latency` (started by the suite)")]
struct Args {
    #[command(subcommand)]
    mode: Mode,
}

#[derive(Subcommand, Debug)]
enum Mode {
    /// Publish camera frames on command (one byte per frame on stdin).
    Camera {
        /// iceoryx2 service.
        #[arg(long)]
        service: String,
        /// grop-ipc namespace.
        #[arg(long)]
        namespace: String,
        /// Unix socket to connect to.
        #[arg(long)]
        uds: PathBuf,
        /// TCP port on 127.0.0.1.
        #[arg(long)]
        tcp_port: u16,
        /// Pause between a command and its frame, us.
        #[arg(long, default_value_t = 300)]
        gap_us: u64,
    },
    /// A cyclic loop on absolute deadlines; prints its lateness.
    Loop {
        /// Rate, Hz.
        #[arg(long)]
        hz: u32,
        /// Cycles.
        #[arg(long)]
        cycles: usize,
        /// Real-time settings (`off`, `on`, `fifo=50,cpu=1,lock,slack=1`, ...).
        #[arg(long, default_value = "off")]
        rt: RtSettings,
        /// Busy work per cycle, us.
        #[arg(long, default_value_t = 50)]
        work_us: u64,
    },
    /// Keep one CPU busy until stdin closes.
    Spin {
        /// The CPU.
        #[arg(long)]
        cpu: usize,
    },
    /// The simulated RMP base on a virtual CAN bus.
    RmpSim {
        /// Bus name.
        #[arg(long)]
        bus: String,
    },
    /// Allocation counts of the steady-state cases.
    Alloc {
        /// Counted cycles per case.
        #[arg(long)]
        cycles: usize,
        /// Warm-up cycles per case.
        #[arg(long, default_value_t = 200)]
        warmup: usize,
    },
}

fn main() -> std::process::ExitCode {
    env_logger::Builder::from_env(env_logger::Env::default().default_filter_or("warn")).init();
    let args = Args::parse();
    let result = match args.mode {
        Mode::Camera {
            service,
            namespace,
            uds,
            tcp_port,
            gap_us,
        } => latency::camera::run_publisher(&latency::camera::PublisherArgs {
            service,
            namespace,
            uds,
            tcp_port,
            gap: Duration::from_micros(gap_us),
        }),
        Mode::Loop {
            hz,
            cycles,
            rt,
            work_us,
        } => {
            latency::jitter::run_loop(hz, cycles, &rt, Duration::from_micros(work_us));
            Ok(())
        }
        Mode::Spin { cpu } => {
            latency::jitter::run_spin(cpu);
            Ok(())
        }
        Mode::RmpSim { bus } => latency::can_loop::run_sim(&bus),
        Mode::Alloc { cycles, warmup } => latency::alloc_count::run_cases(cycles, warmup),
    };
    match result {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            // The suite reads this line and reports it.
            println!("error {e}");
            eprintln!("grop-latency-peer: {e}");
            std::process::ExitCode::FAILURE
        }
    }
}
