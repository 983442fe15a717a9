//! Loop period jitter: a cyclic loop on absolute-deadline sleeps
//! (`grop_clock::WallClock::sleep_until`), how late each cycle wakes, in four configurations:
//! idle or with another core loaded by a busy process, each without and with real-time settings
//! ([`grop_clock::rt`]).
//!
//! Each loop runs in its own peer process (`grop-latency-peer loop`), so that its settings
//! (memory locking, scheduling class) never leak into the caller or the next configuration.
//! The load is another peer (`grop-latency-peer spin`) pinned to the last CPU (or to CPU 0 when
//! the loop itself is pinned to the last one).

use std::path::Path;
use std::time::Duration;

use grop_clock::rt::{self, LoopStats, LoopSummary, RtSettings, RtStep};
use grop_clock::{Clock, WallClock};

use crate::peer::{Peer, field};
use crate::{BenchError, ThreadUsage};

/// One loop configuration.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LoopConfig {
    /// Loop rate, Hz.
    pub hz: u32,
    /// Cycles measured.
    pub cycles: usize,
    /// Another core busy.
    pub loaded: bool,
    /// Real-time settings applied in the loop's process before the loop.
    pub rt: RtSettings,
    /// Busy work per cycle (stands for the control law and I/O).
    pub work: Duration,
}

/// One configuration's outcome.
#[derive(Debug, Clone, PartialEq)]
pub struct LoopResult {
    /// What ran.
    pub config: LoopConfig,
    /// Lateness percentiles and overruns from the loop's own [`LoopStats`].
    pub summary: LoopSummary,
    /// The real-time report, one line per setting (empty when none were asked for).
    pub rt_report: Vec<String>,
    /// Whether `SCHED_FIFO` was asked for and applied.
    pub fifo_applied: bool,
    /// The loop thread's scheduling policy as measured inside the loop process.
    pub policy: String,
    /// Minor page faults during the measured cycles.
    pub minor_faults: u64,
    /// Times the loop thread was preempted during the measured cycles.
    pub involuntary_switches: u64,
    /// Time the loop thread spent runnable but waiting for a CPU during the measured cycles
    /// (`/proc/thread-self/schedstat`), ns; `None` where the kernel does not report it.
    pub run_delay_ns: Option<u64>,
    /// The CPU the load was pinned to, when loaded.
    pub load_cpu: Option<usize>,
}

/// Sizes of the suite of eight loops (50 and 500 Hz, four configurations each).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JitterConfig {
    /// Cycles of the 50 Hz loops.
    pub cycles_50hz: usize,
    /// Cycles of the 500 Hz loops.
    pub cycles_500hz: usize,
    /// The real-time configurations' settings.
    pub rt: RtSettings,
    /// Work per cycle.
    pub work: Duration,
}

impl Default for JitterConfig {
    fn default() -> Self {
        Self {
            cycles_50hz: 500,
            cycles_500hz: 2500,
            rt: RtSettings::ON,
            work: Duration::from_micros(50),
        }
    }
}

/// The four configurations at 50 Hz, then at 500 Hz: idle, idle + RT, loaded, loaded + RT.
pub fn measure(peer_exe: &Path, config: &JitterConfig) -> Result<Vec<LoopResult>, BenchError> {
    let mut results = Vec::new();
    for (hz, cycles) in [(50, config.cycles_50hz), (500, config.cycles_500hz)] {
        for loaded in [false, true] {
            for rt in [RtSettings::OFF, config.rt] {
                results.push(measure_loop(
                    peer_exe,
                    &LoopConfig {
                        hz,
                        cycles,
                        loaded,
                        rt,
                        work: config.work,
                    },
                )?);
            }
        }
    }
    Ok(results)
}

/// The CPU a load should take: the last one, unless the loop is pinned there.
fn load_cpu(rt: &RtSettings) -> usize {
    let cpus = std::thread::available_parallelism().map_or(1, |n| n.get());
    let last = cpus - 1;
    if rt.cpu == Some(last) { 0 } else { last }
}

/// Runs one loop configuration in a peer process (with a load peer when `loaded`).
pub fn measure_loop(peer_exe: &Path, config: &LoopConfig) -> Result<LoopResult, BenchError> {
    let load_cpu = config.loaded.then(|| load_cpu(&config.rt));
    let load = match load_cpu {
        Some(cpu) => Some(Peer::spawn(
            peer_exe,
            &["spin".to_owned(), "--cpu".to_owned(), cpu.to_string()],
        )?),
        None => None,
    };
    let args = vec![
        "loop".to_owned(),
        "--hz".to_owned(),
        config.hz.to_string(),
        "--cycles".to_owned(),
        config.cycles.to_string(),
        "--rt".to_owned(),
        config.rt.to_string(),
        "--work-us".to_owned(),
        config.work.as_micros().to_string(),
    ];
    let (mut peer, _) = Peer::spawn(peer_exe, &args)?;
    let period = Duration::from_secs(1) / config.hz.max(1);
    let expected = period * u32::try_from(config.cycles).unwrap_or(u32::MAX);
    let line = peer.expect("result", expected + Duration::from_secs(30))?;
    peer.finish_ok(Duration::from_secs(5))?;
    drop(load);
    let ns = |key: &str| field::<u64>(&line, key).map(Duration::from_nanos);
    let summary = LoopSummary {
        period,
        count: field(&line, "count")?,
        p50: ns("p50_ns")?,
        p99: ns("p99_ns")?,
        p999: ns("p999_ns")?,
        max: ns("max_ns")?,
        mean: ns("mean_ns")?,
        overruns: field(&line, "overruns")?,
        early: field(&line, "early")?,
    };
    let rt_report: Vec<String> = peer
        .notes()
        .iter()
        .filter_map(|l| l.strip_prefix("rt ").map(str::to_owned))
        .collect();
    Ok(LoopResult {
        config: *config,
        summary,
        fifo_applied: field::<u8>(&line, "fifo")? == 1,
        policy: field(&line, "policy")?,
        minor_faults: field(&line, "minflt")?,
        involuntary_switches: field(&line, "nivcsw")?,
        run_delay_ns: field::<i64>(&line, "run_delay_ns")
            .ok()
            .and_then(|v| u64::try_from(v).ok()),
        rt_report,
        load_cpu,
    })
}

/// The peer side of `loop`: applies `rt` to this (main) thread, prints the report as `rt ...`
/// lines, runs the loop and prints one `result` line.
pub fn run_loop(hz: u32, cycles: usize, rt_settings: &RtSettings, work: Duration) {
    let report = rt::apply(rt_settings);
    if !rt_settings.is_off() {
        for line in report.to_string().lines() {
            println!("rt {line}");
        }
    }
    let fifo = u8::from(report.applied(RtStep::SchedFifo));
    let policy = rt::current_policy();
    println!("ready");
    let clock = WallClock;
    let period = Duration::from_secs(1) / hz.max(1);
    let mut stats = LoopStats::new(period);
    let delay_before = run_delay_ns();
    let before = ThreadUsage::now();
    let mut deadline = clock.now() + period;
    for _ in 0..cycles {
        clock.sleep_until(deadline);
        let woke = clock.now();
        stats.record(deadline, woke);
        // The cycle's work: busy for `work` (wall time, so a preemption does not stretch it).
        while clock.now().saturating_sub(woke) < work {
            std::hint::spin_loop();
        }
        let next = deadline + period;
        stats.record_end(clock.now(), next);
        deadline = next;
    }
    let usage = ThreadUsage::now().since(&before);
    let run_delay = match (delay_before, run_delay_ns()) {
        (Some(a), Some(b)) => i64::try_from(b.saturating_sub(a)).unwrap_or(i64::MAX),
        _ => -1,
    };
    let s = stats.summary();
    let ns = |d: Duration| d.as_nanos();
    println!(
        "result count={} p50_ns={} p99_ns={} p999_ns={} max_ns={} mean_ns={} overruns={} early={} fifo={fifo} policy={policy} minflt={} nivcsw={} run_delay_ns={run_delay}",
        s.count,
        ns(s.p50),
        ns(s.p99),
        ns(s.p999),
        ns(s.max),
        ns(s.mean),
        s.overruns,
        s.early,
        usage.minor_faults,
        usage.involuntary_switches
    );
}

/// Nanoseconds the calling thread has spent runnable, waiting for a CPU (the second field of
/// `/proc/thread-self/schedstat`).
fn run_delay_ns() -> Option<u64> {
    std::fs::read_to_string("/proc/thread-self/schedstat")
        .ok()?
        .split_whitespace()
        .nth(1)?
        .parse()
        .ok()
}

/// The peer side of `spin`: pins itself to `cpu` and burns it until stdin closes.
pub fn run_spin(cpu: usize) {
    let report = rt::apply(&RtSettings {
        cpu: Some(cpu),
        ..RtSettings::OFF
    });
    for line in report.to_string().lines() {
        println!("rt {line}");
    }
    let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let flag = std::sync::Arc::clone(&stop);
    std::thread::spawn(move || {
        let mut sink = Vec::new();
        let _ = std::io::Read::read_to_end(&mut std::io::stdin(), &mut sink);
        flag.store(true, std::sync::atomic::Ordering::Relaxed);
    });
    println!("ready");
    let mut x = 0u64;
    while !stop.load(std::sync::atomic::Ordering::Relaxed) {
        for _ in 0..10_000 {
            x = std::hint::black_box(x.wrapping_mul(6364136223846793005).wrapping_add(1));
        }
    }
}
