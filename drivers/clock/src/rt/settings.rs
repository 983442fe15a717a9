//! The real-time settings and their spec string (`fifo=50,cpu=1,lock,slack=1`, `on`, `off`).

use core::fmt;
use std::str::FromStr;

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
