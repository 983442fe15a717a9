//! Robotiq 2F-140 gripper through the Robotiq URCap's ASCII socket on the controller (port 63352).
//!
//! Why this path and not tool I/O: the 2F-140 talks Modbus RTU over the e-Series tool RS-485;
//! with the Robotiq URCap installed (the usual set-up) the URCap bridges it to a TCP socket on
//! the controller, so the onboard computer needs no extra cable and gets position, object
//! detection and faults, which two digital tool outputs would not give.
//!
//! Protocol: `SET <VAR> <int>[ <VAR> <int> ...]\n` answered by `ack`, and `GET <VAR>\n`
//! answered by `<VAR> <int>`. Variables: ACT (activate), GTO (go to), POS (requested or
//! current position 0 = open .. 255 = closed), SPE and FOR (0..255), STA (0 reset,
//! 1 activating, 3 active), OBJ (0 moving, 1 contact while opening, 2 contact while closing,
//! 3 at the requested position), FLT (fault code, 0 = none), PRE (echo of the request).
//!
//! Each reply has one deadline (the client's timeout from when the request was sent), however
//! the URCap spreads its bytes. `ack` answers every `SET` and nothing numbers the requests, so
//! a reply that misses its deadline could not be told from the next request's answer: after a
//! timeout (or an over-long line) the client drops that connection and sends its next request
//! on a fresh one, so a late reply is never read at all.

use std::io::{self, Write};
use std::net::{SocketAddr, ToSocketAddrs};
use std::time::{Duration, Instant};

use thiserror::Error;

use crate::line_link::{LineError, LineLink, MAX_LINE_LEN};
use crate::transport::{TcpTransport, Transport};

/// Default URCap gripper port.
pub const GRIPPER_PORT: u16 = 63352;
/// Stroke of the 2F-140 (m): fully open finger gap.
pub const STROKE_M: f64 = 0.140;

/// Errors of the gripper client.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum GripperError {
    /// The address did not resolve.
    #[error("cannot resolve gripper address: {0}")]
    Resolve(io::Error),
    /// Socket failure.
    #[error("gripper socket {addr}: {source}")]
    Io {
        /// Address.
        addr: SocketAddr,
        /// Underlying error.
        source: io::Error,
    },
    /// The URCap closed the socket.
    #[error("gripper socket {addr} closed")]
    Closed {
        /// Address.
        addr: SocketAddr,
    },
    /// No whole reply line within the timeout from sending the request (the next request goes
    /// on a fresh connection).
    #[error("gripper {addr}: no reply to {command:?}")]
    Timeout {
        /// Address.
        addr: SocketAddr,
        /// The command.
        command: String,
    },
    /// A reply line longer than 4096 bytes (the next request goes on a fresh connection).
    #[error("gripper {addr}: reply to {command:?} longer than {MAX_LINE_LEN} bytes")]
    LineTooLong {
        /// Address.
        addr: SocketAddr,
        /// The command.
        command: String,
    },
    /// A reply that is not `ack` / `<VAR> <int>`.
    #[error("gripper command {command:?} got unexpected reply {reply:?}")]
    UnexpectedReply {
        /// The command.
        command: String,
        /// The reply.
        reply: String,
    },
    /// The gripper reports a fault (FLT != 0).
    #[error("gripper fault code {code}")]
    Fault {
        /// FLT value.
        code: u8,
    },
    /// Activation or motion did not finish in time.
    #[error("gripper did not {what} within {timeout:?}")]
    NotDone {
        /// Activation or motion.
        what: &'static str,
        /// The timeout.
        timeout: Duration,
    },
}

/// What a finished gripper motion found (OBJ).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum GripOutcome {
    /// Reached the requested position: nothing between the fingers (OBJ 3).
    ReachedPosition,
    /// Stopped on an object while closing (OBJ 2): the object is held.
    ObjectWhileClosing,
    /// Stopped on an obstacle while opening (OBJ 1).
    ObjectWhileOpening,
}

/// A snapshot of the gripper registers.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct GripperStatus {
    /// STA.
    pub activation: u8,
    /// OBJ.
    pub object: u8,
    /// POS (0 open .. 255 closed).
    pub position: u8,
    /// FLT.
    pub fault: u8,
}

impl GripperStatus {
    /// Finger gap (m) for the 2F-140, linear in POS.
    pub fn opening_m(&self) -> f64 {
        STROKE_M * (1.0 - f64::from(self.position) / 255.0)
    }
}

/// A Robotiq URCap socket connection (reconnected after a timeout, see the module docs), over
/// TCP unless built on another [`Transport`] with [`RobotiqGripper::over`].
#[derive(Debug)]
pub struct RobotiqGripper<T = TcpTransport> {
    addr: SocketAddr,
    link: LineLink<T>,
    poll_period: Duration,
}

impl RobotiqGripper<TcpTransport> {
    /// Connects to the URCap socket.
    pub fn connect(addr: impl ToSocketAddrs, timeout: Duration) -> Result<Self, GripperError> {
        let addr = addr
            .to_socket_addrs()
            .map_err(GripperError::Resolve)?
            .next()
            .ok_or_else(|| {
                GripperError::Resolve(io::Error::new(io::ErrorKind::NotFound, "no address"))
            })?;
        let transport = TcpTransport::connect(addr, timeout, timeout)
            .map_err(|source| GripperError::Io { addr, source })?;
        Ok(Self::over(transport, timeout))
    }
}

impl<T: Transport> RobotiqGripper<T> {
    /// A client over an open `transport`, with `timeout` for every reply.
    pub fn over(transport: T, timeout: Duration) -> Self {
        let link = LineLink::new(transport, timeout);
        Self {
            addr: link.peer(),
            link,
            poll_period: Duration::from_millis(10),
        }
    }

    /// One request/reply round trip. The request line is built on the stack and the reply read
    /// into a reused buffer, so a cycle's status poll does not touch the heap (errors may).
    fn exchange(&mut self, command: std::fmt::Arguments<'_>) -> Result<&str, GripperError> {
        let addr = self.addr;
        let mut line = [0u8; 128];
        let len = {
            let mut cursor = io::Cursor::new(&mut line[..]);
            cursor
                .write_fmt(format_args!("{command}\n"))
                .map_err(|source| GripperError::Io { addr, source })?;
            // At most 128: the cursor's buffer length.
            cursor.position() as usize
        };
        if self.link.is_stale() {
            // A fresh connection, so the late reply on the old one is never read.
            self.link
                .reopen()
                .map_err(|source| GripperError::Io { addr, source })?;
            log::info!("gripper {addr}: reconnected after a reply timeout");
        }
        self.link
            .send(&line[..len])
            .map_err(|source| GripperError::Io { addr, source })?;
        match self.link.read_line() {
            Ok(reply) => Ok(reply.trim()),
            Err(LineError::Closed) => Err(GripperError::Closed { addr }),
            Err(LineError::Timeout) => Err(GripperError::Timeout {
                addr,
                command: command.to_string(),
            }),
            Err(LineError::TooLong) => Err(GripperError::LineTooLong {
                addr,
                command: command.to_string(),
            }),
            Err(LineError::Io(source)) => Err(GripperError::Io { addr, source }),
        }
    }

    /// `SET` one or more variables in one command (applied together).
    pub fn set(&mut self, vars: &[(&str, u8)]) -> Result<(), GripperError> {
        let mut command = String::from("SET");
        for (name, value) in vars {
            command.push_str(&format!(" {name} {value}"));
        }
        let reply = self.exchange(format_args!("{command}"))?;
        if reply == "ack" {
            Ok(())
        } else {
            let reply = reply.to_string();
            Err(GripperError::UnexpectedReply { command, reply })
        }
    }

    /// `GET` one variable.
    pub fn get(&mut self, var: &str) -> Result<u8, GripperError> {
        let reply = self.exchange(format_args!("GET {var}"))?;
        let value = reply
            .split_once(' ')
            .filter(|(name, _)| *name == var)
            .and_then(|(_, v)| v.trim().parse::<u8>().ok());
        match value {
            Some(v) => Ok(v),
            None => {
                let reply = reply.to_string();
                Err(GripperError::UnexpectedReply {
                    command: format!("GET {var}"),
                    reply,
                })
            }
        }
    }

    /// Reads STA, OBJ, POS and FLT.
    pub fn status(&mut self) -> Result<GripperStatus, GripperError> {
        Ok(GripperStatus {
            activation: self.get("STA")?,
            object: self.get("OBJ")?,
            position: self.get("POS")?,
            fault: self.get("FLT")?,
        })
    }

    /// Runs `job` to its end, one request per poll, pausing between status polls: the blocking
    /// form of [`GripperJob`], timed on the local monotonic clock.
    fn run_blocking(&mut self, mut job: GripperJob) -> Result<GripperProgress, GripperError> {
        let t0 = Instant::now();
        loop {
            match job.poll(self, t0.elapsed())? {
                GripperProgress::Pending => {
                    if job.is_waiting() {
                        std::thread::sleep(self.poll_period);
                    }
                }
                done => return Ok(done),
            }
        }
    }

    /// Activates the gripper if it is not active yet and waits for STA = 3.
    pub fn activate(&mut self, timeout: Duration) -> Result<(), GripperError> {
        self.run_blocking(GripperJob::activate(timeout, Duration::ZERO))
            .map(|_| ())
    }

    /// Moves the fingers to `position` (0 open .. 255 closed) and waits until they stop.
    pub fn move_to(
        &mut self,
        position: u8,
        speed: u8,
        force: u8,
        timeout: Duration,
    ) -> Result<GripOutcome, GripperError> {
        let job = GripperJob::move_to(position, speed, force, timeout, Duration::ZERO);
        match self.run_blocking(job)? {
            GripperProgress::Moved(outcome) => Ok(outcome),
            // A move job ends only in Moved or an error.
            GripperProgress::Pending | GripperProgress::Activated => {
                unreachable!("a gripper move job ended without a move outcome")
            }
        }
    }

    /// Opens fully.
    pub fn open(&mut self, timeout: Duration) -> Result<GripOutcome, GripperError> {
        self.move_to(0, 255, 128, timeout)
    }

    /// Closes fully with moderate force; [`GripOutcome::ObjectWhileClosing`] means it holds something.
    pub fn close(&mut self, timeout: Duration) -> Result<GripOutcome, GripperError> {
        self.move_to(255, 255, 128, timeout)
    }
}

/// Where a [`GripperJob`] stands after a poll.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum GripperProgress {
    /// Not done; poll again next cycle.
    Pending,
    /// An activation-only job finished: STA = 3.
    Activated,
    /// A move finished.
    Moved(GripOutcome),
}

/// One request the job sends next.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum GripperStep {
    /// GET STA: already active?
    CheckActive,
    /// SET ACT 0 (a reset clears faults, as the URCap does on activation).
    Reset,
    /// SET ACT 1.
    Activate,
    /// GET FLT, then GET STA, until STA = 3.
    WaitActiveFault,
    WaitActiveSta,
    /// SET POS SPE FOR GTO.
    Command,
    /// GET PRE until it echoes the request, so OBJ refers to this motion, not the last one.
    WaitEcho,
    /// GET FLT, then GET OBJ, until OBJ != 0.
    WaitDoneFault,
    WaitDoneObj,
}

/// A gripper activation and/or move as a state machine that sends **one** request per
/// [`GripperJob::poll`], with every timeout measured on the caller's clock (`now`, a monotonic
/// time from the caller: wall time on the robot, simulated time in HIL). This is what lets a
/// cyclic executive drive the gripper without blocking a cycle, and lets a stopped simulated
/// clock stop its timeouts too. The blocking [`RobotiqGripper::activate`] and
/// [`RobotiqGripper::move_to`] run the same machine.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct GripperJob {
    /// POS, SPE, FOR of the move; `None` for activation only.
    target: Option<(u8, u8, u8)>,
    step: GripperStep,
    timeout: Duration,
    /// When the current phase (activation, or motion) began, on the caller's clock.
    phase_started: Duration,
}

impl GripperJob {
    /// Activates if needed (STA != 3), within `timeout` from `now`.
    pub fn activate(timeout: Duration, now: Duration) -> Self {
        Self {
            target: None,
            step: GripperStep::CheckActive,
            timeout,
            phase_started: now,
        }
    }

    /// Moves without checking activation; the move must finish within `timeout` from `now`.
    pub fn move_to(position: u8, speed: u8, force: u8, timeout: Duration, now: Duration) -> Self {
        Self {
            target: Some((position, speed, force)),
            step: GripperStep::Command,
            timeout,
            phase_started: now,
        }
    }

    /// Activates if needed (within `timeout`), then moves (within `timeout` from the command).
    pub fn activate_and_move_to(
        position: u8,
        speed: u8,
        force: u8,
        timeout: Duration,
        now: Duration,
    ) -> Self {
        Self {
            target: Some((position, speed, force)),
            step: GripperStep::CheckActive,
            timeout,
            phase_started: now,
        }
    }

    /// True while the job only polls status (worth pausing between polls when blocking).
    pub fn is_waiting(&self) -> bool {
        matches!(
            self.step,
            GripperStep::WaitActiveFault
                | GripperStep::WaitActiveSta
                | GripperStep::WaitEcho
                | GripperStep::WaitDoneFault
                | GripperStep::WaitDoneObj
        )
    }

    fn expired(&self, now: Duration) -> bool {
        now.saturating_sub(self.phase_started) >= self.timeout
    }

    /// After activation: the move, or done.
    fn activated(&mut self, now: Duration) -> GripperProgress {
        if self.target.is_some() {
            self.step = GripperStep::Command;
            self.phase_started = now;
            GripperProgress::Pending
        } else {
            GripperProgress::Activated
        }
    }

    /// Sends this cycle's one request and advances. An error ends the job.
    pub fn poll<T: Transport>(
        &mut self,
        g: &mut RobotiqGripper<T>,
        now: Duration,
    ) -> Result<GripperProgress, GripperError> {
        let timeout = self.timeout;
        match self.step {
            GripperStep::CheckActive => {
                if g.get("STA")? == 3 {
                    return Ok(self.activated(now));
                }
                self.step = GripperStep::Reset;
            }
            GripperStep::Reset => {
                g.set(&[("ACT", 0)])?;
                self.step = GripperStep::Activate;
            }
            GripperStep::Activate => {
                g.set(&[("ACT", 1)])?;
                self.step = GripperStep::WaitActiveFault;
            }
            GripperStep::WaitActiveFault => {
                let fault = g.get("FLT")?;
                if fault != 0 {
                    return Err(GripperError::Fault { code: fault });
                }
                self.step = GripperStep::WaitActiveSta;
            }
            GripperStep::WaitActiveSta => {
                if g.get("STA")? == 3 {
                    return Ok(self.activated(now));
                }
                if self.expired(now) {
                    return Err(GripperError::NotDone {
                        what: "activate",
                        timeout,
                    });
                }
                self.step = GripperStep::WaitActiveFault;
            }
            GripperStep::Command => {
                let (position, speed, force) = self.target.unwrap_or((0, 0, 0));
                g.set(&[
                    ("POS", position),
                    ("SPE", speed),
                    ("FOR", force),
                    ("GTO", 1),
                ])?;
                self.phase_started = now;
                self.step = GripperStep::WaitEcho;
            }
            GripperStep::WaitEcho => {
                let position = self.target.map_or(0, |t| t.0);
                if g.get("PRE")? == position {
                    self.step = GripperStep::WaitDoneFault;
                } else if self.expired(now) {
                    return Err(GripperError::NotDone {
                        what: "accept the request",
                        timeout,
                    });
                }
            }
            GripperStep::WaitDoneFault => {
                let fault = g.get("FLT")?;
                if fault != 0 {
                    return Err(GripperError::Fault { code: fault });
                }
                self.step = GripperStep::WaitDoneObj;
            }
            GripperStep::WaitDoneObj => {
                match g.get("OBJ")? {
                    1 => return Ok(GripperProgress::Moved(GripOutcome::ObjectWhileOpening)),
                    2 => return Ok(GripperProgress::Moved(GripOutcome::ObjectWhileClosing)),
                    3 => return Ok(GripperProgress::Moved(GripOutcome::ReachedPosition)),
                    _ => {}
                }
                if self.expired(now) {
                    return Err(GripperError::NotDone {
                        what: "finish moving",
                        timeout,
                    });
                }
                self.step = GripperStep::WaitDoneFault;
            }
        }
        Ok(GripperProgress::Pending)
    }
}
