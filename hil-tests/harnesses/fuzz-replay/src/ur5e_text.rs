//! The UR5e's line protocols (`drivers/ur5e`): dashboard server replies and Robotiq URCap
//! gripper replies, each fed to the real client twice: by a fake server on loopback (the TCP
//! transport, ~1 ms per input), and by an in-memory script of connections with timeouts and
//! reconnects (`scripted`, at the parsers' speed).

use std::time::Duration;

use ur5e::dashboard::{DashboardClient, DashboardError, RobotMode, SafetyMode, WELCOME};
use ur5e::gripper::{GripperError, GripperJob, GripperProgress, RobotiqGripper, STROKE_M};
use ur5e::transport::Transport;

use crate::bytes::Bytes;
use crate::net::OneShotServer;
use crate::scripted::ScriptedLine;

const TIMEOUT: Duration = Duration::from_secs(2);

/// Once the server has closed and its bytes are used up, every later call must fail too.
struct AfterClose {
    closed: bool,
}

impl AfterClose {
    fn dashboard<T: std::fmt::Debug>(&mut self, what: &str, r: &Result<T, DashboardError>) {
        match r {
            Ok(v) => assert!(
                !self.closed,
                "{what} returned {v:?} after the server closed"
            ),
            Err(DashboardError::Closed { .. }) => self.closed = true,
            Err(e) => {
                let _ = e.to_string();
            }
        }
    }

    fn gripper<T: std::fmt::Debug>(&mut self, what: &str, r: &Result<T, GripperError>) {
        match r {
            Ok(v) => assert!(
                !self.closed,
                "{what} returned {v:?} after the server closed"
            ),
            Err(GripperError::Closed { .. }) => self.closed = true,
            Err(e) => {
                let _ = e.to_string();
            }
        }
    }
}

/// The dashboard client against a server that sends the input's bytes (after the welcome line
/// when bit 0 of the first byte is set), through every command with a checked reply. A good
/// welcome connects whatever follows; parsed replies are what the documented strings say.
pub fn dashboard_client(data: &[u8]) {
    let mut b = Bytes::new(data);
    let mode = b.u8();
    let canned = mode & 1 == 1;
    let mut stream = if canned {
        format!("{WELCOME}\n").into_bytes()
    } else {
        Vec::new()
    };
    stream.extend_from_slice(b.rest());
    let server = OneShotServer::serve(stream);
    let client = match DashboardClient::connect(server.addr(), TIMEOUT) {
        Ok(c) => c,
        Err(e) => {
            assert!(!canned, "the documented welcome line was refused: {e}");
            return;
        }
    };
    dashboard_session(client);
    drop(server);
}

/// The dashboard client over an in-memory script of connections (`scripted`: `0xFF` ends a
/// connection, `0xFE` times a read out, `0xFD` splits a read; every connection starts with the
/// welcome line when bit 0 of the first byte is set), through the same commands and checks as
/// [`dashboard_client`], and the transport's: no request goes out on a connection whose
/// reply timed out.
pub fn dashboard_replies(data: &[u8]) {
    let mut b = Bytes::new(data);
    let canned = b.u8() & 1 == 1;
    let welcome = format!("{WELCOME}\n");
    let greeting = if canned { welcome.as_bytes() } else { b"" };
    let transport = ScriptedLine::new(b.rest(), greeting);
    match DashboardClient::over(transport, TIMEOUT) {
        Ok(client) => dashboard_session(client),
        Err(e) => assert!(!canned, "the documented welcome line was refused: {e}"),
    }
}

/// Every command with a checked reply, on a connected client.
fn dashboard_session<T: Transport>(mut client: DashboardClient<T>) {
    let mut after = AfterClose { closed: false };
    let mode = client.robot_mode();
    if let Ok(m) = mode {
        assert_eq!(RobotMode::from_name(m.name()), Some(m));
        assert_eq!(RobotMode::from_code(m.code()), Some(m));
    }
    after.dashboard("robotmode", &mode);
    let safety = client.safety_status();
    if let Ok(s) = safety {
        assert_eq!(SafetyMode::from_name(s.name()), Some(s));
        assert_eq!(SafetyMode::from_code(s.code()), Some(s));
    }
    after.dashboard("safetystatus", &safety);
    let r = client.program_state();
    after.dashboard("programState", &r);
    let r = client.running();
    after.dashboard("running", &r);
    let r = client.is_in_remote_control();
    after.dashboard("is in remote control", &r);
    let version = client.polyscope_version();
    if let Ok(v) = &version {
        let parts: Vec<&str> = v.split('.').collect();
        assert_eq!(parts.len(), 4, "{v}");
        assert!(parts.iter().all(|p| p.parse::<u32>().is_ok()), "{v}");
    }
    after.dashboard("PolyscopeVersion", &version);
    let serial = client.serial_number();
    if let Ok(s) = &serial {
        assert!(
            !s.is_empty() && s.bytes().all(|c| c.is_ascii_digit()),
            "{s}"
        );
    }
    after.dashboard("get serial number", &serial);
    let r = client.power_on();
    after.dashboard("power on", &r);
    let r = client.brake_release();
    after.dashboard("brake release", &r);
    let r = client.load("grop.urp");
    after.dashboard("load", &r);
    let r = client.play();
    after.dashboard("play", &r);
    let r = client.pause();
    after.dashboard("pause", &r);
    let r = client.stop();
    after.dashboard("stop", &r);
    let r = client.unlock_protective_stop();
    after.dashboard("unlock protective stop", &r);
    let r = client.close_safety_popup();
    after.dashboard("close safety popup", &r);
    let r = client.power_off();
    after.dashboard("power off", &r);
    let r = client.command("robotmode\nquit");
    assert!(matches!(r, Err(DashboardError::BadCommand { .. })));
    let r = client.command("robotmode");
    if let Ok(line) = &r {
        assert!(!line.contains('\n') && line.len() <= 4096);
    }
    after.dashboard("robotmode (raw)", &r);
    let r = client.quit();
    after.dashboard("quit", &r);
}

/// The gripper client against a server that sends the input's bytes: an activate-and-move job
/// polled on a clock that advances 0.5 s per poll, then a status read and a set. A move job ends
/// only in a move outcome or an error, never in "activated".
pub fn gripper_client(data: &[u8]) {
    let server = OneShotServer::serve(data.to_vec());
    let gripper = match RobotiqGripper::connect(server.addr(), TIMEOUT) {
        Ok(g) => g,
        Err(e) => panic!("connecting to a loopback listener failed: {e}"),
    };
    gripper_session(gripper);
    drop(server);
}

/// The gripper client over an in-memory script of connections (`scripted`, as
/// [`dashboard_replies`]), through the same jobs and checks as [`gripper_client`], and the
/// transport's: no request goes out on a connection whose reply timed out.
pub fn gripper_replies(data: &[u8]) {
    gripper_session(RobotiqGripper::over(ScriptedLine::new(data, b""), TIMEOUT));
}

/// An activate-and-move job, an activation job, a status read, a set and a get.
fn gripper_session<T: Transport>(mut gripper: RobotiqGripper<T>) {
    let mut after = AfterClose { closed: false };
    let timeout = Duration::from_secs(3);
    let mut job = GripperJob::activate_and_move_to(255, 255, 128, timeout, Duration::ZERO);
    for k in 0..32u32 {
        let now = Duration::from_millis(500) * k;
        let r = job.poll(&mut gripper, now);
        after.gripper("job poll", &r);
        match r {
            Ok(GripperProgress::Pending) => {}
            Ok(GripperProgress::Activated) => panic!("a move job ended as activation only"),
            Ok(GripperProgress::Moved(_)) | Err(_) => break,
        }
    }
    let mut job = GripperJob::activate(timeout, Duration::ZERO);
    for k in 0..16u32 {
        let r = job.poll(&mut gripper, Duration::from_millis(500) * k);
        after.gripper("activation poll", &r);
        match r {
            Ok(GripperProgress::Pending) => {}
            Ok(GripperProgress::Moved(_)) => panic!("an activation job ended in a move"),
            Ok(GripperProgress::Activated) | Err(_) => break,
        }
    }
    let status = gripper.status();
    if let Ok(s) = &status {
        let opening = s.opening_m();
        assert!((0.0..=STROKE_M).contains(&opening), "{opening}");
    }
    after.gripper("status", &status);
    let r = gripper.set(&[("POS", 0), ("GTO", 1)]);
    after.gripper("set", &r);
    let r = gripper.get("POS");
    after.gripper("get", &r);
}
