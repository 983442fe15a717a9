//! Real-time hygiene for a cyclic control thread: lock and pre-fault memory, shrink the timer
//! slack, run under `SCHED_FIFO`, pin to a CPU ([`RtSettings`], [`apply`]); and measure the loop
//! that results ([`LoopStats`]: lateness histogram, overruns, percentiles, no allocation).
//!
//! Every step the system refuses is reported, never fatal: a loop without real-time rights
//! still runs, and the [`RtReport`] says which call was refused, why, and what to grant.
//!
//! ```no_run
//! use std::time::Duration;
//! use grop_clock::{Clock, WallClock};
//! use grop_clock::rt::{self, LoopStats, RtSettings};
//!
//! let settings: RtSettings = "fifo=50,cpu=1,lock,slack=1".parse()?; // or "on"
//! let report = rt::apply(&settings); // on the loop's own thread: priority, slack and CPU are per thread
//! eprintln!("{report}");
//! let period = Duration::from_millis(20);
//! let mut stats = LoopStats::new(period);
//! let mut deadline = WallClock.now() + period;
//! for _ in 0..50 {
//!     WallClock.sleep_until(deadline);
//!     stats.record(deadline, WallClock.now());
//!     // ... the cycle's work ...
//!     stats.record_end(WallClock.now(), deadline + period);
//!     deadline += period;
//! }
//! println!("{}", stats.summary());
//! # Ok::<(), grop_clock::rt::RtSpecError>(())
//! ```
#![allow(
    unsafe_code,
    reason = "mlockall, sched_setscheduler, sched_setaffinity, mallopt, getrlimit: the real-time settings"
)]

use core::fmt;
use std::str::FromStr;
use std::time::Duration;

/// `SCHED_FIFO` priority of the `on` preset: 50, the priority PREEMPT_RT gives threaded
/// interrupt handlers (go above it only when the loop must preempt device interrupts).
pub const DEFAULT_FIFO_PRIORITY: i32 = 50;
/// Stack the `on` preset pre-faults: 256 KiB, well inside a spawned thread's 2 MiB.
pub const DEFAULT_PREFAULT_STACK_BYTES: usize = 256 * 1024;
/// Heap the `on` preset pre-faults and keeps: 16 MiB.
pub const DEFAULT_PREFAULT_HEAP_BYTES: usize = 16 * 1024 * 1024;
/// Largest CPU index `sched_setaffinity` takes through a fixed `cpu_set_t` (`CPU_SETSIZE`).
pub const MAX_CPU_INDEX: usize = 1023;
/// Largest pre-fault size accepted in a spec: 1 GiB.
pub const MAX_PREFAULT_BYTES: usize = 1 << 30;
/// Stack left untouched below the pre-faulted region, so pre-faulting never reaches the guard
/// page.
const STACK_MARGIN_BYTES: usize = 64 * 1024;
/// One frame of the stack pre-fault recursion.
const STACK_CHUNK_BYTES: usize = 16 * 1024;

/// What to do to the calling thread (and, for memory, the process) before a real-time loop.
/// `Default` is everything off.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct RtSettings {
    /// `mlockall(MCL_CURRENT | MCL_FUTURE)`: no page of the process is ever paged out, and new
    /// mappings are faulted in when made rather than on first touch in the loop.
    pub lock_memory: bool,
    /// Touch this much of the calling thread's stack now, so the loop's deeper calls do not
    /// fault (clamped to what the stack has left, minus a margin).
    pub prefault_stack_bytes: usize,
    /// Allocate, touch and free this much heap with glibc told to keep freed memory
    /// (`M_TRIM_THRESHOLD = -1`, `M_MMAP_MAX = 0`), so later allocations reuse faulted pages.
    pub prefault_heap_bytes: usize,
    /// `prctl(PR_SET_TIMERSLACK)` in nanoseconds for the calling thread (the default 50 us
    /// lets the kernel delay every wake-up by up to that much to batch timers). At least 1.
    pub timer_slack_ns: Option<u64>,
    /// Run the calling thread under `SCHED_FIFO` at this priority (1..=99).
    pub fifo_priority: Option<i32>,
    /// Pin the calling thread to this CPU.
    pub cpu: Option<usize>,
}

impl RtSettings {
    /// The `on` preset: lock memory, pre-fault 256 KiB of stack and 16 MiB of heap, timer slack
    /// 1 ns, `SCHED_FIFO` 50; no CPU pinning (which CPU is the deployment's choice).
    pub const ON: Self = Self {
        lock_memory: true,
        prefault_stack_bytes: DEFAULT_PREFAULT_STACK_BYTES,
        prefault_heap_bytes: DEFAULT_PREFAULT_HEAP_BYTES,
        timer_slack_ns: Some(1),
        fifo_priority: Some(DEFAULT_FIFO_PRIORITY),
        cpu: None,
    };

    /// Everything off (same as `Default`).
    pub const OFF: Self = Self {
        lock_memory: false,
        prefault_stack_bytes: 0,
        prefault_heap_bytes: 0,
        timer_slack_ns: None,
        fifo_priority: None,
        cpu: None,
    };

    /// Parses a spec: comma-separated items, applied left to right over "everything off".
    ///
    /// | item | meaning |
    /// |---|---|
    /// | `on` | the [`RtSettings::ON`] preset (later items override it: `on,cpu=1`) |
    /// | `off` | everything off |
    /// | `lock` | `mlockall` |
    /// | `prefault` | pre-fault the preset's stack and heap sizes |
    /// | `stack=SIZE`, `heap=SIZE` | pre-fault that much (bytes, or with `K`/`M`/`G`) |
    /// | `slack=NS` | timer slack in ns (>= 1) |
    /// | `fifo=PRIO` | `SCHED_FIFO` at 1..=99 |
    /// | `cpu=N` | pin to CPU N |
    #[allow(
        clippy::too_many_lines,
        reason = "one arm per setting of the spec string"
    )]
    pub fn parse(spec: &str) -> Result<Self, RtSpecError> {
        let spec = spec.trim();
        if spec.is_empty() {
            return Err(RtSpecError::Empty);
        }
        let mut settings = Self::OFF;
        let mut seen: [Option<&str>; 8] = [None; 8];
        for item in spec.split(',') {
            let item = item.trim();
            if item.is_empty() {
                return Err(RtSpecError::EmptyItem);
            }
            let (key, value) = match item.split_once('=') {
                Some((k, v)) => (k.trim(), Some(v.trim())),
                None => (item, None),
            };
            let slot = match key {
                "on" | "off" => None,
                "lock" => Some(0),
                "prefault" => Some(1),
                "stack" => Some(2),
                "heap" => Some(3),
                "slack" => Some(4),
                "fifo" => Some(5),
                "cpu" => Some(6),
                _ => {
                    return Err(RtSpecError::UnknownItem {
                        item: item.to_owned(),
                    });
                }
            };
            if let Some(slot) = slot {
                if seen[slot].is_some() {
                    return Err(RtSpecError::Duplicate {
                        key: key.to_owned(),
                    });
                }
                seen[slot] = Some(key);
            }
            let flag = |settings: Self| match value {
                None => Ok(settings),
                Some(_) => Err(RtSpecError::UnexpectedValue {
                    key: key.to_owned(),
                }),
            };
            let needed = || {
                value
                    .filter(|v| !v.is_empty())
                    .ok_or_else(|| RtSpecError::MissingValue {
                        key: key.to_owned(),
                    })
            };
            settings = match key {
                "on" => flag(Self::ON)?,
                "off" => flag(Self::OFF)?,
                "lock" => flag(Self {
                    lock_memory: true,
                    ..settings
                })?,
                "prefault" => flag(Self {
                    prefault_stack_bytes: DEFAULT_PREFAULT_STACK_BYTES,
                    prefault_heap_bytes: DEFAULT_PREFAULT_HEAP_BYTES,
                    ..settings
                })?,
                "stack" => Self {
                    prefault_stack_bytes: parse_size(key, needed()?)?,
                    ..settings
                },
                "heap" => Self {
                    prefault_heap_bytes: parse_size(key, needed()?)?,
                    ..settings
                },
                "slack" => {
                    let ns = parse_number(key, needed()?)?;
                    if ns == 0 {
                        return Err(RtSpecError::OutOfRange {
                            key: key.to_owned(),
                            value: 0,
                            min: 1,
                            max: u64::MAX,
                        });
                    }
                    Self {
                        timer_slack_ns: Some(ns),
                        ..settings
                    }
                }
                "fifo" => {
                    let prio = parse_number(key, needed()?)?;
                    if !(1..=99).contains(&prio) {
                        return Err(RtSpecError::OutOfRange {
                            key: key.to_owned(),
                            value: prio,
                            min: 1,
                            max: 99,
                        });
                    }
                    Self {
                        // In 1..=99: fits.
                        fifo_priority: Some(prio as i32),
                        ..settings
                    }
                }
                _ => {
                    // "cpu", the only key left.
                    let cpu = parse_number(key, needed()?)?;
                    if cpu > MAX_CPU_INDEX as u64 {
                        return Err(RtSpecError::OutOfRange {
                            key: key.to_owned(),
                            value: cpu,
                            min: 0,
                            max: MAX_CPU_INDEX as u64,
                        });
                    }
                    Self {
                        cpu: Some(cpu as usize),
                        ..settings
                    }
                }
            };
        }
        Ok(settings)
    }

    /// True when nothing is asked for.
    pub fn is_off(&self) -> bool {
        *self == Self::OFF
    }
}

impl FromStr for RtSettings {
    type Err = RtSpecError;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Self::parse(s)
    }
}

impl fmt::Display for RtSettings {
    /// The shortest spec that parses back to these settings (`off`, `on`, `on,cpu=1`,
    /// `lock,heap=64M,fifo=80`, ...).
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.is_off() {
            return f.write_str("off");
        }
        let mut items: Vec<String> = Vec::new();
        let preset = Self {
            cpu: self.cpu,
            ..Self::ON
        };
        if *self == preset {
            items.push("on".to_owned());
        } else {
            if self.lock_memory {
                items.push("lock".to_owned());
            }
            if self.prefault_stack_bytes == DEFAULT_PREFAULT_STACK_BYTES
                && self.prefault_heap_bytes == DEFAULT_PREFAULT_HEAP_BYTES
            {
                items.push("prefault".to_owned());
            } else {
                if self.prefault_stack_bytes > 0 {
                    items.push(format!("stack={}", size_text(self.prefault_stack_bytes)));
                }
                if self.prefault_heap_bytes > 0 {
                    items.push(format!("heap={}", size_text(self.prefault_heap_bytes)));
                }
            }
            if let Some(ns) = self.timer_slack_ns {
                items.push(format!("slack={ns}"));
            }
            if let Some(p) = self.fifo_priority {
                items.push(format!("fifo={p}"));
            }
        }
        if let Some(cpu) = self.cpu {
            items.push(format!("cpu={cpu}"));
        }
        f.write_str(&items.join(","))
    }
}

/// Bytes with the largest exact K/M/G suffix.
fn size_text(bytes: usize) -> String {
    for (shift, suffix) in [(30, "G"), (20, "M"), (10, "K")] {
        if bytes >= 1 << shift && bytes % (1 << shift) == 0 {
            return format!("{}{suffix}", bytes >> shift);
        }
    }
    bytes.to_string()
}

/// Why an `--rt` spec was refused.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum RtSpecError {
    /// The spec is empty.
    #[error("real-time spec is empty (try `on`, `off` or e.g. `fifo=50,cpu=1,lock,slack=1`)")]
    Empty,
    /// Two commas in a row, or a leading/trailing comma.
    #[error("real-time spec has an empty item (stray comma)")]
    EmptyItem,
    /// An item that is none of the known ones.
    #[error(
        "real-time spec item {item:?} is unknown (known: on, off, lock, prefault, stack=SIZE, heap=SIZE, slack=NS, fifo=1..99, cpu=N)"
    )]
    UnknownItem {
        /// The item.
        item: String,
    },
    /// A key that needs a value has none (`fifo`, `fifo=`).
    #[error("real-time spec item {key:?} needs a value ({key}=...)")]
    MissingValue {
        /// The key.
        key: String,
    },
    /// A flag was given a value (`lock=1`).
    #[error("real-time spec item {key:?} takes no value")]
    UnexpectedValue {
        /// The key.
        key: String,
    },
    /// The same key twice.
    #[error("real-time spec item {key:?} is given twice")]
    Duplicate {
        /// The key.
        key: String,
    },
    /// A value that is not a number (or size).
    #[error("real-time spec {key}={value:?} is not a number{hint}")]
    BadNumber {
        /// The key.
        key: String,
        /// The value.
        value: String,
        /// What sizes may look like, for size keys.
        hint: &'static str,
    },
    /// A number outside its range.
    #[error("real-time spec {key}={value} is out of range {min}..={max}")]
    OutOfRange {
        /// The key.
        key: String,
        /// The value.
        value: u64,
        /// Smallest allowed.
        min: u64,
        /// Largest allowed.
        max: u64,
    },
}

fn parse_number(key: &str, value: &str) -> Result<u64, RtSpecError> {
    value.parse::<u64>().map_err(|_| RtSpecError::BadNumber {
        key: key.to_owned(),
        value: value.to_owned(),
        hint: "",
    })
}

fn parse_size(key: &str, value: &str) -> Result<usize, RtSpecError> {
    let bad = || RtSpecError::BadNumber {
        key: key.to_owned(),
        value: value.to_owned(),
        hint: " (bytes, or with a K, M or G suffix)",
    };
    let (digits, scale) = match value.as_bytes().last() {
        Some(b'K' | b'k') => (&value[..value.len() - 1], 1u64 << 10),
        Some(b'M' | b'm') => (&value[..value.len() - 1], 1 << 20),
        Some(b'G' | b'g') => (&value[..value.len() - 1], 1 << 30),
        _ => (value, 1),
    };
    let n: u64 = digits.parse().map_err(|_| bad())?;
    let bytes = n.checked_mul(scale).ok_or_else(bad)?;
    if bytes > MAX_PREFAULT_BYTES as u64 {
        return Err(RtSpecError::OutOfRange {
            key: key.to_owned(),
            value: bytes,
            min: 0,
            max: MAX_PREFAULT_BYTES as u64,
        });
    }
    Ok(bytes as usize)
}

/// One real-time setting, as [`RtReport`] names it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RtStep {
    /// `mlockall`.
    LockMemory,
    /// Stack pre-fault.
    PrefaultStack,
    /// Heap pre-fault.
    PrefaultHeap,
    /// `PR_SET_TIMERSLACK`.
    TimerSlack,
    /// `SCHED_FIFO`.
    SchedFifo,
    /// CPU affinity.
    CpuAffinity,
}

impl RtStep {
    /// Every step, in the order [`apply`] takes them.
    pub const ALL: [RtStep; 6] = [
        RtStep::LockMemory,
        RtStep::PrefaultStack,
        RtStep::PrefaultHeap,
        RtStep::TimerSlack,
        RtStep::SchedFifo,
        RtStep::CpuAffinity,
    ];

    fn label(self) -> &'static str {
        match self {
            RtStep::LockMemory => "lock memory",
            RtStep::PrefaultStack => "pre-fault stack",
            RtStep::PrefaultHeap => "pre-fault heap",
            RtStep::TimerSlack => "timer slack",
            RtStep::SchedFifo => "SCHED_FIFO",
            RtStep::CpuAffinity => "CPU affinity",
        }
    }
}

/// What happened to one setting.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum RtOutcome {
    /// Not asked for.
    NotRequested,
    /// Done; the text says what exactly (sizes, values).
    Applied(String),
    /// The system refused; the loop runs without it.
    Refused(RtRefusal),
}

/// A refused system call: which, the errno, and what to do about it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RtRefusal {
    /// The call, e.g. `sched_setscheduler(SCHED_FIFO, 50)`.
    pub call: String,
    /// errno (0 when the refusal was ours, e.g. a CPU index beyond the machine).
    pub errno: i32,
    /// What to do, e.g. "run as root or grant CAP_SYS_NICE".
    pub advice: String,
}

impl fmt::Display for RtRefusal {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.errno == 0 {
            write!(f, "{}: {}", self.call, self.advice)
        } else {
            write!(
                f,
                "{} refused ({}: {}): {}",
                self.call,
                errno_name(self.errno),
                std::io::Error::from_raw_os_error(self.errno),
                self.advice
            )
        }
    }
}

/// The outcome of every setting of one [`apply`].
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RtReport {
    /// The settings asked for.
    pub settings: RtSettings,
    /// One outcome per [`RtStep::ALL`], in that order.
    pub outcomes: [(RtStep, RtOutcome); 6],
}

impl RtReport {
    /// The outcome of `step`.
    pub fn outcome(&self, step: RtStep) -> &RtOutcome {
        // ALL covers every step, so the search always finds it; the fallback keeps it total.
        self.outcomes
            .iter()
            .find(|(s, _)| *s == step)
            .map(|(_, o)| o)
            .unwrap_or(&RtOutcome::NotRequested)
    }

    /// Whether `step` was applied.
    pub fn applied(&self, step: RtStep) -> bool {
        matches!(self.outcome(step), RtOutcome::Applied(_))
    }

    /// The refused steps.
    pub fn refusals(&self) -> impl Iterator<Item = (RtStep, &RtRefusal)> {
        self.outcomes.iter().filter_map(|(s, o)| match o {
            RtOutcome::Refused(r) => Some((*s, r)),
            _ => None,
        })
    }

    /// True when every requested step was applied.
    pub fn all_applied(&self) -> bool {
        self.refusals().next().is_none()
    }
}

impl fmt::Display for RtReport {
    /// One line per setting: `applied (...)`, `refused: ...` or `off`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (i, (step, outcome)) in self.outcomes.iter().enumerate() {
            if i > 0 {
                writeln!(f)?;
            }
            match outcome {
                RtOutcome::NotRequested => write!(f, "{}: off", step.label())?,
                RtOutcome::Applied(what) => write!(f, "{}: applied ({what})", step.label())?,
                RtOutcome::Refused(r) => write!(f, "{}: refused: {r}", step.label())?,
            }
        }
        Ok(())
    }
}

/// Applies `settings` to the calling thread (priority, slack, affinity, stack) and process
/// (memory locking, heap). Call it on the loop's thread before the loop. Never fails: what the
/// system refuses is in the report.
pub fn apply(settings: &RtSettings) -> RtReport {
    let lock = if settings.lock_memory {
        lock_memory()
    } else {
        RtOutcome::NotRequested
    };
    let stack = if settings.prefault_stack_bytes > 0 {
        prefault_stack(settings.prefault_stack_bytes)
    } else {
        RtOutcome::NotRequested
    };
    let heap = if settings.prefault_heap_bytes > 0 {
        prefault_heap(settings.prefault_heap_bytes)
    } else {
        RtOutcome::NotRequested
    };
    let slack = match settings.timer_slack_ns {
        Some(ns) => set_timer_slack(ns),
        None => RtOutcome::NotRequested,
    };
    let fifo = match settings.fifo_priority {
        Some(p) => set_fifo(p),
        None => RtOutcome::NotRequested,
    };
    let cpu = match settings.cpu {
        Some(cpu) => pin_to_cpu(cpu),
        None => RtOutcome::NotRequested,
    };
    RtReport {
        settings: *settings,
        outcomes: [
            (RtStep::LockMemory, lock),
            (RtStep::PrefaultStack, stack),
            (RtStep::PrefaultHeap, heap),
            (RtStep::TimerSlack, slack),
            (RtStep::SchedFifo, fifo),
            (RtStep::CpuAffinity, cpu),
        ],
    }
}

/// The scheduling policy of the calling thread, as `sched_getscheduler` names it
/// (`SCHED_OTHER`, `SCHED_FIFO`, ...).
pub fn current_policy() -> &'static str {
    // SAFETY: no pointers; pid 0 is the calling thread.
    match unsafe { libc::sched_getscheduler(0) } {
        libc::SCHED_OTHER => "SCHED_OTHER",
        libc::SCHED_FIFO => "SCHED_FIFO",
        libc::SCHED_RR => "SCHED_RR",
        libc::SCHED_BATCH => "SCHED_BATCH",
        libc::SCHED_IDLE => "SCHED_IDLE",
        _ => "unknown",
    }
}

fn last_errno() -> i32 {
    std::io::Error::last_os_error().raw_os_error().unwrap_or(0)
}

fn refused(call: impl Into<String>, errno: i32, advice: impl Into<String>) -> RtOutcome {
    RtOutcome::Refused(RtRefusal {
        call: call.into(),
        errno,
        advice: advice.into(),
    })
}

/// The symbolic name of the errnos these calls return.
fn errno_name(errno: i32) -> &'static str {
    match errno {
        libc::EPERM => "EPERM",
        libc::ENOMEM => "ENOMEM",
        libc::EINVAL => "EINVAL",
        libc::EAGAIN => "EAGAIN",
        libc::ESRCH => "ESRCH",
        libc::EFAULT => "EFAULT",
        libc::ENOSYS => "ENOSYS",
        _ => "errno",
    }
}

fn rlimit(resource: libc::__rlimit_resource_t) -> Option<u64> {
    let mut limit = libc::rlimit {
        rlim_cur: 0,
        rlim_max: 0,
    };
    // SAFETY: `limit` is a valid, writable rlimit.
    let rc = unsafe { libc::getrlimit(resource, &mut limit) };
    (rc == 0).then_some(limit.rlim_cur)
}

fn describe_limit(value: Option<u64>, unit: u64, suffix: &str) -> String {
    match value {
        Some(libc::RLIM_INFINITY) => "unlimited".to_owned(),
        Some(v) => format!("{}{suffix}", v / unit),
        None => "unknown".to_owned(),
    }
}

fn lock_memory() -> RtOutcome {
    // SAFETY: no pointers.
    let rc = unsafe { libc::mlockall(libc::MCL_CURRENT | libc::MCL_FUTURE) };
    if rc == 0 {
        return RtOutcome::Applied("mlockall(MCL_CURRENT|MCL_FUTURE)".to_owned());
    }
    let errno = last_errno();
    let limit = describe_limit(rlimit(libc::RLIMIT_MEMLOCK), 1024, " KiB");
    refused(
        "mlockall(MCL_CURRENT|MCL_FUTURE)",
        errno,
        format!(
            "RLIMIT_MEMLOCK is {limit}: run as root, grant CAP_IPC_LOCK, or raise `memlock` in \
             /etc/security/limits.conf (or LimitMEMLOCK= in the systemd unit)"
        ),
    )
}

/// The stack still available below the current frame of the calling thread, if known.
fn stack_room() -> Option<usize> {
    // SAFETY: pthread_attr_t is plain data that pthread_getattr_np initialises; it is destroyed
    // after use. The pointers passed are valid locals.
    unsafe {
        let mut attr: libc::pthread_attr_t = std::mem::zeroed();
        if libc::pthread_getattr_np(libc::pthread_self(), &mut attr) != 0 {
            return None;
        }
        let mut base: *mut libc::c_void = std::ptr::null_mut();
        let mut size: libc::size_t = 0;
        let rc = libc::pthread_attr_getstack(&attr, &mut base, &mut size);
        libc::pthread_attr_destroy(&mut attr);
        if rc != 0 {
            return None;
        }
        // The stack grows down from base + size to base; a local marks where we are.
        let here = std::ptr::addr_of!(attr) as usize;
        here.checked_sub(base as usize)
    }
}

fn prefault_stack(wanted: usize) -> RtOutcome {
    let Some(room) = stack_room() else {
        return refused(
            "pthread_getattr_np",
            last_errno(),
            "the stack size is unknown, so the stack was not pre-faulted",
        );
    };
    let usable = room.saturating_sub(STACK_MARGIN_BYTES);
    let bytes = wanted.min(usable);
    let chunks = bytes / STACK_CHUNK_BYTES;
    touch_stack(chunks);
    let touched = chunks * STACK_CHUNK_BYTES;
    if touched < wanted {
        RtOutcome::Applied(format!(
            "{} KiB touched; {} KiB asked, the thread's stack has {} KiB left",
            touched / 1024,
            wanted / 1024,
            room / 1024
        ))
    } else {
        RtOutcome::Applied(format!("{} KiB touched", touched / 1024))
    }
}

/// Touches `chunks` stack frames of [`STACK_CHUNK_BYTES`] each (recursion that the optimiser
/// cannot fold: the buffer escapes through `black_box` after the inner call).
#[inline(never)]
fn touch_stack(chunks: usize) {
    if chunks == 0 {
        return;
    }
    let mut buffer = [0u8; STACK_CHUNK_BYTES];
    for i in (0..STACK_CHUNK_BYTES).step_by(4096) {
        buffer[i] = 1;
    }
    std::hint::black_box(&mut buffer);
    touch_stack(chunks - 1);
    std::hint::black_box(&buffer);
}

fn prefault_heap(bytes: usize) -> RtOutcome {
    // Keep freed memory in the heap and serve large blocks from it too, so that the pages
    // faulted here are the ones later allocations get (glibc; the RT wiki's recipe).
    // SAFETY: mallopt takes plain integers.
    let kept = unsafe {
        libc::mallopt(libc::M_TRIM_THRESHOLD, -1) == 1 && libc::mallopt(libc::M_MMAP_MAX, 0) == 1
    };
    let mut block: Vec<u8> = Vec::new();
    if block.try_reserve_exact(bytes).is_err() {
        return refused(
            format!("malloc({bytes})"),
            libc::ENOMEM,
            "not enough memory to pre-fault the heap: ask for less (heap=SIZE)",
        );
    }
    let ptr = block.as_mut_ptr();
    for offset in (0..bytes).step_by(4096) {
        // SAFETY: offset < bytes <= capacity: inside the reserved block; a volatile write so
        // the touch is not optimised away.
        unsafe { ptr.add(offset).write_volatile(0) };
    }
    drop(block);
    if kept {
        RtOutcome::Applied(format!(
            "{} KiB touched and kept by malloc (M_TRIM_THRESHOLD=-1, M_MMAP_MAX=0)",
            bytes / 1024
        ))
    } else {
        RtOutcome::Applied(format!(
            "{} KiB touched; mallopt refused, so malloc may return them to the system",
            bytes / 1024
        ))
    }
}

fn set_timer_slack(ns: u64) -> RtOutcome {
    let ns = ns.max(1);
    let value = libc::c_ulong::try_from(ns).unwrap_or(libc::c_ulong::MAX);
    // SAFETY: PR_SET_TIMERSLACK takes one unsigned long.
    let rc = unsafe { libc::prctl(libc::PR_SET_TIMERSLACK, value, 0, 0, 0) };
    if rc == 0 {
        RtOutcome::Applied(format!("{ns} ns for this thread (default 50000 ns)"))
    } else {
        refused(
            format!("prctl(PR_SET_TIMERSLACK, {ns})"),
            last_errno(),
            "the kernel refused the timer slack; wake-ups keep the default 50 us slack",
        )
    }
}

fn set_fifo(priority: i32) -> RtOutcome {
    let param = libc::sched_param {
        sched_priority: priority,
    };
    // SAFETY: `param` is a valid sched_param; pid 0 is the calling thread.
    let rc = unsafe { libc::sched_setscheduler(0, libc::SCHED_FIFO, &param) };
    if rc == 0 {
        return RtOutcome::Applied(format!("priority {priority} for this thread"));
    }
    let errno = last_errno();
    let rtprio = describe_limit(rlimit(libc::RLIMIT_RTPRIO), 1, "");
    let advice = match errno {
        libc::EPERM => format!(
            "run as root or grant CAP_SYS_NICE (setcap cap_sys_nice+ep BINARY), or set `rtprio` \
             >= {priority} in /etc/security/limits.conf (RLIMIT_RTPRIO is {rtprio}); in a \
             container, allow SYS_NICE"
        ),
        libc::EINVAL => format!("priority {priority} is outside SCHED_FIFO's 1..=99"),
        _ => "the loop runs under SCHED_OTHER".to_owned(),
    };
    refused(
        format!("sched_setscheduler(SCHED_FIFO, {priority})"),
        errno,
        advice,
    )
}

fn pin_to_cpu(cpu: usize) -> RtOutcome {
    if cpu > MAX_CPU_INDEX {
        return refused(
            format!("sched_setaffinity(cpu {cpu})"),
            0,
            format!("CPU {cpu} is beyond CPU_SETSIZE ({})", MAX_CPU_INDEX + 1),
        );
    }
    // SAFETY: cpu_set_t is plain data; all-zero is the empty set; `cpu` is below CPU_SETSIZE
    // (checked above) so CPU_SET stays inside the set; the pointer passed is a valid local.
    let rc = unsafe {
        let mut set: libc::cpu_set_t = std::mem::zeroed();
        libc::CPU_SET(cpu, &mut set);
        libc::sched_setaffinity(0, std::mem::size_of::<libc::cpu_set_t>(), &set)
    };
    if rc == 0 {
        return RtOutcome::Applied(format!("this thread runs on CPU {cpu} only"));
    }
    let errno = last_errno();
    let online = std::thread::available_parallelism()
        .map(|n| n.get().to_string())
        .unwrap_or_else(|_| "?".to_owned());
    let advice = match errno {
        libc::EINVAL => format!(
            "CPU {cpu} is not online or not in this process's cpuset ({online} CPUs available): \
             pick another (cpu=N)"
        ),
        libc::EPERM => "not allowed to change this thread's affinity".to_owned(),
        _ => "the loop runs on any CPU".to_owned(),
    };
    refused(format!("sched_setaffinity(cpu {cpu})"), errno, advice)
}

/// Lateness histogram: 1 us buckets up to this many microseconds ...
const FINE_BUCKETS: usize = 2000;
/// ... then 100 us buckets up to 100 ms ...
const COARSE_BUCKET_US: u64 = 100;
const COARSE_BUCKETS: usize = 980;
/// ... then one bucket for everything later (its exact maximum is kept apart).
const BUCKETS: usize = FINE_BUCKETS + COARSE_BUCKETS + 1;
const FINE_LIMIT_US: u64 = FINE_BUCKETS as u64;
const COARSE_LIMIT_US: u64 = FINE_LIMIT_US + COARSE_BUCKETS as u64 * COARSE_BUCKET_US;

/// Period and lateness recorder for a cyclic loop on absolute deadlines: fixed capacity, no
/// allocation (the histogram is an inline array, about 12 KiB), `Copy`-free but cheap to keep
/// in the loop's state.
///
/// Lateness is how long after its deadline a cycle woke; resolution 1 us up to 2 ms, 100 us
/// up to 100 ms, one bucket beyond; the maximum is exact. Percentiles report the upper edge of
/// the bucket holding the rank (never below the truth), capped at the exact maximum.
#[derive(Clone)]
pub struct LoopStats {
    period: Duration,
    buckets: [u32; BUCKETS],
    count: u64,
    overruns: u64,
    early: u64,
    max_ns: u64,
    sum_ns: u128,
}

impl fmt::Debug for LoopStats {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("LoopStats")
            .field("period", &self.period)
            .field("summary", &self.summary())
            .finish_non_exhaustive()
    }
}

/// Lateness percentiles and counters of a [`LoopStats`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct LoopSummary {
    /// The loop's period.
    pub period: Duration,
    /// Cycles recorded.
    pub count: u64,
    /// Median lateness.
    pub p50: Duration,
    /// 99th percentile lateness.
    pub p99: Duration,
    /// 99.9th percentile lateness.
    pub p999: Duration,
    /// Largest lateness (exact).
    pub max: Duration,
    /// Mean lateness.
    pub mean: Duration,
    /// Cycles whose work ended after the next deadline.
    pub overruns: u64,
    /// Wake-ups before the deadline (should be 0 with absolute sleeps; counted as lateness 0).
    pub early: u64,
}

impl fmt::Display for LoopSummary {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let us = |d: Duration| d.as_secs_f64() * 1e6;
        write!(
            f,
            "{} cycles of {:?}: lateness p50 {:.0} us, p99 {:.0} us, p99.9 {:.0} us, max {:.0} us, mean {:.1} us; {} overruns",
            self.count,
            self.period,
            us(self.p50),
            us(self.p99),
            us(self.p999),
            us(self.max),
            us(self.mean),
            self.overruns
        )?;
        if self.early > 0 {
            write!(f, ", {} early wake-ups", self.early)?;
        }
        Ok(())
    }
}

impl LoopStats {
    /// An empty recorder for a loop of `period`.
    pub fn new(period: Duration) -> Self {
        Self {
            period,
            buckets: [0; BUCKETS],
            count: 0,
            overruns: 0,
            early: 0,
            max_ns: 0,
            sum_ns: 0,
        }
    }

    /// Records one wake-up: the cycle's `deadline` and when it woke, on the same clock.
    pub fn record(&mut self, deadline: Duration, woke_at: Duration) {
        if woke_at < deadline {
            self.early += 1;
        }
        let late_ns =
            u64::try_from(woke_at.saturating_sub(deadline).as_nanos()).unwrap_or(u64::MAX);
        self.record_lateness_ns(late_ns);
    }

    /// Records one lateness value directly.
    pub fn record_lateness_ns(&mut self, late_ns: u64) {
        let index = bucket_of(late_ns);
        self.buckets[index] = self.buckets[index].saturating_add(1);
        self.count += 1;
        self.max_ns = self.max_ns.max(late_ns);
        self.sum_ns += u128::from(late_ns);
    }

    /// Counts one overrun: a cycle whose work ended after the next deadline.
    pub fn record_overrun(&mut self) {
        self.overruns += 1;
    }

    /// Records the end of a cycle's work; counts an overrun if it is after `next_deadline`.
    /// Returns whether it overran.
    pub fn record_end(&mut self, end: Duration, next_deadline: Duration) -> bool {
        let overran = end > next_deadline;
        if overran {
            self.record_overrun();
        }
        overran
    }

    /// Cycles recorded.
    pub fn count(&self) -> u64 {
        self.count
    }

    /// Overruns counted.
    pub fn overruns(&self) -> u64 {
        self.overruns
    }

    /// Largest lateness (exact).
    pub fn max(&self) -> Duration {
        Duration::from_nanos(self.max_ns)
    }

    /// The loop's period.
    pub fn period(&self) -> Duration {
        self.period
    }

    /// Lateness at percentile `p` (0..=100, clamped) by nearest rank; `None` before the first
    /// record. `p = 100` is the exact maximum.
    pub fn percentile(&self, p: f64) -> Option<Duration> {
        if self.count == 0 {
            return None;
        }
        let p = if p.is_nan() {
            100.0
        } else {
            p.clamp(0.0, 100.0)
        };
        if p >= 100.0 {
            return Some(self.max());
        }
        // Nearest rank, 1-based: ceil(p/100 * n), at least 1.
        let rank = ((p / 100.0) * self.count as f64).ceil().max(1.0) as u64;
        let mut seen = 0u64;
        for (index, &n) in self.buckets.iter().enumerate() {
            seen += u64::from(n);
            if seen >= rank {
                return Some(Duration::from_nanos(
                    bucket_upper_ns(index).min(self.max_ns),
                ));
            }
        }
        Some(self.max())
    }

    /// p50, p99, p99.9, max, mean and the counters.
    pub fn summary(&self) -> LoopSummary {
        let at = |p| self.percentile(p).unwrap_or_default();
        let mean_ns = if self.count == 0 {
            0
        } else {
            u64::try_from(self.sum_ns / u128::from(self.count)).unwrap_or(u64::MAX)
        };
        LoopSummary {
            period: self.period,
            count: self.count,
            p50: at(50.0),
            p99: at(99.0),
            p999: at(99.9),
            max: self.max(),
            mean: Duration::from_nanos(mean_ns),
            overruns: self.overruns,
            early: self.early,
        }
    }

    /// Forgets every record (keeps the period).
    pub fn reset(&mut self) {
        *self = Self::new(self.period);
    }
}

fn bucket_of(late_ns: u64) -> usize {
    let us = late_ns / 1000;
    if us < FINE_LIMIT_US {
        us as usize
    } else if us < COARSE_LIMIT_US {
        FINE_BUCKETS + ((us - FINE_LIMIT_US) / COARSE_BUCKET_US) as usize
    } else {
        BUCKETS - 1
    }
}

/// Upper edge (exclusive) of bucket `index`, ns; the overflow bucket has none (u64::MAX, which
/// the caller caps at the exact maximum).
fn bucket_upper_ns(index: usize) -> u64 {
    if index < FINE_BUCKETS {
        (index as u64 + 1) * 1000
    } else if index < BUCKETS - 1 {
        (FINE_LIMIT_US + (index - FINE_BUCKETS + 1) as u64 * COARSE_BUCKET_US) * 1000
    } else {
        u64::MAX
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn specs_parse() {
        assert_eq!(RtSettings::parse("off"), Ok(RtSettings::default()));
        assert_eq!(RtSettings::parse("on"), Ok(RtSettings::ON));
        assert_eq!(
            RtSettings::parse("fifo=50,cpu=1,lock,slack=1"),
            Ok(RtSettings {
                lock_memory: true,
                timer_slack_ns: Some(1),
                fifo_priority: Some(50),
                cpu: Some(1),
                ..RtSettings::OFF
            })
        );
        assert_eq!(
            RtSettings::parse(" on , cpu=0 "),
            Ok(RtSettings {
                cpu: Some(0),
                ..RtSettings::ON
            })
        );
        assert_eq!(
            RtSettings::parse("stack=64K,heap=2M"),
            Ok(RtSettings {
                prefault_stack_bytes: 64 * 1024,
                prefault_heap_bytes: 2 * 1024 * 1024,
                ..RtSettings::OFF
            })
        );
        assert_eq!(
            RtSettings::parse("prefault").map(|s| (s.prefault_stack_bytes, s.prefault_heap_bytes)),
            Ok((DEFAULT_PREFAULT_STACK_BYTES, DEFAULT_PREFAULT_HEAP_BYTES))
        );
        assert!(
            RtSettings::parse("on").is_ok_and(|s| s.cpu.is_none()),
            "on does not pin"
        );
        assert!(RtSettings::parse("off").is_ok_and(|s| s.is_off()));
    }

    #[test]
    fn specs_round_trip_through_display() {
        for spec in [
            "off",
            "on",
            "fifo=10,cpu=3",
            "lock,slack=1000",
            "on,cpu=1",
            "heap=1G",
            "stack=1000,heap=3K",
            "prefault,fifo=2",
        ] {
            let settings = RtSettings::parse(spec).unwrap();
            assert_eq!(settings.to_string(), spec, "shortest form");
            assert_eq!(
                RtSettings::parse(&settings.to_string()),
                Ok(settings),
                "{spec}"
            );
        }
    }

    #[test]
    fn bad_specs_give_named_errors() {
        use RtSpecError as E;
        let err = |s: &str| RtSettings::parse(s).unwrap_err();
        assert_eq!(err(""), E::Empty);
        assert_eq!(err("  "), E::Empty);
        assert_eq!(err("lock,,fifo=5"), E::EmptyItem);
        assert_eq!(err("lock,"), E::EmptyItem);
        assert!(matches!(err("turbo"), E::UnknownItem { item } if item == "turbo"));
        assert!(matches!(err("fifo"), E::MissingValue { key } if key == "fifo"));
        assert!(matches!(err("cpu="), E::MissingValue { .. }));
        assert!(matches!(err("lock=1"), E::UnexpectedValue { key } if key == "lock"));
        assert!(matches!(err("on=1"), E::UnexpectedValue { .. }));
        assert!(matches!(err("fifo=1,fifo=2"), E::Duplicate { key } if key == "fifo"));
        assert!(matches!(err("fifo=high"), E::BadNumber { .. }));
        assert!(matches!(err("fifo=-1"), E::BadNumber { .. }));
        assert!(matches!(err("fifo=0"), E::OutOfRange { value: 0, .. }));
        assert!(matches!(
            err("fifo=100"),
            E::OutOfRange {
                value: 100,
                max: 99,
                ..
            }
        ));
        assert!(matches!(err("slack=0"), E::OutOfRange { .. }));
        assert!(matches!(err("cpu=1024"), E::OutOfRange { .. }));
        assert!(matches!(err("heap=2G"), E::OutOfRange { .. }));
        assert!(matches!(err("heap=12Q"), E::BadNumber { .. }));
        assert!(matches!(err("stack=K"), E::BadNumber { .. }));
        assert!(matches!(
            err("heap=99999999999999999999G"),
            E::BadNumber { .. }
        ));
        // Every error says what it is about.
        for bad in ["", "x", "fifo", "lock=1", "fifo=0", "cpu=z"] {
            assert!(!err(bad).to_string().is_empty());
        }
    }

    #[test]
    fn percentiles_of_known_samples() {
        let mut s = LoopStats::new(Duration::from_millis(20));
        assert_eq!(s.percentile(50.0), None);
        assert_eq!(s.summary().count, 0);
        // 1..=100 us.
        for us in 1..=100u64 {
            s.record(
                Duration::from_secs(1),
                Duration::from_secs(1) + Duration::from_micros(us),
            );
        }
        let at = |p| s.percentile(p).unwrap().as_micros();
        // Buckets are [n, n+1) us, reported by their upper edge, capped at the maximum.
        assert_eq!(at(50.0), 51);
        assert_eq!(at(99.0), 100);
        assert_eq!(at(100.0), 100);
        assert_eq!(at(0.0), 2);
        let sum = s.summary();
        assert_eq!(sum.count, 100);
        assert_eq!(sum.max, Duration::from_micros(100));
        assert_eq!(sum.mean, Duration::from_nanos(50_500));
        assert!(sum.p50 <= sum.p99 && sum.p99 <= sum.p999 && sum.p999 <= sum.max);
    }

    #[test]
    fn coarse_and_overflow_buckets_and_counters() {
        let mut s = LoopStats::new(Duration::from_millis(2));
        s.record_lateness_ns(5_000); // 5 us
        s.record_lateness_ns(3_456_000); // 3.456 ms: coarse bucket 3.4..3.5 ms
        s.record_lateness_ns(250_000_000); // 250 ms: overflow bucket
        assert_eq!(s.percentile(33.0), Some(Duration::from_micros(6)));
        assert_eq!(s.percentile(60.0), Some(Duration::from_micros(3_500)));
        assert_eq!(s.percentile(99.0), Some(Duration::from_millis(250)));
        // Early wake-ups count as on time.
        s.record(Duration::from_secs(2), Duration::from_secs(1));
        assert_eq!(s.summary().early, 1);
        assert!(!s.record_end(Duration::from_millis(10), Duration::from_millis(12)));
        assert!(s.record_end(Duration::from_millis(13), Duration::from_millis(12)));
        s.record_overrun();
        assert_eq!(s.overruns(), 2);
        assert_eq!(s.count(), 4);
        s.reset();
        assert_eq!(s.count(), 0);
        assert_eq!(s.period(), Duration::from_millis(2));
        // Extreme values do not overflow anything.
        s.record(Duration::ZERO, Duration::MAX);
        assert_eq!(s.percentile(50.0), Some(Duration::from_nanos(u64::MAX)));
        assert_eq!(s.percentile(f64::NAN), Some(s.max()));
        assert_eq!(s.percentile(-3.0), Some(s.max()));
    }

    #[test]
    fn bucket_edges_are_consistent() {
        for ns in [
            0, 999, 1000, 1_999_999, 2_000_000, 2_099_999, 2_100_000, 99_999_999,
        ] {
            let b = bucket_of(ns);
            assert!(ns < bucket_upper_ns(b), "{ns} in bucket {b}");
            if b > 0 {
                assert!(ns >= bucket_upper_ns(b - 1), "{ns} above bucket {}", b - 1);
            }
        }
        assert_eq!(bucket_of(100_000_000), BUCKETS - 1);
        assert_eq!(bucket_of(u64::MAX), BUCKETS - 1);
    }

    #[test]
    fn applying_nothing_reports_nothing() {
        let report = apply(&RtSettings::OFF);
        assert!(report.all_applied());
        assert_eq!(report.to_string().lines().count(), 6);
        assert!(report.to_string().lines().all(|l| l.ends_with(": off")));
    }

    /// Steps that never need privileges: timer slack, a bounded stack pre-fault, a small heap
    /// pre-fault. Run on a thread of its own so the test runner's thread keeps its settings.
    #[test]
    fn unprivileged_steps_apply_on_a_thread() {
        let report = std::thread::spawn(|| {
            apply(&RtSettings {
                timer_slack_ns: Some(1),
                prefault_stack_bytes: 64 * 1024,
                prefault_heap_bytes: 1024 * 1024,
                ..RtSettings::OFF
            })
        })
        .join()
        .unwrap();
        assert!(report.applied(RtStep::TimerSlack), "{report}");
        assert!(report.applied(RtStep::PrefaultStack), "{report}");
        assert!(report.applied(RtStep::PrefaultHeap), "{report}");
        assert!(!report.applied(RtStep::SchedFifo));
        // A stack pre-fault bigger than the stack is clamped, not a crash.
        let big = std::thread::Builder::new()
            .stack_size(256 * 1024)
            .spawn(|| prefault_stack(64 * 1024 * 1024))
            .unwrap()
            .join()
            .unwrap();
        assert!(
            matches!(&big, RtOutcome::Applied(t) if t.contains("left")),
            "{big:?}"
        );
    }

    /// Whatever the privileges, FIFO and affinity give an outcome and a line each, never a
    /// panic; a refusal names the call and says what to do.
    #[test]
    fn privileged_steps_report_either_way() {
        let report = std::thread::spawn(|| {
            apply(&RtSettings {
                fifo_priority: Some(1),
                cpu: Some(MAX_CPU_INDEX),
                ..RtSettings::OFF
            })
        })
        .join()
        .unwrap();
        let text = report.to_string();
        assert!(text.contains("SCHED_FIFO: "), "{text}");
        if let RtOutcome::Refused(r) = report.outcome(RtStep::SchedFifo) {
            assert!(
                r.to_string().contains("CAP_SYS_NICE") || r.errno != libc::EPERM,
                "{r}"
            );
        }
        // No machine here has 1024 CPUs in its cpuset.
        if let RtOutcome::Refused(r) = report.outcome(RtStep::CpuAffinity) {
            assert!(r.to_string().contains("sched_setaffinity"), "{r}");
        }
        assert!(matches!(
            pin_to_cpu(MAX_CPU_INDEX + 1),
            RtOutcome::Refused(_)
        ));
    }

    #[test]
    fn refusals_read_well() {
        let r = RtRefusal {
            call: "sched_setscheduler(SCHED_FIFO, 50)".into(),
            errno: libc::EPERM,
            advice: "run as root or grant CAP_SYS_NICE".into(),
        };
        let text = r.to_string();
        assert!(text.contains("(EPERM: Operation not permitted"), "{text}");
        assert!(
            text.ends_with("run as root or grant CAP_SYS_NICE"),
            "{text}"
        );
    }
}
