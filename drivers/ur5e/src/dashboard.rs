//! Dashboard server client (port 29999): one ASCII line per command, one reply line.
//!
//! Replies are checked against the exact strings of PolyScope 5 (reference §4); anything
//! else is a [`DashboardError::UnexpectedReply`] naming the command and the reply.
//!
//! Each reply has one deadline (the client's timeout from when the command was sent), however
//! the server spreads its bytes. The protocol has no sequence numbers or echo, so a reply that
//! misses its deadline could not be told from the next command's answer: after a timeout (or
//! an over-long line) the client drops that connection and sends its next command on a fresh
//! one (welcome line checked again), so a late reply is never read at all.

use std::io;
use std::net::{SocketAddr, ToSocketAddrs};
use std::time::Duration;

use thiserror::Error;

use crate::line_link::{LineError, LineLink, MAX_LINE_LEN};
use crate::transport::{TcpTransport, Transport};

/// Default dashboard port.
pub const DASHBOARD_PORT: u16 = 29999;
/// The welcome line the server sends on connect.
pub const WELCOME: &str = "Connected: Universal Robots Dashboard Server";

/// Errors of dashboard commands.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum DashboardError {
    /// The address did not resolve.
    #[error("cannot resolve dashboard address: {0}")]
    Resolve(io::Error),
    /// Socket failure.
    #[error("dashboard {addr}: {source}")]
    Io {
        /// Server address.
        addr: SocketAddr,
        /// Underlying error.
        source: io::Error,
    },
    /// The server closed the connection.
    #[error("dashboard {addr} closed the connection")]
    Closed {
        /// Server address.
        addr: SocketAddr,
    },
    /// No whole reply line within the timeout from sending the command (the next command goes
    /// on a fresh connection).
    #[error("dashboard {addr}: no reply to {command:?} within {timeout:?}")]
    Timeout {
        /// Server address.
        addr: SocketAddr,
        /// The command.
        command: String,
        /// The timeout.
        timeout: Duration,
    },
    /// The reply is not the documented one.
    #[error("dashboard command {command:?} got unexpected reply {reply:?}")]
    UnexpectedReply {
        /// The command.
        command: String,
        /// The reply line.
        reply: String,
    },
    /// A reply line longer than 4096 bytes (the next command goes on a fresh connection).
    #[error("dashboard {addr}: reply to {command:?} longer than {MAX_LINE_LEN} bytes")]
    LineTooLong {
        /// Server address.
        addr: SocketAddr,
        /// The command.
        command: String,
    },
    /// The command text would break the line protocol.
    #[error("dashboard command {command:?} contains a line break")]
    BadCommand {
        /// The command.
        command: String,
    },
}

/// Robot mode (reference §2.7), as reported by `robotmode` and RTDE `robot_mode`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum RobotMode {
    /// -1.
    NoController,
    /// 0.
    Disconnected,
    /// 1.
    ConfirmSafety,
    /// 2.
    Booting,
    /// 3.
    PowerOff,
    /// 4.
    PowerOn,
    /// 5.
    Idle,
    /// 6.
    Backdrive,
    /// 7: brakes released, ready to move.
    Running,
    /// 8.
    UpdatingFirmware,
}

impl RobotMode {
    const TABLE: [(RobotMode, i32, &'static str); 10] = [
        (Self::NoController, -1, "NO_CONTROLLER"),
        (Self::Disconnected, 0, "DISCONNECTED"),
        (Self::ConfirmSafety, 1, "CONFIRM_SAFETY"),
        (Self::Booting, 2, "BOOTING"),
        (Self::PowerOff, 3, "POWER_OFF"),
        (Self::PowerOn, 4, "POWER_ON"),
        (Self::Idle, 5, "IDLE"),
        (Self::Backdrive, 6, "BACKDRIVE"),
        (Self::Running, 7, "RUNNING"),
        (Self::UpdatingFirmware, 8, "UPDATING_FIRMWARE"),
    ];

    /// From the RTDE `robot_mode` value.
    pub fn from_code(code: i32) -> Option<Self> {
        Self::TABLE.iter().find(|e| e.1 == code).map(|e| e.0)
    }

    /// The RTDE value.
    pub fn code(self) -> i32 {
        Self::TABLE.iter().find(|e| e.0 == self).map_or(-1, |e| e.1)
    }

    /// From the dashboard name.
    pub fn from_name(name: &str) -> Option<Self> {
        Self::TABLE.iter().find(|e| e.2 == name).map(|e| e.0)
    }

    /// The dashboard name.
    pub fn name(self) -> &'static str {
        Self::TABLE
            .iter()
            .find(|e| e.0 == self)
            .map_or("NO_CONTROLLER", |e| e.2)
    }
}

/// Safety mode / status (reference §2.7; the values 1..=13 of PolyScope 5).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum SafetyMode {
    /// 1.
    Normal,
    /// 2.
    Reduced,
    /// 3: the arm hit something or a limit; needs `unlock protective stop`.
    ProtectiveStop,
    /// 4.
    Recovery,
    /// 5.
    SafeguardStop,
    /// 6.
    SystemEmergencyStop,
    /// 7.
    RobotEmergencyStop,
    /// 8.
    Violation,
    /// 9.
    Fault,
    /// 10.
    ValidateJointId,
    /// 11.
    UndefinedSafetyMode,
    /// 12.
    AutomaticModeSafeguardStop,
    /// 13.
    SystemThreePositionEnablingStop,
}

impl SafetyMode {
    const TABLE: [(SafetyMode, i32, &'static str); 13] = [
        (Self::Normal, 1, "NORMAL"),
        (Self::Reduced, 2, "REDUCED"),
        (Self::ProtectiveStop, 3, "PROTECTIVE_STOP"),
        (Self::Recovery, 4, "RECOVERY"),
        (Self::SafeguardStop, 5, "SAFEGUARD_STOP"),
        (Self::SystemEmergencyStop, 6, "SYSTEM_EMERGENCY_STOP"),
        (Self::RobotEmergencyStop, 7, "ROBOT_EMERGENCY_STOP"),
        (Self::Violation, 8, "VIOLATION"),
        (Self::Fault, 9, "FAULT"),
        (Self::ValidateJointId, 10, "VALIDATE_JOINT_ID"),
        (Self::UndefinedSafetyMode, 11, "UNDEFINED_SAFETY_MODE"),
        (
            Self::AutomaticModeSafeguardStop,
            12,
            "AUTOMATIC_MODE_SAFEGUARD_STOP",
        ),
        (
            Self::SystemThreePositionEnablingStop,
            13,
            "SYSTEM_THREE_POSITION_ENABLING_STOP",
        ),
    ];

    /// From the RTDE `safety_mode` value.
    pub fn from_code(code: i32) -> Option<Self> {
        Self::TABLE.iter().find(|e| e.1 == code).map(|e| e.0)
    }

    /// The RTDE value.
    pub fn code(self) -> i32 {
        Self::TABLE.iter().find(|e| e.0 == self).map_or(11, |e| e.1)
    }

    /// From the dashboard name.
    pub fn from_name(name: &str) -> Option<Self> {
        Self::TABLE.iter().find(|e| e.2 == name).map(|e| e.0)
    }

    /// The dashboard name.
    pub fn name(self) -> &'static str {
        Self::TABLE
            .iter()
            .find(|e| e.0 == self)
            .map_or("UNDEFINED_SAFETY_MODE", |e| e.2)
    }
}

/// Program state from `programState`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ProgramState {
    /// `STOPPED <name>`.
    Stopped(String),
    /// `PLAYING <name>`.
    Playing(String),
    /// `PAUSED <name>`.
    Paused(String),
}

/// A dashboard connection (reconnected after a timeout, see the module docs), over TCP unless
/// built on another [`Transport`] with [`DashboardClient::over`].
#[derive(Debug)]
pub struct DashboardClient<T = TcpTransport> {
    addr: SocketAddr,
    link: LineLink<T>,
}

impl DashboardClient<TcpTransport> {
    /// Connects and checks the welcome line.
    pub fn connect(addr: impl ToSocketAddrs, timeout: Duration) -> Result<Self, DashboardError> {
        let addr = addr
            .to_socket_addrs()
            .map_err(DashboardError::Resolve)?
            .next()
            .ok_or_else(|| {
                DashboardError::Resolve(io::Error::new(io::ErrorKind::NotFound, "no address"))
            })?;
        let transport = TcpTransport::connect(addr, timeout, timeout)
            .map_err(|source| DashboardError::Io { addr, source })?;
        Self::over(transport, timeout)
    }
}

impl<T: Transport> DashboardClient<T> {
    /// A client over an open `transport` (its peer sends the welcome line first), with
    /// `timeout` for every reply; checks the welcome line.
    pub fn over(transport: T, timeout: Duration) -> Result<Self, DashboardError> {
        let link = LineLink::new(transport, timeout);
        let mut client = Self {
            addr: link.peer(),
            link,
        };
        client.check_welcome()?;
        Ok(client)
    }

    fn check_welcome(&mut self) -> Result<(), DashboardError> {
        let welcome = self.read_line("<welcome>")?;
        if welcome != WELCOME {
            return Err(DashboardError::UnexpectedReply {
                command: "<welcome>".into(),
                reply: welcome,
            });
        }
        Ok(())
    }

    /// A fresh connection after a timeout, so the late reply on the old one is never read.
    fn resync(&mut self) -> Result<(), DashboardError> {
        let addr = self.addr;
        self.link
            .reopen()
            .map_err(|source| DashboardError::Io { addr, source })?;
        log::info!("dashboard {addr}: reconnected after a reply timeout");
        self.check_welcome()
    }

    fn read_line(&mut self, command: &str) -> Result<String, DashboardError> {
        let addr = self.addr;
        let timeout = self.link.timeout();
        match self.link.read_line() {
            Ok(line) => Ok(line.trim_end_matches('\r').to_string()),
            Err(LineError::Closed) => Err(DashboardError::Closed { addr }),
            Err(LineError::Timeout) => Err(DashboardError::Timeout {
                addr,
                command: command.into(),
                timeout,
            }),
            Err(LineError::TooLong) => Err(DashboardError::LineTooLong {
                addr,
                command: command.into(),
            }),
            Err(LineError::Io(source)) => Err(DashboardError::Io { addr, source }),
        }
    }

    /// Sends one command line and returns the reply line (without the line break).
    pub fn command(&mut self, command: &str) -> Result<String, DashboardError> {
        if command.contains(['\n', '\r']) {
            return Err(DashboardError::BadCommand {
                command: command.into(),
            });
        }
        if self.link.is_stale() {
            self.resync()?;
        }
        let addr = self.addr;
        let mut line = String::with_capacity(command.len() + 1);
        line.push_str(command);
        line.push('\n');
        self.link
            .send(line.as_bytes())
            .map_err(|source| DashboardError::Io { addr, source })?;
        self.read_line(command)
    }

    fn expect(&mut self, command: &str, reply: &str) -> Result<(), DashboardError> {
        let got = self.command(command)?;
        if got == reply {
            Ok(())
        } else {
            Err(DashboardError::UnexpectedReply {
                command: command.into(),
                reply: got,
            })
        }
    }

    fn unexpected(command: &str, reply: String) -> DashboardError {
        DashboardError::UnexpectedReply {
            command: command.into(),
            reply,
        }
    }

    /// `power on` (robot goes POWER_ON -> IDLE).
    pub fn power_on(&mut self) -> Result<(), DashboardError> {
        self.expect("power on", "Powering on")
    }

    /// `power off`.
    pub fn power_off(&mut self) -> Result<(), DashboardError> {
        self.expect("power off", "Powering off")
    }

    /// `brake release` (IDLE -> RUNNING).
    pub fn brake_release(&mut self) -> Result<(), DashboardError> {
        self.expect("brake release", "Brake releasing")
    }

    /// `play` the loaded program.
    pub fn play(&mut self) -> Result<(), DashboardError> {
        self.expect("play", "Starting program")
    }

    /// `stop` the running program (the arm stops).
    pub fn stop(&mut self) -> Result<(), DashboardError> {
        self.expect("stop", "Stopped")
    }

    /// `pause` the running program.
    pub fn pause(&mut self) -> Result<(), DashboardError> {
        self.expect("pause", "Pausing program")
    }

    /// `unlock protective stop`.
    pub fn unlock_protective_stop(&mut self) -> Result<(), DashboardError> {
        self.expect("unlock protective stop", "Protective stop releasing")
    }

    /// `close safety popup`.
    pub fn close_safety_popup(&mut self) -> Result<(), DashboardError> {
        self.expect("close safety popup", "closing safety popup")
    }

    /// `robotmode`.
    pub fn robot_mode(&mut self) -> Result<RobotMode, DashboardError> {
        let reply = self.command("robotmode")?;
        reply
            .strip_prefix("Robotmode: ")
            .and_then(RobotMode::from_name)
            .ok_or_else(|| Self::unexpected("robotmode", reply.clone()))
    }

    /// `safetystatus` (PolyScope 5.4 and later).
    pub fn safety_status(&mut self) -> Result<SafetyMode, DashboardError> {
        let reply = self.command("safetystatus")?;
        reply
            .strip_prefix("Safetystatus: ")
            .and_then(SafetyMode::from_name)
            .ok_or_else(|| Self::unexpected("safetystatus", reply.clone()))
    }

    /// `programState`.
    pub fn program_state(&mut self) -> Result<ProgramState, DashboardError> {
        let reply = self.command("programState")?;
        let (state, name) = reply.split_once(' ').unwrap_or((reply.as_str(), ""));
        let name = name.to_string();
        match state {
            "STOPPED" => Ok(ProgramState::Stopped(name)),
            "PLAYING" => Ok(ProgramState::Playing(name)),
            "PAUSED" => Ok(ProgramState::Paused(name)),
            _ => Err(Self::unexpected("programState", reply)),
        }
    }

    /// `running`.
    pub fn running(&mut self) -> Result<bool, DashboardError> {
        match self.command("running")?.as_str() {
            "Program running: true" => Ok(true),
            "Program running: false" => Ok(false),
            other => Err(Self::unexpected("running", other.into())),
        }
    }

    /// `is in remote control` (5.6 and later).
    pub fn is_in_remote_control(&mut self) -> Result<bool, DashboardError> {
        match self.command("is in remote control")?.as_str() {
            "true" => Ok(true),
            "false" => Ok(false),
            other => Err(Self::unexpected("is in remote control", other.into())),
        }
    }

    /// `PolyscopeVersion`: returns the four-part version (`5.21.0.1210631`).
    pub fn polyscope_version(&mut self) -> Result<String, DashboardError> {
        let reply = self.command("PolyscopeVersion")?;
        // "URSoftware 5.19.0.1210631 (Oct 23 2024)": the text between the first space and " (".
        let version = reply
            .split_once(' ')
            .map(|(_, rest)| rest.split(" (").next().unwrap_or(rest).to_string());
        match version {
            Some(v)
                if v.split('.').count() == 4 && v.split('.').all(|p| p.parse::<u32>().is_ok()) =>
            {
                Ok(v)
            }
            _ => Err(Self::unexpected("PolyscopeVersion", reply)),
        }
    }

    /// `get serial number` (digits only).
    pub fn serial_number(&mut self) -> Result<String, DashboardError> {
        let reply = self.command("get serial number")?;
        if !reply.is_empty() && reply.bytes().all(|b| b.is_ascii_digit()) {
            Ok(reply)
        } else {
            Err(Self::unexpected("get serial number", reply))
        }
    }

    /// `load <program.urp>`.
    pub fn load(&mut self, program: &str) -> Result<(), DashboardError> {
        let command = format!("load {program}");
        let expected = format!("Loading program: {program}");
        self.expect(&command, &expected)
    }

    /// `quit`: the server answers `Disconnected` and closes.
    pub fn quit(mut self) -> Result<(), DashboardError> {
        self.expect("quit", "Disconnected")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mode_tables_round_trip() {
        for code in -1..=8 {
            let m = RobotMode::from_code(code).unwrap();
            assert_eq!(m.code(), code);
            assert_eq!(RobotMode::from_name(m.name()), Some(m));
        }
        for code in 1..=13 {
            let m = SafetyMode::from_code(code).unwrap();
            assert_eq!(m.code(), code);
            assert_eq!(SafetyMode::from_name(m.name()), Some(m));
        }
        assert_eq!(RobotMode::from_code(9), None);
        assert_eq!(SafetyMode::from_code(0), None);
    }
}
