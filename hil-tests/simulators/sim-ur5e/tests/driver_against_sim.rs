//! HIL: the `ur5e` drivers against the simulated controller on loopback TCP (free ports, so
//! tests run in parallel).
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failure panics with its message

use std::io::{Read, Write};
use std::net::TcpStream;
use std::thread;
use std::time::{Duration, Instant};

use sim_ur5e::{PortKind, RobotInit, SimConfig, Ur5eSim};
use ur5e::dashboard::{DashboardClient, ProgramState, RobotMode, SafetyMode};
use ur5e::rtde::{DataPackage, RtdeClient, RtdeSetupError, RtdeTimeouts, RtdeType, RtdeValue};
use ur5e::{ArmConfig, GripOutcome, SkillError, TcpPose, Ur5eArm};

const H: f64 = std::f64::consts::FRAC_PI_2;
const HOME: [f64; 6] = [0.0, -H, H, -H, -H, 0.0];

fn sim_with(f: impl FnOnce(&mut SimConfig)) -> Ur5eSim {
    let mut cfg = SimConfig::ephemeral();
    f(&mut cfg);
    Ur5eSim::start(cfg).expect("simulator starts")
}

fn arm_config(sim: &Ur5eSim) -> ArmConfig {
    let p = sim.ports();
    ArmConfig {
        rtde_port: p.rtde.port(),
        dashboard_port: p.dashboard.port(),
        script_port: p.secondary.port(),
        gripper_port: Some(p.gripper.port()),
        // Generous under a loaded CI machine: a starved test thread must not look like a
        // lost link (a cut socket is still detected at once, by EOF).
        stale_after: Duration::from_millis(500),
        watchdog_min_hz: 2.0,
        ..ArmConfig::default()
    }
}

fn rtde(sim: &Ur5eSim) -> RtdeClient {
    RtdeClient::connect(sim.ports().rtde, RtdeTimeouts::default()).expect("RTDE connects")
}

fn wait_for(what: &str, timeout: Duration, mut pred: impl FnMut() -> bool) {
    let t0 = Instant::now();
    while !pred() {
        assert!(t0.elapsed() < timeout, "timed out waiting for {what}");
        thread::sleep(Duration::from_millis(5));
    }
}

#[test]
fn rtde_handshake_types_rate_and_newest_package() {
    let sim = sim_with(|_| {});
    let mut c = rtde(&sim);
    let v = c.controller_version().unwrap();
    assert_eq!((v.major, v.minor), (5, 21));
    let names = [
        "timestamp",
        "actual_q",
        "joint_mode",
        "actual_digital_input_bits",
        "runtime_state",
        "input_double_register_30",
    ];
    let recipe = c.setup_outputs(&names, 125.0).unwrap().clone();
    assert_eq!(
        recipe.types,
        [
            RtdeType::Double,
            RtdeType::Vector6d,
            RtdeType::Vector6Int32,
            RtdeType::Uint64,
            RtdeType::Uint32,
            RtdeType::Double
        ]
    );
    let input = c.setup_inputs(&["input_double_register_30"]).unwrap();
    assert_eq!(
        input.id, 1,
        "input recipes are numbered from 1 per connection"
    );
    c.start().unwrap();
    c.send_inputs(&input, &[RtdeValue::Double(2.5)]).unwrap();
    let mut pkg = DataPackage::for_recipe(&recipe);
    let mut stamps = Vec::new();
    let mut read_back = false;
    for _ in 0..20 {
        c.receive_latest(&mut pkg, Duration::from_secs(1)).unwrap();
        stamps.push(pkg.values[0].as_f64().unwrap());
        read_back |= pkg.values[5] == RtdeValue::Double(2.5);
    }
    assert!(read_back, "input register read back as an output");
    for w in stamps.windows(2) {
        let step = w[1] - w[0];
        // 125 Hz from a 500 Hz controller: every 4th cycle.
        assert!(
            (step / 0.008 - (step / 0.008).round()).abs() < 1e-6 && step > 0.0,
            "step {step}"
        );
    }
    // Newest wins: after a pause in reading, the package returned is the latest one, not the
    // oldest one still buffered (which would be one 8 ms step after the last one read).
    let before = pkg.values[0].as_f64().unwrap();
    thread::sleep(Duration::from_millis(100));
    c.receive_latest(&mut pkg, Duration::from_secs(1)).unwrap();
    assert!(pkg.skipped >= 5, "skipped {}", pkg.skipped);
    let after = pkg.values[0].as_f64().unwrap();
    assert!(
        after - before >= 0.048,
        "got {after} after {before}: not the newest"
    );
    c.pause().unwrap();
    c.start().unwrap();
    c.receive_latest(&mut pkg, Duration::from_secs(1)).unwrap();
}

#[test]
fn unknown_outputs_and_inputs_held_by_another_connection_are_refused() {
    let sim = sim_with(|_| {});
    let mut a = rtde(&sim);
    let mut b = rtde(&sim);
    assert!(matches!(
        a.setup_outputs(&["timestamp", "no_such_field"], 500.0),
        Err(RtdeSetupError::NotFound { names }) if names == ["no_such_field"]
    ));
    a.setup_inputs(&["input_int_register_24"]).unwrap();
    // The same connection may list an input again (ur_rtde does).
    let again = a
        .setup_inputs(&["input_int_register_24", "input_int_register_25"])
        .unwrap();
    assert_eq!(again.id, 2);
    assert!(matches!(
        b.setup_inputs(&["input_int_register_24"]),
        Err(RtdeSetupError::InUse { .. })
    ));
    a.disconnect();
    // Released when the holder's connection closes.
    wait_for("input released", Duration::from_secs(2), || {
        b.setup_inputs(&["input_int_register_24"]).is_ok()
    });
}

#[test]
fn several_clients_stream_at_500_hz_at_once() {
    let sim = sim_with(|_| {});
    let mut clients: Vec<_> = (0..3)
        .map(|_| {
            let mut c = rtde(&sim);
            let r = c.setup_outputs(&["timestamp"], 500.0).unwrap().clone();
            c.start().unwrap();
            (c, DataPackage::for_recipe(&r))
        })
        .collect();
    for (c, p) in &mut clients {
        let mut last = -1.0;
        let mut packages = 0u64;
        for _ in 0..50 {
            c.receive_latest(p, Duration::from_secs(1)).unwrap();
            let t = p.values[0].as_f64().unwrap();
            assert!(t > last);
            last = t;
            packages += 1 + u64::from(p.skipped);
        }
        assert!(packages >= 50);
    }
}

#[test]
fn dashboard_replies_are_the_documented_strings() {
    let sim = sim_with(|c| c.programs = vec!["unload.urp".into()]);
    let mut d = DashboardClient::connect(sim.ports().dashboard, Duration::from_secs(2)).unwrap();
    assert_eq!(d.robot_mode().unwrap(), RobotMode::Running);
    assert_eq!(d.safety_status().unwrap(), SafetyMode::Normal);
    assert_eq!(d.polyscope_version().unwrap(), "5.21.0.1210631");
    assert!(d.is_in_remote_control().unwrap());
    assert!(!d.running().unwrap());
    assert!(
        d.serial_number()
            .unwrap()
            .bytes()
            .all(|b| b.is_ascii_digit())
    );
    assert!(matches!(
        d.program_state().unwrap(),
        ProgramState::Stopped(_)
    ));
    d.load("unload.urp").unwrap();
    assert_eq!(
        d.command("load missing.urp").unwrap(),
        "File not found: missing.urp"
    );
    assert_eq!(
        d.command("get loaded program").unwrap(),
        "Loaded program: unload.urp"
    );
    assert_eq!(d.command("pause").unwrap(), "Failed to execute: pause");
    d.stop().unwrap();
    d.power_off().unwrap();
    assert_eq!(d.robot_mode().unwrap(), RobotMode::PowerOff);
    d.power_on().unwrap();
    wait_for("IDLE", Duration::from_secs(2), || {
        d.robot_mode().unwrap() == RobotMode::Idle
    });
    d.brake_release().unwrap();
    wait_for("RUNNING", Duration::from_secs(2), || {
        d.robot_mode().unwrap() == RobotMode::Running
    });
    sim.trigger_protective_stop("test");
    assert_eq!(d.safety_status().unwrap(), SafetyMode::ProtectiveStop);
    d.close_safety_popup().unwrap();
    d.unlock_protective_stop().unwrap();
    assert_eq!(d.safety_status().unwrap(), SafetyMode::Normal);
    assert!(d.command("line\nbreak").is_err());
    d.quit().unwrap();
}

#[test]
fn move_joints_and_move_linear_reach_their_goals() {
    let sim = sim_with(|_| {});
    let mut arm = Ur5eArm::connect(arm_config(&sim)).unwrap();
    let goal = [0.4, -1.3, 1.4, -1.6, -H, 0.3];
    let report = arm
        .move_joints(goal, 1.05, 1.4, Duration::from_secs(10))
        .unwrap();
    assert!(report.final_error <= 0.002);
    for (a, b) in sim.snapshot().q.iter().zip(goal) {
        assert!((a - b).abs() < 1e-6);
    }
    let mut pose = arm.state().tcp_pose;
    pose.z_m -= 0.10;
    pose.x_m += 0.05;
    let report = arm
        .move_linear(pose, 0.25, 1.2, Duration::from_secs(10))
        .unwrap();
    assert!(report.final_error <= 0.001, "{report:?}");
    let snap = sim.snapshot();
    let reached = TcpPose::from_array(snap.tcp_pose);
    assert!(reached.position_distance_m(&pose) < 1e-4);
    assert!(reached.orientation_distance_rad(&pose) < 1e-4);
    // A move to where the arm already is completes too.
    arm.move_joints(snap.q, 1.0, 1.0, Duration::from_secs(5))
        .unwrap();
}

#[test]
fn gripper_closes_on_an_object_and_opens() {
    let sim = sim_with(|c| c.gripper_object_width_m = Some(0.06));
    let mut arm = Ur5eArm::connect(arm_config(&sim)).unwrap();
    assert_eq!(
        arm.close_gripper(Duration::from_secs(5)).unwrap(),
        GripOutcome::ObjectWhileClosing
    );
    assert!((sim.snapshot().gripper_opening_m - 0.06).abs() < 1e-6);
    assert_eq!(
        arm.open_gripper(Duration::from_secs(5)).unwrap(),
        GripOutcome::ReachedPosition
    );
    sim.set_gripper_object(None);
    assert_eq!(
        arm.close_gripper(Duration::from_secs(5)).unwrap(),
        GripOutcome::ReachedPosition
    );
}

#[test]
fn protective_stop_mid_move_is_an_error_and_can_be_recovered() {
    let sim = sim_with(|_| {});
    let mut arm = Ur5eArm::connect(arm_config(&sim)).unwrap();
    let result = thread::scope(|s| {
        s.spawn(|| {
            wait_for("motion", Duration::from_secs(5), || {
                sim.snapshot().qd[0].abs() > 0.1
            });
            sim.trigger_protective_stop("collision");
        });
        arm.move_joints([2.0, -H, H, -H, -H, 0.0], 0.5, 1.0, Duration::from_secs(20))
    });
    assert!(
        matches!(result, Err(SkillError::ProtectiveStop { .. })),
        "{result:?}"
    );
    // Motion is refused until the stop is unlocked.
    assert!(matches!(
        arm.move_joints(HOME, 1.0, 1.0, Duration::from_secs(10)),
        Err(SkillError::ProtectiveStop { .. })
    ));
    arm.recover_protective_stop(Duration::from_secs(2)).unwrap();
    arm.move_joints(HOME, 1.0, 1.0, Duration::from_secs(10))
        .unwrap();
}

#[test]
fn floor_contact_surfaces_as_a_protective_stop() {
    let sim = sim_with(|c| c.init.floor_z_m = Some(0.25));
    let mut arm = Ur5eArm::connect(arm_config(&sim)).unwrap();
    let down = [0.0, -0.3, 0.3, -H, -H, 0.0];
    let result = arm.move_joints(down, 1.0, 1.4, Duration::from_secs(10));
    assert!(
        matches!(result, Err(SkillError::ProtectiveStop { .. })),
        "{result:?}"
    );
    assert!(
        sim.snapshot().tcp_pose[2] > 0.2,
        "stopped near the floor, not through it"
    );
}

#[test]
fn lost_rtde_link_mid_move_stops_the_arm_and_reports() {
    let sim = sim_with(|_| {});
    let mut arm = Ur5eArm::connect(arm_config(&sim)).unwrap();
    let goal = [3.0, -H, H, -H, -H, 0.0];
    let result = thread::scope(|s| {
        s.spawn(|| {
            wait_for("motion", Duration::from_secs(5), || {
                sim.snapshot().qd[0].abs() > 0.3
            });
            sim.cut_rtde_connections();
        });
        arm.move_joints(goal, 1.0, 2.0, Duration::from_secs(20))
    });
    assert!(
        matches!(
            result,
            Err(SkillError::ConnectionLost {
                stop_sent: true,
                ..
            })
        ),
        "{result:?}"
    );
    wait_for("arm at rest", Duration::from_secs(3), || {
        let s = sim.snapshot();
        s.qd.iter().all(|v| v.abs() < 1e-9) && s.runtime_state == 1
    });
    assert!(sim.snapshot().q[0] < 2.5, "stopped well short of the goal");
}

#[test]
fn controller_watchdog_stops_the_arm_when_the_client_vanishes() {
    // The onboard computer dies mid-move: no stop command can be sent, so the program's
    // rtde_set_watchdog must stop the arm by itself.
    let sim = sim_with(|_| {});
    let mut c = rtde(&sim);
    let hb = c.setup_inputs(&["input_int_register_24"]).unwrap();
    let mut script = TcpStream::connect(sim.ports().secondary).unwrap();
    script
        .write_all(
            b"def grop_motion():\n  rtde_set_watchdog(\"input_int_register_24\", 2, \"stop\")\n  \
              movej([3.0, -1.5707963, 1.5707963, -1.5707963, -1.5707963, 0.0], a=2, v=1)\nend\n",
        )
        .unwrap();
    for k in 0..20 {
        c.send_inputs(&hb, &[RtdeValue::Int32(k)]).unwrap();
        thread::sleep(Duration::from_millis(25));
    }
    assert_eq!(
        sim.snapshot().runtime_state,
        2,
        "fed watchdog: the move goes on"
    );
    drop(c);
    wait_for("watchdog stop", Duration::from_secs(3), || {
        let s = sim.snapshot();
        s.runtime_state == 1 && s.qd.iter().all(|v| v.abs() < 1e-9)
    });
    assert!(sim.snapshot().q[0] < 2.9, "stopped short of the goal");
}

#[test]
fn timeout_stops_the_arm() {
    let sim = sim_with(|_| {});
    let mut arm = Ur5eArm::connect(arm_config(&sim)).unwrap();
    let far = [3.0, -H, H, -H, -H, 0.0];
    let result = arm.move_joints(far, 0.5, 1.0, Duration::from_millis(500));
    assert!(
        matches!(result, Err(SkillError::Timeout { .. })),
        "{result:?}"
    );
    let s = sim.snapshot();
    assert!(s.qd.iter().all(|v| v.abs() < 1e-9));
    assert!(s.q[0] < 1.0);
}

#[test]
fn skills_refuse_a_powered_off_robot_and_bad_targets() {
    let sim = sim_with(|c| {
        c.init = RobotInit {
            powered: false,
            ..RobotInit::default()
        }
    });
    let mut arm = Ur5eArm::connect(arm_config(&sim)).unwrap();
    assert!(matches!(
        arm.move_joints(HOME, 1.0, 1.0, Duration::from_secs(1)),
        Err(SkillError::NotReady { robot_mode: 3 })
    ));
    assert!(matches!(
        arm.move_joints(
            [f64::NAN, 0.0, 0.0, 0.0, 0.0, 0.0],
            1.0,
            1.0,
            Duration::from_secs(1)
        ),
        Err(SkillError::InvalidTarget { .. })
    ));
    assert!(matches!(
        arm.move_joints(
            [7.0, 0.0, 0.0, 0.0, 0.0, 0.0],
            1.0,
            1.0,
            Duration::from_secs(1)
        ),
        Err(SkillError::InvalidTarget { .. })
    ));
    assert!(matches!(
        arm.move_joints(HOME, 4.0, 1.0, Duration::from_secs(1)),
        Err(SkillError::InvalidTarget { .. })
    ));
}

#[test]
fn unsupported_scripts_are_rejected_and_do_not_move_the_arm() {
    let sim = sim_with(|_| {});
    let q0 = sim.snapshot().q;
    let mut s = TcpStream::connect(sim.ports().secondary).unwrap();
    s.write_all(b"def bad():\n  movej([1,0,0,0,0,0])\n  launch_rockets(3)\nend\n")
        .unwrap();
    s.write_all(b"def rtde_control():\n  sleep(1)\nend\n")
        .unwrap();
    thread::sleep(Duration::from_millis(200));
    let snap = sim.snapshot();
    assert_eq!(snap.runtime_state, 1);
    assert_eq!(snap.q, q0);
}

#[test]
fn secondary_and_realtime_streams_carry_the_state() {
    let sim = sim_with(|_| {});
    let mut sec = TcpStream::connect(sim.ports().secondary).unwrap();
    sec.set_read_timeout(Some(Duration::from_secs(2))).unwrap();
    let read_package = |s: &mut TcpStream| {
        let mut h = [0u8; 5];
        s.read_exact(&mut h).unwrap();
        let len = u32::from_be_bytes([h[0], h[1], h[2], h[3]]) as usize;
        let mut body = vec![0u8; len - 5];
        s.read_exact(&mut body).unwrap();
        (h[4], body)
    };
    let (ty, body) = read_package(&mut sec);
    assert_eq!(ty, 20, "version message first");
    assert_eq!(body[9], 3, "message type VERSION");
    let (ty, body) = read_package(&mut sec);
    assert_eq!(ty, 16);
    assert_eq!(body.len(), 47 + 251 + 101);
    assert_eq!(
        body[8 + 5 + 7] as i8,
        7,
        "robot mode RUNNING in RobotModeData"
    );
    let mut rt = TcpStream::connect(sim.ports().realtime).unwrap();
    rt.set_read_timeout(Some(Duration::from_secs(2))).unwrap();
    let mut packet = vec![0u8; 1116];
    rt.read_exact(&mut packet).unwrap();
    assert_eq!(i32::from_be_bytes(packet[..4].try_into().unwrap()), 1116);
    let q1 = f64::from_be_bytes(packet[4 + 32 * 8..4 + 33 * 8].try_into().unwrap());
    assert!((q1 - HOME[1]).abs() < 1e-6, "q actual[1] = {q1}");
}

#[test]
fn the_simulator_runs_as_its_own_process() {
    let dir = std::env::temp_dir().join(format!("sim-ur5e-proc-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let ports_file = dir.join("ports.json");
    let child = std::process::Command::new(env!("CARGO_BIN_EXE_sim-ur5e"))
        .args(["--ephemeral", "--ports-file"])
        .arg(&ports_file)
        .env("RUST_LOG", "warn")
        .stdout(std::process::Stdio::null())
        .spawn()
        .unwrap();
    struct Kill(std::process::Child);
    impl Drop for Kill {
        fn drop(&mut self) {
            let _ = self.0.kill();
            let _ = self.0.wait();
        }
    }
    let _guard = Kill(child);
    wait_for("ports file", Duration::from_secs(10), || {
        ports_file.exists()
    });
    let ports: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&ports_file).unwrap()).unwrap();
    let port = |k: &str| ports[k].as_u64().unwrap() as u16;
    let cfg = ArmConfig {
        rtde_port: port("rtde"),
        dashboard_port: port("dashboard"),
        script_port: port("secondary"),
        gripper_port: Some(port("gripper")),
        ..ArmConfig::default()
    };
    let mut arm = Ur5eArm::connect(cfg).unwrap();
    let goal = [0.2, -1.4, 1.4, -H, -H, 0.1];
    arm.move_joints(goal, 1.0, 2.0, Duration::from_secs(10))
        .unwrap();
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn with_every_socket_cut_the_controller_watchdog_still_stops_the_arm() {
    // No channel is left to send a stop: the skill says so, and the heartbeat watchdog in the
    // motion program brings the arm to rest on its own.
    let sim = sim_with(|_| {});
    let mut arm = Ur5eArm::connect(arm_config(&sim)).unwrap();
    let goal = [3.0, -H, H, -H, -H, 0.0];
    let result = thread::scope(|s| {
        s.spawn(|| {
            wait_for("motion", Duration::from_secs(5), || {
                sim.snapshot().qd[0].abs() > 0.3
            });
            // The stop channels go first, so the RTDE loss finds nothing left to send on.
            sim.cut_connections(PortKind::Secondary);
            sim.cut_connections(PortKind::Dashboard);
            thread::sleep(Duration::from_millis(50));
            sim.cut_all_connections();
        });
        arm.move_joints(goal, 1.0, 2.0, Duration::from_secs(20))
    });
    assert!(
        matches!(
            result,
            Err(SkillError::ConnectionLost {
                stop_sent: false,
                ..
            })
        ),
        "{result:?}"
    );
    wait_for("watchdog stop", Duration::from_secs(5), || {
        let s = sim.snapshot();
        s.runtime_state == 1 && s.qd.iter().all(|v| v.abs() < 1e-9)
    });
    assert!(sim.snapshot().q[0] < 2.9, "stopped short of the goal");
}

/// Raw protocol-1 exchange (URCL falls back to it): no frequency in `O`, no recipe id in the
/// `O` reply or in data packages. Written with literal bytes, independent of the client.
#[test]
fn protocol_version_1_is_served_in_its_own_layout() {
    let sim = sim_with(|_| {});
    let mut s = TcpStream::connect(sim.ports().rtde).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(2))).unwrap();
    let read = |s: &mut TcpStream| {
        let mut h = [0u8; 3];
        s.read_exact(&mut h).unwrap();
        let mut p = vec![0u8; u16::from_be_bytes([h[0], h[1]]) as usize - 3];
        s.read_exact(&mut p).unwrap();
        (h[2], p)
    };
    s.write_all(&[0, 5, b'V', 0, 1]).unwrap();
    assert_eq!(read(&mut s), (b'V', vec![1]));
    s.write_all(&[0, 3 + 9, b'O']).unwrap();
    s.write_all(b"timestamp").unwrap();
    assert_eq!(read(&mut s), (b'O', b"DOUBLE".to_vec()));
    s.write_all(&[0, 3, b'S']).unwrap();
    assert_eq!(read(&mut s), (b'S', vec![1]));
    let (ty, payload) = read(&mut s);
    assert_eq!(ty, b'U');
    assert_eq!(
        payload.len(),
        8,
        "v1 data package: the double only, no recipe id"
    );
    // An unknown protocol version is refused.
    let mut s2 = TcpStream::connect(sim.ports().rtde).unwrap();
    s2.set_read_timeout(Some(Duration::from_secs(2))).unwrap();
    s2.write_all(&[0, 5, b'V', 0, 9]).unwrap();
    assert_eq!(read(&mut s2), (b'V', vec![0]));
}

#[test]
fn dashboard_pause_and_play_resume_a_move() {
    let sim = sim_with(|_| {});
    let mut d = DashboardClient::connect(sim.ports().dashboard, Duration::from_secs(2)).unwrap();
    let mut s = TcpStream::connect(sim.ports().realtime).unwrap();
    s.write_all(b"def long_move():\n  movej([1.5, -1.2, 1.2, -1.5, -1.5, 0.0], a=2, v=0.5)\nend\n")
        .unwrap();
    wait_for("moving", Duration::from_secs(3), || {
        sim.snapshot().qd[0].abs() > 0.2
    });
    d.pause().unwrap();
    wait_for("paused at rest", Duration::from_secs(3), || {
        let s = sim.snapshot();
        s.runtime_state == 4 && s.qd.iter().all(|v| v.abs() < 1e-9)
    });
    assert!(
        matches!(d.program_state().unwrap(), ProgramState::Paused(name) if name == "long_move")
    );
    let held = sim.snapshot().q[0];
    thread::sleep(Duration::from_millis(100));
    assert_eq!(sim.snapshot().q[0], held, "a paused arm holds still");
    d.play().unwrap();
    wait_for("finished", Duration::from_secs(10), || {
        sim.snapshot().runtime_state == 1
    });
    assert!((sim.snapshot().q[0] - 1.5).abs() < 1e-9);
}

#[test]
fn primary_port_takes_primary_commands_and_scripts() {
    let sim = sim_with(|_| {});
    let mut p = TcpStream::connect(sim.ports().primary).unwrap();
    p.write_all(b"power off\n").unwrap();
    wait_for("powered off", Duration::from_secs(2), || {
        sim.snapshot().robot_mode == 3
    });
    p.write_all(b"power on\n").unwrap();
    wait_for("idle", Duration::from_secs(2), || {
        sim.snapshot().robot_mode == 5
    });
    p.write_all(b"set robotmode run\n").unwrap();
    wait_for("running", Duration::from_secs(2), || {
        sim.snapshot().robot_mode == 7
    });
    p.write_all(b"movej([0.1, -1.5, 1.5, -1.5, -1.5, 0.0], a=1.4, v=1.05)\n")
        .unwrap();
    wait_for("moved", Duration::from_secs(5), || {
        let s = sim.snapshot();
        s.runtime_state == 1 && (s.q[0] - 0.1).abs() < 1e-9
    });
}

#[test]
fn move_linear_targets_the_configured_tool_centre_point() {
    let sim = sim_with(|_| {});
    // A 0.2 m gripper along the flange z axis.
    let tcp = TcpPose::from_array([0.0, 0.0, 0.2, 0.0, 0.0, 0.0]);
    let mut arm = Ur5eArm::connect(ArmConfig {
        tcp_offset: Some(tcp),
        ..arm_config(&sim)
    })
    .unwrap();
    let flange_before = sim.snapshot().tcp_pose;
    // The first motion program sets the TCP; a no-op joint move applies it.
    arm.move_joints(sim.snapshot().q, 1.0, 1.0, Duration::from_secs(5))
        .unwrap();
    arm.update().unwrap();
    let tool = arm.state().tcp_pose;
    let shift = TcpPose::from_array(flange_before).position_distance_m(&tool);
    assert!((shift - 0.2).abs() < 1e-9, "TCP moved by {shift} m");
    let mut goal = tool;
    goal.y_m += 0.05;
    goal.z_m -= 0.05;
    arm.move_linear(goal, 0.2, 1.0, Duration::from_secs(10))
        .unwrap();
    let reached = TcpPose::from_array(sim.snapshot().tcp_pose);
    assert!(reached.position_distance_m(&goal) < 1e-4);
}
