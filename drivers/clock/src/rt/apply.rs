//! Applying the settings: one system call per step, each refusal reported with its errno and
//! what to grant.

#![allow(
    unsafe_code,
    reason = "mlockall, sched_setscheduler, sched_setaffinity, mallopt, getrlimit: the real-time settings"
)]

use core::fmt;

use super::settings::{MAX_CPU_INDEX, RtSettings};

/// Stack left untouched below the pre-faulted region, so pre-faulting never reaches the guard
/// page.
const STACK_MARGIN_BYTES: usize = 64 * 1024;
/// One frame of the stack pre-fault recursion.
const STACK_CHUNK_BYTES: usize = 16 * 1024;

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

pub(super) fn prefault_stack(wanted: usize) -> RtOutcome {
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

pub(super) fn pin_to_cpu(cpu: usize) -> RtOutcome {
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
