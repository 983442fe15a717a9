//! ur_rtde's register command loop over the wire, in lock-step: a Rust client that speaks
//! ur_rtde's protocol (its recipes, its command codes, its handshake on `output_int_register_0`)
//! uploads a control script on the real-time port and runs moves; the same mission takes the
//! same number of steps however fast the machine is.
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failure panics with its message

use std::io::Write;
use std::net::TcpStream;
use std::time::Duration;

use sim_ur5e::robot::rtde_commands as cmd;
use sim_ur5e::{RTDE_CONTROL_PROGRAM, SimConfig, Stepping, Ur5eSim};
use ur5e::rtde::{DataPackage, InputRecipe, RtdeClient, RtdeTimeouts, RtdeValue};

/// ur_rtde's control script as ur_rtde 1.6 uploads it, cut to the lines the simulator reads:
/// the register offsets ur_rtde injects after their comments, `exec_move_path` with an
/// injected path, and the loop's functions that identify the script.
fn control_script(path: &str) -> String {
    format!(
        "def rtde_control():\n    global reg_offset_float = # float register offset\n0    \
         global reg_offset_int = # int register offset\n0    global force_mode_type = 2\n    \
         def exec_move_path():\n        textmsg(\"exec_move_path\")\n        # inject move path\n{path}    end\n    \
         def signal_ready():\n        write_output_integer_reg(0, 1)\n    end\n    \
         def process_cmd(cmd):\n        return cmd != 255\n    end\n    signal_ready()\nend\n"
    )
}

struct Client {
    rtde: RtdeClient,
    pkg: DataPackage,
    command: InputRecipe,
    clear: InputRecipe,
}

const OUT: [&str; 5] = [
    "robot_status_bits",
    "runtime_state",
    "output_int_register_0",
    "output_int_register_2",
    "actual_q",
];

impl Client {
    fn connect(sim: &Ur5eSim) -> Self {
        let mut rtde = RtdeClient::connect(sim.ports().rtde, RtdeTimeouts::default()).unwrap();
        let recipe = rtde.setup_outputs(&OUT, 500.0).unwrap().clone();
        // ur_rtde's recipe 1 (moves) and its "no command" recipe.
        let command = rtde
            .setup_inputs(&[
                "input_int_register_0",
                "input_double_register_0",
                "input_double_register_1",
                "input_double_register_2",
                "input_double_register_3",
                "input_double_register_4",
                "input_double_register_5",
                "input_double_register_6",
                "input_double_register_7",
                "input_int_register_1",
            ])
            .unwrap();
        let clear = rtde.setup_inputs(&["input_int_register_0"]).unwrap();
        rtde.start().unwrap();
        let mut pkg = DataPackage::for_recipe(&recipe);
        assert!(
            rtde.receive_newest(&mut pkg, Duration::from_secs(1))
                .unwrap()
        );
        Self {
            rtde,
            pkg,
            command,
            clear,
        }
    }

    /// One step of the world; the package of this cycle is in the socket when it returns.
    fn step(&mut self, sim: &Ur5eSim) {
        sim.step().unwrap();
        assert!(
            self.rtde
                .receive_newest(&mut self.pkg, Duration::ZERO)
                .unwrap()
        );
    }

    fn int(&self, i: usize) -> i64 {
        match self.pkg.values[i] {
            RtdeValue::Int32(v) => i64::from(v),
            RtdeValue::Uint32(v) => i64::from(v),
            ref other => panic!("{other:?}"),
        }
    }

    fn state(&self) -> i64 {
        self.int(2)
    }

    fn q(&self) -> [f64; 6] {
        match self.pkg.values[4] {
            RtdeValue::Vector6d(q) => q,
            ref other => panic!("{other:?}"),
        }
    }

    fn send(&mut self, command: i32, d: [f64; 8], async_: i32) {
        let mut v = vec![RtdeValue::Int32(command)];
        v.extend(d.iter().map(|&x| RtdeValue::Double(x)));
        v.push(RtdeValue::Int32(async_));
        let recipe = self.command.clone();
        self.rtde.send_inputs(&recipe, &v).unwrap();
    }

    fn clear(&mut self) {
        let recipe = self.clear.clone();
        self.rtde
            .send_inputs(&recipe, &[RtdeValue::Int32(0)])
            .unwrap();
    }

    /// ur_rtde's `sendCommand`: wait ready, send, wait done, clear, wait ready. Returns the
    /// steps it took.
    fn command(&mut self, sim: &Ur5eSim, command: i32, d: [f64; 8], async_: i32) -> u64 {
        let mut n = 0;
        while self.state() != 1 {
            self.step(sim);
            n += 1;
            assert!(n < 100, "never ready");
        }
        self.send(command, d, async_);
        while self.state() != 2 {
            self.step(sim);
            n += 1;
            assert!(n < 10_000, "command {command} never done");
        }
        self.clear();
        while self.state() != 1 {
            self.step(sim);
            n += 1;
        }
        n
    }
}

const GOAL: [f64; 6] = [0.6, -1.2, 1.3, -1.6, -1.4, 0.3];

fn movej_args(q: [f64; 6]) -> [f64; 8] {
    [q[0], q[1], q[2], q[3], q[4], q[5], 1.05, 1.4]
}

/// Uploads the script, runs a movej and an async path; returns the steps each took and the
/// final joints.
fn mission(pause_wall: bool) -> (u64, u64, [f64; 6]) {
    let sim = Ur5eSim::start(SimConfig {
        stepping: Stepping::External,
        ..SimConfig::ephemeral()
    })
    .unwrap();
    let mut c = Client::connect(&sim);
    let waypoint = [0.2, -1.5, 1.5, -1.5, -1.6, 0.0];
    let path = format!(
        "\tsignal_async_progress(0)\n\tmovej([{}],a=1.4,v=1.05,r=0)\n",
        waypoint.map(|v| v.to_string()).join(",")
    );
    TcpStream::connect(sim.ports().realtime)
        .unwrap()
        .write_all(control_script(&path).as_bytes())
        .unwrap();
    let mut n = 0;
    while c.int(1) != 2 || c.state() != 1 {
        c.step(&sim);
        n += 1;
        assert!(n < 100, "control script not running");
    }
    assert_eq!(c.int(0) & 2, 2, "robot_status_bits: program running");
    assert_eq!(
        sim.with_robot(|r| r.program_name().map(str::to_string)),
        Some(RTDE_CONTROL_PROGRAM.to_string())
    );
    if pause_wall {
        std::thread::sleep(Duration::from_millis(30));
    }
    let movej_steps = c.command(&sim, cmd::MOVEJ, movej_args(GOAL), 0);
    assert!(
        c.q().iter().zip(GOAL).all(|(a, b)| (a - b).abs() < 1e-9),
        "{:?}",
        c.q()
    );
    // Async path: the command returns at once, the progress register reports the waypoint.
    let started = c.command(&sim, cmd::MOVE_PATH, [0.0; 8], 1);
    assert!(started < 10, "async returned after {started} steps");
    let mut path_steps = 0;
    while c.int(3) & 0x8000 != 0 {
        if pause_wall && path_steps % 100 == 0 {
            std::thread::sleep(Duration::from_millis(5));
        }
        c.step(&sim);
        path_steps += 1;
        assert!(path_steps < 10_000);
    }
    assert!(
        c.q()
            .iter()
            .zip(waypoint)
            .all(|(a, b)| (a - b).abs() < 1e-9),
        "{:?} after {path_steps} steps, register {:#x}",
        c.q(),
        c.int(3)
    );
    // stopScript: the program ends.
    c.send(cmd::STOP_SCRIPT, [0.0; 8], 0);
    c.step(&sim);
    c.step(&sim);
    assert_eq!(c.int(1), 1, "runtime state STOPPED");
    (movej_steps, path_steps, c.q())
}

#[test]
fn the_register_loop_runs_in_lock_step_the_same_whatever_the_wall_clock() {
    let (a_movej, a_path, a_q) = mission(false);
    let (b_movej, b_path, b_q) = mission(true);
    assert_eq!((a_movej, a_path), (b_movej, b_path));
    assert_eq!(a_q, b_q);
    assert!(a_movej > 100, "a movej over ~1 rad takes more than 0.2 s");
}
