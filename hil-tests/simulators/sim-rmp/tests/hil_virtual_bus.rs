//! Hardware-in-the-loop: the `sim-rmp` binary runs as its own process on the iceoryx2 virtual
//! CAN bus and the real driver drives it in real time at 50 Hz from this process.
//!
//! Covers: mode change across processes, motion and odometry against the simulator's own
//! ground truth, the driver watchdog bringing the base to rest when inputs go stale, the base
//! going silent (driver error), and the simulator exiting when its controller goes away.
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failure panics with its message

use std::io::{BufRead, BufReader, Write};
use std::process::{Child, ChildStdin, Command, Stdio};
use std::sync::atomic::{AtomicU32, Ordering};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use can_bus::VirtualCanBus;
use grop_clock::{Clock, WallClock};
use motion_control::Twist;
use rmp_base::{BaseError, BaseMode, CanLink, RmpBase, RmpBaseConfig};

static COUNTER: AtomicU32 = AtomicU32::new(0);

fn unique_bus(test: &str) -> String {
    format!(
        "rmp-{test}-{}-{}",
        std::process::id(),
        COUNTER.fetch_add(1, Ordering::Relaxed)
    )
}

/// The simulator process; killed if the test panics before it exits by itself.
struct SimProcess {
    child: Child,
    stdin: Option<ChildStdin>,
    lines: mpsc::Receiver<String>,
}

impl SimProcess {
    fn spawn(bus: &str) -> Self {
        let mut child = Command::new(env!("CARGO_BIN_EXE_sim-rmp"))
            .args(["--bus", bus, "--exit-after-s", "60"])
            .env("RUST_LOG", "warn")
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .spawn()
            .expect("sim-rmp binary starts");
        let stdin = child.stdin.take();
        let stdout = child.stdout.take().expect("piped stdout");
        let (tx, lines) = mpsc::channel();
        std::thread::spawn(move || {
            for line in BufReader::new(stdout).lines().map_while(Result::ok) {
                if tx.send(line).is_err() {
                    break;
                }
            }
        });
        let sim = Self {
            child,
            stdin,
            lines,
        };
        let ready = sim.expect_line("sim-rmp ready", Duration::from_secs(20));
        assert!(ready.contains(bus), "{ready}");
        sim
    }

    fn send(&mut self, line: &str) {
        let stdin = self.stdin.as_mut().expect("stdin open");
        writeln!(stdin, "{line}").expect("control line written");
        stdin.flush().expect("flushed");
    }

    fn expect_line(&self, prefix: &str, timeout: Duration) -> String {
        let deadline = Instant::now() + timeout;
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            match self.lines.recv_timeout(left) {
                Ok(line) if line.starts_with(prefix) => return line,
                Ok(_) => continue,
                Err(_) => panic!("sim-rmp printed no {prefix:?} line within {timeout:?}"),
            }
        }
    }

    /// `status` line fields as (key, value).
    fn status(&mut self) -> Vec<(String, String)> {
        self.send("status");
        let line = self.expect_line("status", Duration::from_secs(5));
        line.split_whitespace()
            .skip(1)
            .filter_map(|kv| kv.split_once('='))
            .map(|(k, v)| (k.to_string(), v.to_string()))
            .collect()
    }
}

impl Drop for SimProcess {
    fn drop(&mut self) {
        if let Ok(None) = self.child.try_wait() {
            let _ = self.child.kill();
            let _ = self.child.wait();
        }
    }
}

fn field(status: &[(String, String)], key: &str) -> String {
    status
        .iter()
        .find(|(k, _)| k == key)
        .map(|(_, v)| v.clone())
        .unwrap_or_else(|| panic!("no {key} in {status:?}"))
}

fn num(status: &[(String, String)], key: &str) -> f64 {
    field(status, key).parse().expect("numeric field")
}

#[test]
fn driver_drives_the_simulated_base_process_over_the_virtual_bus() {
    let bus_name = unique_bus("drive");
    let mut sim = SimProcess::spawn(&bus_name);
    let bus = VirtualCanBus::join(&bus_name, "driver").expect("driver joins the bus");
    let mut base = RmpBase::new(CanLink::new(bus), RmpBaseConfig::default()).unwrap();
    let clock = WallClock;
    let period = base.config().command_period;
    let mut next = clock.now();

    // 1. Tractor.
    base.request_mode(BaseMode::Tractor, clock.now());
    let mut reached = false;
    for _ in 0..150 {
        let tick = base.tick(clock.now()).expect("healthy start-up");
        if tick.mode_reached == Some(BaseMode::Tractor) {
            reached = true;
            break;
        }
        next += period;
        clock.sleep_until(next);
    }
    assert!(reached, "tractor confirmed across processes");
    assert_eq!(field(&sim.status(), "state"), "Tractor");

    // 2. Drive 0.3 m/s for 1.5 s, then stop feeding inputs: the watchdog ramps to zero.
    let drive_until = clock.now() + Duration::from_millis(1500);
    let stop_by = drive_until + Duration::from_millis(1500);
    let mut stale_ticks = 0;
    while clock.now() < stop_by {
        if clock.now() < drive_until {
            base.set_velocity(Twist::new(0.3, 0.0), clock.now());
        }
        let tick = base.tick(clock.now()).expect("base answers while driving");
        if tick.input_stale {
            stale_ticks += 1;
        }
        next += period;
        clock.sleep_until(next);
    }
    assert!(stale_ticks > 20, "the watchdog took over: {stale_ticks}");
    let status = sim.status();
    let odo = *base.odometry();
    assert!(num(&status, "speed_mps").abs() < 1e-6, "{status:?}");
    let x = num(&status, "x_m");
    // 0.3 m/s for ~1.5 s minus the ramps: somewhere near 0.4 m.
    assert!(x > 0.25 && x < 0.6, "{status:?}");
    assert!(
        (odo.x_m - x).abs() < 0.01,
        "odometry {odo:?} vs sim {status:?}"
    );
    assert!(odo.y_m.abs() < 0.01);

    // 3. The base stops answering: the driver reports it within its response timeout.
    sim.send("silent on");
    let silent_from = clock.now();
    let mut silent_error = None;
    while clock.now() < silent_from + Duration::from_secs(2) {
        if let Err(e) = base.tick(clock.now()) {
            silent_error = Some(e);
            break;
        }
        next += period;
        clock.sleep_until(next);
    }
    match silent_error {
        Some(BaseError::Silent { .. }) => {}
        other => panic!("expected BaseError::Silent, got {other:?}"),
    }

    // 4. The controller goes away (stdin closes): the simulator exits on its own.
    drop(sim.stdin.take());
    let deadline = Instant::now() + Duration::from_secs(10);
    loop {
        if let Ok(Some(status)) = sim.child.try_wait() {
            assert!(status.success(), "sim-rmp exit status {status}");
            break;
        }
        assert!(
            Instant::now() < deadline,
            "sim-rmp did not exit after stdin closed"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
}
