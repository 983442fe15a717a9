//! URScript programs and their sender (secondary interface, port 30002).
//!
//! Programs are built from typed commands, so a NaN or a missing `end` can never reach the
//! controller. A new program replaces the one running (G-SCRIPT): that is how `stopj` stops
//! a `movej` in progress.

use std::fmt::Write as _;
use std::io::{self, Read, Write};
use std::net::{SocketAddr, TcpStream, ToSocketAddrs};
use std::time::Duration;

use thiserror::Error;

use crate::pose::TcpPose;

/// Default secondary-interface port (URScript in, state out at 10 Hz).
pub const SECONDARY_PORT: u16 = 30002;
/// Default primary-interface port.
pub const PRIMARY_PORT: u16 = 30001;
/// Default real-time interface port.
pub const REALTIME_PORT: u16 = 30003;

/// What the controller does when an RTDE watchdog input goes stale (`rtde_set_watchdog`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum WatchdogAction {
    /// Log only.
    Ignore,
    /// Pause the program.
    Pause,
    /// Stop the program (the arm decelerates to rest).
    Stop,
}

impl WatchdogAction {
    fn word(self) -> &'static str {
        match self {
            Self::Ignore => "ignore",
            Self::Pause => "pause",
            Self::Stop => "stop",
        }
    }
}

/// The URScript subset the unload skills use (and the simulator executes).
#[derive(Debug, Clone, PartialEq)]
pub enum ScriptCommand {
    /// `movej(q, a, v)`: joint-space move, all joints arrive together.
    MoveJ {
        /// Target joints (rad).
        q_rad: [f64; 6],
        /// Leading-joint acceleration (rad/s^2).
        accel_radps2: f64,
        /// Leading-joint speed (rad/s).
        speed_radps: f64,
    },
    /// `movel(p[...], a, v)`: straight-line tool move.
    MoveL {
        /// Target TCP pose in the base frame.
        pose: TcpPose,
        /// Tool acceleration (m/s^2).
        accel_mps2: f64,
        /// Tool speed (m/s).
        speed_mps: f64,
    },
    /// `stopj(a)`: decelerate in joint space to rest.
    StopJ {
        /// Deceleration (rad/s^2).
        decel_radps2: f64,
    },
    /// `stopl(a)`: decelerate the tool to rest.
    StopL {
        /// Deceleration (m/s^2).
        decel_mps2: f64,
    },
    /// `speedj(qd, a, t)`: joint velocity for `t` seconds.
    SpeedJ {
        /// Joint speeds (rad/s).
        qd_radps: [f64; 6],
        /// Acceleration (rad/s^2).
        accel_radps2: f64,
        /// Duration (s).
        time_s: f64,
    },
    /// `set_tcp(p[...])`: tool centre point relative to the flange (e.g. the gripper's length).
    SetTcp(TcpPose),
    /// `sleep(t)`.
    Sleep {
        /// Seconds.
        time_s: f64,
    },
    /// `textmsg("...")`: a log line on the controller.
    TextMsg(String),
    /// `rtde_set_watchdog("name", f, "action")`: act when the RTDE input `name` is not
    /// updated at least `min_frequency_hz` times per second.
    RtdeWatchdog {
        /// The watched RTDE input variable.
        input: String,
        /// Minimum update frequency (Hz).
        min_frequency_hz: f64,
        /// What to do when it goes stale.
        action: WatchdogAction,
    },
}

/// Errors while building or sending a program.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum ScriptError {
    /// A number is NaN or infinite.
    #[error("URScript {command}: argument {argument} is not finite")]
    NonFinite {
        /// The command.
        command: &'static str,
        /// The argument.
        argument: &'static str,
    },
    /// A speed, acceleration or time is not positive.
    #[error("URScript {command}: {argument} must be positive, got {value}")]
    NotPositive {
        /// The command.
        command: &'static str,
        /// The argument.
        argument: &'static str,
        /// The value.
        value: f64,
    },
    /// A text that would break the script (quote or line break) or a bad program name.
    #[error("URScript text {text:?} is not allowed: {reason}")]
    BadText {
        /// The text.
        text: String,
        /// Why.
        reason: &'static str,
    },
    /// Raw script text not framed as `def name():` ... `end`.
    #[error("URScript program is not framed as def ...(): ... end")]
    BadFraming,
    /// The address did not resolve.
    #[error("cannot resolve URScript address: {0}")]
    Resolve(io::Error),
    /// Socket failure.
    #[error("URScript connection {addr}: {source}")]
    Io {
        /// Controller address.
        addr: SocketAddr,
        /// Underlying error.
        source: io::Error,
    },
    /// The controller closed the connection.
    #[error("URScript connection {addr} closed by the controller")]
    Closed {
        /// Controller address.
        addr: SocketAddr,
    },
}

fn finite(command: &'static str, argument: &'static str, v: f64) -> Result<(), ScriptError> {
    if v.is_finite() {
        Ok(())
    } else {
        Err(ScriptError::NonFinite { command, argument })
    }
}

fn positive(command: &'static str, argument: &'static str, v: f64) -> Result<(), ScriptError> {
    finite(command, argument, v)?;
    if v > 0.0 {
        Ok(())
    } else {
        Err(ScriptError::NotPositive {
            command,
            argument,
            value: v,
        })
    }
}

fn plain_text(text: &str) -> Result<(), ScriptError> {
    if text.contains(['"', '\n', '\r', '\\']) {
        Err(ScriptError::BadText {
            text: text.into(),
            reason: "quotes, backslashes and line breaks are not allowed",
        })
    } else {
        Ok(())
    }
}

fn list(out: &mut String, v: &[f64]) {
    out.push('[');
    for (i, x) in v.iter().enumerate() {
        if i > 0 {
            out.push_str(", ");
        }
        // Rust's Display never uses an exponent, which URScript would not parse.
        let _ = write!(out, "{x}");
    }
    out.push(']');
}

impl ScriptCommand {
    /// Checks arguments and appends the URScript line (indented, with newline).
    pub fn write_line(&self, out: &mut String) -> Result<(), ScriptError> {
        out.push_str("  ");
        match self {
            Self::MoveJ {
                q_rad,
                accel_radps2,
                speed_radps,
            } => {
                for q in q_rad {
                    finite("movej", "q", *q)?;
                }
                positive("movej", "a", *accel_radps2)?;
                positive("movej", "v", *speed_radps)?;
                out.push_str("movej(");
                list(out, q_rad);
                let _ = write!(out, ", a={accel_radps2}, v={speed_radps})");
            }
            Self::MoveL {
                pose,
                accel_mps2,
                speed_mps,
            } => {
                for x in pose.as_array() {
                    finite("movel", "pose", x)?;
                }
                positive("movel", "a", *accel_mps2)?;
                positive("movel", "v", *speed_mps)?;
                out.push_str("movel(p");
                list(out, &pose.as_array());
                let _ = write!(out, ", a={accel_mps2}, v={speed_mps})");
            }
            Self::StopJ { decel_radps2 } => {
                positive("stopj", "a", *decel_radps2)?;
                let _ = write!(out, "stopj({decel_radps2})");
            }
            Self::StopL { decel_mps2 } => {
                positive("stopl", "a", *decel_mps2)?;
                let _ = write!(out, "stopl({decel_mps2})");
            }
            Self::SpeedJ {
                qd_radps,
                accel_radps2,
                time_s,
            } => {
                for v in qd_radps {
                    finite("speedj", "qd", *v)?;
                }
                positive("speedj", "a", *accel_radps2)?;
                positive("speedj", "t", *time_s)?;
                out.push_str("speedj(");
                list(out, qd_radps);
                let _ = write!(out, ", {accel_radps2}, {time_s})");
            }
            Self::SetTcp(pose) => {
                for x in pose.as_array() {
                    finite("set_tcp", "pose", x)?;
                }
                out.push_str("set_tcp(p");
                list(out, &pose.as_array());
                out.push(')');
            }
            Self::Sleep { time_s } => {
                positive("sleep", "t", *time_s)?;
                let _ = write!(out, "sleep({time_s})");
            }
            Self::TextMsg(text) => {
                plain_text(text)?;
                let _ = write!(out, "textmsg(\"{text}\")");
            }
            Self::RtdeWatchdog {
                input,
                min_frequency_hz,
                action,
            } => {
                plain_text(input)?;
                positive("rtde_set_watchdog", "min_frequency", *min_frequency_hz)?;
                let _ = write!(
                    out,
                    "rtde_set_watchdog(\"{input}\", {min_frequency_hz}, \"{}\")",
                    action.word()
                );
            }
        }
        out.push('\n');
        Ok(())
    }
}

/// A URScript program: `def <name>():`, the commands, `end`.
#[derive(Debug, Clone, PartialEq)]
pub struct UrScriptProgram {
    /// Program name (an identifier).
    pub name: String,
    /// Body, in order.
    pub commands: Vec<ScriptCommand>,
}

impl UrScriptProgram {
    /// A program with the given name and body.
    pub fn new(name: impl Into<String>, commands: Vec<ScriptCommand>) -> Self {
        Self {
            name: name.into(),
            commands,
        }
    }

    /// The script text, validated.
    pub fn to_script(&self) -> Result<String, ScriptError> {
        let ident_ok = self
            .name
            .chars()
            .next()
            .is_some_and(|c| c.is_ascii_alphabetic() || c == '_')
            && self
                .name
                .chars()
                .all(|c| c.is_ascii_alphanumeric() || c == '_');
        if !ident_ok {
            return Err(ScriptError::BadText {
                text: self.name.clone(),
                reason: "program names are identifiers",
            });
        }
        let mut out = String::with_capacity(64 + 96 * self.commands.len());
        let _ = writeln!(out, "def {}():", self.name);
        for c in &self.commands {
            c.write_line(&mut out)?;
        }
        out.push_str("end\n");
        Ok(out)
    }
}

/// Checks the G-SCRIPT framing of raw program text.
pub fn check_framing(script: &str) -> Result<(), ScriptError> {
    let mut lines = script.lines().filter(|l| !l.trim().is_empty());
    let first = lines.next().ok_or(ScriptError::BadFraming)?;
    let last = lines.next_back().ok_or(ScriptError::BadFraming)?;
    let header_ok = (first.starts_with("def ") || first.starts_with("sec "))
        && first.trim_end().ends_with("):");
    if header_ok && last.trim_end() == "end" {
        Ok(())
    } else {
        Err(ScriptError::BadFraming)
    }
}

/// Sends URScript programs on the secondary (or primary/real-time) port.
///
/// The controller streams its state on the same socket; it is read and discarded on every
/// send so the controller never blocks on us.
#[derive(Debug)]
pub struct ScriptSender {
    addr: SocketAddr,
    stream: TcpStream,
    sink: Vec<u8>,
}

impl ScriptSender {
    /// Connects to the URScript port.
    pub fn connect(addr: impl ToSocketAddrs, timeout: Duration) -> Result<Self, ScriptError> {
        let addr = addr
            .to_socket_addrs()
            .map_err(ScriptError::Resolve)?
            .next()
            .ok_or_else(|| {
                ScriptError::Resolve(io::Error::new(io::ErrorKind::NotFound, "no address"))
            })?;
        let io_err = |source| ScriptError::Io { addr, source };
        let stream = TcpStream::connect_timeout(&addr, timeout).map_err(io_err)?;
        stream.set_nodelay(true).map_err(io_err)?;
        stream.set_write_timeout(Some(timeout)).map_err(io_err)?;
        Ok(Self {
            addr,
            stream,
            sink: vec![0u8; 16 * 1024],
        })
    }

    /// The controller address.
    pub fn peer(&self) -> SocketAddr {
        self.addr
    }

    /// Sends a program; it replaces any program running.
    pub fn send(&mut self, program: &UrScriptProgram) -> Result<(), ScriptError> {
        let text = program.to_script()?;
        self.send_raw(&text)
    }

    /// Sends checked raw program text.
    pub fn send_raw(&mut self, script: &str) -> Result<(), ScriptError> {
        check_framing(script)?;
        self.drain()?;
        let addr = self.addr;
        self.stream
            .write_all(script.as_bytes())
            .map_err(|source| ScriptError::Io { addr, source })
    }

    /// Reads and discards the state stream the controller sent since the last call.
    pub fn drain(&mut self) -> Result<(), ScriptError> {
        let addr = self.addr;
        let io_err = |source| ScriptError::Io { addr, source };
        self.stream.set_nonblocking(true).map_err(io_err)?;
        let result = loop {
            match self.stream.read(&mut self.sink) {
                Ok(0) => break Err(ScriptError::Closed { addr }),
                Ok(_) => continue,
                Err(e) if e.kind() == io::ErrorKind::WouldBlock => break Ok(()),
                Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
                Err(source) => break Err(ScriptError::Io { addr, source }),
            }
        };
        self.stream.set_nonblocking(false).map_err(io_err)?;
        result
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn program_text_is_framed_and_exact() {
        let p = UrScriptProgram::new(
            "grop_move",
            vec![
                ScriptCommand::RtdeWatchdog {
                    input: "input_int_register_24".into(),
                    min_frequency_hz: 10.0,
                    action: WatchdogAction::Stop,
                },
                ScriptCommand::MoveJ {
                    q_rad: [0.0, -1.5, 1.25, -0.5, 0.0, 0.125],
                    accel_radps2: 1.4,
                    speed_radps: 1.05,
                },
                ScriptCommand::StopJ { decel_radps2: 2.0 },
            ],
        );
        let text = p.to_script().unwrap();
        assert_eq!(
            text,
            "def grop_move():\n  rtde_set_watchdog(\"input_int_register_24\", 10, \"stop\")\n  \
             movej([0, -1.5, 1.25, -0.5, 0, 0.125], a=1.4, v=1.05)\n  stopj(2)\nend\n"
        );
        check_framing(&text).unwrap();
    }

    #[test]
    fn tiny_numbers_are_written_without_exponent() {
        let mut s = String::new();
        ScriptCommand::Sleep { time_s: 1e-7 }
            .write_line(&mut s)
            .unwrap();
        assert_eq!(s, "  sleep(0.0000001)\n");
    }

    #[test]
    fn non_finite_and_non_positive_arguments_are_rejected() {
        let mut s = String::new();
        let nan = ScriptCommand::MoveJ {
            q_rad: [0.0, f64::NAN, 0.0, 0.0, 0.0, 0.0],
            accel_radps2: 1.0,
            speed_radps: 1.0,
        };
        assert!(matches!(
            nan.write_line(&mut s),
            Err(ScriptError::NonFinite { .. })
        ));
        let zero = ScriptCommand::StopJ { decel_radps2: 0.0 };
        assert!(matches!(
            zero.write_line(&mut s),
            Err(ScriptError::NotPositive { .. })
        ));
        let quote = ScriptCommand::TextMsg("a\"b".into());
        assert!(matches!(
            quote.write_line(&mut s),
            Err(ScriptError::BadText { .. })
        ));
    }

    #[test]
    fn framing_check_rejects_unframed_text() {
        assert!(check_framing("movej([0,0,0,0,0,0])\n").is_err());
        assert!(check_framing("def a():\n  sleep(1)\n").is_err());
        assert!(check_framing("def a():\n  sleep(1)\nend\n").is_ok());
        assert!(UrScriptProgram::new("1bad", vec![]).to_script().is_err());
    }
}
