//! External Control of the Universal Robots Client Library (URCL, the UR ROS 2 driver's
//! robot side), as the simulated controller serves it.
//!
//! URCL runs servers on the PC and sends the robot a program (`external_control.urscript`,
//! headless: over the primary port; with the External Control URCap: the URCap asks the
//! script sender for it with `request_program\n`). That program connects back to three PC
//! sockets and runs a command loop; the simulator recognises the program by its sockets and
//! serves that loop natively (like ur_rtde's control script), on the arm's motion model:
//!
//! - **reverse socket** (URCL default 50001): messages of 8 big-endian `i32`,
//!   `[read_timeout_ms, v0..v5, control_mode]`, values scaled by `MULT_jointstate` (10^6).
//!   The first read blocks; afterwards a message must come within `read_timeout_ms` (0: no
//!   limit) or the program ends ("Socket timed out waiting for command on reverse_socket").
//!   Modes: [`mode`]. In `FORWARD`, `v0` is the trajectory action: 1 receive `v1` points, -1
//!   cancel, 0 nothing.
//! - **trajectory socket** (50003): points of 21 `i32`: block 1 (position, joints or pose),
//!   block 2 (velocities for splines), block 3 (`[velocity, acceleration, ..]` for moves,
//!   accelerations for quintic splines), time (x `MULT_time`, 1000), blend radius or spline
//!   type (x `MULT_time`), motion type ([`motion`]). The robot answers each trajectory with one
//!   `i32` result ([`result`]).
//! - **script command socket** (50004): commands of 28 `i32`, `[command, args..]`.
//!
//! Times are controller time: in lock-step the keep-alive runs on the world's clock.

use std::net::{IpAddr, SocketAddr};

use crate::urscript::ScriptParseError;

/// Control modes of the reverse interface (`control_mode`).
pub mod mode {
    /// The program ends.
    pub const STOPPED: i32 = -2;
    /// No mode yet.
    pub const UNINITIALIZED: i32 = -1;
    /// Hold still.
    pub const IDLE: i32 = 0;
    /// Stream joint targets (`servoj`).
    pub const SERVOJ: i32 = 1;
    /// Stream joint speeds (`speedj`).
    pub const SPEEDJ: i32 = 2;
    /// Trajectory forwarding (points on the trajectory socket).
    pub const FORWARD: i32 = 3;
    /// Stream tool twists (`speedl`).
    pub const SPEEDL: i32 = 4;
    /// Stream poses (servo through IK).
    pub const POSE: i32 = 5;
    /// Freedrive (not emulated).
    pub const FREEDRIVE: i32 = 6;
    /// Tool in contact (not emulated).
    pub const TOOL_IN_CONTACT: i32 = 7;
    /// Torque control (not emulated).
    pub const TORQUE: i32 = 8;
}

/// Trajectory actions in `FORWARD` mode (reverse message `v0`).
pub mod trajectory_action {
    /// Receive `v1` points.
    pub const RECEIVE: i32 = 1;
    /// Nothing.
    pub const NOOP: i32 = 0;
    /// Cancel the running trajectory.
    pub const CANCEL: i32 = -1;
}

/// Motion types of a trajectory point (its last `i32`).
pub mod motion {
    /// `movej` to joints.
    pub const MOVEJ: i32 = 0;
    /// `movel` to a pose.
    pub const MOVEL: i32 = 1;
    /// `movej` to a pose (through IK).
    pub const MOVEJ_POSE: i32 = 6;
    /// `movel` to joints.
    pub const MOVEL_JOINT: i32 = 7;
    /// Joint spline (URCL before 2024 sent 2).
    pub const SPLINE: i32 = 51;
    /// The older code of [`SPLINE`].
    pub const SPLINE_LEGACY: i32 = 2;
    /// Spline type (blend slot of a spline point): cubic.
    pub const SPLINE_CUBIC: i32 = 1;
    /// Quintic.
    pub const SPLINE_QUINTIC: i32 = 2;
}

/// Trajectory results, sent by the robot on the trajectory socket.
pub mod result {
    /// Every point executed.
    pub const SUCCESS: i32 = 0;
    /// Canceled (cancel action, mode change, a point too fast).
    pub const CANCELED: i32 = 1;
    /// A point failed (not received in time, unknown type).
    pub const FAILURE: i32 = 2;
}

/// `i32` in one reverse message.
pub const REVERSE_MESSAGE_INTS: usize = 8;
/// `i32` in one trajectory point.
pub const TRAJECTORY_POINT_INTS: usize = 21;
/// `i32` in one script command.
pub const SCRIPT_COMMAND_INTS: usize = 28;

/// What the simulator reads from an External Control program: where to connect and the
/// scale factors.
#[derive(Debug, Clone, PartialEq)]
pub struct ExternalControlScript {
    /// Reverse socket address.
    pub reverse: SocketAddr,
    /// Trajectory socket address.
    pub trajectory: SocketAddr,
    /// Script command socket address.
    pub script_command: SocketAddr,
    /// `MULT_jointstate` (URCL: 1000000).
    pub mult_jointstate: f64,
    /// `MULT_time` (URCL: 1000).
    pub mult_time: f64,
}

/// Whether `text` is an External Control program: it opens the reverse and trajectory
/// sockets.
pub fn is_external_control(text: &str) -> bool {
    text.contains("\"reverse_socket\"") && text.contains("\"trajectory_socket\"")
}

/// Reads the socket addresses and scale factors of an External Control program (placeholders
/// already filled in by URCL). Errors name the line or what is missing.
pub fn parse_external_control(text: &str) -> Result<ExternalControlScript, ScriptParseError> {
    let address = |name: &str| -> Result<SocketAddr, ScriptParseError> {
        let quoted = format!("\"{name}\"");
        for (i, line) in text.lines().enumerate() {
            let Some(at) = line.find(&quoted) else {
                continue;
            };
            // `socket_open("host", port, "name")` or `connect_socket_with_retry(..)`.
            let Some(open) = line[..at].rfind('(') else {
                continue;
            };
            let args: Vec<&str> = line[open + 1..at].split(',').map(str::trim).collect();
            if args.len() < 3 {
                continue;
            }
            let fail = |reason: &str| ScriptParseError::Statement {
                line: i + 1,
                reason: format!("{name}: {reason}"),
                text: line.trim().into(),
            };
            let host = args[0]
                .strip_prefix('"')
                .and_then(|h| h.strip_suffix('"'))
                .ok_or_else(|| fail("host is not a string"))?;
            let ip: IpAddr = match host {
                "localhost" => IpAddr::from([127, 0, 0, 1]),
                h => h.parse().map_err(|_| fail("host is not an IP address"))?,
            };
            let port: u16 = args[1].parse().map_err(|_| fail("port is not a number"))?;
            return Ok(SocketAddr::new(ip, port));
        }
        Err(ScriptParseError::Framing(format!(
            "External Control program without a socket_open of {quoted}"
        )))
    };
    let constant = |name: &str, default: f64| -> Result<f64, ScriptParseError> {
        for (i, line) in text.lines().enumerate() {
            let l = line.trim();
            let value = l
                .strip_prefix(name)
                .map(str::trim_start)
                .and_then(|rest| rest.strip_prefix('='));
            if let Some(value) = value {
                return value
                    .trim()
                    .parse::<f64>()
                    .ok()
                    .filter(|v| v.is_finite() && *v > 0.0)
                    .ok_or_else(|| ScriptParseError::Statement {
                        line: i + 1,
                        reason: format!("{name} must be a positive number"),
                        text: l.into(),
                    });
            }
        }
        Ok(default)
    };
    Ok(ExternalControlScript {
        reverse: address("reverse_socket")?,
        trajectory: address("trajectory_socket")?,
        script_command: address("script_command_socket")?,
        mult_jointstate: constant("MULT_jointstate", 1_000_000.0)?,
        mult_time: constant("MULT_time", 1000.0)?,
    })
}

/// Decodes big-endian `i32`s (`out.len()` of them) from `bytes`.
pub fn decode_ints(bytes: &[u8], out: &mut [i32]) {
    for (v, chunk) in out.iter_mut().zip(bytes.chunks_exact(4)) {
        *v = i32::from_be_bytes([chunk[0], chunk[1], chunk[2], chunk[3]]);
    }
}

/// Encodes `ints` big-endian into `out` (appended).
pub fn encode_ints(ints: &[i32], out: &mut Vec<u8>) {
    for v in ints {
        out.extend_from_slice(&v.to_be_bytes());
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn addresses_and_scales_are_read_from_the_filled_in_program() {
        let text = "def externalControl():\n  MULT_jointstate = 1000000\n  MULT_time = 1000\n  \
                    traj_flag = connect_socket_with_retry(\"127.0.0.1\", 50003, \"trajectory_socket\")\n  \
                    com_flag = connect_socket_with_retry(\"127.0.0.1\", 50004, \"script_command_socket\")\n  \
                    socket_open(\"10.0.0.2\", 50001, \"reverse_socket\")\n  \
                    socket_close(\"reverse_socket\")\nend\n";
        assert!(is_external_control(text));
        let s = parse_external_control(text).unwrap();
        assert_eq!(s.reverse, "10.0.0.2:50001".parse().unwrap());
        assert_eq!(s.trajectory, "127.0.0.1:50003".parse().unwrap());
        assert_eq!(s.script_command, "127.0.0.1:50004".parse().unwrap());
        assert_eq!((s.mult_jointstate, s.mult_time), (1e6, 1000.0));
    }

    #[test]
    fn unfilled_placeholders_are_an_error_naming_the_line() {
        let text = "socket_open(\"{{SERVER_IP_REPLACE}}\", 50001, \"reverse_socket\")\n\
                    socket_open(\"1.2.3.4\", 50003, \"trajectory_socket\")\n";
        let e = parse_external_control(text).unwrap_err().to_string();
        assert!(e.contains("line 1") && e.contains("reverse_socket"), "{e}");
    }

    #[test]
    fn ints_round_trip_big_endian() {
        let mut b = Vec::new();
        encode_ints(&[1, -2, 1_000_000], &mut b);
        assert_eq!(&b[..4], &[0, 0, 0, 1]);
        let mut out = [0; 3];
        decode_ints(&b, &mut out);
        assert_eq!(out, [1, -2, 1_000_000]);
    }
}
