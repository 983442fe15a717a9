//! The dashboard and gripper clients (one ASCII line per request, one per reply) against
//! scripted servers that answer slowly: a deadline holds per reply, not per read, and a reply
//! that comes after its deadline is never taken as the answer to the next request.
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failure panics with its message

use std::io::{BufRead, BufReader, Write};
use std::net::{TcpListener, TcpStream};
use std::thread;
use std::time::Duration;

use ur5e::dashboard::{DashboardClient, DashboardError, RobotMode, SafetyMode, WELCOME};
use ur5e::gripper::{GripperError, RobotiqGripper};

const TIMEOUT: Duration = Duration::from_millis(200);

/// Writes `line` one byte every 90 ms (each byte alone is well inside the 200 ms timeout; the
/// whole line is far outside it).
fn dribble(s: &mut TcpStream, line: &str) {
    for b in line.bytes() {
        thread::sleep(Duration::from_millis(90));
        if s.write_all(&[b]).is_err() {
            return;
        }
    }
}

/// Reads one request line.
fn request(r: &mut BufReader<TcpStream>) -> String {
    let mut line = String::new();
    r.read_line(&mut line).unwrap();
    line.trim_end().to_string()
}

/// Serves `connections` connections in turn, each with `serve(index, stream, reader)`; returns
/// the port and a handle that yields how many connections were accepted.
fn server(
    connections: usize,
    serve: impl Fn(usize, &mut TcpStream, &mut BufReader<TcpStream>) + Send + 'static,
) -> (u16, thread::JoinHandle<usize>) {
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let port = listener.local_addr().unwrap().port();
    let handle = thread::spawn(move || {
        let mut accepted = 0;
        for k in 0..connections {
            let (mut s, _) = listener.accept().unwrap();
            accepted += 1;
            let mut r = BufReader::new(s.try_clone().unwrap());
            serve(k, &mut s, &mut r);
        }
        accepted
    });
    (port, handle)
}

#[test]
fn dashboard_deadline_is_per_reply_and_a_late_reply_never_answers_the_next_command() {
    let (port, server) = server(2, |k, s, r| {
        s.write_all(format!("{WELCOME}\n").as_bytes()).unwrap();
        if k == 0 {
            assert_eq!(request(r), "robotmode");
            // 19 bytes at 90 ms: 1.7 s for a reply the client waits 200 ms for.
            dribble(s, "Robotmode: RUNNING\n");
            // Whatever comes next on this socket would be answered with the stale line.
            let mut rest = String::new();
            let _ = r.read_line(&mut rest);
        } else {
            assert_eq!(request(r), "safetystatus");
            s.write_all(b"Safetystatus: NORMAL\n").unwrap();
            assert_eq!(request(r), "robotmode");
            s.write_all(b"Robotmode: IDLE\n").unwrap();
            let mut rest = String::new();
            let _ = r.read_line(&mut rest);
        }
    });
    let mut d = DashboardClient::connect(("127.0.0.1", port), TIMEOUT).unwrap();
    match d.robot_mode() {
        Err(DashboardError::Timeout { command, .. }) => assert_eq!(command, "robotmode"),
        other => panic!("a reply dribbled over 1.7 s beat a 200 ms deadline: {other:?}"),
    }
    // Let the late reply arrive in full before the next command.
    thread::sleep(Duration::from_millis(1900));
    assert_eq!(d.safety_status().unwrap(), SafetyMode::Normal);
    assert_eq!(d.robot_mode().unwrap(), RobotMode::Idle);
    drop(d);
    assert_eq!(
        server.join().unwrap(),
        2,
        "the client resynchronised on a new connection"
    );
}

#[test]
fn gripper_deadline_is_per_reply_and_a_late_reply_never_answers_the_next_request() {
    let (port, server) = server(2, |k, s, r| {
        if k == 0 {
            assert_eq!(request(r), "GET POS");
            dribble(s, "POS 255\n");
            let mut rest = String::new();
            let _ = r.read_line(&mut rest);
        } else {
            assert_eq!(request(r), "GET POS");
            s.write_all(b"POS 17\n").unwrap();
            assert_eq!(request(r), "SET GTO 1");
            s.write_all(b"ack\n").unwrap();
            let mut rest = String::new();
            let _ = r.read_line(&mut rest);
        }
    });
    let mut g = RobotiqGripper::connect(("127.0.0.1", port), TIMEOUT).unwrap();
    match g.get("POS") {
        Err(GripperError::Timeout { command, .. }) => assert_eq!(command, "GET POS"),
        other => panic!("a reply dribbled over 0.7 s beat a 200 ms deadline: {other:?}"),
    }
    thread::sleep(Duration::from_millis(900));
    // The stale "POS 255" must not answer this.
    assert_eq!(g.get("POS").unwrap(), 17);
    g.set(&[("GTO", 1)]).unwrap();
    drop(g);
    assert_eq!(
        server.join().unwrap(),
        2,
        "the client resynchronised on a new connection"
    );
}

#[test]
fn an_over_long_reply_line_is_an_error_and_its_tail_never_answers_the_next_command() {
    let (port, server) = server(2, |k, s, r| {
        s.write_all(format!("{WELCOME}\n").as_bytes()).unwrap();
        if k == 0 {
            assert_eq!(request(r), "robotmode");
            let mut long = "x".repeat(5000);
            long.push_str("Robotmode: RUNNING\n");
            s.write_all(long.as_bytes()).unwrap();
            let mut rest = String::new();
            let _ = r.read_line(&mut rest);
        } else {
            assert_eq!(request(r), "robotmode");
            s.write_all(b"Robotmode: IDLE\n").unwrap();
            let mut rest = String::new();
            let _ = r.read_line(&mut rest);
        }
    });
    let mut d = DashboardClient::connect(("127.0.0.1", port), TIMEOUT).unwrap();
    assert!(d.robot_mode().is_err());
    assert_eq!(d.robot_mode().unwrap(), RobotMode::Idle);
    drop(d);
    assert_eq!(server.join().unwrap(), 2);
}
