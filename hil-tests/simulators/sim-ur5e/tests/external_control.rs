//! A minimal External Control client of our own: the PC side of the Universal Robots Client
//! Library's protocol (reverse, trajectory and script command sockets, the script sender),
//! written from its documentation (module `sim_ur5e::external_control`), against the simulated
//! controller in lock-step.
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failure panics with its message

use std::io::{Read, Write};
use std::net::{SocketAddr, TcpListener, TcpStream};
use std::time::{Duration, Instant};

use sim_ur5e::external_control::{mode, motion, result, trajectory_action};
use sim_ur5e::{EXTERNAL_CONTROL_PROGRAM, SimConfig, Stepping, Ur5eSim};

const MULT: f64 = 1_000_000.0;
const MULT_TIME: f64 = 1000.0;
/// Keep-alive: the robot ends the program when no reverse message comes for this long.
const READ_TIMEOUT_MS: i32 = 100;

/// The PC's three servers, as URCL opens them.
struct Pc {
    reverse: TcpListener,
    trajectory: TcpListener,
    command: TcpListener,
}

/// The connected session, PC side.
struct Session {
    reverse: TcpStream,
    trajectory: TcpStream,
    _command: TcpStream,
}

impl Pc {
    fn new() -> Self {
        let bind = || TcpListener::bind("127.0.0.1:0").unwrap();
        Self {
            reverse: bind(),
            trajectory: bind(),
            command: bind(),
        }
    }

    fn port(l: &TcpListener) -> u16 {
        l.local_addr().unwrap().port()
    }

    /// The robot program with URCL's placeholders filled in; the simulator takes the sockets
    /// and scale factors from it and serves the command loop itself.
    fn program(&self) -> String {
        format!(
            "def externalControl():\n  MULT_jointstate = {MULT}\n  MULT_time = {MULT_TIME}\n  \
             traj_flag = connect_socket_with_retry(\"127.0.0.1\", {}, \"trajectory_socket\")\n  \
             com_flag = connect_socket_with_retry(\"127.0.0.1\", {}, \"script_command_socket\")\n  \
             rev_flag = connect_socket_with_retry(\"127.0.0.1\", {}, \"reverse_socket\")\n  \
             # command loop: served natively by the simulator\nend\n",
            Self::port(&self.trajectory),
            Self::port(&self.command),
            Self::port(&self.reverse),
        )
    }

    /// Accepts the robot's connections in the order the program opens them.
    fn accept(&self) -> Session {
        let accept = |l: &TcpListener| {
            let (s, _) = l.accept().unwrap();
            s.set_nodelay(true).unwrap();
            s
        };
        let trajectory = accept(&self.trajectory);
        let command = accept(&self.command);
        let reverse = accept(&self.reverse);
        Session {
            reverse,
            trajectory,
            _command: command,
        }
    }
}

fn ints(v: &[i32]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_be_bytes()).collect()
}

fn scaled(x: f64) -> i32 {
    (x * MULT).round() as i32
}

impl Session {
    fn reverse(&mut self, v: [i32; 6], control_mode: i32) {
        let mut msg = vec![READ_TIMEOUT_MS];
        msg.extend(v);
        msg.push(control_mode);
        self.reverse.write_all(&ints(&msg)).unwrap();
    }

    fn keepalive(&mut self, control_mode: i32) {
        self.reverse([trajectory_action::NOOP, 0, 0, 0, 0, 0], control_mode);
    }

    fn start_trajectory(&mut self, points: i32) {
        self.reverse(
            [trajectory_action::RECEIVE, points, 0, 0, 0, 0],
            mode::FORWARD,
        );
    }

    /// One trajectory point: `[pos x6, block2 x6, block3 x6, time, blend/spline type, type]`.
    fn point(
        &mut self,
        q: [f64; 6],
        block2: [f64; 6],
        block3: [f64; 6],
        time_s: f64,
        kind: (i32, i32),
    ) {
        let mut p: Vec<i32> = q.iter().map(|&x| scaled(x)).collect();
        p.extend(block2.iter().map(|&x| scaled(x)));
        p.extend(block3.iter().map(|&x| scaled(x)));
        p.push((time_s * MULT_TIME).round() as i32);
        p.push(kind.0);
        p.push(kind.1);
        assert_eq!(p.len(), 21);
        self.trajectory.write_all(&ints(&p)).unwrap();
    }

    /// A trajectory result, if one has arrived.
    fn result(&mut self) -> Option<i32> {
        self.trajectory.set_nonblocking(true).unwrap();
        let mut b = [0u8; 4];
        let got = match self.trajectory.read(&mut b) {
            Ok(4) => Some(i32::from_be_bytes(b)),
            Ok(0) => panic!("the robot closed the trajectory socket"),
            Ok(n) => {
                self.trajectory.set_nonblocking(false).unwrap();
                self.trajectory.read_exact(&mut b[n..]).unwrap();
                Some(i32::from_be_bytes(b))
            }
            Err(_) => None,
        };
        self.trajectory.set_nonblocking(false).unwrap();
        got
    }
}

fn lockstep_sim(f: impl FnOnce(&mut SimConfig)) -> Ur5eSim {
    let mut cfg = SimConfig {
        stepping: Stepping::External,
        ..SimConfig::ephemeral()
    };
    f(&mut cfg);
    Ur5eSim::start(cfg).unwrap()
}

/// Steps (with a keep-alive every 10 cycles) until the trajectory result comes; returns it.
fn run_until_result(sim: &Ur5eSim, s: &mut Session, max_cycles: u64) -> i32 {
    for n in 0..max_cycles {
        if n % 10 == 0 {
            s.keepalive(mode::FORWARD);
        }
        sim.step().unwrap();
        if let Some(r) = s.result() {
            return r;
        }
    }
    panic!("no trajectory result in {max_cycles} cycles");
}

fn wait_running(sim: &Ur5eSim) {
    let t0 = Instant::now();
    while sim.snapshot().runtime_state != 2 {
        assert!(t0.elapsed() < Duration::from_secs(5), "program not running");
        sim.step().unwrap();
        std::thread::sleep(Duration::from_millis(1));
    }
    assert_eq!(
        sim.with_robot(|r| r.program_name().map(str::to_string)),
        Some(EXTERNAL_CONTROL_PROGRAM.to_string())
    );
}

/// Headless mode: the program goes to the primary port, the robot connects back.
fn headless(sim: &Ur5eSim) -> Session {
    let pc = Pc::new();
    let mut primary = TcpStream::connect(sim.ports().primary).unwrap();
    primary.write_all(pc.program().as_bytes()).unwrap();
    let mut s = pc.accept();
    wait_running(sim);
    s.keepalive(mode::IDLE);
    sim.step().unwrap();
    s
}

fn close(a: &[f64], b: &[f64], tol: f64) -> bool {
    a.iter().zip(b).all(|(x, y)| (x - y).abs() <= tol)
}

const A: [f64; 6] = [0.3, -1.4, 1.4, -1.5, -1.5, 0.1];
const B: [f64; 6] = [0.5, -1.3, 1.3, -1.6, -1.4, 0.2];
const C: [f64; 6] = [0.2, -1.5, 1.5, -1.5, -1.6, 0.0];
const Z: [f64; 6] = [0.0; 6];

#[test]
fn a_forwarded_joint_trajectory_runs_and_reports_success() {
    let sim = lockstep_sim(|_| {});
    let mut s = headless(&sim);
    s.start_trajectory(3);
    // movej in a given time; a cubic spline ending at rest; movej with speed and acceleration.
    s.point(A, Z, Z, 1.0, (0, motion::MOVEJ));
    s.point(B, Z, Z, 1.0, (motion::SPLINE_CUBIC, motion::SPLINE));
    s.point(
        C,
        Z,
        [1.05, 1.4, 0.0, 0.0, 0.0, 0.0],
        0.0,
        (0, motion::MOVEJ),
    );
    let t0 = sim.snapshot().time_s;
    let r = run_until_result(&sim, &mut s, 3000);
    assert_eq!(r, result::SUCCESS);
    let snap = sim.snapshot();
    assert!(close(&snap.q, &C, 1e-3), "{:?}", snap.q);
    // The first two points take their 1 s each on the controller's clock.
    assert!(snap.time_s - t0 > 2.0, "took {} s", snap.time_s - t0);
    assert_eq!(snap.runtime_state, 2, "the program keeps running");
    // Mode STOPPED ends the program.
    s.reverse([0; 6], mode::STOPPED);
    sim.step().unwrap();
    sim.step().unwrap();
    assert_eq!(sim.snapshot().runtime_state, 1);
}

#[test]
fn a_canceled_trajectory_stops_the_arm_and_reports_canceled() {
    let sim = lockstep_sim(|_| {});
    let mut s = headless(&sim);
    s.start_trajectory(2);
    s.point(
        [2.0, -1.2, 1.2, -1.6, -1.4, 0.2],
        Z,
        Z,
        4.0,
        (0, motion::MOVEJ),
    );
    s.point(A, Z, Z, 2.0, (0, motion::MOVEJ));
    for n in 0..200 {
        if n % 10 == 0 {
            s.keepalive(mode::FORWARD);
        }
        sim.step().unwrap();
    }
    assert!(sim.snapshot().qd[0] > 0.1, "moving");
    s.reverse([trajectory_action::CANCEL, 0, 0, 0, 0, 0], mode::FORWARD);
    let r = run_until_result(&sim, &mut s, 100);
    assert_eq!(r, result::CANCELED);
    for n in 0..300 {
        if n % 10 == 0 {
            s.keepalive(mode::FORWARD);
        }
        sim.step().unwrap();
    }
    assert!(sim.snapshot().qd.iter().all(|v| v.abs() < 1e-9));
    assert!(sim.snapshot().q[0] < 1.5, "stopped before the goal");
}

#[test]
fn servoj_mode_tracks_streamed_targets() {
    let sim = lockstep_sim(|_| {});
    let mut s = headless(&sim);
    let q0 = sim.snapshot().q;
    let mut q = q0;
    for k in 0..500 {
        q[0] = q0[0] + 0.3 * (k as f64 / 499.0);
        s.reverse(core::array::from_fn(|i| scaled(q[i])), mode::SERVOJ);
        sim.step().unwrap();
    }
    for _ in 0..5 {
        s.reverse(core::array::from_fn(|i| scaled(q[i])), mode::SERVOJ);
        sim.step().unwrap();
    }
    assert!(close(&sim.snapshot().q, &q, 1e-6), "{:?}", sim.snapshot().q);
}

#[test]
fn a_silent_pc_ends_the_program_after_the_read_timeout() {
    let sim = lockstep_sim(|_| {});
    let mut s = headless(&sim);
    // 100 ms of controller time = 50 cycles without a message.
    for _ in 0..49 {
        sim.step().unwrap();
    }
    assert_eq!(sim.snapshot().runtime_state, 2);
    for _ in 0..3 {
        sim.step().unwrap();
    }
    assert_eq!(sim.snapshot().runtime_state, 1, "program ended");
    // The robot closes its sockets.
    s.trajectory
        .set_read_timeout(Some(Duration::from_secs(5)))
        .unwrap();
    let mut b = [0u8; 4];
    loop {
        match s.trajectory.read(&mut b) {
            Ok(0) | Err(_) => break,
            Ok(_) => {}
        }
    }
}

#[test]
fn the_urcap_asks_the_script_sender_for_the_program_on_play() {
    let sender = TcpListener::bind("127.0.0.1:0").unwrap();
    let addr: SocketAddr = sender.local_addr().unwrap();
    let sim = lockstep_sim(|c| {
        c.urcap_script_sender = Some(addr);
        c.programs = vec!["external_control.urp".into()];
    });
    let pc = Pc::new();
    let dash = TcpStream::connect(sim.ports().dashboard).unwrap();
    let mut writer = dash.try_clone().unwrap();
    let mut reader = std::io::BufReader::new(dash);
    let mut banner = String::new();
    std::io::BufRead::read_line(&mut reader, &mut banner).unwrap();
    let mut line = |cmd: &str| {
        writer.write_all(format!("{cmd}\n").as_bytes()).unwrap();
        let mut reply = String::new();
        std::io::BufRead::read_line(&mut reader, &mut reply).unwrap();
        reply
    };
    assert!(line("load external_control.urp").contains("Loading program"));
    assert!(line("play").contains("Starting program"));
    let (mut c, _) = sender.accept().unwrap();
    let mut req = [0u8; 16];
    c.read_exact(&mut req).unwrap();
    assert_eq!(&req, b"request_program\n");
    c.write_all(pc.program().as_bytes()).unwrap();
    drop(c);
    let mut s = pc.accept();
    wait_running(&sim);
    s.start_trajectory(1);
    s.point(B, Z, Z, 1.0, (0, motion::MOVEJ));
    assert_eq!(run_until_result(&sim, &mut s, 2000), result::SUCCESS);
    assert!(close(&sim.snapshot().q, &B, 1e-3));
}
