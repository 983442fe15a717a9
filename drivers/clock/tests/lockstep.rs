//! The simulated clock across participants: lock-step order, pace, crash detection, loss.
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failure panics with its message

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use grop_clock::{Clock, HostConfig, SimClock, SimClockHost};

static COUNTER: AtomicU64 = AtomicU64::new(0);

fn unique(test: &str) -> String {
    format!(
        "t{}-{}-{test}",
        std::process::id(),
        COUNTER.fetch_add(1, Ordering::Relaxed)
    )
}

const MS: Duration = Duration::from_millis(1);

/// A participant thread that wakes every `period` until `end` and logs (time, name).
fn spawn_periodic(
    clock_name: &str,
    name: &'static str,
    rank: u32,
    period: Duration,
    end: Duration,
    log: Arc<Mutex<Vec<(Duration, &'static str)>>>,
) -> std::thread::JoinHandle<()> {
    let clock = SimClock::join(clock_name, name, rank, Duration::from_secs(5)).unwrap();
    std::thread::spawn(move || {
        let mut deadline = clock.now();
        while deadline < end {
            deadline += period;
            clock.sleep_until(deadline);
            log.lock().unwrap().push((clock.now(), name));
        }
    })
}

#[test]
fn participants_run_in_rank_order_at_every_instant_and_time_never_overtakes_them() {
    let name = unique("order");
    let mut host = SimClockHost::create(&name, HostConfig::default()).unwrap();
    let log = Arc::new(Mutex::new(Vec::new()));
    let end = 100 * MS;
    // Joined in the "wrong" order: rank decides, not join order.
    let exec = spawn_periodic(&name, "executive", 20, 2 * MS, end, Arc::clone(&log));
    let plan = spawn_periodic(&name, "planner", 10, 10 * MS, end, Arc::clone(&log));
    let mut t = Duration::ZERO;
    while t < end + 20 * MS {
        t += MS;
        host.advance_to(t);
        assert_eq!(host.now(), t);
    }
    exec.join().unwrap();
    plan.join().unwrap();
    let log = log.lock().unwrap().clone();
    let exec_wakes: Vec<_> = log.iter().filter(|(_, n)| *n == "executive").collect();
    let plan_wakes: Vec<_> = log.iter().filter(|(_, n)| *n == "planner").collect();
    assert_eq!(exec_wakes.len(), 50);
    assert_eq!(plan_wakes.len(), 10);
    // Each wake sees exactly its deadline: the host never moved time while one ran.
    for (k, (at, _)) in exec_wakes.iter().enumerate() {
        assert_eq!(*at, 2 * MS * (k as u32 + 1));
    }
    // At shared instants the planner (rank 10) ran before the executive (rank 20).
    for w in log.windows(2) {
        if w[0].0 == w[1].0 {
            assert_eq!((w[0].1, w[1].1), ("planner", "executive"), "{w:?}");
        }
        assert!(w[0].0 <= w[1].0, "time went backwards: {w:?}");
    }
    // The same run twice gives the same log (determinism of the order).
    assert!(host.take_departures().is_empty());
}

#[test]
fn a_slow_participant_holds_simulated_time_still() {
    let name = unique("slow");
    let mut host = SimClockHost::create(&name, HostConfig::default()).unwrap();
    let clock = SimClock::join(&name, "slow", 10, Duration::from_secs(5)).unwrap();
    let seen = Arc::new(Mutex::new(Vec::new()));
    let seen2 = Arc::clone(&seen);
    let worker = std::thread::spawn(move || {
        for k in 1..=3u32 {
            clock.sleep_until(k * 10 * MS);
            let before = clock.now();
            std::thread::sleep(Duration::from_millis(30)); // "computing"
            seen2.lock().unwrap().push((before, clock.now()));
        }
    });
    host.advance_to(50 * MS);
    worker.join().unwrap();
    for (before, after) in seen.lock().unwrap().iter() {
        assert_eq!(before, after, "time moved while the participant computed");
    }
}

#[test]
fn paced_clock_runs_no_faster_than_asked() {
    let name = unique("paced");
    let mut host = SimClockHost::create(
        &name,
        HostConfig {
            pace: Some(1.0),
            ..HostConfig::default()
        },
    )
    .unwrap();
    let started = Instant::now();
    let mut t = Duration::ZERO;
    for _ in 0..30 {
        t += 2 * MS;
        host.advance_to(t);
    }
    // A lower bound only (never a maximum): 60 ms simulated took at least ~60 ms wall.
    assert!(started.elapsed() >= Duration::from_millis(55));
}

#[test]
fn participants_of_a_closed_clock_are_lost_and_do_not_hang() {
    let name = unique("closed");
    let host = SimClockHost::create(&name, HostConfig::default()).unwrap();
    let clock = SimClock::join(&name, "orphan", 10, Duration::from_secs(5)).unwrap();
    drop(host);
    assert!(clock.is_lost());
    let before = clock.now();
    clock.sleep_until(before + 10 * MS); // returns (on the wall clock)
    assert!(clock.now() >= before);
}

#[test]
fn bad_specs_and_names_are_errors() {
    assert!(grop_clock::open("sundial", "x", 1).is_err());
    assert!(grop_clock::open("sim:../etc", "x", 1).is_err());
    assert!(grop_clock::open("sim:", "x", 1).is_err());
    let missing = SimClock::join(&unique("nohost"), "x", 1, Duration::from_millis(30));
    assert!(matches!(
        missing,
        Err(grop_clock::ClockError::NoHost { .. })
    ));
    let wall = grop_clock::open("wall", "x", 1).unwrap();
    let t0 = wall.now();
    wall.sleep_until(t0 + MS);
    assert!(wall.now() >= t0 + MS);
}

/// Child side of the crash test: joins and exits without leaving (as a killed process would).
#[test]
fn child_joins_and_dies() {
    let Ok(name) = std::env::var("GROP_CLOCK_CHILD") else {
        return; // only meaningful as a child process
    };
    let clock = SimClock::join(&name, "doomed", 10, Duration::from_secs(5)).unwrap();
    clock.sleep_until(4 * MS);
    // Dies while running (holding the clock), without Drop.
    std::process::exit(0);
}

#[test]
fn a_dead_participant_is_released_and_reported() {
    let name = unique("dead");
    let mut host = SimClockHost::create(&name, HostConfig::default()).unwrap();
    let mut child = std::process::Command::new(std::env::current_exe().unwrap())
        .args(["--exact", "child_joins_and_dies", "--nocapture"])
        .env("GROP_CLOCK_CHILD", &name)
        .stdout(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let started = Instant::now();
    while host.participants().is_empty() && started.elapsed() < Duration::from_secs(20) {
        std::thread::sleep(MS);
    }
    assert_eq!(host.participants().len(), 1, "the child never joined");
    // The child runs at 4 ms and exits without sleeping again: advancing must not hang.
    host.advance_to(20 * MS);
    let _ = child.wait();
    assert_eq!(host.now(), 20 * MS);
    let gone = host.take_departures();
    assert_eq!(gone.len(), 1, "{gone:?}");
    assert_eq!(gone[0].name, "doomed");
    assert_eq!(gone[0].at, 4 * MS);
    assert!(host.participants().is_empty());
}
