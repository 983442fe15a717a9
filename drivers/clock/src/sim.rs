//! The lock-step simulated clock: a small table in shared memory (`/dev/shm/grop-clock-<name>`)
//! that the HIL world creates ([`SimClockHost`]) and every other process joins
//! ([`SimClock`]).
//!
//! Protocol. Each participant owns a slot: `RUNNING` while it computes, `SLEEPING` with a wake
//! time while it waits in [`Clock::sleep_until`]. The host advances time only while no slot is
//! `RUNNING`: to the earliest wake time (or its own next step), then releases the participants
//! due at that instant one at a time, lowest rank first, waiting for each to sleep again before
//! the next runs. So at every instant the order of work is fixed (determinism), and a slow
//! computation stops simulated time instead of being overtaken by it. Wake-ups are futexes on
//! words of the mapping (process-shared), so a hand-over costs two context switches.
//!
//! Crashes. The host checks the pid of a participant it waits for; a dead one (gone or a
//! zombie) is freed and reported as a [`Departure`]. A participant whose host is gone (or
//! closed the clock) is *lost*: its sleeps return at once, `now()` continues on the wall
//! clock from the last simulated time, and [`Clock::is_lost`] says so, so its own watchdogs
//! fire and it can stop what it drives.
#![allow(
    unsafe_code,
    reason = "the simulated clock's state lives in a shared mmap'ed page (atomics only)"
)]

use std::fs::OpenOptions;
use std::os::fd::AsRawFd;
use std::os::unix::fs::OpenOptionsExt;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, AtomicU32, AtomicU64, Ordering};
use std::time::{Duration, Instant};

use crate::{Clock, ClockError, check_name, futex, monotonic_now, pid_alive};

/// Most processes that can share one simulated clock.
pub const MAX_PARTICIPANTS: usize = 16;

/// "gropclk" and the layout version.
const MAGIC: u64 = 0x6772_6f70_636c_6b02;

const FREE: u32 = 0;
const CLAIMED: u32 = 1;
const RUNNING: u32 = 2;
const SLEEPING: u32 = 3;

/// How long a waiter sleeps on a futex before it checks that its peer still lives.
const LIVENESS_POLL: Duration = Duration::from_millis(50);

#[repr(C)]
struct Slot {
    state: AtomicU32,
    pid: AtomicU32,
    rank: AtomicU32,
    /// Bumped by the host to release the participant (its futex word).
    run_gen: AtomicU32,
    /// Work of the participant in progress on another of its threads ([`Clock::begin_hold`]):
    /// the host treats a sleeping participant with holds as running.
    holds: AtomicU32,
    reserved: u32,
    wake_ns: AtomicU64,
    name: [AtomicU64; 4],
}

#[repr(C)]
struct Shared {
    magic: AtomicU64,
    now_ns: AtomicU64,
    host_pid: AtomicU32,
    /// Bumped by participants when they sleep, join or leave (the host's futex word).
    host_word: AtomicU32,
    closed: AtomicU32,
    reserved: u32,
    slots: [Slot; MAX_PARTICIPANTS],
}

fn shm_path(name: &str) -> PathBuf {
    PathBuf::from(format!("/dev/shm/grop-clock-{name}"))
}

/// A `MAP_SHARED` mapping of the clock file.
struct Mapping {
    ptr: *mut Shared,
    len: usize,
}

// SAFETY: the mapping is only accessed through atomics.
unsafe impl Send for Mapping {}
// SAFETY: as above.
unsafe impl Sync for Mapping {}

impl Mapping {
    fn map(file: &std::fs::File, path: &str) -> Result<Self, ClockError> {
        let len = size_of::<Shared>();
        // SAFETY: mapping a regular file we opened read-write, at least `len` long (checked or
        // truncated by the callers); the result is checked against MAP_FAILED.
        let ptr = unsafe {
            libc::mmap(
                std::ptr::null_mut(),
                len,
                libc::PROT_READ | libc::PROT_WRITE,
                libc::MAP_SHARED,
                file.as_raw_fd(),
                0,
            )
        };
        if ptr == libc::MAP_FAILED {
            return Err(ClockError::Os {
                path: path.to_owned(),
                stage: "mapping",
                source: std::io::Error::last_os_error(),
            });
        }
        Ok(Self {
            ptr: ptr.cast(),
            len,
        })
    }

    fn shared(&self) -> &Shared {
        // SAFETY: `ptr` is a live mapping of `size_of::<Shared>()` bytes, page-aligned, and
        // `Shared` consists of atomics (valid for any bytes, zero included).
        unsafe { &*self.ptr }
    }
}

impl Drop for Mapping {
    fn drop(&mut self) {
        // SAFETY: unmapping exactly what `map` mapped; no reference outlives `self`.
        unsafe {
            libc::munmap(self.ptr.cast(), self.len);
        }
    }
}

fn encode_name(name: &str) -> [u64; 4] {
    let mut bytes = [0u8; 32];
    let n = name.len().min(32);
    bytes[..n].copy_from_slice(&name.as_bytes()[..n]);
    let mut words = [0u64; 4];
    for (i, w) in words.iter_mut().enumerate() {
        let mut b = [0u8; 8];
        b.copy_from_slice(&bytes[i * 8..i * 8 + 8]);
        *w = u64::from_le_bytes(b);
    }
    words
}

fn decode_name(words: &[AtomicU64; 4]) -> String {
    let mut bytes = Vec::with_capacity(32);
    for w in words {
        bytes.extend_from_slice(&w.load(Ordering::Relaxed).to_le_bytes());
    }
    let end = bytes.iter().position(|&b| b == 0).unwrap_or(bytes.len());
    String::from_utf8_lossy(&bytes[..end]).into_owned()
}

fn ns(d: Duration) -> u64 {
    u64::try_from(d.as_nanos()).unwrap_or(u64::MAX)
}

/// A participant that left the clock without saying so: its process died.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Departure {
    /// The name it joined with.
    pub name: String,
    /// Its process id.
    pub pid: u32,
    /// Simulated time when the host noticed.
    pub at: Duration,
}

/// Settings of the host.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HostConfig {
    /// `None`: lock-step, as fast as the processes compute. `Some(r)`: no faster than `r`
    /// simulated seconds per wall second (1.0 = wall-clock pace).
    pub pace: Option<f64>,
    /// A participant that computes longer than this without sleeping is reported in the log
    /// (it holds simulated time still; nothing else happens).
    pub slow_participant_warning: Duration,
}

impl Default for HostConfig {
    fn default() -> Self {
        Self {
            pace: None,
            slow_participant_warning: Duration::from_secs(5),
        }
    }
}

/// The owner of a simulated clock (the HIL world). Dropping it closes the clock: every
/// participant becomes lost.
pub struct SimClockHost {
    map: Mapping,
    path: PathBuf,
    config: HostConfig,
    pace_origin: Option<(Duration, Instant)>,
    departures: Vec<Departure>,
    order: Vec<usize>,
}

impl core::fmt::Debug for SimClockHost {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("SimClockHost")
            .field("path", &self.path)
            .field("now", &self.now())
            .finish_non_exhaustive()
    }
}

impl SimClockHost {
    /// Creates the clock `name` at time zero, replacing a leftover of a crashed run.
    pub fn create(name: &str, config: HostConfig) -> Result<Self, ClockError> {
        check_name(name)?;
        let path = shm_path(name);
        let shown = path.display().to_string();
        let _ = std::fs::remove_file(&path);
        let os = |stage, source| ClockError::Os {
            path: shown.clone(),
            stage,
            source,
        };
        let file = OpenOptions::new()
            .read(true)
            .write(true)
            .create_new(true)
            .mode(0o600)
            .open(&path)
            .map_err(|e| os("creating", e))?;
        file.set_len(size_of::<Shared>() as u64)
            .map_err(|e| os("sizing", e))?;
        let map = Mapping::map(&file, &shown)?;
        let shared = map.shared();
        shared.now_ns.store(0, Ordering::Relaxed);
        shared.host_pid.store(std::process::id(), Ordering::Relaxed);
        shared.magic.store(MAGIC, Ordering::Release);
        Ok(Self {
            map,
            path,
            config,
            pace_origin: None,
            departures: Vec::new(),
            order: Vec::with_capacity(MAX_PARTICIPANTS),
        })
    }

    fn shared(&self) -> &Shared {
        self.map.shared()
    }

    /// Simulated time now.
    pub fn now(&self) -> Duration {
        Duration::from_nanos(self.shared().now_ns.load(Ordering::Acquire))
    }

    /// Changes the pace (see [`HostConfig::pace`]) from now on.
    pub fn set_pace(&mut self, pace: Option<f64>) {
        self.config.pace = pace;
        self.pace_origin = None;
    }

    /// The participants now joined: name, pid, rank.
    pub fn participants(&self) -> Vec<(String, u32, u32)> {
        self.shared()
            .slots
            .iter()
            .filter(|s| matches!(s.state.load(Ordering::Acquire), RUNNING | SLEEPING))
            .map(|s| {
                (
                    decode_name(&s.name),
                    s.pid.load(Ordering::Relaxed),
                    s.rank.load(Ordering::Relaxed),
                )
            })
            .collect()
    }

    /// Participants whose process died since the last call.
    pub fn take_departures(&mut self) -> Vec<Departure> {
        std::mem::take(&mut self.departures)
    }

    /// Frees `slot` if its process is dead; true if it did.
    fn reap_if_dead(&mut self, index: usize) -> bool {
        let now = self.now();
        let slot = &self.shared().slots[index];
        let pid = slot.pid.load(Ordering::Relaxed);
        if pid_alive(pid) {
            return false;
        }
        let name = decode_name(&slot.name);
        slot.holds.store(0, Ordering::Release);
        slot.state.store(FREE, Ordering::Release);
        log::warn!("simulated clock: participant {name:?} (pid {pid}) died; released");
        self.departures.push(Departure { name, pid, at: now });
        true
    }

    /// Waits until slot `only` (or, with `None`, every slot) is not running.
    fn wait_not_running(&mut self, only: Option<usize>) {
        let started = Instant::now();
        let mut warned = false;
        loop {
            let word = self.shared().host_word.load(Ordering::Acquire);
            let is_busy = |s: &Slot| match s.state.load(Ordering::Acquire) {
                RUNNING => true,
                SLEEPING => s.holds.load(Ordering::Acquire) > 0,
                _ => false,
            };
            let busy: Option<usize> = match only {
                Some(i) => is_busy(&self.shared().slots[i]).then_some(i),
                None => self.shared().slots.iter().position(is_busy),
            };
            let Some(index) = busy else {
                return;
            };
            futex::wait(&self.shared().host_word, word, LIVENESS_POLL);
            if self.shared().host_word.load(Ordering::Acquire) == word {
                // Nothing happened for a while: is it still alive?
                if self.reap_if_dead(index) {
                    continue;
                }
                if !warned && started.elapsed() > self.config.slow_participant_warning {
                    warned = true;
                    log::warn!(
                        "simulated clock: {:?} has computed for {:?} without sleeping",
                        decode_name(&self.shared().slots[index].name),
                        started.elapsed()
                    );
                }
            }
        }
    }

    fn pace(&mut self, target: Duration) {
        let Some(rate) = self.config.pace.filter(|r| *r > 0.0 && r.is_finite()) else {
            return;
        };
        let (sim0, wall0) = *self.pace_origin.get_or_insert((self.now(), Instant::now()));
        let due = wall0 + target.saturating_sub(sim0).div_f64(rate);
        let wait = due.saturating_duration_since(Instant::now());
        if !wait.is_zero() {
            std::thread::sleep(wait);
        }
    }

    /// Waits until no participant is running (each is asleep, or waits for its turn): after
    /// this, everything the participants set up before their first sleep (subscriptions,
    /// connections) exists, so what the host does next reaches all of them the same way every
    /// run.
    pub fn settle(&mut self) {
        self.wait_not_running(None);
    }

    /// Fault injection: time jumps to `target` at once (a stalled machine, a suspended VM).
    /// Unlike [`advance_to`](Self::advance_to), nobody runs at the instants in between: every
    /// participant whose wake time passed wakes at `target`, late. No-op if `target` is not
    /// later than now.
    pub fn jump_to(&mut self, target: Duration) {
        self.wait_not_running(None);
        let target_ns = ns(target);
        if target_ns <= self.shared().now_ns.load(Ordering::Acquire) {
            return;
        }
        self.shared().now_ns.store(target_ns, Ordering::Release);
        // The pace origin moves with the jump: no catching up in wall time afterwards.
        self.pace_origin = None;
        self.advance_to(target);
    }

    /// Moves simulated time forward to `target`: waits until every participant sleeps, steps to
    /// each earlier wake time in turn and runs the participants due then (one at a time, lowest
    /// rank first), and ends with time at `target` and every participant asleep. Participants
    /// due exactly at `target` have run when this returns.
    pub fn advance_to(&mut self, target: Duration) {
        let target_ns = ns(target);
        loop {
            self.wait_not_running(None);
            let now_ns = self.shared().now_ns.load(Ordering::Acquire);
            let earliest = self
                .shared()
                .slots
                .iter()
                .filter(|s| s.state.load(Ordering::Acquire) == SLEEPING)
                .map(|s| s.wake_ns.load(Ordering::Acquire))
                .min()
                .unwrap_or(u64::MAX);
            let step_ns = earliest.max(now_ns).min(target_ns.max(now_ns));
            self.pace(Duration::from_nanos(step_ns));
            self.shared().now_ns.store(step_ns, Ordering::Release);

            // Who is due, in rank order (slot index breaks ties: join order).
            let mut order = std::mem::take(&mut self.order);
            order.clear();
            for (i, s) in self.shared().slots.iter().enumerate() {
                if s.state.load(Ordering::Acquire) == SLEEPING
                    && s.wake_ns.load(Ordering::Acquire) <= step_ns
                {
                    order.push(i);
                }
            }
            order.sort_by_key(|&i| (self.shared().slots[i].rank.load(Ordering::Relaxed), i));
            for &i in &order {
                let slot = &self.shared().slots[i];
                slot.state.store(RUNNING, Ordering::Release);
                slot.run_gen.fetch_add(1, Ordering::Release);
                futex::wake_all(&slot.run_gen);
                self.wait_not_running(Some(i));
            }
            self.order = order;
            if step_ns >= target_ns {
                return;
            }
        }
    }
}

impl Drop for SimClockHost {
    fn drop(&mut self) {
        let shared = self.shared();
        shared.closed.store(1, Ordering::Release);
        for slot in &shared.slots {
            slot.run_gen.fetch_add(1, Ordering::Release);
            futex::wake_all(&slot.run_gen);
        }
        let _ = std::fs::remove_file(&self.path);
    }
}

/// A process's membership of a simulated clock (see the module docs). Leaving (drop) frees the
/// slot.
pub struct SimClock {
    map: Mapping,
    slot: usize,
    lost: AtomicBool,
    /// Simulated ns at the moment the clock was lost, and the wall time then.
    lost_at: std::sync::Mutex<Option<(u64, Duration)>>,
}

impl core::fmt::Debug for SimClock {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("SimClock")
            .field("slot", &self.slot)
            .field("lost", &self.lost.load(Ordering::Relaxed))
            .finish_non_exhaustive()
    }
}

impl SimClock {
    /// Joins the simulated clock `name` as `participant` with `rank`, waiting up to `wait`
    /// for its host to create it. The participant starts running (it holds the clock until
    /// its first sleep).
    pub fn join(
        name: &str,
        participant: &str,
        rank: u32,
        wait: Duration,
    ) -> Result<Self, ClockError> {
        check_name(name)?;
        let path = shm_path(name);
        let shown = path.display().to_string();
        let started = Instant::now();
        let map = loop {
            if let Ok(file) = OpenOptions::new().read(true).write(true).open(&path) {
                let len = file.metadata().map(|m| m.len()).unwrap_or(0);
                if len >= size_of::<Shared>() as u64 {
                    let map = Mapping::map(&file, &shown)?;
                    match map.shared().magic.load(Ordering::Acquire) {
                        MAGIC => break map,
                        0 => {} // being created
                        _ => return Err(ClockError::Incompatible { path: shown }),
                    }
                }
            }
            if started.elapsed() > wait {
                return Err(ClockError::NoHost {
                    name: name.to_owned(),
                    waited: wait,
                });
            }
            std::thread::sleep(Duration::from_millis(10));
        };
        let shared = map.shared();
        let slot = shared
            .slots
            .iter()
            .position(|s| {
                s.state
                    .compare_exchange(FREE, CLAIMED, Ordering::AcqRel, Ordering::Acquire)
                    .is_ok()
            })
            .ok_or(ClockError::Full {
                name: name.to_owned(),
                max: MAX_PARTICIPANTS,
            })?;
        let s = &shared.slots[slot];
        s.pid.store(std::process::id(), Ordering::Relaxed);
        s.rank.store(rank, Ordering::Relaxed);
        for (w, v) in s.name.iter().zip(encode_name(participant)) {
            w.store(v, Ordering::Relaxed);
        }
        s.wake_ns.store(0, Ordering::Relaxed);
        s.holds.store(0, Ordering::Relaxed);
        s.state.store(RUNNING, Ordering::Release);
        shared.host_word.fetch_add(1, Ordering::Release);
        futex::wake_all(&shared.host_word);
        Ok(Self {
            map,
            slot,
            lost: AtomicBool::new(false),
            lost_at: std::sync::Mutex::new(None),
        })
    }

    fn shared(&self) -> &Shared {
        self.map.shared()
    }

    fn host_gone(&self) -> bool {
        let shared = self.shared();
        shared.closed.load(Ordering::Acquire) != 0
            || !pid_alive(shared.host_pid.load(Ordering::Relaxed))
    }

    fn mark_lost(&self) {
        if !self.lost.swap(true, Ordering::AcqRel) {
            let sim = self.shared().now_ns.load(Ordering::Acquire);
            if let Ok(mut at) = self.lost_at.lock() {
                *at = Some((sim, monotonic_now()));
            }
            log::error!("simulated clock lost: its host ended");
        }
    }
}

impl Clock for SimClock {
    fn now(&self) -> Duration {
        if self.lost.load(Ordering::Acquire) {
            if let Ok(at) = self.lost_at.lock() {
                if let Some((sim, wall)) = *at {
                    return Duration::from_nanos(sim) + monotonic_now().saturating_sub(wall);
                }
            }
        }
        Duration::from_nanos(self.shared().now_ns.load(Ordering::Acquire))
    }

    fn sleep_until(&self, deadline: Duration) {
        if self.lost.load(Ordering::Acquire) {
            let now = self.now();
            // Lost: keep the caller's loop at roughly its rate on the wall clock.
            std::thread::sleep(deadline.saturating_sub(now).min(Duration::from_millis(100)));
            return;
        }
        if ns(deadline) <= self.shared().now_ns.load(Ordering::Acquire) {
            return;
        }
        self.sleep_registered(ns(deadline));
    }

    fn is_simulated(&self) -> bool {
        true
    }

    fn wait_turn(&self) {
        if self.lost.load(Ordering::Acquire) {
            return;
        }
        let now = self.shared().now_ns.load(Ordering::Acquire);
        self.sleep_registered(now);
    }

    fn is_lost(&self) -> bool {
        // Cheap enough for every cycle: the pid check happens while sleeping.
        self.lost.load(Ordering::Acquire) || self.shared().closed.load(Ordering::Acquire) != 0
    }

    fn begin_hold(&self) {
        self.shared().slots[self.slot]
            .holds
            .fetch_add(1, Ordering::AcqRel);
    }

    fn end_hold(&self) {
        let shared = self.shared();
        let holds = &shared.slots[self.slot].holds;
        // Never below zero, whatever a caller does.
        let _ = holds.fetch_update(Ordering::AcqRel, Ordering::Acquire, |h| h.checked_sub(1));
        shared.host_word.fetch_add(1, Ordering::Release);
        futex::wake_all(&shared.host_word);
    }
}

impl SimClock {
    /// Sleeps until the host runs this participant at `wake_ns` (in rank order).
    fn sleep_registered(&self, wake_ns: u64) {
        let shared = self.shared();
        let slot = &shared.slots[self.slot];
        let generation = slot.run_gen.load(Ordering::Acquire);
        slot.wake_ns.store(wake_ns, Ordering::Release);
        slot.state.store(SLEEPING, Ordering::Release);
        shared.host_word.fetch_add(1, Ordering::Release);
        futex::wake_all(&shared.host_word);
        loop {
            if slot.run_gen.load(Ordering::Acquire) != generation {
                if shared.closed.load(Ordering::Acquire) != 0 {
                    self.mark_lost();
                }
                return;
            }
            futex::wait(&slot.run_gen, generation, LIVENESS_POLL);
            if slot.run_gen.load(Ordering::Acquire) == generation && self.host_gone() {
                self.mark_lost();
                return;
            }
        }
    }
}

impl Drop for SimClock {
    fn drop(&mut self) {
        let shared = self.shared();
        shared.slots[self.slot].state.store(FREE, Ordering::Release);
        shared.host_word.fetch_add(1, Ordering::Release);
        futex::wake_all(&shared.host_word);
    }
}
