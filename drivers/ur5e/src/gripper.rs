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

use std::io::{self, BufRead, BufReader, Read, Write};
use std::net::{SocketAddr, TcpStream, ToSocketAddrs};
use std::time::{Duration, Instant};

use thiserror::Error;

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
    /// No reply in time.
    #[error("gripper {addr}: no reply to {command:?}")]
    Timeout {
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

/// A Robotiq URCap socket connection.
#[derive(Debug)]
pub struct RobotiqGripper {
    addr: SocketAddr,
    reader: BufReader<TcpStream>,
    writer: TcpStream,
    line: String,
    poll_period: Duration,
}

impl RobotiqGripper {
    /// Connects to the URCap socket.
    pub fn connect(addr: impl ToSocketAddrs, timeout: Duration) -> Result<Self, GripperError> {
        let addr = addr
            .to_socket_addrs()
            .map_err(GripperError::Resolve)?
            .next()
            .ok_or_else(|| {
                GripperError::Resolve(io::Error::new(io::ErrorKind::NotFound, "no address"))
            })?;
        let io_err = |source| GripperError::Io { addr, source };
        let stream = TcpStream::connect_timeout(&addr, timeout).map_err(io_err)?;
        stream.set_nodelay(true).map_err(io_err)?;
        stream.set_read_timeout(Some(timeout)).map_err(io_err)?;
        stream.set_write_timeout(Some(timeout)).map_err(io_err)?;
        let writer = stream.try_clone().map_err(io_err)?;
        Ok(Self {
            addr,
            reader: BufReader::new(stream),
            writer,
            line: String::new(),
            poll_period: Duration::from_millis(10),
        })
    }

    fn exchange(&mut self, command: &str) -> Result<String, GripperError> {
        let addr = self.addr;
        self.writer
            .write_all(format!("{command}\n").as_bytes())
            .map_err(|source| GripperError::Io { addr, source })?;
        self.line.clear();
        match (&mut self.reader).take(4096).read_line(&mut self.line) {
            Ok(0) => Err(GripperError::Closed { addr }),
            Ok(_) => Ok(self.line.trim().to_string()),
            Err(e)
                if matches!(
                    e.kind(),
                    io::ErrorKind::WouldBlock | io::ErrorKind::TimedOut
                ) =>
            {
                Err(GripperError::Timeout {
                    addr,
                    command: command.into(),
                })
            }
            Err(source) => Err(GripperError::Io { addr, source }),
        }
    }

    /// `SET` one or more variables in one command (applied together).
    pub fn set(&mut self, vars: &[(&str, u8)]) -> Result<(), GripperError> {
        let mut command = String::from("SET");
        for (name, value) in vars {
            command.push_str(&format!(" {name} {value}"));
        }
        let reply = self.exchange(&command)?;
        if reply == "ack" {
            Ok(())
        } else {
            Err(GripperError::UnexpectedReply { command, reply })
        }
    }

    /// `GET` one variable.
    pub fn get(&mut self, var: &str) -> Result<u8, GripperError> {
        let command = format!("GET {var}");
        let reply = self.exchange(&command)?;
        let value = reply
            .split_once(' ')
            .filter(|(name, _)| *name == var)
            .and_then(|(_, v)| v.trim().parse::<u8>().ok());
        value.ok_or(GripperError::UnexpectedReply { command, reply })
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

    /// Activates the gripper if it is not active yet and waits for STA = 3.
    pub fn activate(&mut self, timeout: Duration) -> Result<(), GripperError> {
        if self.get("STA")? == 3 {
            return Ok(());
        }
        // A reset (ACT 0) first clears faults, as the URCap does on activation.
        self.set(&[("ACT", 0)])?;
        self.set(&[("ACT", 1)])?;
        let deadline = Instant::now() + timeout;
        loop {
            let status = self.status()?;
            if status.fault != 0 {
                return Err(GripperError::Fault { code: status.fault });
            }
            if status.activation == 3 {
                return Ok(());
            }
            if Instant::now() >= deadline {
                return Err(GripperError::NotDone {
                    what: "activate",
                    timeout,
                });
            }
            std::thread::sleep(self.poll_period);
        }
    }

    /// Moves the fingers to `position` (0 open .. 255 closed) and waits until they stop.
    pub fn move_to(
        &mut self,
        position: u8,
        speed: u8,
        force: u8,
        timeout: Duration,
    ) -> Result<GripOutcome, GripperError> {
        self.set(&[
            ("POS", position),
            ("SPE", speed),
            ("FOR", force),
            ("GTO", 1),
        ])?;
        let deadline = Instant::now() + timeout;
        // The request must be echoed (PRE) before OBJ refers to this motion, not the last one.
        loop {
            if self.get("PRE")? == position {
                break;
            }
            if Instant::now() >= deadline {
                return Err(GripperError::NotDone {
                    what: "accept the request",
                    timeout,
                });
            }
            std::thread::sleep(self.poll_period);
        }
        loop {
            let status = self.status()?;
            if status.fault != 0 {
                return Err(GripperError::Fault { code: status.fault });
            }
            match status.object {
                1 => return Ok(GripOutcome::ObjectWhileOpening),
                2 => return Ok(GripOutcome::ObjectWhileClosing),
                3 => return Ok(GripOutcome::ReachedPosition),
                _ => {}
            }
            if Instant::now() >= deadline {
                return Err(GripperError::NotDone {
                    what: "finish moving",
                    timeout,
                });
            }
            std::thread::sleep(self.poll_period);
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
