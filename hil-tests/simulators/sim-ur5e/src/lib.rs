//! Simulated UR5e controller on loopback TCP, for hardware-in-the-loop tests.
//!
//! It serves what a PolyScope 5 controller serves: RTDE on 30004 (protocol 1 and 2, recipes,
//! 500 Hz, several clients at once), the dashboard on 29999 with the exact reply strings,
//! primary/secondary/real-time on 30001/30002/30003 (state streams; URScript programs with
//! `movej`, `movel`, `stopj`, `stopl`, `speedj`, `sleep`, `rtde_set_watchdog`, ...), and the
//! Robotiq URCap gripper socket on 63352. Motion follows the UR5e kinematics
//! (`ur5e_kin::Ur5e`) and its joint speed limit. Two uploaded programs are recognised and their
//! command loops served natively instead of interpreted: ur_rtde's control script (its RTDE
//! register protocol, [`robot::rtde_commands`]) and the UR client library's External Control
//! program (its reverse, trajectory and script command sockets, [`external_control`]).
//! Protocol facts, command by command: `docs/ur5e.md`.
//!
//! Run it as its own process (`sim-ur5e --help`) or in-process:
//!
//! ```no_run
//! let sim = sim_ur5e::Ur5eSim::start(sim_ur5e::SimConfig::ephemeral())?;
//! println!("RTDE on {}", sim.ports().rtde);
//! sim.trigger_protective_stop("test");
//! # Ok::<(), std::io::Error>(())
//! ```
//!
//! In a closed-loop HIL world that owns a simulated clock, start it with
//! [`Stepping::External`] and advance it one control period per [`Ur5eSim::step`]: when `step`
//! returns, every started RTDE client already has this cycle's data package in its socket, and
//! what a client sent before the call and the kernel has delivered was applied first (module
//! [`stepping`], which also names the known gap under load):
//!
//! ```no_run
//! use sim_ur5e::{SimConfig, Stepping, Ur5eSim};
//! let sim = Ur5eSim::start(SimConfig { stepping: Stepping::External, ..SimConfig::ephemeral() })?;
//! let report = sim.step()?; // one 2 ms cycle, at whatever speed the world runs
//! assert_eq!(report.cycle, 1);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

pub mod external_control;
pub mod fields;
pub mod gripper;
pub mod inputs;
pub mod primary;
pub mod robot;
mod server;
pub mod stepping;
pub mod urscript;

use std::io;
use std::net::{IpAddr, Ipv4Addr, SocketAddr, TcpStream};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::thread::JoinHandle;
use std::time::Duration;

pub use robot::{EXTERNAL_CONTROL_PROGRAM, RTDE_CONTROL_PROGRAM, RobotInit, Snapshot};
pub use server::PortKind;
use server::Shared;
use stepping::lock;
pub use stepping::{StepError, StepReport, Stepping};
pub use ur5e::rtde::ControllerVersion;

/// Simulator settings.
#[derive(Debug, Clone, PartialEq)]
pub struct SimConfig {
    /// Address to listen on (IPv4 loopback: ur_rtde connects over IPv4 only).
    pub bind_ip: IpAddr,
    /// RTDE port (30004; 0 = any free port).
    pub rtde_port: u16,
    /// Dashboard port (29999).
    pub dashboard_port: u16,
    /// Primary port (30001).
    pub primary_port: u16,
    /// Secondary port (30002).
    pub secondary_port: u16,
    /// Real-time port (30003).
    pub realtime_port: u16,
    /// Robotiq URCap gripper port (63352).
    pub gripper_port: u16,
    /// Control rate (Hz): 500 on e-Series.
    pub rate_hz: f64,
    /// Version reported by RTDE `v` and the dashboard (5.21: ur_rtde exercises its dashboard
    /// path from 5.6 on and avoids the 5.23-only fields below 5.23).
    pub version: ControllerVersion,
    /// `get serial number` reply (digits only).
    pub serial_number: String,
    /// `is in remote control` reply.
    pub remote_control: bool,
    /// Program files `load` accepts.
    pub programs: Vec<String>,
    /// Robot state at start.
    pub init: RobotInit,
    /// Width of an object between the gripper fingers (m), if any.
    pub gripper_object_width_m: Option<f64>,
    /// Who advances the controller: its own wall-clock thread, or the owner through
    /// [`Ur5eSim::step`] (lock-step HIL).
    pub stepping: Stepping,
    /// The External Control URCap's script sender (URCL, default port 50002): dashboard
    /// `play` of a loaded program asks it for the External Control program and runs it.
    pub urcap_script_sender: Option<SocketAddr>,
}

impl Default for SimConfig {
    /// The real controller's ports on 127.0.0.1.
    fn default() -> Self {
        Self {
            bind_ip: IpAddr::V4(Ipv4Addr::LOCALHOST),
            rtde_port: 30004,
            dashboard_port: 29999,
            primary_port: 30001,
            secondary_port: 30002,
            realtime_port: 30003,
            gripper_port: 63352,
            rate_hz: 500.0,
            version: ControllerVersion {
                major: 5,
                minor: 21,
                bugfix: 0,
                build: 1_210_631,
            },
            serial_number: "20235500001".into(),
            remote_control: true,
            programs: Vec::new(),
            init: RobotInit::default(),
            gripper_object_width_m: None,
            stepping: Stepping::WallClock,
            urcap_script_sender: None,
        }
    }
}

impl SimConfig {
    /// Every port 0 (the OS picks free ones), for tests running in parallel.
    pub fn ephemeral() -> Self {
        Self {
            rtde_port: 0,
            dashboard_port: 0,
            primary_port: 0,
            secondary_port: 0,
            realtime_port: 0,
            gripper_port: 0,
            ..Self::default()
        }
    }
}

/// The addresses the simulator listens on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SimPorts {
    /// RTDE.
    pub rtde: SocketAddr,
    /// Dashboard.
    pub dashboard: SocketAddr,
    /// Primary.
    pub primary: SocketAddr,
    /// Secondary.
    pub secondary: SocketAddr,
    /// Real-time.
    pub realtime: SocketAddr,
    /// Gripper.
    pub gripper: SocketAddr,
}

/// A running simulator; dropping it stops every thread and closes every socket.
pub struct Ur5eSim {
    shared: Arc<Shared>,
    ports: SimPorts,
    threads: Vec<JoinHandle<()>>,
}

impl core::fmt::Debug for Ur5eSim {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("Ur5eSim")
            .field("ports", &self.ports)
            .finish_non_exhaustive()
    }
}

impl Ur5eSim {
    /// Binds every port and, with [`Stepping::WallClock`], starts the control loop.
    pub fn start(cfg: SimConfig) -> io::Result<Self> {
        if !(cfg.rate_hz > 0.0 && cfg.rate_hz <= 10_000.0) {
            return Err(io::Error::new(
                io::ErrorKind::InvalidInput,
                "rate_hz must be in (0, 10000]",
            ));
        }
        let shared = Arc::new(Shared::new(cfg.clone()));
        let mut threads = Vec::new();
        let mut bind = |kind, port| -> io::Result<SocketAddr> {
            let (addr, handle) = server::listen(&shared, kind, port)?;
            threads.push(handle);
            Ok(addr)
        };
        let ports = SimPorts {
            rtde: bind(PortKind::Rtde, cfg.rtde_port)?,
            dashboard: bind(PortKind::Dashboard, cfg.dashboard_port)?,
            primary: bind(PortKind::Primary, cfg.primary_port)?,
            secondary: bind(PortKind::Secondary, cfg.secondary_port)?,
            realtime: bind(PortKind::Realtime, cfg.realtime_port)?,
            gripper: bind(PortKind::Gripper, cfg.gripper_port)?,
        };
        if cfg.stepping == Stepping::WallClock {
            let control = {
                let shared = Arc::clone(&shared);
                std::thread::Builder::new()
                    .name("sim-ur5e-control".into())
                    .spawn(move || server::control_loop(shared))?
            };
            threads.push(control);
        }
        Ok(Self {
            shared,
            ports,
            threads,
        })
    }

    /// Where it listens.
    pub fn ports(&self) -> SimPorts {
        self.ports
    }

    /// [`Stepping::External`] only: advances the controller by exactly one period
    /// (`1 / rate_hz`), publishes the new state, and blocks (at most [`stepping::STEP_WAIT`]
    /// per phase, wall time) until input sent before the call was applied and every started
    /// RTDE connection due this cycle has written its data package. A client can therefore
    /// read the package at once, without waiting: that is what makes lock-step deterministic.
    pub fn step(&self) -> Result<StepReport, StepError> {
        if self.shared.cfg.stepping != Stepping::External {
            return Err(StepError::NotExternal);
        }
        Ok(self.shared.step_external())
    }

    /// The control period, `1 / rate_hz` (rounded to whole nanoseconds).
    pub fn period(&self) -> Duration {
        Duration::from_nanos((1e9 / self.shared.cfg.rate_hz).round() as u64)
    }

    /// Controller time: cycles stepped so far times [`Self::period`] (the RTDE `timestamp` is
    /// the same value in seconds, `cycle / rate_hz`).
    pub fn controller_time(&self) -> Duration {
        let cycle = lock(&self.shared.published).snap.cycle;
        let ns = u64::try_from(self.period().as_nanos()).unwrap_or(u64::MAX);
        Duration::from_nanos(ns.saturating_mul(cycle))
    }

    /// How this simulator is clocked.
    pub fn stepping(&self) -> Stepping {
        self.shared.cfg.stepping
    }

    /// The newest published state.
    pub fn snapshot(&self) -> Snapshot {
        lock(&self.shared.published).snap
    }

    /// Control cycles that fell more than 5 periods behind (machine stalls).
    pub fn overruns(&self) -> u64 {
        self.shared.overruns.load(Ordering::Relaxed)
    }

    /// Fault injection: a protective stop, as after a collision.
    pub fn trigger_protective_stop(&self, reason: &str) {
        lock(&self.shared.ctl).robot.protective_stop(reason);
    }

    /// Fault injection: cuts every RTDE connection (a pulled cable as the client sees it).
    pub fn cut_rtde_connections(&self) -> usize {
        self.shared.cut(Some(PortKind::Rtde))
    }

    /// Fault injection: cuts every connection on one kind of port.
    pub fn cut_connections(&self, kind: PortKind) -> usize {
        self.shared.cut(Some(kind))
    }

    /// Fault injection: cuts every connection of every port.
    pub fn cut_all_connections(&self) -> usize {
        self.shared.cut(None)
    }

    /// Fault injection at the controller's sockets (connections stay open).
    pub fn link_faults(&self) -> &LinkFaults {
        &self.shared.link_faults
    }

    /// Fault injection: the safeguard input opens (`open`) or closes again.
    pub fn set_safeguard_stop(&self, open: bool, reason: &str) {
        let robot = &mut lock(&self.shared.ctl).robot;
        if open {
            robot.safeguard_stop(reason);
        } else {
            robot.safeguard_release();
        }
    }

    /// Fault injection: an emergency stop (the red button on the teach pendant).
    pub fn trigger_emergency_stop(&self, reason: &str) {
        lock(&self.shared.ctl).robot.emergency_stop(reason);
    }

    /// Fault injection: the gripper reports fault `code` (FLT) and stops moving until it is
    /// re-activated.
    pub fn trigger_gripper_fault(&self, code: u8) {
        lock(&self.shared.ctl).robot.gripper.inject_fault(code);
    }

    /// Puts an object of this width between the gripper fingers (or removes it).
    pub fn set_gripper_object(&self, width_m: Option<f64>) {
        lock(&self.shared.ctl).robot.gripper.object_width_m = width_m;
    }

    /// Runs `f` on the robot model under the control lock (inspection, fault injection).
    pub fn with_robot<R>(&self, f: impl FnOnce(&mut robot::RobotModel) -> R) -> R {
        f(&mut lock(&self.shared.ctl).robot)
    }
}

/// Faults injected at the controller's sockets: the connections stay open, what goes through
/// them changes. Set from any thread; every connection sees them at once.
#[derive(Debug, Default)]
pub struct LinkFaults {
    /// RTDE data packages are no longer written (the controller stays connected and silent);
    /// external steps are not held up by it.
    pub rtde_muted: AtomicBool,
    /// Gripper (63352) requests are read and acted on but never answered.
    pub gripper_muted: AtomicBool,
    /// Every dashboard reply is held back this long (wall time, ms).
    pub dashboard_delay_ms: AtomicU64,
}

impl Drop for Ur5eSim {
    fn drop(&mut self) {
        self.shared.shutdown.store(true, Ordering::Release);
        self.shared.tick.notify_all();
        self.shared.cut(None);
        // Wake the accept threads so they see the shutdown flag.
        for addr in [
            self.ports.rtde,
            self.ports.dashboard,
            self.ports.primary,
            self.ports.secondary,
            self.ports.realtime,
            self.ports.gripper,
        ] {
            let _ = TcpStream::connect(addr);
        }
        for t in self.threads.drain(..) {
            let _ = t.join();
        }
    }
}
